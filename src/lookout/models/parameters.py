"""Unknown parameters that enter a manipulator's dynamics affinely (Calugi 2002, Property 4.2).

Calugi (2002), master thesis, Lund, Property 4.2 (ch. 4; used by ch. 3's estimator,
ch. 4's adaptive observer and ch. 5's backstepping): for a chosen vector theta of
unknown parameters,

    M(q; theta) psi + C(q, xi; theta) xi + F(theta) xi + G(q; theta)
        = phi0(q, xi, psi) + phi(q, xi, psi) theta                      (Property 4.2)

for all joint positions q, velocities xi and accelerations psi, with the regressor
phi (n x p) and phi0 free of theta. (The viscous friction F is part of the left side
here, because lookout keeps it apart from C; a friction coefficient can then be one of
the unknowns. Coulomb friction is not in the model and enters as an input.)

How the split is computed. An :class:`AffineParameters` says how theta builds the
model (:meth:`AffineParameters.model`); the regressor is the derivative of the left
side with respect to theta (``jax.linearize`` at :attr:`AffineParameters.reference`,
the true values by convention) and phi0 = left(theta_ref) - phi theta_ref. The split
is exact when the left side is affine in theta, which the constructor checks on
concrete values: the left side at random theta, q, xi, psi must equal phi0 + phi theta
to rounding (:meth:`AffineParameters.affine_residual`), or a ValueError names the
parameters that do not enter affinely (a length, say).

Two kinds of parameter set:

* :class:`ModelParameters`: fields of any model, ``("mass",)`` or ``("masses[1]",)``:
  masses, friction coefficients and, for models written in them, inertia constants.
* :class:`PendulumInertia`: the free pendulum in theta = (m l^2, m l), Calugi's ch. 3
  second simulation, where neither m nor l enters affinely but both products do.
"""

# no `from __future__ import annotations` here: equinox reads AbstractVar annotations, and
# refuses them as strings (a stringified one would silently become an ordinary field)

import abc
import operator
import re
from collections.abc import Iterable
from typing import final

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

from lookout import _validation as check
from lookout._math import matvec
from lookout.components import Signal
from lookout.declare import Part, Value, component
from lookout.models.manipulators import FreePendulum, ManipulatorModel

#: Relative residual above which a parameter set is not affine (random points, float64).
AFFINE_TOLERANCE = 1e-9


class AffineParameters(eqx.Module):
    """Unknown parameters theta (p of them) of a manipulator model, entering affinely.

    Subclasses give :meth:`model` (theta -> model), the parameters' names and units,
    and the reference theta; the split and the regressor are computed here.
    """

    reference: eqx.AbstractVar[Array]
    names: eqx.AbstractVar[tuple[str, ...]]
    units: eqx.AbstractVar[tuple[str, ...]]

    @abc.abstractmethod
    def model(self, theta: Array) -> ManipulatorModel:
        """The model with parameters theta (the others as given)."""

    @property
    def size(self) -> int:
        """p, the number of unknown parameters."""
        return len(self.names)

    def left_side(self, theta: Array, q: Array, xi: Array, psi: Array) -> Array:
        """M(q; theta) psi + C(q, xi; theta) xi + F(theta) xi + G(q; theta)."""
        model = self.model(theta)
        return matvec(model.mass_matrix(q), psi) + model.coriolis_force(q, xi) + model.friction_force(xi) + model.gravity(q)

    def split(self, q: Array, xi: Array, psi: Array) -> tuple[Array, Array]:
        """``(phi0, phi)`` of Property 4.2 at (q, xi, psi): shapes (n,) and (n, p)."""
        value, tangent = jax.linearize(lambda theta: self.left_side(theta, q, xi, psi), self.reference)
        phi = jax.vmap(tangent, in_axes=1, out_axes=1)(jnp.eye(self.size))
        return value - matvec(phi, self.reference), phi

    def regressor(self, q: Array, xi: Array, psi: Array) -> Array:
        """phi(q, xi, psi), shape (n, p)."""
        return self.split(q, xi, psi)[1]

    def affine_residual(self, seed: int = 0, samples: int = 8) -> float:
        """Largest relative difference between the left side and phi0 + phi theta over
        random theta (0.5..2 times the reference), q, xi, psi (standard normal)."""
        rng = np.random.default_rng(seed)
        n = self.model(self.reference).size
        thetas = jnp.asarray(np.asarray(self.reference) * rng.uniform(0.5, 2.0, (samples, self.size)))
        q, xi, psi = (jnp.asarray(rng.normal(size=(samples, n))) for _ in range(3))
        return float(_affine_residuals(self, thetas, q, xi, psi))

    def _check_affine(self) -> None:
        if check.is_concrete(self.reference):
            residual = self.affine_residual()
            if not residual <= AFFINE_TOLERANCE:
                raise check.ParameterError(
                    "parameters",
                    f"parameters {', '.join(self.names)} must enter the dynamics affinely (Property 4.2); "
                    f"the split misses the dynamics by {residual:.2g} (relative) at random points",
                )


