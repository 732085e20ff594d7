"""Rigid-link manipulators in Lagrangian form: pendulum, two-link arm, cart-pendulum, Furuta.

Calugi (2002), master thesis, Lund, chapter 2, eq. (2.1)::

    M(q) q'' + C(q, q') q' + G(q) = tau

with the thesis's viscous friction taken out of C and kept as its own diagonal
matrix F (the thesis folds ``c_i`` into the diagonal of C)::

    M(q) q'' + C(q, q') q' + F q' + G(q) = tau                         (2.1), F apart

Which C. Only the product C(q, q') q' is physics; the matrix C is a choice of
factorization. :meth:`ManipulatorModel.coriolis_matrix` is the Christoffel-symbol
factorization computed from the derivative of M(q) (``jax.jacfwd``)::

    C_kj(q, v) = sum_i 1/2 (dM_kj/dq_i + dM_ki/dq_j - dM_ij/dq_k) v_i

For it, M' - 2C is skew-symmetric and Property 2.2, C(q, a) b = C(q, b) a, holds
(the three-term bracket is symmetric in i and j because M is). The matrices printed
in Section 2.3, friction taken out, are this Christoffel C for the pendulum, the
cart-pendulum and the Furuta pendulum; the two-link arm's is another factorization,
for which Property 2.2 does *not* hold (its (1, 1) entry -2 m2 l1 l2 sin(q2) q2'
gives C(q, a) b != C(q, b) a; the Christoffel one is m2 l1 l2 sin(q2) [[-q2',
-(q1' + q2')], [q1', 0]]). For all four, the printed C(q, q') q' equals the
Christoffel C(q, q') q' + F q' (tested in ``tests/test_manipulators.py``). The
thesis's proof of Theorem 2.1 uses Property 2.2, so the bound C_M of Property 2.3
(:mod:`lookout.analysis.velocity`) is computed for the Christoffel C.

The four systems of Section 2.3, with the printed parameters as defaults (the
thesis writes ``n`` for g in its gravity terms; g = 9.81 m/s^2 here):

* :class:`FreePendulum`: M = m l^2, G = m g l sin q (q from the downward vertical).
* :class:`TwoLinkArm`: point masses at the link ends, angles from the horizontal
  (q2 relative to link 1).
* :class:`CartPendulum` ("pendulum-on-the-coach"): q1 the cart position (m,
  prismatic), q2 the pendulum angle from the upward vertical.
* :class:`FurutaPendulum`: uniform rods plus a point mass m3 at the pendulum's tip,
  pendulum angle from the upward vertical.

Parameters are array fields (vmappable, differentiable); the value checks run on
concrete values only (:mod:`lookout._validation`), so a model can be built inside
``jax.jit`` or ``jax.vmap``.

:class:`ManipulatorPlant` wraps any model as a :class:`lookout.components.Plant`
with state :class:`JointState`.
"""

# no `from __future__ import annotations` here: equinox reads AbstractVar annotations, and
# refuses them as strings (a stringified one would silently become an ordinary field)

import abc
from typing import ClassVar, final

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import numpy.typing as npt
from jax import Array
from jax.typing import ArrayLike

from lookout import _validation as check
from lookout._math import matvec, solve
from lookout.components import JOINT_SPACE, DivergenceBound, Layout, Plant, Signal
from lookout.declare import NON_NEGATIVE, POSITIVE, Part, Value, component, initial_values

#: Standard gravity (m/s^2), the thesis's ``n``.
STANDARD_GRAVITY = 9.81

#: Joint kinds.
REVOLUTE = "revolute"
PRISMATIC = "prismatic"
#: Label dimension of the results for each kind of joint.
JOINT_DIMS = {REVOLUTE: "revolute_joint", PRISMATIC: "prismatic_joint"}

#: (name, units, long name) of each joint quantity, per joint kind; one unit per signal.
JOINT_POSITION = {REVOLUTE: ("joint_angle", "rad", "joint angle"), PRISMATIC: ("joint_position", "m", "joint position")}
JOINT_VELOCITY = {REVOLUTE: ("joint_rate", "rad/s", "joint angular rate"), PRISMATIC: ("joint_speed", "m/s", "joint speed")}
JOINT_INPUT = {REVOLUTE: ("joint_torque", "N m", "joint torque"), PRISMATIC: ("joint_force", "N", "joint force")}
JOINT_MEASUREMENT = {
    REVOLUTE: ("measured_joint_angle", "rad", "measured joint angle (held samples; NaN = dropout)"),
    PRISMATIC: ("measured_joint_position", "m", "measured joint position (held samples; NaN = dropout)"),
}


