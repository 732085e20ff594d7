"""Observers on recorded data and live: a jitted scan over a log, a compiled stepper.

A log is rows ``(t_k, y_k, u_k)``: the time of the row (s, increasing, regular or
not), the measurement (NaN marks a missing channel: the observer gets no
innovation from it for that row) and the input applied from t_k to t_{k+1}. Each
row runs the engine's observer steps in the engine's order::

    S = observer.update(S, t_k, y_k);  e_k = observer.output(S, y_k)
    S = observer.predict(S, t_k, y_k, u_k, t_{k+1} - t_k)

starting from ``observer.init(y_0, guess)``; so filtering a simulation's own
recorded measurements and inputs gives the simulation's estimates.
"""

from __future__ import annotations

import math
import operator
import warnings
from typing import TYPE_CHECKING, Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import numpy.typing as npt
from jax import Array
from jax.flatten_util import ravel_pytree
from jax.typing import ArrayLike

from lookout.components import Layout, Observer
from lookout.results import RecordSignals, Trajectory

if TYPE_CHECKING:
    import xarray as xr

#: A prediction step whose linearization multiplies a small state error by more than
#: this (spectral radius) makes the estimates diverge at that step: the step is
#: refused. A stable observer at a usable step gives at most about 1; explicit
#: integration over a step far beyond the observer's time constants gives orders of
#: magnitude more (a 10 Hz log read as milliseconds: 5e6 for the passive observer).
MAX_STEP_AMPLIFICATION = 2.0


def _describe(tree) -> str:
    """``VesselState with eta (3,), nu (3,), ...``: a PyTree's type and leaf shapes."""
    leaves = jax.tree_util.tree_flatten_with_path(tree)[0]
    parts = [f"{jax.tree_util.keystr(path).lstrip('.') or 'value'} {tuple(np.shape(leaf))}" for path, leaf in leaves]
    return f"{type(tree).__name__} with {', '.join(parts)}" if parts else type(tree).__name__


def real_array(name: str, value: object) -> np.ndarray:
    """``value`` as a float64 array, or a ValueError naming ``name`` (text, complex numbers
    and objects are not measurements)."""
    try:
        array = np.asarray(value)
    except Exception as error:  # ragged sequences
        raise ValueError(f"{name} must be an array of numbers; {error}") from None
    if array.dtype.kind not in "iuf":
        kinds = {"b": "booleans", "c": "complex numbers", "U": "text", "S": "text", "O": "objects", "M": "dates", "m": "time spans"}
        raise ValueError(f"{name} must hold real numbers; got {kinds.get(array.dtype.kind, array.dtype.name)}")
    return array.astype(float)


def checked_guess(observer: Observer, guess: Any) -> Any:
    """``guess``, or the observer's own ``guess()`` when it is None; refused (ValueError
    naming ``guess``) unless it has the structure of ``observer.guess()`` with leaves
    that broadcast to its shapes and finite entries (NaN only where ``observer.guess()``
    has NaN: a state left to the first measurement, :mod:`lookout.observers.start`)."""
    expected = observer.guess()
    if guess is None:
        return expected
    given_leaves, given_tree = jax.tree.flatten(guess)
    expected_leaves, expected_tree = jax.tree.flatten(expected)
    if given_tree != expected_tree:  # type: ignore[operator]  # jaxlib ships no stub for PyTreeDef, so mypy cannot resolve jax.tree.flatten's treedef type
        raise ValueError(f"guess must be shaped like observer.guess() ({_describe(expected)}); got {_describe(guess)}")
    for (path, given), wanted in zip(jax.tree_util.tree_flatten_with_path(guess)[0], expected_leaves):
        name = "guess" + jax.tree_util.keystr(path)
        shape = np.shape(wanted)
        try:
            broadcast: tuple[int, ...] | None = np.broadcast_shapes(np.shape(given), shape)
        except ValueError:
            broadcast = None
        if broadcast != shape:
            raise ValueError(f"{name} must have shape {shape} (as in observer.guess()); got shape {np.shape(given)}")
        values = np.broadcast_to(real_array(name, given), shape)
        left_to_measurement = np.isnan(np.broadcast_to(np.asarray(wanted, dtype=float), shape))
        if not np.all(np.isfinite(values) | (np.isnan(values) & left_to_measurement)):
            where = " (NaN only where observer.guess() leaves a state to the first measurement)" if left_to_measurement.any() else ""
            raise ValueError(f"{name} must be finite{where}; got {np.asarray(given).tolist()}")
    # every leaf in the observer's own dtype: an integer guess would change the state's types
    return jax.tree.map(lambda leaf, wanted: jnp.asarray(leaf, dtype=jnp.result_type(wanted)), guess, expected)


