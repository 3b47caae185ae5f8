"""Input time series from a CSV file, as functions of time for an offline run.

Columns: ``time_s`` (s, increasing), then per muscle ``<muscle>.excitation`` (drive U, a fraction
in [0, 1]: anything else is an error, see vm_ros.offline.excitations) and
``<muscle>.path_length`` (m), optionally ``<muscle>.path_velocity`` (m/s). Values between rows
are interpolated linearly (held constant outside the table); a missing path velocity is the
finite-difference derivative of the path length (numpy.gradient).
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from vm_ros.errors import ConfigError
from vm_ros.offline.excitations import check_drive_range

QUANTITIES = ("excitation", "path_length", "path_velocity")
REQUIRED = ("excitation", "path_length")


@dataclass(frozen=True)
class InputSeries:
    """Tabulated inputs: time_s (k,), and (k, n) arrays per quantity, columns in ``muscles``."""

    path: Path
    muscles: tuple
    time_s: np.ndarray
    values: dict

    @property
    def duration_s(self) -> float:
        return float(self.time_s[-1] - self.time_s[0])

    def _interpolate(self, quantity: str, t) -> np.ndarray:
        """At t (s from the table's start) a number: (n,); t an array (k,): (k, n)."""
        table = self.values[quantity]
        return np.stack([np.interp(t, self.time_s, table[:, i])
                         for i in range(table.shape[1])], axis=-1)

    def excitation(self, t: float) -> np.ndarray:
        return self._interpolate("excitation", t + self.time_s[0])

    def path_length(self, t: float) -> np.ndarray:
        return self._interpolate("path_length", t + self.time_s[0])

    def path_velocity(self, t: float) -> np.ndarray:
        return self._interpolate("path_velocity", t + self.time_s[0])

    def select(self, muscles) -> InputSeries:
        """The same series restricted to (and ordered as) ``muscles``."""
        missing = [m for m in muscles if m not in self.muscles]
        if missing:
            raise ConfigError(self.path, f"{missing[0]}.excitation", None,
                              f"no columns for muscle {missing[0]!r} (have: "
                              f"{', '.join(self.muscles)})")
        index = [self.muscles.index(m) for m in muscles]
        return InputSeries(self.path, tuple(muscles), self.time_s,
                           {q: a[:, index] for q, a in self.values.items()})


def load_input_series(path) -> InputSeries:
    """Read and check a CSV of inputs (see module docstring); ConfigError names the problem."""
    path = Path(path)
    try:
        with open(path, newline="", encoding="utf-8") as handle:
            rows = list(csv.reader(handle))
    except OSError as exc:
        raise ConfigError(path, "<file>", None, f"cannot read: {exc.strerror or exc}") from exc
    if not rows or "time_s" not in rows[0]:
        raise ConfigError(path, "time_s", None, "missing column 'time_s' in the header row")
    header = [h.strip() for h in rows[0]]
    try:
        table = np.array([[float(x) for x in row] for row in rows[1:] if row], dtype=float)
    except ValueError as exc:
        raise ConfigError(path, "<rows>", None, f"not a number: {exc}") from exc
    if table.ndim != 2 or table.shape[0] < 2 or table.shape[1] != len(header):
        raise ConfigError(path, "<rows>", table.shape, "need at least 2 full rows")
    if not np.all(np.isfinite(table)):
        raise ConfigError(path, "<rows>", None, "values must be finite")
    time_s = table[:, header.index("time_s")]
    if np.any(np.diff(time_s) <= 0):
        raise ConfigError(path, "time_s", None, "times must increase strictly")
    muscles: list[str] = []
    for name in header:
        muscle, dot, quantity = name.rpartition(".")
        if name == "time_s":
            continue
        if not dot or quantity not in QUANTITIES:
            raise ConfigError(path, name, None, "columns are time_s and <muscle>.<quantity> "
                              f"with quantity one of {', '.join(QUANTITIES)}")
        if muscle not in muscles:
            muscles.append(muscle)
    values = {}
    for quantity in QUANTITIES:
        columns = []
        for muscle in muscles:
            key = f"{muscle}.{quantity}"
            if key in header:
                columns.append(table[:, header.index(key)])
            elif quantity in REQUIRED:
                raise ConfigError(path, key, None, "missing column")
            else:
                lengths = table[:, header.index(f"{muscle}.path_length")]
                columns.append(np.gradient(lengths, time_s))
        values[quantity] = np.stack(columns, axis=1)
    check_drive_range(values["excitation"], muscles, time_s, f"inputs {path}")
    return InputSeries(path, tuple(muscles), time_s, values)