def joint_groups(joint_names: tuple[str, ...], joint_kinds: tuple[str, ...]) -> list[tuple[str, tuple[str, ...]]]:
    """The joints as runs of one kind, in joint order: ``[(kind, names), ...]``.

    A :class:`~lookout.components.Layout` lays signals end to end, and each signal
    holds the joints of one kind, so the joints of one kind must be contiguous
    (the cart-pendulum's prismatic cart first, then its revolute pendulum, is fine;
    revolute, prismatic, revolute is not).

    Raises
    ------
    ValueError
        When names and kinds differ in number, a kind is unknown, names repeat, or
        the joints of one kind are not contiguous.
    """
    joint_names, joint_kinds = tuple(joint_names), tuple(joint_kinds)
    if len(joint_names) != len(joint_kinds) or not joint_names:
        raise check.ParameterError(
            "joint_names", f"joint_names and joint_kinds must be non-empty and of one length; got {joint_names} and {joint_kinds}"
        )
    if len(set(joint_names)) != len(joint_names):
        raise check.ParameterError("joint_names", f"joint_names must be distinct; got {joint_names}")
    unknown = [kind for kind in joint_kinds if kind not in JOINT_DIMS]
    if unknown:
        raise check.ParameterError("joint_kinds", f"joint_kinds must be {REVOLUTE!r} or {PRISMATIC!r}; got {unknown}")
    groups: list[tuple[str, list[str]]] = []
    for name, kind in zip(joint_names, joint_kinds):
        if groups and groups[-1][0] == kind:
            groups[-1][1].append(name)
        elif any(kind == seen for seen, _ in groups):
            raise ValueError(
                f"the {kind} joints must be contiguous (a Layout lays one signal per joint kind end to end); "
                f"got joint_kinds {joint_kinds}: reorder the joints"
            )
        else:
            groups.append((kind, [name]))
    return [(kind, tuple(names)) for kind, names in groups]


def joint_layout(joint_names: tuple[str, ...], joint_kinds: tuple[str, ...], quantities: dict[str, tuple[str, str, str]]) -> Layout:
    """One signal per joint kind, in joint order, labelled by joint name.

    The one helper by which the plant, the encoder and the velocity observer map a
    joint vector to named signals: ``joint_layout(...).split(vector)``.

    Parameters
    ----------
    joint_names, joint_kinds : tuple of str
        As :attr:`ManipulatorModel.joint_names` and :attr:`ManipulatorModel.joint_kinds`.
    quantities : dict
        ``{kind: (name, units, long_name)}``, e.g. :data:`JOINT_POSITION`.

    Returns
    -------
    Layout
        Signals over the dims ``revolute_joint`` / ``prismatic_joint``; revolute
        joint angles are marked ``angle`` (their differences wrap).
    """
    signals = []
    for kind, names in joint_groups(joint_names, joint_kinds):
        name, units, long_name = quantities[kind]
        is_angle = kind == REVOLUTE and units == "rad"
        signals.append(Signal(name, units, long_name, JOINT_SPACE, names, JOINT_DIMS[kind], angle=is_angle))
    return Layout(tuple(signals))


def _scalar(name: str, value) -> Array:
    """A float scalar parameter, or a ValueError naming it."""
    if check.is_concrete(value) and np.ndim(value) != 0:
        raise check.ParameterError(check.key(name), f"{name} must be a scalar; got shape {np.shape(value)}")
    array = jnp.asarray(value, dtype=float)
    if array.ndim != 0:
        raise check.ParameterError(check.key(name), f"{name} must be a scalar; got shape {array.shape}")
    return array


class ManipulatorModel(eqx.Module):
    """Abstract n-joint rigid manipulator, M(q) q'' + C(q, q') q' + F q' + G(q) = tau.

    Calugi (2002), eq. (2.1), with the viscous friction F = diag(:attr:`friction`)
    kept apart from C. A subclass gives :meth:`mass_matrix`, :meth:`gravity` and
    :meth:`potential_energy` (G is written as printed in the thesis and V from the
    geometry, so that G = dV/dq is a check, not an identity) and the joints' names
    and kinds; everything else is derived here and never overridden.

    Attributes
    ----------
    friction : Array, shape (n,)
        Diagonal of F: viscous friction per joint, N m s/rad (revolute) or N s/m
        (prismatic), >= 0.
    joint_names : tuple of str
        One name per joint (labels of the results).
    joint_kinds : tuple of str
        ``"revolute"`` or ``"prismatic"`` per joint.
    """

    friction: eqx.AbstractVar[Array]
    joint_names: eqx.AbstractClassVar[tuple[str, ...]]
    joint_kinds: eqx.AbstractClassVar[tuple[str, ...]]

    @abc.abstractmethod
    def mass_matrix(self, q: Array) -> Array:
        """M(q), shape (n, n), symmetric positive definite (Property 2.1)."""

    @abc.abstractmethod
    def gravity(self, q: Array) -> Array:
        """G(q), shape (n,): the generalized gravity forces, dV/dq."""

    @abc.abstractmethod
    def potential_energy(self, q: Array) -> Array:
        """V(q), J: gravitational potential energy (zero at a reference configuration)."""

    @property
    def size(self) -> int:
        """Number of joints n."""
        return len(self.joint_names)

    @property
    def revolute(self) -> tuple[bool, ...]:
        """Per joint: True for a revolute joint, False for a prismatic one."""
        return tuple(kind == REVOLUTE for kind in self.joint_kinds)

    def coriolis_matrix(self, q: Array, v: Array) -> Array:
        """C(q, v), the Christoffel-symbol factorization of the Coriolis and centripetal terms.

        ``C_kj = sum_i 1/2 (dM_kj/dq_i + dM_ki/dq_j - dM_ij/dq_k) v_i`` with dM/dq
        from ``jax.jacfwd``. For it M' - 2C is skew-symmetric and C(q, a) b =
        C(q, b) a (Property 2.2). Friction is not in it (see :attr:`friction`).
        """
        dM = jax.jacfwd(self.mass_matrix)(q)  # dM[k, j, i] = dM_kj / dq_i
        christoffel = 0.5 * (dM + jnp.swapaxes(dM, 1, 2) - jnp.transpose(dM, (2, 1, 0)))
        return jnp.sum(christoffel * v, axis=-1)  # sum over i; elementwise, so it fuses

    def coriolis_force(self, q: Array, v: Array) -> Array:
        """C(q, v) v, the same for every factorization of C."""
        return matvec(self.coriolis_matrix(q, v), v)

    def friction_force(self, v: Array) -> Array:
        """F v, the viscous friction forces, plus F_c sign(v) for a model with Coulomb
        friction (an array field ``coulomb_friction``, shape (n,); Calugi 2002 ch. 6's
        Furuta arm). A plant that must stick at v = 0 handles that itself: sign(0) = 0
        here, which is what an observer's model wants (the thesis's sgn x1_hat)."""
        coulomb = getattr(self, "coulomb_friction", None)
        return self.friction * v if coulomb is None else self.friction * v + coulomb * jnp.sign(v)

    def acceleration(self, q: Array, v: Array, tau: Array) -> Array:
        """q'' = M(q)^-1 [tau - C(q, v) v - F v - G(q)] (eq. 2.1, or 2.4)."""
        force = tau - self.coriolis_force(q, v) - self.friction_force(v) - self.gravity(q)
        return solve(self.mass_matrix(q), force)

    def kinetic_energy(self, q: Array, v: Array) -> Array:
        """T = 1/2 v^T M(q) v (J)."""
        return 0.5 * v @ self.mass_matrix(q) @ v

    def energy(self, q: Array, v: Array) -> Array:
        """T + V (J): constant along unforced, frictionless motion."""
        return self.kinetic_energy(q, v) + self.potential_energy(q)