def _columns(name: str, array: np.ndarray, rows: int, layout: Layout, owner: str) -> None:
    if array.ndim != 2 or array.shape != (rows, layout.size):
        names = ", ".join(layout.names) or "none"
        raise ValueError(
            f"{name} must have shape ({rows}, {layout.size}): {rows} rows and the {layout.size} columns {owner} reads ({names}); got shape {array.shape}"
        )


def step_amplification(observer: Observer, guess: Any, y: npt.ArrayLike, u: npt.ArrayLike, dt: ArrayLike) -> float:
    """The spectral radius of the Jacobian of one prediction step of ``dt`` (s), at the
    state after the first sample: how much one step multiplies a small state error.

    A screening check of the step length, not a stability proof: the observer is
    nonlinear and this is its linearization at one state. Above
    :data:`MAX_STEP_AMPLIFICATION` the step is too long for the observer (its
    integration leaves the stable region, or a discrete form is unstable there).
    """
    y = jnp.asarray(y, dtype=float)
    u = jnp.asarray(u, dtype=float)
    state = observer.update(observer.init(y, guess), 0.0, y)
    return _radius(observer, state, y, u, dt)


def _radius(observer: Observer, state, y, u, dt) -> float:
    """The spectral radius (inf when the Jacobian itself is not finite: the step overflows)."""
    flat, unravel = ravel_pytree(state)
    if not flat.size:
        return 0.0
    jacobian = np.asarray(_prediction_jacobian(observer, unravel, flat, y, u, jnp.asarray(dt, dtype=float)))
    if not np.all(np.isfinite(jacobian)):
        return float("inf")
    return float(np.max(np.abs(np.linalg.eigvals(jacobian))))


@eqx.filter_jit
def _prediction_jacobian(observer, unravel, flat, y, u, dt):
    return jax.jacfwd(lambda vector: ravel_pytree(observer.predict(unravel(vector), 0.0, y, u, dt))[0])(flat)


def check_step_length(observer: Observer, guess: Any, y: npt.ArrayLike, u: npt.ArrayLike, dt: float, where: str) -> float:
    """Refuse a time step the observer cannot take in one prediction: the screening of
    :func:`step_amplification` against :data:`MAX_STEP_AMPLIFICATION`, the test that
    tells a log read in the wrong unit (milliseconds) from one in seconds. Used by
    :func:`filter` on a log's longest row step and by ``lookout replay`` on a log's
    typical step between lines.

    Parameters
    ----------
    where : str
        What the step is, for the message (``"the longest row step (row 3 to 4),"``).

    Returns
    -------
    float
        The amplification (spectral radius) found.

    Raises
    ------
    ValueError
        ``"{where} {dt} s is too long for this observer: ...; are the times in seconds?"``.
    """
    radius = step_amplification(observer, guess, y, u, dt)
    if not radius <= MAX_STEP_AMPLIFICATION:
        raise ValueError(_too_long(radius, float(dt), where))
    return radius


def _too_long(radius: float, dt: float, where: str) -> str:
    return (
        f"{where} {dt:g} s is too long for this observer: one prediction step multiplies a state error by {radius:.3g} "
        f"(above {MAX_STEP_AMPLIFICATION:g} the estimates diverge); are the times in seconds? (a log in milliseconds has steps 1000 times too long)"
    )


