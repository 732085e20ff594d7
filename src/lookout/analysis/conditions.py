"""One vocabulary for the papers' sufficient conditions: Verdict, Inequality, Condition, Report.

Every check in :mod:`lookout.analysis` states its result in these terms, and every
``lookout design`` command prints and dumps them through the same code:

* an :class:`Inequality` is one inequality of a paper evaluated on concrete numbers:
  its two sides, the comparison, the units, the margin and the verdict, and where it
  comes from (paper and equation);
* a :class:`Condition` is a numbered condition of a paper (e.g. Calugi et al. (2003),
  (57)): its inequalities, the verdict they give, and a one-line reason;
* a :class:`Report` is the set of conditions checked for one design, with the numbers
  they were built from.

Verdicts (:class:`Verdict`): ``holds``, ``fails``, or ``unverified`` where the numbers
cannot decide it: the two sides agree within the rounding tolerance, a side is NaN, or a
search for a certificate (a KYP pair P, Q) found none, which does not prove that none
exists. A condition fails when one of its inequalities fails and holds when all hold;
a report likewise over its conditions.

JSON (:meth:`Report.to_dict`), one layout for every report::

    {"title": str, "verdict": "holds" | "fails" | "unverified", "holds": bool,
     "verdicts": {key: verdict, ...},          # one per condition, in order
     key: {"key", "name", "title", "source", "verdict", "reason",
           "inequalities": [inequality, ...], "informational": [inequality, ...],
           "quantities": {...}},               # one block per condition, under its key
     "quantities": {...}, "summary": [str, ...], "notes": [str, ...]}

    inequality = {"name", "relation", "left", "comparison", "right", "units", "source",
                  "verdict", "margin", "factor", "tolerance"}

(non-finite numbers are null). Each inequality is written once, in its condition's
block; ``verdicts`` gives the blocks' keys in order (:func:`inequalities_in` reads them
all back as one table). Terminal
(:meth:`Report.lines`): the title and verdict, the summary lines, then per condition a
header (name, title, source, verdict), its reason and one line per inequality (name,
relation, the two sides, units, verdict, margin), then the notes.
"""

from __future__ import annotations

import dataclasses
import enum
import math
import operator
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from lookout import _validation as check
from lookout._json import json_safe

#: Relative tolerance within which the two sides of an inequality count as equal.
TOLERANCE = 1e-12

#: The comparisons an :class:`Inequality` may make, left against right.
COMPARISONS = {">": operator.gt, ">=": operator.ge, "<": operator.lt, "<=": operator.le}

#: Top-level keys of :meth:`Report.to_dict` (and those a design command adds), which no
#: condition key may take.
RESERVED_KEYS = frozenset({"title", "verdict", "holds", "verdicts", "quantities", "summary", "notes", "design", "inputs"})


class Verdict(enum.StrEnum):
    """The verdict of an inequality, a condition or a report; compares equal to its value."""

    HOLDS = "holds"
    FAILS = "fails"
    UNVERIFIED = "unverified"

    @classmethod
    def combine(cls, verdicts: Iterable[Verdict]) -> Verdict:
        """``fails`` when one fails, ``holds`` when there is at least one and all hold,
        else ``unverified`` (nothing checked, or something undecided)."""
        verdicts = list(verdicts)
        if cls.FAILS in verdicts:
            return cls.FAILS
        if verdicts and all(v == cls.HOLDS for v in verdicts):
            return cls.HOLDS
        return cls.UNVERIFIED


def number(value: float, digits: int = 4) -> str:
    """``value`` with ``digits`` significant digits; nan, inf and -inf spelled out."""
    value = float(value)
    if math.isnan(value):
        return "nan"
    if math.isinf(value):
        return "inf" if value > 0 else "-inf"
    return f"{value:.{digits}g}"


def numbers(values: npt.ArrayLike, digits: int = 3) -> str:
    """The values of an array, each by :func:`number` right-aligned in 9 columns."""
    return " ".join(f"{number(v, digits):>9}" for v in np.ravel(np.asarray(values, dtype=float)))