@component(
    "model",
    "pendulum",
    summary="Free pendulum of Calugi (2002), Section 2.3: M = m l^2, G = m g l sin q.",
    parameters=(
        Value("mass", "float", "m, the point mass at the pendulum's end (kg); Section 2.3: 0.5.", range=POSITIVE),
        Value("length", "float", "l, the distance of the mass from the pivot (m); Section 2.3: 0.5.", range=POSITIVE),
        Value("friction", "float", "c, the viscous friction at the pivot (N m s/rad); Section 2.3: 0.1.", range=NON_NEGATIVE),
        Value("gravity_acceleration", "float", "g (m/s^2); 9.81, the thesis's n.", range=NON_NEGATIVE),
    ),
)
@final
class FreePendulum(ManipulatorModel):
    """Free pendulum of Calugi (2002), Section 2.3: M = m l^2, G = m g l sin q.

    q is measured from the downward vertical (q = 0 hangs at rest); the thesis's
    C = c is the friction here, and the Christoffel C is zero (M is constant).
    Defaults are the printed parameters.

    Parameters
    ----------
    mass : float, positive
        m, the point mass at the pendulum's end (kg); Section 2.3: 0.5.
    length : float, positive
        l, the distance of the mass from the pivot (m); Section 2.3: 0.5.
    friction : float, non-negative
        c, the viscous friction at the pivot (N m s/rad); Section 2.3: 0.1.
    gravity_acceleration : float, non-negative
        g (m/s^2); 9.81, the thesis's n.
    """

    mass: Array
    length: Array
    friction: Array
    gravity_acceleration: Array
    joint_names: ClassVar[tuple[str, ...]] = ("pendulum",)
    joint_kinds: ClassVar[tuple[str, ...]] = (REVOLUTE,)

    def __init__(
        self, mass: ArrayLike = 0.5, length: ArrayLike = 0.5, friction: npt.ArrayLike = 0.1, gravity_acceleration: ArrayLike = STANDARD_GRAVITY
    ):
        self.mass = _scalar("pendulum mass", mass)
        self.length = _scalar("pendulum length", length)
        self.friction = jnp.asarray(check.vector("pendulum friction", friction, 1))
        self.gravity_acceleration = _scalar("gravity_acceleration", gravity_acceleration)

    def __check_init__(self):
        check.positive("pendulum mass", self.mass)
        check.positive("pendulum length", self.length)
        check.positive("pendulum friction", self.friction, allow_zero=True)
        check.positive("gravity_acceleration", self.gravity_acceleration, allow_zero=True)

    def mass_matrix(self, q: Array) -> Array:
        """M = m l^2."""
        del q
        return jnp.reshape(self.mass * self.length**2, (1, 1))

    def gravity(self, q: Array) -> Array:
        """G = m g l sin q (the thesis's ``mnl sin(q)``)."""
        return self.mass * self.gravity_acceleration * self.length * jnp.sin(q)

    def potential_energy(self, q: Array) -> Array:
        """V = m g l (1 - cos q)."""
        return self.mass * self.gravity_acceleration * self.length * (1.0 - jnp.cos(q[0]))