def _check_steps(observer: Observer, guess, times: np.ndarray, measurements: np.ndarray, inputs: np.ndarray) -> None:
    """Refuse row steps the observer cannot take: not its declared sample period (a
    discrete-time observer), or so long that one prediction step amplifies errors."""
    steps = np.diff(times)
    if steps.size == 0:
        return
    period = observer.sample_period
    if period is not None:
        off = np.abs(steps - period) > 1e-9 * period
        if np.any(off):
            row = int(np.argmax(off))
            raise ValueError(
                f"times must step by the observer's sample_period {period:g} s (a discrete-time observer); the step from row {row} to {row + 1} "
                f"is {steps[row]:g} s; are the times in seconds?"
            )
        return
    row = int(np.argmax(steps))
    check_step_length(observer, guess, measurements[0], inputs[0], float(steps[row]), f"times: the longest row step (row {row} to {row + 1}),")


def _check_log_fits(observer: Observer, guess, n_y: int, n_u: int) -> None:
    """One line naming the observer and the log when their shapes do not fit."""
    y, u = jnp.zeros(n_y), jnp.zeros(n_u)

    def one_row():
        state = observer.update(observer.init(y, guess), 0.0, y)
        return observer.output(state, y), observer.predict(state, 0.0, y, u, observer.sample_period or 1.0)

    try:
        jax.eval_shape(one_row)
    except Exception as error:
        raise ValueError(f"observer and log do not fit ({n_y} measurement and {n_u} input columns): {str(error).strip().splitlines()[0]}") from None


@eqx.filter_jit
def _filter_scan(observer: Observer, guess, times: Array, measurements: Array, inputs: Array):
    steps = jnp.diff(times, append=times[-1:])  # the last row is not propagated

    def row(state, data):
        t, y, u, dt = data
        state = observer.update(state, t, y)
        estimate = observer.output(state, y)
        return observer.predict(state, t, y, u, dt), estimate

    _, estimates = jax.lax.scan(row, observer.init(measurements[0], guess), (times, measurements, inputs, steps))
    return estimates


def filter(  # noqa: A001 - lookout.filter, as the docs name it
    observer: Observer,
    times: npt.ArrayLike,
    measurements: npt.ArrayLike,
    inputs: npt.ArrayLike | None = None,
    *,
    guess: Any = None,
    measurement_layout: Layout | None = None,
    input_layout: Layout | None = None,
) -> xr.Dataset:
    """Run ``observer`` over a log in one jitted scan; return the simulation's Dataset layout.

    Parameters
    ----------
    observer : Observer
    times : array_like, shape (n,)
        Row times in seconds, strictly increasing (regular or irregular). A
        discrete-time observer (one with a ``sample_period``) needs rows exactly one
        period apart; for the others the longest step must not make one prediction
        step amplify errors more than :data:`MAX_STEP_AMPLIFICATION` times.
    measurements : array_like, shape (n, n_y)
        Measurements laid out as ``observer.measurement_layout``; NaN marks a missing
        channel of a row (at least one entry of the log must be finite).
    inputs : array_like, shape (n, n_u), optional
        Input applied from each row's time to the next, laid out as
        ``observer.input_layout`` (default: zero).
    guess : PyTree, optional
        The observer's initial guess (as for a simulation's ``initial_estimate``),
        shaped as ``observer.guess()``; default ``observer.guess()``.
    measurement_layout, input_layout : Layout, optional
        Names and units of the columns; default the observer's own.

    Returns
    -------
    xarray.Dataset
        Estimates (``v_hat``), the observer's extra outputs, the measurements and the
        inputs (as applied), with dims run (one), time and the label dims.

    Raises
    ------
    ValueError
        Naming the argument: shapes that do not fit the observer, times that do not
        increase or whose steps the observer cannot take, a log without one finite
        measurement, infinite measurements, non-finite inputs, or a guess that is not
        shaped as ``observer.guess()``.
    """
    rows, values, applied, guess, measurement_layout, input_layout = checked_log(
        observer, times, measurements, inputs, guess, measurement_layout, input_layout
    )
    estimates = _filter_scan(observer, guess, jnp.asarray(rows), jnp.asarray(values), jnp.asarray(applied))
    finite = np.all([np.isfinite(np.asarray(leaf)).reshape(rows.size, -1).all(axis=1) for leaf in jax.tree.leaves(estimates)], axis=0)
    if not finite.all():
        row = int(np.argmin(finite))
        cause = max(row - 1, 0)  # the prediction from the row before made them so
        warnings.warn(
            f"lookout.filter: the estimates are not finite from row {row} (t = {rows[row]:g} s) on, after row {cause}'s measurement "
            f"{np.array2string(values[cause], precision=4)} and input {np.array2string(applied[cause], precision=4)}; the Dataset's status says 'diverged'",
            RuntimeWarning,
            stacklevel=2,
        )
    return filtered_dataset(observer, rows, estimates, values, applied, measurement_layout, input_layout)


