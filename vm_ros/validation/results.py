"""Validation results: a numeric criterion and the outcome of one validation item."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class Criterion:
    """One numeric criterion: ``value`` must lie in [low, high] (None: unbounded).

    A criterion with neither bound is a number reported beside the criteria, not a criterion:
    its status is 'reported' and ``vm-ros validate`` counts it apart (it cannot pass or fail).

    ``known_gap``: where the model is known to miss this criterion, why (and where the report says
    more). The bounds stay the published ones; a known gap that fails is reported as GAP, not as
    an unexplained failure, and one that passes is reported as passing. A band set from the
    model's own output is not a criterion: the published band is kept and the miss is a known gap.
    """

    description: str
    value: float
    low: float | None = None
    high: float | None = None
    known_gap: str = ""

    @property
    def bounded(self) -> bool:
        """True when at least one bound is set (False: a number reported without a bound)."""
        return self.low is not None or self.high is not None

    @property
    def status(self) -> str:
        """'pass', 'GAP' (fails, known and explained), 'FAIL', or 'reported' (no bound)."""
        if not self.bounded:
            return "reported"
        if self.passed:
            return "pass"
        return "GAP" if self.known_gap else "FAIL"

    @property
    def passed(self) -> bool:
        return bool(np.isfinite(self.value)
                    and (self.low is None or self.value >= self.low)
                    and (self.high is None or self.value <= self.high))

    def bounds(self) -> str:
        low = "-inf" if self.low is None else f"{self.low:g}"
        high = "inf" if self.high is None else f"{self.high:g}"
        return f"[{low}, {high}]"


@dataclass
class CheckResult:
    """Outcome of one validation item: the paper's claim, the criteria and the data to plot."""

    item: str
    title: str
    claim: str
    criteria: list = field(default_factory=list)
    data: dict = field(default_factory=dict)
    seconds: float = 0.0

    @property
    def passed(self) -> bool:
        return all(c.passed for c in self.criteria)

    @property
    def status(self) -> str:
        """'PASS', 'PASS with known gaps' or 'FAIL' (a failure that is not a known gap)."""
        statuses = {c.status for c in self.criteria if c.bounded}
        if "FAIL" in statuses:
            return "FAIL"
        return "PASS with known gaps" if "GAP" in statuses else "PASS"


STATUSES = ("pass", "FAIL", "GAP", "reported")


def count_statuses(criteria) -> dict[str, int]:
    """How many of ``criteria`` have each status of :data:`STATUSES`."""
    statuses = [c.status for c in criteria]
    return {status: statuses.count(status) for status in STATUSES}


def counts_line(counts: dict[str, int]) -> str:
    """The headline of a validation run: the bounded criteria (passed / failed / known gaps)
    and, apart, the numbers reported without a bound."""
    bounded = counts["pass"] + counts["FAIL"] + counts["GAP"]
    return (f"{bounded} criteria bounded: {counts['pass']} passed / {counts['FAIL']} failed / "
            f"{counts['GAP']} known gaps\n{counts['reported']} numbers reported without a bound")