@component(
    "model",
    "two-link-arm",
    summary="Two-link planar arm of Calugi (2002), Section 2.3, with point masses at the link ends.",
    parameters=(
        Value(
            "masses", "array", "m1, m2: the point masses at the ends of links 1 and 2 (kg); Section 2.3: (0.5, 0.7).", shape="(2,)", range=POSITIVE
        ),
        Value("lengths", "array", "l1, l2: the links' lengths (m); Section 2.3: (1, 1.5).", shape="(2,)", range=POSITIVE),
        Value(
            "friction", "array", "c1, c2: the viscous friction at the joints (N m s/rad); Section 2.3: (0.5, 0.1).", shape="(2,)", range=NON_NEGATIVE
        ),
        Value("gravity_acceleration", "float", "g (m/s^2); 9.81, the thesis's n.", range=NON_NEGATIVE),
    ),
)
@final
class TwoLinkArm(ManipulatorModel):
    """Two-link planar arm of Calugi (2002), Section 2.3, with point masses at the link ends.

    q1 is the first link's angle from the horizontal, q2 the second link's angle
    relative to the first; M and G are the printed ones. Defaults are the printed
    parameters.

    Parameters
    ----------
    masses : array_like, shape (2,), positive
        m1, m2: the point masses at the ends of links 1 and 2 (kg); Section 2.3: (0.5, 0.7).
    lengths : array_like, shape (2,), positive
        l1, l2: the links' lengths (m); Section 2.3: (1, 1.5).
    friction : array_like, shape (2,), non-negative
        c1, c2: the viscous friction at the joints (N m s/rad); Section 2.3: (0.5, 0.1).
    gravity_acceleration : float, non-negative
        g (m/s^2); 9.81, the thesis's n.
    """

    masses: Array
    lengths: Array
    friction: Array
    gravity_acceleration: Array
    joint_names: ClassVar[tuple[str, ...]] = ("shoulder", "elbow")
    joint_kinds: ClassVar[tuple[str, ...]] = (REVOLUTE, REVOLUTE)

    def __init__(
        self,
        masses: npt.ArrayLike = (0.5, 0.7),
        lengths: npt.ArrayLike = (1.0, 1.5),
        friction: npt.ArrayLike = (0.5, 0.1),
        gravity_acceleration: ArrayLike = STANDARD_GRAVITY,
    ):
        self.masses = jnp.asarray(check.vector("two-link masses", masses, 2))
        self.lengths = jnp.asarray(check.vector("two-link lengths", lengths, 2))
        self.friction = jnp.asarray(check.vector("two-link friction", friction, 2))
        self.gravity_acceleration = _scalar("gravity_acceleration", gravity_acceleration)

    def __check_init__(self):
        check.positive("two-link masses", self.masses)
        check.positive("two-link lengths", self.lengths)
        check.positive("two-link friction", self.friction, allow_zero=True)
        check.positive("gravity_acceleration", self.gravity_acceleration, allow_zero=True)

    def mass_matrix(self, q: Array) -> Array:
        """The printed M(q) of Section 2.3."""
        m1, m2 = self.masses
        l1, l2 = self.lengths
        c2 = jnp.cos(q[1])
        m22 = m2 * l2**2
        m12 = m22 + m2 * l1 * l2 * c2
        m11 = m22 + 2.0 * m2 * l1 * l2 * c2 + (m1 + m2) * l1**2
        return jnp.array([[m11, m12], [m12, m22]])

    def gravity(self, q: Array) -> Array:
        """The printed G(q): [m2 l2 g cos(q1 + q2) + (m1 + m2) l1 g cos q1, m2 l2 g cos(q1 + q2)]."""
        m1, m2 = self.masses
        l1, l2 = self.lengths
        g = self.gravity_acceleration
        outer = m2 * l2 * g * jnp.cos(q[0] + q[1])
        return jnp.array([outer + (m1 + m2) * l1 * g * jnp.cos(q[0]), outer])

    def potential_energy(self, q: Array) -> Array:
        """V = g [m1 l1 sin q1 + m2 (l1 sin q1 + l2 sin(q1 + q2))], heights of the point masses."""
        m1, m2 = self.masses
        l1, l2 = self.lengths
        elbow_height = l1 * jnp.sin(q[0])
        tip_height = elbow_height + l2 * jnp.sin(q[0] + q[1])
        return self.gravity_acceleration * (m1 * elbow_height + m2 * tip_height)