def _sides(left: float, right: float) -> tuple[str, str]:
    """Both sides with 4 significant digits, or as many more as it takes to show that they differ."""
    for digits in range(4, 18):
        shown = number(left, digits), number(right, digits)
        if shown[0] != shown[1] or left == right or not (math.isfinite(left) and math.isfinite(right)):
            break
    return shown


@dataclass(frozen=True)
class Inequality:
    """One inequality of a paper, ``left <comparison> right``, on concrete numbers.

    Build it with :meth:`check`, which decides the verdict.

    Attributes
    ----------
    name : str
        A short label, e.g. ``"(22a)"`` or the DOF of a per-DOF inequality.
    relation : str
        The inequality in the paper's symbols, e.g. ``"sigma1 > g1/4 + ..."``.
    left, right : float
        The two sides (SI).
    comparison : str
        One of ``>``, ``>=``, ``<``, ``<=``: what ``left`` must be to ``right``.
    units : str
        Units of the sides.
    source : str
        Paper and equation, e.g. ``"Calugi et al. (2003), eq. (57)"``.
    verdict : Verdict
    margin : float
        By how much it holds, in the units of the sides: ``left - right`` for ``>``,
        ``>=`` and ``right - left`` for ``<``, ``<=``; negative when it fails.
    factor : float
        The same as a ratio: ``left / right`` for ``>``, ``>=`` and ``right / left`` for
        ``<``, ``<=`` (> 1 when it holds); inf when the smaller side is 0 and the larger
        positive, nan when a side is negative.
    tolerance : float
        Sides closer than this (absolute) are numerically equal: ``unverified``.
    """

    name: str
    relation: str
    left: float
    comparison: str
    right: float
    units: str
    source: str
    verdict: Verdict
    margin: float
    factor: float
    tolerance: float

    @classmethod
    def check(
        cls,
        name: str,
        relation: str,
        left: float,
        comparison: str,
        right: float,
        *,
        units: str,
        source: str,
        tolerance: float | None = None,
        failure: Verdict = Verdict.FAILS,
    ) -> Inequality:
        """Evaluate ``left <comparison> right`` and decide its verdict.

        ``holds`` when the comparison is true by more than ``tolerance`` (default
        :data:`TOLERANCE` times the larger finite side), or for ``>=``, ``<=`` when the
        two sides are the same number; ``unverified`` when they are equal within the
        tolerance or a side is NaN; otherwise ``failure``: ``fails``, or ``unverified``
        for a test whose failure does not disprove the condition (a certificate search).
        """
        if comparison not in COMPARISONS:
            raise check.ParameterError("comparison", f"comparison must be one of {', '.join(COMPARISONS)}; got {comparison!r}")
        left, right = float(left), float(right)
        big, small = (left, right) if comparison in (">", ">=") else (right, left)
        with np.errstate(invalid="ignore"):
            margin = big - small
        if small > 0 and big >= 0:
            factor = big / small
        elif small == 0 and big > 0:
            factor = math.inf
        else:
            factor = math.nan
        if tolerance is None:
            finite = [abs(v) for v in (left, right) if math.isfinite(v)]
            tolerance = TOLERANCE * max(finite, default=0.0)
        if math.isnan(margin):
            verdict = Verdict.UNVERIFIED
        elif left == right and comparison in (">=", "<="):
            verdict = Verdict.HOLDS
        elif abs(margin) <= tolerance:
            verdict = Verdict.UNVERIFIED
        else:
            verdict = Verdict.HOLDS if COMPARISONS[comparison](left, right) else Verdict(failure)
        return cls(name, relation, left, comparison, right, units, source, verdict, margin, factor, float(tolerance))

    @property
    def holds(self) -> bool:
        """True when the verdict is ``holds``."""
        return self.verdict == Verdict.HOLDS

    def to_dict(self) -> dict:
        """JSON-safe form (non-finite numbers are None)."""
        return json_safe(
            {
                "name": self.name,
                "relation": self.relation,
                "left": self.left,
                "comparison": self.comparison,
                "right": self.right,
                "units": self.units,
                "source": self.source,
                "verdict": self.verdict,
                "margin": self.margin,
                "factor": self.factor,
                "tolerance": self.tolerance,
            }
        )

    def describe(self) -> str:
        """One line: name, relation, both sides, units, verdict and margin."""
        left, right = _sides(self.left, self.right)
        units = f" {self.units}" if self.units else ""
        ratio = f", factor {number(self.factor, 3)}" if math.isfinite(self.factor) else ""
        return f"{self.name}: {self.relation}: {left} {self.comparison} {right}{units}: {self.verdict}, margin {number(self.margin, 3)}{ratio}"


