"""The component contract: what every plant, sensor, observer, reference, controller
and actuator provides, and the labelled signals they exchange.

Every component is an ``equinox.Module``: a frozen dataclass and a JAX PyTree whose
arrays (parameters, gains) can be vmapped and differentiated, and whose static
fields (sizes, labels, periods) fix the structure of the compiled loop. The classes
here are abstract; every implementation is final (it is not subclassed again, and
overrides nothing concrete).

Signals
-------
A :class:`Signal` names one physical quantity with one unit (so that a NetCDF
variable has one unit that CF tools parse): a scalar (``heading``, rad) or a vector
whose components share the unit (``position`` over ``north, east``, m). A
:class:`Layout` lays several signals end to end in one flat vector, as a sensor's
measurement or a plant's input is passed around; ``split`` gives them back by name.

The sample loop (see :mod:`lookout.sim`)
----------------------------------------
At sample k, time t_k::

    y_k   = sensor.sample(t_k, x(t_k), normals)     channels not due hold their last sample
    S     = observer.update(S, t_k, y_k)            correction (discrete observers)
    e_k   = observer.output(S, y_k)                 labelled estimate at t_k
    R, r_k = reference.step(R, t_k, dt, normals)
    C, u_k = controller.step(C, t_k, y_k, e_k, r_k, dt)
    A, v_k = actuator.step(A, t_k, u_k, dt)         applied input (and actuator outputs a_k)
    record (truth, e_k, y_k, r_k, u_k, v_k, a_k)
    x(t_k+1) = integrate plant.vector_field(t, x, v_k, w) over [t_k, t_k+1]
    S     = observer.predict(S, t_k, y_k, v_k, dt)
"""

# no `from __future__ import annotations` here: equinox reads AbstractVar annotations, and
# refuses them as strings (a stringified one would silently become an ordinary field)
import abc
from dataclasses import dataclass, field
from typing import Any, ClassVar, NamedTuple, TypeVar, cast

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jax import Array
from jax.typing import ArrayLike

#: Frames a signal can be expressed in (free text is allowed; these are the common ones).
EARTH_FIXED = "Earth-fixed"
BODY_FIXED = "body-fixed"
JOINT_SPACE = "joint space"


#: A flat vector split by a :class:`Layout`: a JAX array, or a NumPy one (results).
_Vector = TypeVar("_Vector", Array, np.ndarray)


@dataclass(frozen=True)
class Signal:
    """One physical quantity with one unit: a scalar or a vector of labelled components.

    Parameters
    ----------
    name : str
        Variable name in the results (``position``); an observer's estimate of a
        plant variable has the same name, and the results add ``_hat``.
    units : str
        One unit that UDUNITS parses (``m``, ``rad/s``, ``N m``, ``1``).
    long_name : str
        Human-readable description.
    frame : str
        ``"Earth-fixed"``, ``"body-fixed"``, ``"joint space"`` or ``""``.
    labels : tuple of str
        Component labels (``("north", "east")``); empty for a scalar.
    dim : str, optional
        Name of the label dimension in the results; signals that share a ``dim``
        must share its labels. Required for a vector, absent for a scalar.
    angle : bool
        An angle: differences go through ``ssa`` (estimation errors).
    """

    name: str
    units: str
    long_name: str
    frame: str = ""
    labels: tuple[str, ...] = ()
    dim: str | None = None
    angle: bool = False

    def __post_init__(self) -> None:
        if not all(part.isidentifier() for part in self.name.split(".")):
            raise ValueError(f"Signal name must be an identifier, or identifiers joined by dots (a suite's sensor.signal); got {self.name!r}")
        if not self.units:
            raise ValueError(f"Signal {self.name!r} needs a unit ('1' if dimensionless)")
        if bool(self.labels) != (self.dim is not None):
            raise ValueError(f"Signal {self.name!r}: give labels and dim together (a vector), or neither (a scalar)")
        if len(set(self.labels)) != len(self.labels):
            raise ValueError(f"Signal {self.name!r}: labels must be distinct; got {self.labels}")

    @property
    def size(self) -> int:
        """Number of components (1 for a scalar)."""
        return max(1, len(self.labels))

    @property
    def shape(self) -> tuple[int, ...]:
        """Shape of one sample: () for a scalar, (n,) for a vector."""
        return (len(self.labels),) if self.labels else ()

    def renamed(self, name: str, long_name: str | None = None) -> "Signal":
        """The same quantity under another name (an innovation, a reference, a measurement)."""
        return Signal(name, self.units, long_name or self.long_name, self.frame, self.labels, self.dim, self.angle)


