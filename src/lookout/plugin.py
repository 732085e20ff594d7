"""What a plugin author imports: one public module for a kind of one's own.

A plugin is a Python file (or a module, or an installed package's module under the
entry-point group ``lookout.components``) that declares one or more kinds with
:func:`component`; a scenario names it in ``plugins = [...]`` and uses its kinds as it
uses lookout's (docs/architecture.md, "Adding an observer";
``examples/plugins/luenberger.py`` is one). This module gathers what such a file needs
beyond the contract (:mod:`lookout.components`) and the models (:mod:`lookout.models`):

Declaring a kind
    :func:`component` (a class decorator), :func:`register` (a statement),
    :class:`Rule`, :class:`Value`, :class:`Part`, :class:`Context`, :class:`Range`
    with :data:`POSITIVE` and :data:`NON_NEGATIVE`, and :func:`initial_values` for a
    ``guess`` or a ``state`` (:mod:`lookout.declare` describes each).
Refusing a parameter
    :class:`ParameterError` (a ``ValueError`` carrying the key, so that a scenario file's
    error names the key and its line) and the checks under :class:`check`
    (``check.vector``, ``check.positive``, ``check.finite``, ``check.square``,
    ``check.symmetric_positive_definite``, ``check.dissipative``), each raising a
    ParameterError that names the parameter.
Planar kinematics
    :func:`ssa` (an angle wrapped to [-pi, pi)), :func:`rotation` (J(psi) of Fossen &
    Strand 1999, eq. 2), :func:`rotate` and :func:`rotate_transpose` (J(psi) v and
    J(psi)^T v written out), :func:`skew` (S(r), d/dt J = J S), :func:`matvec` (a small
    matrix times a vector, written out).
A continuous-time observer's sampled step
    :func:`integrate_sample` (Runge–Kutta or Euler steps over one sample, the
    ``predict`` of lookout's own continuous-time observers) and
    :func:`from_first_measurement` (an ``init`` that starts the measured states from the
    first measurement where the guess leaves them NaN).

A discrete-time observer gets its sample period from the composition: declare
``Context("filter_period")`` and the composition passes ``[simulation] sample_period``.

Every name is the object lookout's own components use (re-exported here, not copied),
so a plugin behaves as a built-in kind does.
"""

from __future__ import annotations

from lookout import _validation
from lookout._math import matvec, rotate, rotate_transpose, rotation, ssa
from lookout._validation import ParameterError
from lookout.declare import (
    NON_NEGATIVE,
    POSITIVE,
    Context,
    Part,
    Range,
    Rule,
    Value,
    component,
    initial_values,
    register,
)
from lookout.models.cybership import skew
from lookout.observers.start import from_first_measurement
from lookout.sim.integrators import integrate_sample


class check:  # noqa: N801 - a namespace, used as check.vector(...)
    """The checks of a parameter's value, each raising a :class:`ParameterError` whose
    message names the parameter and the condition (``bandwidth must be positive; got
    [0.05, 0, 0.05]``). Each takes the parameter's name first; on a JAX tracer (a
    component built inside ``jit`` or ``vmap``) a check of values passes, as the values
    were checked when the concrete component was built.

    Attributes
    ----------
    vector : callable
        ``vector(name, value, size=3)``: a scalar or a sequence as a float vector of
        ``size`` entries.
    finite : callable
        ``finite(name, value)``: every entry finite.
    positive : callable
        ``positive(name, value, allow_zero=False)``: every entry > 0 (>= 0).
    square : callable
        ``square(name, matrix, size=3)``: a finite ``size`` x ``size`` matrix.
    symmetric_positive_definite : callable
        ``symmetric_positive_definite(name, matrix, size=None)``: a mass or gain matrix.
    dissipative : callable
        ``dissipative(name, matrix)``: a damping matrix, nu^T D nu >= 0.
    ParameterError : type
        The error the checks raise (:class:`lookout.plugin.ParameterError`).
    """

    vector = staticmethod(_validation.vector)
    finite = staticmethod(_validation.finite)
    positive = staticmethod(_validation.positive)
    square = staticmethod(_validation.square)
    symmetric_positive_definite = staticmethod(_validation.symmetric_positive_definite)
    dissipative = staticmethod(_validation.dissipative)
    ParameterError = _validation.ParameterError

    def __new__(cls, *args, **kwargs):
        raise TypeError("lookout.plugin.check is a namespace of checks (check.vector(...)), not a class to instantiate")


__all__ = [
    "Context",
    "NON_NEGATIVE",
    "POSITIVE",
    "ParameterError",
    "Part",
    "Range",
    "Rule",
    "Value",
    "check",
    "component",
    "from_first_measurement",
    "initial_values",
    "integrate_sample",
    "matvec",
    "register",
    "rotate",
    "rotate_transpose",
    "rotation",
    "skew",
    "ssa",
]