def _reason(verdict: Verdict, inequalities: Sequence[Inequality]) -> str:
    """The reason a condition gives when none is stated: which inequalities decide it."""
    if not inequalities:
        return "nothing was checked"
    if verdict == Verdict.HOLDS:
        return "every inequality holds" if len(inequalities) > 1 else "the inequality holds"
    chosen = [item for item in inequalities if item.verdict == verdict]
    what = "fails" if verdict == Verdict.FAILS else "is not decided numerically"
    return "; ".join(f"{item.name}: {item.relation} {what}" for item in chosen)


@dataclass(frozen=True)
class Condition:
    """A numbered condition of a paper: its inequalities, their verdict, a one-line reason.

    Attributes
    ----------
    key : str
        Identifier in JSON, e.g. ``"closed_loop_57"``.
    name : str
        The paper's number for it, e.g. ``"(57)"``.
    title : str
        What it asks, in a few words.
    source : str
        Paper and equation.
    inequalities : sequence of Inequality
        The inequalities that decide the verdict (stored as a tuple).
    reason : str
        One line: why the verdict is what it is; by default the inequalities that
        decide it.
    informational : sequence of Inequality
        Inequalities reported alongside that do not enter the verdict (a tighter
        variant, a margin worth seeing).
    quantities : mapping
        The numbers it was built from (SI).
    """

    key: str
    name: str
    title: str
    source: str
    inequalities: Sequence[Inequality]
    reason: str = ""
    informational: Sequence[Inequality] = ()
    quantities: Mapping = field(default_factory=dict)

    def __post_init__(self):
        object.__setattr__(self, "inequalities", tuple(self.inequalities))
        object.__setattr__(self, "informational", tuple(self.informational))
        if not self.reason:
            object.__setattr__(self, "reason", _reason(self.verdict, self.inequalities))
        if "\n" in self.reason:
            raise ValueError(f"a condition's reason is one line; got {self.reason!r}")

    @property
    def verdict(self) -> Verdict:
        """``fails`` when an inequality fails, ``holds`` when every one holds, else
        ``unverified`` (also when there are none)."""
        return Verdict.combine(item.verdict for item in self.inequalities)

    @property
    def holds(self) -> bool:
        """True when the verdict is ``holds``."""
        return self.verdict == Verdict.HOLDS

    def to_dict(self) -> dict:
        """JSON-safe form: the block of :meth:`Report.to_dict` under ``key``."""
        return json_safe(
            {
                "key": self.key,
                "name": self.name,
                "title": self.title,
                "source": self.source,
                "verdict": self.verdict,
                "reason": self.reason,
                "inequalities": [item.to_dict() for item in self.inequalities],
                "informational": [item.to_dict() for item in self.informational],
                "quantities": dict(self.quantities),
            }
        )

    def lines(self) -> list[str]:
        """The header, the reason, one line per inequality (informational ones marked)."""
        lines = [f"{self.name} {self.title} [{self.source}]: {self.verdict}", f"  {self.reason}"]
        lines += [f"    {item.describe()}" for item in self.inequalities]
        lines += [f"    (not in the verdict) {item.describe()}" for item in self.informational]
        return lines