@dataclass(frozen=True)
class Layout:
    """Signals laid end to end in one flat vector (a measurement, an input).

    Parameters
    ----------
    signals : tuple of Signal
        In order; scalars take one entry, vectors ``len(labels)``.
    """

    signals: tuple[Signal, ...] = field(default_factory=tuple)

    def __post_init__(self) -> None:
        names = [s.name for s in self.signals]
        if len(set(names)) != len(names):
            raise ValueError(f"Layout signal names must be distinct; got {names}")

    @property
    def size(self) -> int:
        """Length of the flat vector."""
        return sum(s.size for s in self.signals)

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(s.name for s in self.signals)

    def split(self, vector: _Vector) -> dict[str, _Vector]:
        """The flat vector (last axis) as ``{name: part}``; scalars lose the axis."""
        parts: dict[str, _Vector] = {}
        start = 0
        for s in self.signals:
            part = vector[..., start : start + s.size]
            parts[s.name] = part[..., 0] if not s.labels else part
            start += s.size
        return parts

    def join(self, parts: dict[str, Any]) -> Array:
        """Inverse of :meth:`split`."""
        pieces = [jnp.asarray(parts[s.name]) if s.labels else jnp.asarray(parts[s.name])[..., None] for s in self.signals]
        return jnp.concatenate(pieces, axis=-1)

    def renamed(self, prefix: str = "", suffix: str = "", long_prefix: str = "") -> "Layout":
        """The same layout with every name given a prefix and suffix."""
        return Layout(tuple(s.renamed(f"{prefix}{s.name}{suffix}", f"{long_prefix}{s.long_name}") for s in self.signals))


class DivergenceBound(NamedTuple):
    """When a run has failed: the estimation or tracking error of the plant variable
    ``signal`` beyond ``limit`` (in the signal's units) at any record. A non-finite truth
    or estimate is a failed run whatever the bound."""

    signal: str
    limit: float


class Plant(eqx.Module):
    """A continuous-time plant ``dx/dt = f(t, x, u, w)``.

    ``x`` is any PyTree, ``u`` a flat input vector laid out as :attr:`input_layout`,
    ``w`` unit white noise of size :attr:`noise_size` (held over an integration step;
    the engine scales it by ``1/sqrt(step)``).

    :attr:`divergence` is the plant kind's :class:`DivergenceBound`, the default of
    ``[simulation] divergence`` (None: only a non-finite truth or estimate is a failed run).
    """

    divergence: ClassVar[DivergenceBound | None] = None
    input_layout: eqx.AbstractVar[Layout]
    noise_size: eqx.AbstractVar[int]
    variable_signals: eqx.AbstractVar[tuple[Signal, ...]]

    @abc.abstractmethod
    def vector_field(self, t: ArrayLike, x: Any, u: Array, w: Array) -> Any:
        """dx/dt, a PyTree shaped like ``x``."""

    @abc.abstractmethod
    def normalize(self, x: Any) -> Any:
        """``x`` with angles wrapped where the model wants them wrapped (after each sample)."""

    @abc.abstractmethod
    def variables(self, x: Any) -> dict[str, Array]:
        """The recorded quantities of state ``x``, named and shaped as :attr:`variable_signals`."""

    @abc.abstractmethod
    def realize(self, key: Array) -> "Plant":
        """This plant with its per-run random parts drawn from ``key`` (or itself)."""

    # (*args, **parts) of Any: each plant names its own parts, and mypy takes this
    # signature as compatible with any override
    @abc.abstractmethod
    def state(self, *args: Any, **parts: Any) -> Any:
        """A state of this plant from named parts, zeros where not given (a
        composition's ``[plant.initial]``; the keyword arguments are documented)."""

    @abc.abstractmethod
    def models(self) -> tuple:
        """The models of this plant that an observer or a controller may be designed
        for, by default (a vessel's M and D, a manipulator's model): a composition
        gives a model-based component the plant's own model unless its table gives one."""