def checked_log(
    observer: Observer,
    times: npt.ArrayLike,
    measurements: npt.ArrayLike,
    inputs: npt.ArrayLike | None,
    guess: Any,
    measurement_layout: Layout | None,
    input_layout: Layout | None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, Any, Layout, Layout]:
    """``(times, measurements, inputs, guess, measurement_layout, input_layout)`` of a log
    checked as :func:`filter` checks it (its Raises), the defaults filled in."""
    if not isinstance(observer, Observer):
        raise ValueError(f"observer must be a lookout Observer (a scenario's is scenario.observer); got {type(observer).__name__}")
    times = real_array("times", times)
    measurements = real_array("measurements", measurements)
    if times.ndim != 1 or times.size < 1:
        raise ValueError(f"times must be a 1-D array with at least one row; got shape {times.shape}")
    if not np.all(np.isfinite(times)):
        row = int(np.argmin(np.isfinite(times)))
        raise ValueError(f"times must be finite; row {row} is {times[row]}")
    if np.any(np.diff(times) <= 0):
        row = int(np.argmax(np.diff(times) <= 0))
        raise ValueError(f"times must be strictly increasing; row {row + 1} ({times[row + 1]:g} s) does not come after row {row} ({times[row]:g} s)")
    measurement_layout = measurement_layout or observer.measurement_layout
    input_layout = input_layout or observer.input_layout
    for name, layout, wanted in (
        ("measurement_layout", measurement_layout, observer.measurement_layout),
        ("input_layout", input_layout, observer.input_layout),
    ):
        if layout.size != wanted.size:
            raise ValueError(f"{name} must have {wanted.size} entries (the observer reads {', '.join(wanted.names) or 'none'}); got {layout.size}")
    _columns("measurements", measurements, times.size, observer.measurement_layout, "the observer")
    inputs = np.zeros((times.size, observer.input_layout.size)) if inputs is None else real_array("inputs", inputs)
    _columns("inputs", inputs, times.size, observer.input_layout, "the observer's prediction")
    if np.any(np.isinf(measurements)):
        row, column = np.argwhere(np.isinf(measurements))[0]
        raise ValueError(f"measurements must be finite or NaN (a missing channel); row {row}, column {column} is {measurements[row, column]}")
    if not np.any(np.isfinite(measurements)):
        raise ValueError(f"measurements hold no finite value ({measurements.shape[0]} rows, all NaN): the observer would have nothing to correct it")
    if not np.all(np.isfinite(inputs)):
        row, column = np.argwhere(~np.isfinite(inputs))[0]
        raise ValueError(
            f"inputs must be finite (a missing input has no meaning for the prediction); row {row}, column {column} is {inputs[row, column]}"
        )
    guess = checked_guess(observer, guess)
    _check_log_fits(observer, guess, measurements.shape[1], inputs.shape[1])
    _check_steps(observer, guess, times, measurements, inputs)
    return times, measurements, inputs, guess, measurement_layout, input_layout