def parameter_signal_name(name: str) -> str:
    """A parameter's name as an identifier: ``masses[1]`` -> ``masses_1``."""
    return name.replace("[", "_").replace("]", "")


def parameter_signals(parameters: AffineParameters, suffix: str = "", long_prefix: str = "") -> tuple[Signal, ...]:
    """One scalar signal per parameter, named ``<name><suffix>`` in the parameter's unit.

    Raises
    ------
    ValueError
        When a parameter has no unit (``ModelParameters(..., units=...)`` gives them).
    """
    signals = []
    for name, unit in zip(parameters.names, parameters.units):
        if not unit:
            raise ValueError(
                f"parameters.units must give every parameter's unit (UDUNITS, e.g. 'kg'); {name!r} has none: build the parameters with units=(...)"
            )
        signals.append(Signal(f"{parameter_signal_name(name)}{suffix}", unit, f"{long_prefix}parameter {name}"))
    return tuple(signals)


@eqx.filter_jit
def _affine_residuals(parameters: AffineParameters, thetas: Array, q: Array, xi: Array, psi: Array) -> Array:
    """The largest relative residual of the split over the sample rows; one compiled program
    per kind of parameter set, reused by every instance of it."""

    def one(theta, q, xi, psi):
        phi0, phi = parameters.split(q, xi, psi)
        exact = parameters.left_side(theta, q, xi, psi)
        scale = jnp.max(jnp.abs(exact)) + jnp.max(jnp.abs(phi0)) + 1e-300
        return jnp.max(jnp.abs(exact - phi0 - matvec(phi, theta))) / scale

    return jnp.max(jax.vmap(one)(thetas, q, xi, psi))


_FIELD = re.compile(r"^([A-Za-z_][A-Za-z0-9_]*)(?:\[(\d+)\])?$")


def _parse_field(entry: str) -> tuple[str, int | None]:
    match = _FIELD.match(entry)
    if match is None:
        raise check.ParameterError("parameter", f"parameter fields must look like 'mass' or 'masses[1]'; got {entry!r}")
    return match.group(1), None if match.group(2) is None else int(match.group(2))