class Outage(eqx.Module):
    """Channels of a sensor that measure nothing (NaN) over ``[start, start + duration)``:
    a position reference that loses its fix for a minute, a gyro that stops. The
    observer rides through it as through any dropout.

    Parameters
    ----------
    start, duration : float
        When the outage begins and how long it lasts (s); a duration of 0 is no
        outage (the sensor keeps the structure of one, so that a study over outages
        compiles once).
    channels : tuple of bool
        Per channel of the measurement: whether the outage silences it (static).
    """

    start: Array
    duration: Array
    channels: tuple[bool, ...] = eqx.field(static=True)

    def lost(self, t: ArrayLike) -> Array:
        """Per channel: whether it is silenced at ``t``."""
        inside = (t >= self.start) & (t < self.start + self.duration)
        # an Array whatever ``t`` is: NumPy defers a comparison with an Array to JAX
        # (its stubs give an ndarray)
        return cast(Array, inside & jnp.asarray(self.channels))


class Sensor(eqx.Module):
    """A sampled measurement ``y = h(x) + noise``; NaN marks a dropped channel.

    Each entry of ``y`` is a channel with its own sample period; between samples
    the engine holds a channel's last value. ``outage`` (an :class:`Outage`, or None)
    silences channels over a time window; the engine samples through :meth:`sample`,
    which applies it.
    """

    measurement_layout: eqx.AbstractVar[Layout]
    sample_period: eqx.AbstractVar[tuple[float, ...]]
    noise_size: eqx.AbstractVar[int]
    outage: Outage | None = eqx.field(default=None, kw_only=True)

    @abc.abstractmethod
    def measure(self, x: Any, normals: Array) -> Array:
        """One sample of every channel, from ``noise_size`` standard normals."""

    @abc.abstractmethod
    def ideal(self, x: Any) -> Array:
        """The noise-free, never-dropped measurement (continuous-time analysis)."""

    def sample(self, t: ArrayLike, x: Any, normals: Array) -> Array:
        """:meth:`measure` at time ``t``, with the channels of an outage NaN."""
        y = self.measure(x, normals)
        return y if self.outage is None else jnp.where(self.outage.lost(t), jnp.nan, y)