@component(
    "model",
    "printed-inertia-arm",
    summary="The two-link arm with M_22 = printed_mass l2^2, whatever the mass parameter m2 is.",
    parameters=(
        Value("masses", "array", "m1, m2 (kg) of M_11, M_12 and G, as in two-link-arm.", shape="(2,)"),
        Value("lengths", "array", "l1, l2 (m).", shape="(2,)"),
        Value("friction", "array", "c1, c2 (N m s/rad).", shape="(2,)"),
        Value("gravity_acceleration", "float", "g (m/s^2)."),
        Value("printed_mass", "float", "The mass of M_22 = printed_mass l2^2 (kg), whatever masses[1] is."),
    ),
)
@final
class PrintedInertiaArm(ManipulatorModel):
    """The two-link arm with M_22 = printed_mass l2^2, whatever the mass parameter m2 is.

    M_11, M_12, G and the Christoffel C (M_22 is constant either way) are those of
    :class:`TwoLinkArm` with ``masses``; only M_22 keeps a mass of its own. As the model
    of an observer that estimates m2, it is an inertia matrix printed with the true m2 in
    M_22: Calugi (2002)'s (5.37), whose ``printed`` case
    :mod:`lookout.papers.calugi_2002_backstepping` runs. Defaults are those of
    :class:`TwoLinkArm`.

    Parameters
    ----------
    masses : array_like, shape (2,)
        m1, m2 (kg) of M_11, M_12 and G, as in two-link-arm.
    lengths : array_like, shape (2,)
        l1, l2 (m).
    friction : array_like, shape (2,)
        c1, c2 (N m s/rad).
    gravity_acceleration : float
        g (m/s^2).
    printed_mass : float
        The mass of M_22 = printed_mass l2^2 (kg), whatever ``masses[1]`` is.
    """

    masses: Array
    lengths: Array
    friction: Array
    gravity_acceleration: Array
    printed_mass: Array
    joint_names: ClassVar[tuple[str, ...]] = TwoLinkArm.joint_names
    joint_kinds: ClassVar[tuple[str, ...]] = (REVOLUTE, REVOLUTE)

    def __init__(
        self,
        masses: npt.ArrayLike = (0.5, 0.7),
        lengths: npt.ArrayLike = (1.0, 1.5),
        friction: npt.ArrayLike = (0.5, 0.1),
        gravity_acceleration: float = STANDARD_GRAVITY,
        *,
        printed_mass: float,
    ):
        self.masses = jnp.asarray(check.vector("two-link masses", masses, 2))
        self.lengths = jnp.asarray(check.vector("two-link lengths", lengths, 2))
        self.friction = jnp.asarray(check.vector("two-link friction", friction, 2))
        self.gravity_acceleration = jnp.asarray(float(gravity_acceleration))
        self.printed_mass = jnp.asarray(float(printed_mass))

    def _arm(self) -> TwoLinkArm:
        return TwoLinkArm(self.masses, self.lengths, self.friction, self.gravity_acceleration)

    def mass_matrix(self, q: Array) -> Array:
        """TwoLinkArm's M(q) with M_22 = printed_mass l2^2."""
        return self._arm().mass_matrix(q).at[1, 1].set(self.printed_mass * self.lengths[1] ** 2)

    def gravity(self, q: Array) -> Array:
        return self._arm().gravity(q)

    def potential_energy(self, q: Array) -> Array:
        return self._arm().potential_energy(q)


@component(
    "model",
    "cart-pendulum",
    summary='Inverted pendulum on a cart ("pendulum-on-the-coach"), Calugi (2002), Section 2.3.',
    parameters=(
        Value("cart_mass", "float", "m1, the cart's mass (kg); Section 2.3: 2.", range=POSITIVE),
        Value("pendulum_mass", "float", "m2, the point mass at the pendulum's end (kg); Section 2.3: 0.2.", range=POSITIVE),
        Value("pendulum_length", "float", "l, the distance of m2 from the pivot on the cart (m); Section 2.3: 0.5.", range=POSITIVE),
        Value(
            "friction",
            "array",
            "c1 (N s/m), the cart's viscous friction, and c2 (N m s/rad), the pivot's; Section 2.3: (0.4, 0.1).",
            shape="(2,)",
            range=NON_NEGATIVE,
        ),
        Value("gravity_acceleration", "float", "g (m/s^2); 9.81, the thesis's n.", range=NON_NEGATIVE),
    ),
)
@final
class CartPendulum(ManipulatorModel):
    """Inverted pendulum on a cart ("pendulum-on-the-coach"), Calugi (2002), Section 2.3.

    q1 is the cart position (m, a prismatic joint), q2 the pendulum angle from the
    upward vertical (a point mass m2 at distance l)::

        M = [[m1 + m2, m2 l cos q2], [m2 l cos q2, m2 l^2]],   G = [0, -m2 l g sin q2]

    Defaults are the printed parameters.

    Parameters
    ----------
    cart_mass : float, positive
        m1, the cart's mass (kg); Section 2.3: 2.
    pendulum_mass : float, positive
        m2, the point mass at the pendulum's end (kg); Section 2.3: 0.2.
    pendulum_length : float, positive
        l, the distance of m2 from the pivot on the cart (m); Section 2.3: 0.5.
    friction : array_like, shape (2,), non-negative
        c1 (N s/m), the cart's viscous friction, and c2 (N m s/rad), the pivot's; Section 2.3: (0.4, 0.1).
    gravity_acceleration : float, non-negative
        g (m/s^2); 9.81, the thesis's n.
    """

    cart_mass: Array
    pendulum_mass: Array
    pendulum_length: Array
    friction: Array
    gravity_acceleration: Array
    joint_names: ClassVar[tuple[str, ...]] = ("cart", "pendulum")
    joint_kinds: ClassVar[tuple[str, ...]] = (PRISMATIC, REVOLUTE)

    def __init__(
        self,
        cart_mass: ArrayLike = 2.0,
        pendulum_mass: ArrayLike = 0.2,
        pendulum_length: ArrayLike = 0.5,
        friction: npt.ArrayLike = (0.4, 0.1),
        gravity_acceleration: ArrayLike = STANDARD_GRAVITY,
    ):
        self.cart_mass = _scalar("cart_mass", cart_mass)
        self.pendulum_mass = _scalar("pendulum_mass", pendulum_mass)
        self.pendulum_length = _scalar("pendulum_length", pendulum_length)
        self.friction = jnp.asarray(check.vector("cart-pendulum friction", friction, 2))
        self.gravity_acceleration = _scalar("gravity_acceleration", gravity_acceleration)

    def __check_init__(self):
        check.positive("cart_mass", self.cart_mass)
        check.positive("pendulum_mass", self.pendulum_mass)
        check.positive("pendulum_length", self.pendulum_length)
        check.positive("cart-pendulum friction", self.friction, allow_zero=True)
        check.positive("gravity_acceleration", self.gravity_acceleration, allow_zero=True)

    def mass_matrix(self, q: Array) -> Array:
        """The printed M(q) (independent of the cart position q1)."""
        m1, m2, l = self.cart_mass, self.pendulum_mass, self.pendulum_length
        coupling = m2 * l * jnp.cos(q[1])
        return jnp.array([[m1 + m2, coupling], [coupling, m2 * l**2]])

    def gravity(self, q: Array) -> Array:
        """The printed G(q) = [0, -m2 l g sin q2]."""
        m2, l, g = self.pendulum_mass, self.pendulum_length, self.gravity_acceleration
        return jnp.array([jnp.zeros_like(q[1]), -m2 * l * g * jnp.sin(q[1])])

    def potential_energy(self, q: Array) -> Array:
        """V = m2 g l cos q2 (height of the pendulum mass above the pivot)."""
        return self.pendulum_mass * self.gravity_acceleration * self.pendulum_length * jnp.cos(q[1])