@component(
    "parameters",
    "model-fields",
    summary="Fields of a model as the unknown parameters theta of Property 4.2.",
    parameters=(
        Part("base", role="model", doc="The model (in a composition, the plant's unless given)."),
        Value("fields", "strings", 'The unknown parameters: scalar fields ("mass") or elements ("masses[1]").'),
        Value("units", "strings", 'One UDUNITS unit per field ("kg"), for the records of theta_hat.'),
    ),
)
@final
class ModelParameters(AffineParameters):
    """Fields of a model as the unknown parameters theta of Property 4.2.

    ``ModelParameters(arm, ("masses[1]",))`` is Calugi's ch. 5 theta = m2,
    ``ModelParameters(pendulum, ("mass",))`` ch. 3's and ch. 4's theta = m. Each entry
    names a scalar field or one element of a vector field; the reference is the model's
    own values. Fields that do not enter affinely (a length) are refused.

    Parameters
    ----------
    base : ManipulatorModel
        The model (in a composition, the plant's unless given).
    fields : sequence of str
        The unknown parameters: scalar fields (``"mass"``) or elements (``"masses[1]"``).
    units : sequence of str, optional
        One UDUNITS unit per field (``"kg"``), for the records of theta_hat.
    """

    base: ManipulatorModel
    reference: Array
    names: tuple[str, ...] = eqx.field(static=True)
    units: tuple[str, ...] = eqx.field(static=True)

    def __init__(self, base: ManipulatorModel, fields: str | Iterable[str], units: Iterable[str] | None = None):
        if not isinstance(base, ManipulatorModel):
            raise check.ParameterError("base", f"base must be a ManipulatorModel; got {type(base).__name__}")
        fields = (fields,) if isinstance(fields, str) else tuple(fields)
        if not fields or len(set(fields)) != len(fields):
            raise check.ParameterError("fields", f"fields must be distinct field names; got {fields}")
        values = []
        for entry in fields:
            name, index = _parse_field(entry)
            if not hasattr(base, name) or name in ("joint_names", "joint_kinds"):
                raise ValueError(f"{type(base).__name__} has no parameter field {name!r}")
            value = jnp.asarray(getattr(base, name))
            if index is None and value.ndim != 0:
                raise check.ParameterError("field", f"field {name!r} of {type(base).__name__} is a vector: name one element, like '{name}[0]'")
            if index is not None and not (value.ndim == 1 and index < value.shape[0]):
                raise check.ParameterError("field", f"field {entry!r}: {name} has shape {value.shape}, so index {index} is out of range")
            values.append(value if index is None else value[index])
        self.base = base
        self.reference = jnp.stack(values).astype(float)
        self.names = fields
        self.units = tuple(units) if units is not None else ("",) * len(fields)
        if len(self.units) != len(fields):
            raise check.ParameterError("units", f"units must give one unit per field; got {len(self.units)} for {len(fields)}")

    def __check_init__(self):
        self._check_affine()

    def model(self, theta: Array) -> ManipulatorModel:
        model = self.base
        for k, entry in enumerate(self.names):
            name, index = _parse_field(entry)
            if index is None:
                model = eqx.tree_at(operator.attrgetter(name), model, theta[k])
            else:
                model = eqx.tree_at(operator.attrgetter(name), model, getattr(model, name).at[index].set(theta[k]))
        return model


@component(
    "parameters",
    "pendulum-inertia",
    summary="The free pendulum in theta = (m l^2, m l) (kg m^2, kg m): M = theta_1, G = theta_2 g sin q, F as given.",
    parameters=(Part("base", role="model", doc="The pendulum whose m l^2 and m l are the unknowns (in a composition, the plant's unless given)."),),
)
@final
class PendulumInertia(AffineParameters):
    """The free pendulum in theta = (m l^2, m l) (kg m^2, kg m): M = theta_1,
    G = theta_2 g sin q, F as given. Calugi (2002), ch. 3, second simulation (3.13) with
    phi = [q'', g sin q] (plus the friction's phi0 = c q').

    Parameters
    ----------
    base : FreePendulum
        The pendulum whose m l^2 and m l are the unknowns (in a composition, the plant's unless given).
    """

    base: FreePendulum  # type: ignore[misc]  # follows the inherited names and units, which have defaults here; __init__ is the class's own
    reference: Array
    names: tuple[str, ...] = eqx.field(static=True, default=("inertia", "moment"))
    units: tuple[str, ...] = eqx.field(static=True, default=("kg m2", "kg m"))

    def __init__(self, base: FreePendulum):
        if not isinstance(base, FreePendulum):
            raise check.ParameterError("base", f"base must be a FreePendulum; got {type(base).__name__}")
        self.base = base
        self.reference = jnp.stack([base.mass * base.length**2, base.mass * base.length])

    def __check_init__(self):
        self._check_affine()

    def model(self, theta: Array) -> FreePendulum:
        inertia, moment = theta[0], theta[1]
        # m = (m l)^2 / (m l^2) and l = (m l^2) / (m l): M = m l^2 = theta_1, G = m l g sin q = theta_2 g sin q
        return FreePendulum(moment**2 / inertia, inertia / moment, self.base.friction, self.base.gravity_acceleration)


__all__ = ["AFFINE_TOLERANCE", "AffineParameters", "ModelParameters", "PendulumInertia", "parameter_signal_name", "parameter_signals"]
