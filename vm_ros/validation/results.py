"""Validation results: a numeric criterion and the outcome of one validation item."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class Criterion:
    """One numeric criterion: ``value`` must lie in [low, high] (None: unbounded).

    ``known_gap``: where the model is known to miss this criterion, why (and where the report says
    more). The bounds stay the published ones; a known gap that fails is reported as GAP, not as
    an unexplained failure, and one that passes is reported as passing.
    """

    description: str
    value: float
    low: float | None = None
    high: float | None = None
    known_gap: str = ""

    @property
    def status(self) -> str:
        """'pass', 'GAP' (fails, known and explained) or 'FAIL'."""
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
        statuses = {c.status for c in self.criteria}
        if "FAIL" in statuses:
            return "FAIL"
        return "PASS with known gaps" if "GAP" in statuses else "PASS"