@component(
    "model",
    "furuta-pendulum",
    summary="Furuta (rotary) pendulum of Calugi (2002), Section 2.3.",
    parameters=(
        Value("pillar_inertia", "float", "J, the pillar's moment of inertia about its axis (kg m^2); Section 2.3: 1.", range=POSITIVE),
        Value("arm_mass", "float", "m1, the horizontal arm's mass, a uniform rod (kg); Section 2.3: 0.4.", range=POSITIVE),
        Value("pendulum_mass", "float", "m2, the pendulum's mass, a uniform rod (kg); Section 2.3: 0.1.", range=POSITIVE),
        Value("tip_mass", "float", "m3, the point mass at the pendulum's tip (kg); Section 2.3: 0.5.", range=NON_NEGATIVE),
        Value("arm_length", "float", "l1, the arm's length (m); Section 2.3: 0.7.", range=POSITIVE),
        Value("pendulum_length", "float", "l2, the pendulum's length (m); Section 2.3: 0.5.", range=POSITIVE),
        Value(
            "friction",
            "array",
            "c1, c2: the viscous friction of the arm and the pendulum (N m s/rad); Section 2.3: (0.4, 0.2).",
            shape="(2,)",
            range=NON_NEGATIVE,
        ),
        Value("gravity_acceleration", "float", "g (m/s^2); 9.81, the thesis's n.", range=NON_NEGATIVE),
    ),
)
@final
class FurutaPendulum(ManipulatorModel):
    """Furuta (rotary) pendulum of Calugi (2002), Section 2.3.

    q1 is the horizontal arm's angle about the pillar, q2 the pendulum's angle from
    the upward vertical. With uniform rods (arm m1, l1; pendulum m2, l2), a point
    mass m3 at the pendulum's tip and pillar inertia J::

        alpha = J + (m3 + m1/3 + m2) l1^2,   beta = (m3 + m2/3) l2^2,
        gamma = (m3 + m2/2) l1 l2,           delta = (m3 + m2/2) g l2,
        M = [[alpha + beta sin^2 q2, gamma cos q2], [gamma cos q2, beta]],
        G = [0, -delta sin q2]

    Defaults are the printed parameters.

    Parameters
    ----------
    pillar_inertia : float, positive
        J, the pillar's moment of inertia about its axis (kg m^2); Section 2.3: 1.
    arm_mass : float, positive
        m1, the horizontal arm's mass, a uniform rod (kg); Section 2.3: 0.4.
    pendulum_mass : float, positive
        m2, the pendulum's mass, a uniform rod (kg); Section 2.3: 0.1.
    tip_mass : float, non-negative
        m3, the point mass at the pendulum's tip (kg); Section 2.3: 0.5.
    arm_length : float, positive
        l1, the arm's length (m); Section 2.3: 0.7.
    pendulum_length : float, positive
        l2, the pendulum's length (m); Section 2.3: 0.5.
    friction : array_like, shape (2,), non-negative
        c1, c2: the viscous friction of the arm and the pendulum (N m s/rad); Section 2.3: (0.4, 0.2).
    gravity_acceleration : float, non-negative
        g (m/s^2); 9.81, the thesis's n.
    """

    pillar_inertia: Array
    arm_mass: Array
    pendulum_mass: Array
    tip_mass: Array
    arm_length: Array
    pendulum_length: Array
    friction: Array
    gravity_acceleration: Array
    joint_names: ClassVar[tuple[str, ...]] = ("arm", "pendulum")
    joint_kinds: ClassVar[tuple[str, ...]] = (REVOLUTE, REVOLUTE)

    def __init__(
        self,
        pillar_inertia: ArrayLike = 1.0,
        arm_mass: ArrayLike = 0.4,
        pendulum_mass: ArrayLike = 0.1,
        tip_mass: ArrayLike = 0.5,
        arm_length: ArrayLike = 0.7,
        pendulum_length: ArrayLike = 0.5,
        friction: npt.ArrayLike = (0.4, 0.2),
        gravity_acceleration: ArrayLike = STANDARD_GRAVITY,
    ):
        self.pillar_inertia = _scalar("pillar_inertia", pillar_inertia)
        self.arm_mass = _scalar("arm_mass", arm_mass)
        self.pendulum_mass = _scalar("pendulum_mass", pendulum_mass)
        self.tip_mass = _scalar("tip_mass", tip_mass)
        self.arm_length = _scalar("arm_length", arm_length)
        self.pendulum_length = _scalar("pendulum_length", pendulum_length)
        self.friction = jnp.asarray(check.vector("Furuta friction", friction, 2))
        self.gravity_acceleration = _scalar("gravity_acceleration", gravity_acceleration)

    def __check_init__(self):
        check.positive("pillar_inertia", self.pillar_inertia)
        check.positive("arm_mass", self.arm_mass)
        check.positive("pendulum_mass", self.pendulum_mass)
        check.positive("tip_mass", self.tip_mass, allow_zero=True)
        check.positive("arm_length", self.arm_length)
        check.positive("pendulum_length", self.pendulum_length)
        check.positive("Furuta friction", self.friction, allow_zero=True)
        check.positive("gravity_acceleration", self.gravity_acceleration, allow_zero=True)

    def inertia_constants(self) -> tuple[Array, Array, Array, Array]:
        """(alpha, beta, gamma, delta) of Section 2.3."""
        m1, m2, m3 = self.arm_mass, self.pendulum_mass, self.tip_mass
        l1, l2 = self.arm_length, self.pendulum_length
        alpha = self.pillar_inertia + (m3 + m1 / 3.0 + m2) * l1**2
        beta = (m3 + m2 / 3.0) * l2**2
        gamma = (m3 + m2 / 2.0) * l1 * l2
        delta = (m3 + m2 / 2.0) * self.gravity_acceleration * l2
        return alpha, beta, gamma, delta

    def mass_matrix(self, q: Array) -> Array:
        """The printed M(q) (independent of the arm angle q1)."""
        alpha, beta, gamma, _ = self.inertia_constants()
        coupling = gamma * jnp.cos(q[1])
        return jnp.array([[alpha + beta * jnp.sin(q[1]) ** 2, coupling], [coupling, beta]])

    def gravity(self, q: Array) -> Array:
        """The printed G(q) = [0, -delta sin q2]."""
        delta = self.inertia_constants()[3]
        return jnp.array([jnp.zeros_like(q[1]), -delta * jnp.sin(q[1])])

    def potential_energy(self, q: Array) -> Array:
        """V = delta cos q2 (centre of mass of pendulum rod and tip mass above the arm)."""
        return self.inertia_constants()[3] * jnp.cos(q[1])