class KinematicSensor(Sensor):
    """A sensor that measures the plant through its kinematics at the applied input,
    and keeps a memory from sample to sample: a suite of position references, gyros,
    an IMU and speed sensors, with their correlated errors and their failures.

    The engine calls :meth:`read` at every sample with the plant's kinematics
    (:func:`kinematics_of`: position, heading, velocities and accelerations, named) at
    the input applied over the interval that ends at the sample, which channels are
    due and the samples held so far; the sensor returns its memory and the whole
    measurement (channels not due hold their value, or what a failure makes of it).
    Its noise comes in one stream per member (:attr:`noise_streams`), so that adding
    a member never changes another's draws.
    """

    #: ``(stream, count)`` per member: the engine draws ``count`` standard normals of
    #: each stream and passes them end to end (their sum is :attr:`noise_size`).
    noise_streams: eqx.AbstractVar[tuple[tuple[int, int], ...]]

    @abc.abstractmethod
    def initial_memory(self, kinematics: dict[str, Array]) -> Any:
        """The memory before the first sample (a PyTree of arrays)."""

    @abc.abstractmethod
    def read(self, memory: Any, t: ArrayLike, kinematics: dict[str, Array], normals: Array, due: Array, held: Array) -> tuple[Any, Array]:
        """``(memory, y)``: the measurement at ``t``; ``due`` per channel, ``held`` the
        last measurement (the first sample passes every channel due)."""

    @abc.abstractmethod
    def expected(self, kinematics: dict[str, Array]) -> Array:
        """The noise-free, fault-free measurement of every channel (a Kalman filter's h)."""

    def measure(self, x: Any, normals: Array) -> Array:
        raise TypeError("a kinematic sensor measures through the plant's kinematics (lookout.components.kinematics_of), not from the state alone")

    def ideal(self, x: Any) -> Array:
        raise TypeError("a kinematic sensor measures through the plant's kinematics (lookout.components.kinematics_of), not from the state alone")


def kinematics_of(plant: "Plant", t: ArrayLike, x: Any, u: Array) -> dict[str, Array]:
    """What a sensor can measure of ``plant`` at ``t`` in state ``x`` under the applied
    input ``u``: ``plant.kinematics(t, x, u)``, a dict of named quantities (a vessel's ``position``,
    ``heading``, ``velocity``, ``yaw_rate``, ``acceleration``, ``yaw_acceleration``, ...).
    A ValueError names the plant when it has none."""
    kinematics = getattr(plant, "kinematics", None)
    if kinematics is None:
        raise ValueError(f"plant {type(plant).__name__} gives no kinematics (position, heading, rates) for a sensor suite to measure")
    return kinematics(t, x, u)


class Observer(eqx.Module):
    """A state observer: internal state ``S``, corrected by samples, propagated between them.

    ``estimate_signals`` are estimates of plant variables, named, shaped and united
    as the plant's (the results pair ``v`` with ``v_hat``); ``extra_signals`` are the
    observer's other outputs (innovations, parameter estimates, sliding surfaces).

    What it consumes is declared too: ``measurement_layout`` (the measurement ``y``
    it reads, NaN marking a missing channel) and ``input_layout`` (the applied input
    ``u`` of :meth:`predict`), so that a log or a live stream can be checked against
    it; ``sample_period`` is the one step (s) the observer is written for (a
    discrete-time observer), or None when :meth:`predict` takes any step ``dt``.
    """

    estimate_signals: eqx.AbstractVar[tuple[Signal, ...]]
    extra_signals: eqx.AbstractVar[tuple[Signal, ...]]
    measurement_layout: eqx.AbstractVar[Layout]
    input_layout: eqx.AbstractVar[Layout]
    sample_period: eqx.AbstractVar[float | None]

    @abc.abstractmethod
    def guess(self) -> Any:
        """A default initial guess, shaped as :meth:`init` takes it (zeros, or the
        observer's own starting values); the keyword arguments of each observer's
        ``guess`` set its parts."""

    @abc.abstractmethod
    def init(self, y0: Array, guess: Any) -> Any:
        """Internal state at t_0 from the first sample and the initial guess."""

    @abc.abstractmethod
    def update(self, state: Any, t: ArrayLike, y: Array) -> Any:
        """Correction when sample ``y`` arrives at ``t`` (identity for continuous observers)."""

    @abc.abstractmethod
    def output(self, state: Any, y: Array) -> dict[str, Array]:
        """The estimate at the sample: :attr:`estimate_signals` and :attr:`extra_signals` by name."""

    @abc.abstractmethod
    def predict(self, state: Any, t: ArrayLike, y: Array, u: Array, dt: ArrayLike) -> Any:
        """From t to t + dt with ``y`` and ``u`` held."""