@dataclass(frozen=True)
class Report:
    """The conditions checked for one design, and the numbers they were built from.

    Attributes
    ----------
    title : str
        The paper and what was checked.
    conditions : tuple of Condition
        Their keys are unique and none is one of :data:`RESERVED_KEYS`.
    quantities : mapping
        Numbers that the conditions share (gains, model bounds), JSON-able.
    summary : tuple of str
        Lines that describe the design checked, printed under the title.
    notes : tuple of str
        Lines printed after the conditions.
    """

    title: str
    # any sequence is taken; __post_init__ keeps a tuple
    conditions: Sequence[Condition]
    quantities: Mapping = field(default_factory=dict)
    summary: Sequence[str] = ()
    notes: Sequence[str] = ()

    def __post_init__(self):
        object.__setattr__(self, "conditions", tuple(self.conditions))
        object.__setattr__(self, "summary", tuple(self.summary))
        object.__setattr__(self, "notes", tuple(self.notes))
        keys = [condition.key for condition in self.conditions]
        if len(set(keys)) != len(keys):
            raise check.ParameterError("condition", f"condition keys must be unique; got {keys}")
        clash = sorted(set(keys) & RESERVED_KEYS)
        if clash:
            raise check.ParameterError("condition", f"condition keys must not be a report key ({', '.join(sorted(RESERVED_KEYS))}); got {clash}")

    @property
    def verdict(self) -> Verdict:
        """``fails`` when a condition fails, ``holds`` when every one holds, else
        ``unverified`` (also when there are none)."""
        return Verdict.combine(condition.verdict for condition in self.conditions)

    @property
    def holds(self) -> bool:
        """True when the verdict is ``holds``."""
        return self.verdict == Verdict.HOLDS

    @property
    def verdicts(self) -> dict[str, Verdict]:
        """The verdict of each condition, by key, in order."""
        return {condition.key: condition.verdict for condition in self.conditions}

    @property
    def inequalities(self) -> tuple[Inequality, ...]:
        """Every inequality of every condition, in order (informational ones left out)."""
        return tuple(item for condition in self.conditions for item in condition.inequalities)

    def __getitem__(self, key: str) -> Condition:
        for condition in self.conditions:
            if condition.key == key:
                return condition
        raise KeyError(f"no condition {key!r}; the report has {', '.join(self.verdicts) or 'none'}")

    def extended(self, *, summary: Iterable[str] = (), notes: Iterable[str] = (), quantities: Mapping | None = None) -> Report:
        """This report with ``summary`` lines put first, ``notes`` added last and
        ``quantities`` added (a design command adds what it chose)."""
        return dataclasses.replace(
            self,
            summary=(*summary, *self.summary),
            notes=(*self.notes, *notes),
            quantities={**self.quantities, **(quantities or {})},
        )

    def to_dict(self) -> dict:
        """JSON-safe form, the layout of the module docstring."""
        return json_safe(
            {
                "title": self.title,
                "verdict": self.verdict,
                "holds": self.holds,
                "verdicts": self.verdicts,
                **{condition.key: condition.to_dict() for condition in self.conditions},
                "quantities": dict(self.quantities),
                "summary": list(self.summary),
                "notes": list(self.notes),
            }
        )

    def lines(self) -> list[str]:
        """The terminal form (module docstring)."""
        lines = [f"{self.title}: {self.verdict}", *(f"  {line}" for line in self.summary)]
        for condition in self.conditions:
            lines += condition.lines()
        return lines + [f"note: {note}" for note in self.notes]

    def text(self) -> str:
        """:meth:`lines` joined by newlines."""
        return "\n".join(self.lines())


def inequalities_in(data: Mapping) -> list[dict]:
    """Every inequality of a report's JSON (:meth:`Report.to_dict`, as a summary.json holds
    it), condition by condition in the order of its ``verdicts`` (the table view)."""
    return [item for key in data["verdicts"] for item in data[key]["inequalities"]]


__all__ = [
    "COMPARISONS",
    "RESERVED_KEYS",
    "TOLERANCE",
    "Condition",
    "Inequality",
    "Report",
    "Verdict",
    "inequalities_in",
    "number",
    "numbers",
]