class JointState(eqx.Module):
    """State of a manipulator: joint coordinates and their rates.

    Attributes
    ----------
    q : Array, shape (n,)
        Joint coordinates: angles (rad, not wrapped) and positions (m), in joint order.
    qdot : Array, shape (n,)
        Their time derivatives (rad/s, m/s).
    """

    q: Array
    qdot: Array


@component(
    "plant",
    "manipulator",
    summary="A ManipulatorModel as a continuous-time plant with state JointState.",
    parameters=(
        Part("model", "The true manipulator (it may differ from the observer's and controller's model)."),
        Value(
            "force_noise",
            "array",
            "Standard deviation of the white force disturbance per joint (N m sqrt(s) or N sqrt(s)); default 0, none.",
            shape="(n,)",
            range=NON_NEGATIVE,
        ),
    ),
)
@final
class ManipulatorPlant(Plant):
    """A :class:`ManipulatorModel` as a continuous-time plant with state :class:`JointState`.

    ``q' = qdot``, ``qdot' = M^-1 [u + sigma w - C(q, qdot) qdot - F qdot - G(q)]``,
    with u the joint torques and forces in joint order (:attr:`input_layout`) and
    w unit white noise of size n (the engine scales it by ``1/sqrt(step)``), so
    ``sigma w`` is a white generalized-force disturbance of intensity
    ``force_noise`` (N m sqrt(s) or N sqrt(s)).

    Joint angles are not wrapped (:meth:`normalize` is the identity): the models
    depend on the angles only through sines and cosines, so wrapping would not
    change the motion, but a measured angle that jumps by 2 pi would make the
    reduced-order velocity observer's estimate ``z + K q`` jump by 2 pi K, and an
    incremental encoder counts turns (a Furuta arm that turns twice is at 4 pi).

    Parameters
    ----------
    model : ManipulatorModel
        The true manipulator (it may differ from the observer's and controller's model).
    force_noise : float or array_like, shape (n,), non-negative
        Standard deviation of the white force disturbance per joint (N m sqrt(s) or
        N sqrt(s)); default 0, none.

    Raises
    ------
    ValueError
        When the joints of one kind are not contiguous (see :func:`joint_groups`).
    """

    #: a failed run: a joint-rate error of 100 rad/s (about 950 rpm): beyond any arm's motion
    divergence: ClassVar[DivergenceBound] = DivergenceBound("joint_rate", 100.0)

    model: ManipulatorModel
    force_noise: Array
    noise_size: int = eqx.field(static=True)
    input_layout: Layout = eqx.field(static=True)
    variable_signals: tuple[Signal, ...] = eqx.field(static=True)
    position_layout: Layout = eqx.field(static=True)
    velocity_layout: Layout = eqx.field(static=True)

    def __init__(self, model: ManipulatorModel, force_noise: npt.ArrayLike = 0.0):
        if not isinstance(model, ManipulatorModel):
            raise check.ParameterError("model", f"model must be a ManipulatorModel; got {type(model).__name__}")
        n = model.size
        names, kinds = model.joint_names, model.joint_kinds
        self.model = model
        self.force_noise = jnp.asarray(check.vector("force_noise", force_noise, n))
        self.noise_size = n
        self.input_layout = joint_layout(names, kinds, JOINT_INPUT)
        self.position_layout = joint_layout(names, kinds, JOINT_POSITION)
        self.velocity_layout = joint_layout(names, kinds, JOINT_VELOCITY)
        self.variable_signals = self.position_layout.signals + self.velocity_layout.signals

    def __check_init__(self):
        check.positive("force_noise", self.force_noise, allow_zero=True)

    def vector_field(self, t: ArrayLike, x: JointState, u: Array, w: Array) -> JointState:
        """(q', qdot') of eq. (2.1) with friction F and the force disturbance."""
        del t
        tau = u + self.force_noise * w
        return JointState(x.qdot, self.model.acceleration(x.q, x.qdot, tau))

    @initial_values(
        Value(
            "q",
            "array",
            "Joint coordinates in joint order (rad, m; zeros when not given; an observer's guess takes it from the first measurement).",
            shape="(n,)",
        ),
        Value("qdot", "array", "Their rates (rad/s, m/s).", shape="(n,)"),
    )
    def state(self, q: npt.ArrayLike | None = None, qdot: npt.ArrayLike = 0.0) -> JointState:
        """A state of this plant (zeros where not given): a composition's ``[plant.initial]``.

        Parameters
        ----------
        q : array_like, shape (n,), optional
            Joint coordinates in joint order (rad, m; zeros when not given; an observer's guess takes it from the first measurement).
        qdot : array_like, shape (n,)
            Their rates (rad/s, m/s).
        """
        n = self.model.size
        return JointState(jnp.asarray(check.vector("q", 0.0 if q is None else q, n)), jnp.asarray(check.vector("qdot", qdot, n)))

    def models(self) -> tuple:
        """The manipulator model (M, C, F, G)."""
        return (self.model,)

    def normalize(self, x: JointState) -> JointState:
        """The identity: joint angles are not wrapped (see the class docstring)."""
        return x

    def variables(self, x: JointState) -> dict[str, Array]:
        """``joint_angle`` / ``joint_position`` and ``joint_rate`` / ``joint_speed`` by joint name."""
        return {**self.position_layout.split(x.q), **self.velocity_layout.split(x.qdot)}

    def realize(self, key: Array) -> "ManipulatorPlant":
        """No per-run randomness beyond the white noise: the plant itself."""
        del key
        return self