class ContinuousObserver(Observer):
    """An observer given as a vector field, which the engine can also integrate jointly
    with the plant on the noise-free measurement (``observer_mode="continuous"``)."""

    @abc.abstractmethod
    def vector_field(self, t: ArrayLike, state: Any, y: Array, u: Array) -> Any:
        """dS/dt with the measurement ``y`` and input ``u``."""

    @abc.abstractmethod
    def normalize(self, state: Any) -> Any:
        """``state`` with its angles wrapped (after a joint integration with the plant)."""


class Reference(eqx.Module):
    """A reference generator: desired trajectory samples for the controller."""

    reference_signals: eqx.AbstractVar[tuple[Signal, ...]]
    noise_size: eqx.AbstractVar[int]

    @abc.abstractmethod
    def init(self) -> Any:
        """Internal state at t_0."""

    @abc.abstractmethod
    def step(self, state: Any, t: ArrayLike, dt: ArrayLike, normals: Array) -> tuple[Any, dict[str, Array]]:
        """``(state, sample)``: the reference at ``t`` as ``{name: value}`` and the state at t + dt."""


class Controller(eqx.Module):
    """A control law; open-loop inputs and "no control" are controllers too.

    What it reads is declared (names, checked against the parts that provide them
    before anything is compiled): ``estimate_needs`` of the observer's outputs,
    ``measurement_needs`` of the sensor's channels, ``reference_needs`` of the
    reference's signals. A field or a property may declare them.
    """

    estimate_needs: eqx.AbstractVar[tuple[str, ...]]
    measurement_needs: eqx.AbstractVar[tuple[str, ...]]
    reference_needs: eqx.AbstractVar[tuple[str, ...]]

    @abc.abstractmethod
    def init(self) -> Any:
        """Internal state at t_0."""

    @abc.abstractmethod
    def step(self, state: Any, t: ArrayLike, y: Array, estimate: dict[str, Array], reference: dict[str, Array], dt: ArrayLike) -> tuple[Any, Array]:
        """``(state, u)``: the commanded input at ``t``, laid out as the plant's input."""

    def follow(self, observer: Observer) -> "Controller":
        """This controller with the gains it copies from ``observer`` taken again
        (traceable): after the observer's gains change (tuning). A controller that
        copies none returns itself."""
        return self


class Actuator(eqx.Module):
    """What the plant receives for a commanded input: limits, thrusters and their allocation.

    An actuator may have a state (a thruster's delivered thrust and angle, the last
    allocation) that the engine carries from sample to sample: :meth:`step` maps the
    command ``u_k`` at ``t_k`` to the input applied over [t_k, t_k+1] and the state at
    t_k+1. ``output_signals`` are what it records besides the applied input (each
    thruster's commanded and delivered thrust), by name, as :meth:`step` returns them.
    """

    output_signals: eqx.AbstractVar[tuple[Signal, ...]]

    @abc.abstractmethod
    def init(self) -> Any:
        """Internal state at t_0 (a PyTree; ``()`` for none)."""

    @abc.abstractmethod
    def step(self, state: Any, t: ArrayLike, u: Array, dt: ArrayLike) -> tuple[Any, Array, dict[str, Array]]:
        """``(state, applied, outputs)``: the input applied over [t, t + dt] for the
        command ``u``, the state at t + dt, and ``{name: value}`` of :attr:`output_signals`."""


class StatelessActuator(Actuator):
    """An actuator that is a function of the command alone (saturation, identity)."""

    @property  # type: ignore[misc]  # equinox takes a property for an AbstractVar
    def output_signals(self) -> tuple[Signal, ...]:  # type: ignore[override]  # (read-only: a stateless actuator records nothing)
        return ()

    def init(self) -> tuple[()]:
        return ()

    def step(self, state: Any, t: ArrayLike, u: Array, dt: ArrayLike) -> tuple[Any, Array, dict[str, Array]]:
        return state, self.apply(u), {}

    @abc.abstractmethod
    def apply(self, u: Array) -> Array:
        """The applied input."""