def filtered_dataset(
    observer: Observer,
    times: np.ndarray,
    estimates: dict[str, Any],
    measurements: np.ndarray,
    inputs: np.ndarray,
    measurement_layout: Layout,
    input_layout: Layout,
) -> xr.Dataset:
    """The Dataset of :func:`filter` from a run's estimates."""
    signals = RecordSignals(
        truth=(),
        estimate=tuple(observer.estimate_signals),
        extra=tuple(observer.extra_signals),
        measurement=measurement_layout,
        reference=(),
        input=input_layout,
    )
    trajectory = Trajectory(
        times,
        {},
        estimates,
        measurements,
        {},
        inputs,
        inputs,
        signals=signals,
        batched=False,
        attrs={"observer": type(observer).__name__, "source_of_data": "log"},
    )
    return trajectory.to_xarray()


class Stepper:
    """An observer for live use: one compiled call per incoming sample.

    The observer's functions are compiled once, with the observer's gains baked in.
    State and inputs cross the boundary as one flat float64 vector, the next state
    and the estimate come back as another, so a call is one dispatch of a compiled
    function with one argument, not a trace (docs/benchmarks.md, "Live stepping
    against MCSimPython").

    A bad call never changes the state: non-finite ``t``, ``dt`` or ``u``, infinite
    ``y``, ``dt <= 0``, ``t`` not after the previous call's, a ``dt`` other than a
    discrete-time observer's ``sample_period`` or one so long that a prediction step
    amplifies errors (checked the first time a longer ``dt`` comes), and a step whose
    result is not finite each raise ``ValueError`` and leave the state as it was.
    NaN in ``y`` is a missing channel: the observer predicts through it.

    Parameters
    ----------
    observer : Observer
    guess : PyTree, optional
        Initial guess, shaped as ``observer.guess()`` (the default).
    y0 : array_like
        The first measurement, laid out as ``observer.measurement_layout`` (NaN for a
        missing channel).
    input_size : int, optional
        Length of the input vector ``u`` passed to each call; it must be the
        observer's (``observer.input_layout.size``, the default).

    Examples
    --------
    >>> stepper = Stepper(observer, observer.guess(), y0, input_size=3)   # doctest: +SKIP
    >>> estimate = stepper(t, y, u, dt)   # estimate at t; the state moves to t + dt
    """

    _FLOATS = (float, np.float64)  # times a call takes as they are (checked for finiteness)
    _FLOAT64 = np.dtype(np.float64)

    def __init__(self, observer: Observer, guess: Any = None, y0: npt.ArrayLike | None = None, input_size: int | None = None):
        if not isinstance(observer, Observer):
            raise ValueError(f"observer must be a lookout Observer; got {type(observer).__name__}")
        n_y, n_u = observer.measurement_layout.size, observer.input_layout.size
        if y0 is None:
            raise ValueError(f"y0 must be the first measurement ({n_y} entries: {', '.join(observer.measurement_layout.names)}); got None")
        y0 = self._measurement("y0", y0, n_y, observer)
        if input_size is None:
            input_size = n_u
        if isinstance(input_size, bool) or not isinstance(input_size, (int, np.integer)) or input_size != n_u:
            raise ValueError(
                f"input_size must be {n_u}, the length of the observer's input ({', '.join(observer.input_layout.names) or 'none'}); got {input_size!r}"
            )
        guess = checked_guess(observer, guess)
        self.observer = observer
        self._measurement_size = n_y
        self._input_size = n_u
        flat_state, unravel_state = ravel_pytree(observer.init(jnp.asarray(y0), guess))
        template = jax.eval_shape(lambda s: observer.output(s, jnp.asarray(y0)), unravel_state(flat_state))
        leaves, self._estimate_tree = jax.tree.flatten(template)
        ends = np.cumsum([int(np.prod(leaf.shape)) for leaf in leaves])
        # (start, end, shape) of each output in the flat estimate (np.split costs 70 us here)
        self._pieces = [(int(end) - int(np.prod(leaf.shape)), int(end), leaf.shape) for end, leaf in zip(ends, leaves)]

        def advance(flat, packed):
            state = unravel_state(flat)
            t, dt, y, u = packed[0], packed[1], packed[2 : 2 + n_y], packed[2 + n_y :]
            state = observer.update(state, t, y)
            estimate = observer.output(state, y)
            state = ravel_pytree(observer.predict(state, t, y, u, dt))[0]
            flat_estimate = jnp.concatenate([jnp.ravel(leaf) for leaf in jax.tree.leaves(estimate)])
            # one flag rides with the estimate: was the step finite? The state and the
            # estimates of plant variables must be; an extra output may be NaN where a
            # channel is missing (the innovation of a dropout)
            estimates = [jnp.ravel(estimate[signal.name]) for signal in observer.estimate_signals if signal.name in estimate]
            healthy = jnp.all(jnp.isfinite(state)) & jnp.all(jnp.isfinite(jnp.concatenate(estimates) if estimates else flat_estimate))
            return state, jnp.concatenate([flat_estimate, healthy[None].astype(flat_estimate.dtype)])

        self._advance_step = advance
        self._advance = jax.jit(advance)
        self._unravel_state = unravel_state
        self._flat_state = flat_state
        self._last_time: float | None = None
        self._checked_step = 0.0  # the longest dt whose amplification was checked
        self._period = observer.sample_period
        # The call's path when state and estimate are float64 (lookout's default): one
        # buffer [state, t, dt, y, u] in and one vector [next state, estimate, flag]
        # out, the same operations as `advance`. One argument and one result instead of
        # two each, no per-call allocation of the input, and the estimate's pieces read
        # back by precomputed indices (docs/benchmarks.md, "Live stepping against
        # MCSimPython").
        n_s = int(flat_state.size)
        self._state_size = n_s
        self._step = None
        if flat_state.dtype == np.float64 and all(leaf.dtype == np.float64 for leaf in leaves):

            def step(buffer):
                state, flat_estimate = advance(buffer[:n_s], buffer[n_s:])
                return jnp.concatenate([state, flat_estimate])

            self._step = jax.jit(step)
            self._buffer = np.zeros(n_s + 2 + n_y + n_u)
            self._measured = self._buffer[n_s + 2 : n_s + 2 + n_y]  # views the call fills
            self._applied = self._buffer[n_s + 2 + n_y :]
        # a dict of scalars and vectors (every observer's output) is read back as views
        # of the result by index; anything else through the tree
        index = jax.tree.unflatten(self._estimate_tree, list(range(len(leaves))))
        self._names = None
        if type(index) is dict and all(type(i) is int for i in index.values()) and all(len(leaf.shape) <= 1 for leaf in leaves):
            keys = [(n_s + start, Ellipsis) if shape == () else slice(n_s + start, n_s + end) for start, end, shape in self._pieces]
            keys = [keys[i] for i in index.values()]
            self._names = tuple(index)
            self._take = operator.itemgetter(*keys) if len(keys) > 1 else (lambda flat, key=keys[0]: (flat[key],))

    @staticmethod
    def _measurement(name: str, y, size: int, observer: Observer) -> np.ndarray:
        y = real_array(name, y).ravel()
        if y.shape != (size,):
            raise ValueError(f"{name} must have {size} entries ({', '.join(observer.measurement_layout.names)}); got {y.shape[0]}")
        if np.any(np.isinf(y)):
            raise ValueError(f"{name} must be finite or NaN (a missing channel); got {y.tolist()}")
        return y

    @property
    def state(self) -> Any:
        """The observer's internal state (a PyTree), at the time the next call expects."""
        return self._unravel_state(self._flat_state)

    def __call__(self, t, y, u, dt) -> dict:
        """The estimate at ``t`` from the measurement ``y`` (NaN = missing channel);
        then the internal state is propagated to ``t + dt`` with input ``u``.

        Returns
        -------
        dict of numpy.ndarray
            The observer's outputs by name.

        Raises
        ------
        ValueError
            On a bad argument (see the class docstring); the state is left as it was.
        """
        # A Python or NumPy float, and a float64 vector of the right length, pass the
        # checks here; anything else, or anything these checks refuse, goes through the
        # full conversion and checks, which give the messages.
        t = float(t) if t.__class__ in self._FLOATS and math.isfinite(t) else self._number("t", t)
        dt = float(dt) if dt.__class__ in self._FLOATS and math.isfinite(dt) else self._number("dt", dt)
        if not dt > 0:
            raise ValueError(f"dt must be positive (s, the time to the next sample); got {dt:g}")
        if self._last_time is not None and not t > self._last_time:
            raise ValueError(f"t must come after the previous call's t = {self._last_time:g} s; got {t:g} s (time must not go backwards)")
        n_y, n_u = self._measurement_size, self._input_size
        if not (y.__class__ is np.ndarray and y.dtype is self._FLOAT64 and y.shape == (n_y,) and not any(map(math.isinf, y.tolist()))):
            y = self._measurement("y", y, n_y, self.observer)
        if not (u.__class__ is np.ndarray and u.dtype is self._FLOAT64 and u.shape == (n_u,) and all(map(math.isfinite, u.tolist()))):
            u = real_array("u", u).ravel()
            if u.shape != (n_u,):
                raise ValueError(f"u must have {n_u} entries ({', '.join(self.observer.input_layout.names) or 'none'}); got {u.shape[0]}")
            if not np.all(np.isfinite(u)):
                raise ValueError(f"u must be finite (the input applied until t + dt); got {u.tolist()}")
        if self._period is not None or dt > self._checked_step:
            self._check_step(dt, y, u)
        n_s = self._state_size
        if self._step is None:
            flat_state, flat_estimate = self._advance(self._flat_state, np.concatenate(([t, dt], y, u)))
            flat = np.asarray(flat_estimate)
        else:
            buffer = self._buffer
            buffer[:n_s] = self._flat_state
            buffer[n_s] = t
            buffer[n_s + 1] = dt
            self._measured[:] = y
            self._applied[:] = u
            flat = np.asarray(self._step(buffer))
            flat_state = flat[:n_s]
        if flat[-1] != 1.0:
            raise ValueError(f"the step at t = {t:g} s over dt = {dt:g} s gives a non-finite state or estimate; refused, the state is kept as it was")
        self._flat_state = flat_state
        self._last_time = t
        if self._step is None:
            return jax.tree.unflatten(self._estimate_tree, [flat[start:end].reshape(shape) for start, end, shape in self._pieces])
        if self._names is None:
            return jax.tree.unflatten(self._estimate_tree, [flat[n_s + start : n_s + end].reshape(shape) for start, end, shape in self._pieces])
        return dict(zip(self._names, self._take(flat)))

    @staticmethod
    def _number(name: str, value) -> float:
        array = real_array(name, value)
        if array.shape != ():
            raise ValueError(f"{name} must be a number (s); got shape {array.shape}")
        if not np.isfinite(array):
            raise ValueError(f"{name} must be finite (s); got {float(array)}")
        return float(array)

    def _check_step(self, dt: float, y: np.ndarray, u: np.ndarray) -> None:
        period = self.observer.sample_period
        if period is not None:
            if abs(dt - period) > 1e-9 * period:
                raise ValueError(f"dt must be the observer's sample_period {period:g} s (a discrete-time observer); got {dt:g} s")
            return
        if dt <= self._checked_step:
            return
        radius = _radius(self.observer, self.observer.update(self.state, 0.0, jnp.asarray(y)), jnp.asarray(y), jnp.asarray(u), dt)
        if not radius <= MAX_STEP_AMPLIFICATION:
            raise ValueError("dt: " + _too_long(radius, dt, "a step of"))
        self._checked_step = dt

    def template(self) -> dict:
        """The estimate's names and shapes (arrays of NaN), without stepping."""
        return jax.tree.unflatten(self._estimate_tree, [np.full(shape, np.nan) for _, _, shape in self._pieces])

    def run(self, times: npt.ArrayLike, ys: npt.ArrayLike, us: npt.ArrayLike, dt: ArrayLike) -> tuple[dict, np.ndarray]:
        """Several calls in one compiled scan: step ``i`` is ``self(times[i], ys[i],
        us[i], dt)``. A step whose result is not finite is refused as a call would be
        (the state stays as it was before it; its row of estimates is NaN), and the
        scan goes on with the next.

        Returns
        -------
        estimates : dict of numpy.ndarray
            One row per step.
        healthy : numpy.ndarray of bool
            False where a step was refused.
        """
        times = real_array("times", times).ravel()
        ys = real_array("ys", ys)
        us = real_array("us", us)
        dt = self._number("dt", dt)
        n = times.size
        if n == 0 or ys.shape != (n, self._measurement_size) or us.shape != (n, self._input_size):
            raise ValueError(
                f"times, ys and us must have one row per step ({n}) of 1, {self._measurement_size} and {self._input_size} entries; "
                f"got shapes {times.shape}, {ys.shape}, {us.shape}"
            )
        if not dt > 0:
            raise ValueError(f"dt must be positive (s, the time to the next sample); got {dt:g}")
        if not np.all(np.isfinite(times)) or np.any(np.diff(times) <= 0) or (self._last_time is not None and not times[0] > self._last_time):
            raise ValueError("times must be finite and increasing, after the previous call's t")
        if np.any(np.isinf(ys)):
            raise ValueError("ys must be finite or NaN (a missing channel)")
        if not np.all(np.isfinite(us)):
            raise ValueError("us must be finite (the input applied until t + dt)")
        self._check_step(dt, ys[0], us[0])
        packed = np.concatenate([times[:, None], np.full((n, 1), dt), ys, us], axis=1)
        # rows padded to a power of two (at least 64, and at least the largest block so
        # far) and masked: one compilation serves every block up to that size, a
        # replay's last, shorter block included
        size = max(64, 1 << (n - 1).bit_length(), getattr(self, "_scan_size", 0))
        self._scan_size = size
        valid = np.arange(size) < n
        packed = np.concatenate([packed, np.repeat(packed[-1:], size - n, axis=0)])
        if not hasattr(self, "_scan"):
            advance = self._advance_step

            def scan(flat, rows, valid):
                def body(state, row_valid):
                    row, ok = row_valid
                    new, flat_estimate = advance(state, row)
                    healthy = flat_estimate[-1] == 1.0
                    return jnp.where(healthy & ok, new, state), flat_estimate

                return jax.lax.scan(body, flat, (rows, valid))

            self._scan = jax.jit(scan)
        flat_state, flat = self._scan(self._flat_state, packed, valid)
        flat = np.array(flat[:n])
        healthy = flat[:, -1] == 1.0
        flat[~healthy, :-1] = np.nan
        self._flat_state = flat_state
        self._last_time = float(times[healthy][-1]) if healthy.any() else self._last_time
        pieces = [flat[:, start:end].reshape((n, *shape)) for start, end, shape in self._pieces]
        return jax.tree.unflatten(self._estimate_tree, pieces), healthy

    def reset(self, y0: npt.ArrayLike, guess: Any = None) -> None:
        """Start over from the first measurement ``y0`` and ``guess`` (default the
        observer's), keeping what is compiled: a live session compiles on a stand-in
        measurement before data comes, then resets on the first real one."""
        y0 = self._measurement("y0", y0, self._measurement_size, self.observer)
        guess = checked_guess(self.observer, guess)
        self._flat_state = ravel_pytree(self.observer.init(jnp.asarray(y0), guess))[0]
        self._last_time = None