# ---------------------------------------------------------------- configurations

#: Random configurations at which the dependence of M on each coordinate is probed.
PROBE_CONFIGURATIONS = 16


def configuration_angles(model: ManipulatorModel) -> tuple[int, ...]:
    """Indices of the revolute joints whose angle M(q) depends on.

    Probed at :data:`PROBE_CONFIGURATIONS` fixed pseudo-random configurations (angles
    in [-pi, pi), prismatic coordinates in [-10, 10]).

    Raises
    ------
    ValueError
        When M(q) depends on a prismatic coordinate (its range is unbounded, so the
        bounds of Properties 2.1 and 2.3 are not defined over it).
    """
    rng = np.random.default_rng(20020)
    n = model.size
    scale = np.where(np.array(model.revolute), np.pi, 10.0)
    q = rng.uniform(-1.0, 1.0, size=(PROBE_CONFIGURATIONS, n)) * scale
    probe = jax.jit(jax.vmap(lambda c: (model.mass_matrix(c), jax.jacfwd(model.mass_matrix)(c))))
    inertia, derivative = (np.asarray(a) for a in probe(jnp.asarray(q)))  # derivative[probe, k, j, i]
    sensitivity = np.abs(derivative).max(axis=(0, 1, 2))
    scale_of_m = max(float(np.abs(inertia).max()), np.finfo(float).tiny)
    depends = sensitivity > 1e-12 * scale_of_m
    for i, kind in enumerate(model.joint_kinds):
        if kind == PRISMATIC and depends[i]:
            raise ValueError(
                f"M(q) depends on the prismatic coordinate of joint {model.joint_names[i]!r}: "
                "the bounds M_m, C_M over an unbounded coordinate are not defined"
            )
    return tuple(i for i, kind in enumerate(model.joint_kinds) if kind == REVOLUTE and depends[i])


def configuration_grid(model: ManipulatorModel, angles: tuple[int, ...], grid_points: int) -> np.ndarray:
    """Configurations: the given angles on a grid over [-pi, pi), the others 0."""
    if not (isinstance(grid_points, int) and grid_points >= 2):
        raise check.ParameterError("grid_points", f"grid_points must be an integer >= 2; got {grid_points!r}")
    if grid_points ** len(angles) > 2_000_000:
        raise check.ParameterError("grid_points", f"a grid of {grid_points}^{len(angles)} configurations is too large; lower grid_points")
    axis = -np.pi + 2.0 * np.pi * np.arange(grid_points) / grid_points
    mesh = np.meshgrid(*([axis] * len(angles)), indexing="ij")
    q = np.zeros((grid_points ** len(angles), model.size))
    for column, index in enumerate(angles):
        q[:, index] = mesh[column].ravel()
    return q
