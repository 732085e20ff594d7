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

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax import Array
from jax.flatten_util import ravel_pytree

from lookout.components import Layout, Observer, Signal
from lookout.results import RecordSignals, Trajectory


def _generic_layout(prefix: str, size: int) -> Layout:
    labels = tuple(f"{prefix}{i}" for i in range(size))
    return Layout((Signal(prefix, "1", f"logged {prefix}", labels=labels, dim=f"{prefix}_channel"),)) if size else Layout()


def _check_log_fits(observer: Observer, guess, n_y: int, n_u: int) -> None:
    """One line naming the observer and the log when their shapes do not fit."""
    y, u = jnp.zeros(n_y), jnp.zeros(n_u)

    def one_row():
        state = observer.update(observer.init(y, guess), 0.0, y)
        return observer.output(state, y), observer.predict(state, 0.0, y, u, 1.0)

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


def filter(  # noqa: A001 - lookout.filter, as the issue and the docs name it
    observer: Observer,
    times,
    measurements,
    inputs=None,
    *,
    guess,
    measurement_layout: Layout | None = None,
    input_layout: Layout | None = None,
):
    """Run ``observer`` over a log in one jitted scan; return the simulation's Dataset layout.

    Parameters
    ----------
    observer : Observer
    times : array_like, shape (n,)
        Row times in seconds, strictly increasing (regular or irregular).
    measurements : array_like, shape (n, n_y)
        Measurements; NaN marks a missing channel of a row.
    inputs : array_like, shape (n, n_u), optional
        Input applied from each row's time to the next (default: none, zero columns).
    guess : PyTree
        The observer's initial guess (as for a simulation's ``initial_estimate``).
    measurement_layout, input_layout : Layout, optional
        Names and units of the columns (a sensor's ``measurement_layout``, a plant's
        ``input_layout``); default: unnamed dimensionless columns.

    Returns
    -------
    xarray.Dataset
        Estimates (``v_hat``), the observer's extra outputs, the measurements and the
        inputs (as applied), with dims run (one), time and the label dims.

    Raises
    ------
    ValueError
        On inconsistent shapes, times that do not increase, or non-finite times or inputs.
    """
    times = np.asarray(times, dtype=float)
    measurements = np.asarray(measurements, dtype=float)
    if times.ndim != 1 or times.size < 1:
        raise ValueError(f"times must be a 1-D array with at least one row; got shape {times.shape}")
    if not np.all(np.isfinite(times)) or np.any(np.diff(times) <= 0):
        raise ValueError("times must be finite and strictly increasing")
    if measurements.ndim != 2 or measurements.shape[0] != times.size:
        raise ValueError(f"measurements must have shape ({times.size}, n_y); got {measurements.shape}")
    inputs = np.zeros((times.size, 0)) if inputs is None else np.asarray(inputs, dtype=float)
    if inputs.ndim != 2 or inputs.shape[0] != times.size:
        raise ValueError(f"inputs must have shape ({times.size}, n_u); got {inputs.shape}")
    if not np.all(np.isfinite(inputs)):
        raise ValueError("inputs must be finite (a missing input has no meaning for the prediction)")
    measurement_layout = measurement_layout or _generic_layout("y", measurements.shape[1])
    input_layout = input_layout or _generic_layout("u", inputs.shape[1])
    if measurement_layout.size != measurements.shape[1]:
        raise ValueError(f"measurement_layout has {measurement_layout.size} channels, the measurements {measurements.shape[1]}")
    if input_layout.size != inputs.shape[1]:
        raise ValueError(f"input_layout has {input_layout.size} entries, the inputs {inputs.shape[1]}")
    _check_log_fits(observer, guess, measurements.shape[1], inputs.shape[1])
    estimates = _filter_scan(observer, guess, jnp.asarray(times), jnp.asarray(measurements), jnp.asarray(inputs))
    signals = RecordSignals(
        truth=(), estimate=tuple(observer.estimate_signals), extra=tuple(observer.extra_signals),
        measurement=measurement_layout, reference=(), input=input_layout,
    )
    trajectory = Trajectory(
        times, {}, estimates, measurements, {}, inputs, inputs, signals=signals, batched=False,
        attrs={"observer": type(observer).__name__, "source_of_data": "log"},
    )
    return trajectory.to_xarray()


class Stepper:
    """An observer for live use: one compiled call per incoming sample.

    The observer's functions are compiled once, with the observer's gains baked in.
    State, inputs and estimate cross the boundary as one flat float64 vector each,
    so a call is one dispatch of a compiled function with two arguments (about
    10 us on the development machine, docs/benchmarks.md), not a trace.

    Parameters
    ----------
    observer : Observer
    guess : PyTree
        Initial guess.
    y0 : array_like
        The first measurement (NaN for a missing channel).
    input_size : int
        Length of the input vector ``u`` passed to each call.

    Examples
    --------
    >>> stepper = Stepper(observer, observer.guess(), y0, input_size=3)   # doctest: +SKIP
    >>> estimate = stepper(t, y, u, dt)   # estimate at t; the state moves to t + dt
    """

    def __init__(self, observer: Observer, guess, y0, input_size: int):
        y0 = jnp.asarray(y0, dtype=float)
        self.observer = observer
        self._measurement_size = int(y0.shape[0])
        flat_state, unravel_state = ravel_pytree(observer.init(y0, guess))
        template = jax.eval_shape(lambda s: observer.output(s, y0), unravel_state(flat_state))
        leaves, self._estimate_tree = jax.tree.flatten(template)
        ends = np.cumsum([int(np.prod(leaf.shape)) for leaf in leaves])
        # (start, end, shape) of each output in the flat estimate (np.split costs 70 us here)
        self._pieces = [(int(end) - int(np.prod(leaf.shape)), int(end), leaf.shape) for end, leaf in zip(ends, leaves)]
        n_y = self._measurement_size

        def advance(flat, packed):
            state = unravel_state(flat)
            t, dt, y, u = packed[0], packed[1], packed[2 : 2 + n_y], packed[2 + n_y :]
            state = observer.update(state, t, y)
            estimate = observer.output(state, y)
            state = observer.predict(state, t, y, u, dt)
            return ravel_pytree(state)[0], jnp.concatenate([jnp.ravel(leaf) for leaf in jax.tree.leaves(estimate)])

        self._advance = jax.jit(advance)
        self._input_size = int(input_size)
        self._unravel_state = unravel_state
        self._flat_state = flat_state

    @property
    def state(self):
        """The observer's internal state (a PyTree), at the time the next call expects."""
        return self._unravel_state(self._flat_state)

    def __call__(self, t, y, u, dt) -> dict:
        """The estimate at ``t`` from the measurement ``y`` (NaN = missing channel);
        then the internal state is propagated to ``t + dt`` with input ``u``.

        Returns
        -------
        dict of numpy.ndarray
            The observer's outputs by name.
        """
        packed = np.concatenate(([t, dt], np.asarray(y, dtype=float).ravel(), np.asarray(u, dtype=float).ravel()))
        if packed.shape[0] != 2 + self._measurement_size + self._input_size:
            raise ValueError(f"y and u must have {self._measurement_size} and {self._input_size} entries; got {packed.shape[0] - 2} in all")
        self._flat_state, flat_estimate = self._advance(self._flat_state, packed)
        flat = np.asarray(flat_estimate)
        return jax.tree.unflatten(self._estimate_tree, [flat[start:end].reshape(shape) for start, end, shape in self._pieces])
