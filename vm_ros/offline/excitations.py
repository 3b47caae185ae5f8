"""Drive time series for `vm-ros simulate --motion`: an OpenSim storage file, a CSV, or a constant.

Files (the format by suffix):

- ``.sto`` / ``.mot``: OpenSim storage, header lines up to ``endheader``, a line of column labels
  starting with ``time``, then rows of numbers (tab- or space-separated). Columns per muscle, as
  OpenSim writes controls: ``NAME`` (CMC ``*_controls.sto``, Static Optimization, Storage
  controls), ``/forceset/NAME`` (Moco trajectories), ``/forceset/NAME|excitation`` or
  ``NAME|excitation`` (TableReporter outputs), ``.../NAME/excitation`` and ``NAME.excitation``.
  Other paths (``/forceset/NAME/activation``, ``/jointset/...`` state columns) are not
  excitations and are skipped; columns for actuators that are not muscles of the run (reserve or
  residual actuators, other muscles) are ignored and listed in ``ignored``.
- ``.csv``: a header row ``time_s`` and one column per muscle (``NAME`` or ``NAME.excitation``),
  one row per sample. Here every column must be a muscle of the run (a misspelt name is an error).

Every muscle of the run needs a column (unless the caller gives a drive for muscles without one:
`vm-ros closed-loop` gives 0). Values are drives U, fractions in [0, 1]: a muscle's value
outside [-DRIVE_TOLERANCE, 1 + DRIVE_TOLERANCE] is an error (a file in percent says so), since
clipping it would change the result without a word. Values are interpolated linearly in time and
held constant outside the table.

The table's time axis is the run's (`vm-ros simulate --motion`: the motion's; `vm-ros
closed-loop`: 0 s at the start): a run whose span the table does not reach at all is an error;
one it covers only in part holds the first or last row for the rest, and
``ExcitationSeries.coverage`` says so (a warning; ``--strict`` makes it an error).
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from vm_ros.errors import VmRosError
from vm_ros.storage import numeric_rows, parse_storage

STORAGE_SUFFIXES = (".sto", ".mot")
_SUFFIXES = ("|excitation", "/excitation", ".excitation")
# Drives are fractions in [0, 1]; values beyond by more than this are an error, not clipped.
DRIVE_TOLERANCE = 1e-6
# A gap between the run's span and a table's time axis shorter than this is not reported (s).
COVERAGE_TOLERANCE_S = 1e-3
MOTION_AXIS = "the motion's time axis"   # the run's time axis of `vm-ros simulate --motion`


@dataclass(frozen=True)
class ExcitationSeries:
    """Drive per muscle over time: ``time_s`` (k,) s on the file's own time axis, ``values``
    (k, n) in ``muscles`` order; ``ignored``: file columns that were not used; ``absent``:
    muscles without a column (given the caller's drive)."""

    source: str
    muscles: tuple
    time_s: np.ndarray
    values: np.ndarray
    ignored: tuple = ()
    constant: bool = False
    absent: tuple = ()

    def coverage(self, start_s: float, end_s: float, axis: str = MOTION_AXIS) -> list[str]:
        """Warnings for the run span [start_s, end_s] (s, on the table's axis) where the table
        does not reach it and its first or last row is held; VmRosError when they do not
        overlap at all, saying the table must be on ``axis`` (the run's time axis, in words).
        None for a constant."""
        if self.constant:
            return []
        first, last = float(self.time_s[0]), float(self.time_s[-1])
        span = f"excitations {self.source} cover {first:.6g}-{last:.6g} s"
        if last < start_s or first > end_s:
            raise VmRosError(f"{span}, the run {start_s:.6g}-{end_s:.6g} s: no overlap; they "
                             f"must be on {axis}")
        held = []
        if first - start_s > COVERAGE_TOLERANCE_S:
            held.append(f"their first row for the {first - start_s:.6g} s before {first:.6g} s")
        if end_s - last > COVERAGE_TOLERANCE_S:
            held.append(f"their last row for the {end_s - last:.6g} s after {last:.6g} s")
        if not held:
            return []
        return [f"{span}, the run {start_s:.6g}-{end_s:.6g} s: the drives hold "
                f"{' and '.join(held)}"]

    def at(self, t_s: float) -> np.ndarray:
        """(n,) drives at time ``t_s`` (linear between rows, held outside)."""
        return self.at_many(np.array([t_s]))[0]

    def at_many(self, times_s) -> np.ndarray:
        """(k, n) drives at each of ``times_s`` (``at`` at each, element for element)."""
        return interpolate_rows(self.time_s, self.values, times_s)


def interpolate_rows(time_s, table, times_s) -> np.ndarray:
    """Rows of ``table`` (k_table, n) at ``time_s`` (increasing), linear between them and held
    outside, at each of ``times_s`` (k,): (k, n), row i + w (row i+1 - row i) with
    w = (t - time i) / (time i+1 - time i)."""
    times_s = np.asarray(times_s, dtype=float)
    out = np.empty((len(times_s), table.shape[1]))
    first, last = times_s <= time_s[0], times_s >= time_s[-1]
    out[first] = table[0]
    out[last & ~first] = table[-1]
    inside = ~(first | last)
    if inside.any():
        t = times_s[inside]
        i = np.searchsorted(time_s, t, side="right") - 1
        w = (t - time_s[i]) / (time_s[i + 1] - time_s[i])
        out[inside] = table[i] + w[:, None] * (table[i + 1] - table[i])
    return out


def constant_excitation(muscles, drive: float) -> ExcitationSeries:
    """The same drive for every muscle at every time."""
    if not np.isfinite(drive):
        raise VmRosError(f"--excitation must be a finite number (got {drive})")
    check_drive_range(np.array([[drive]]), ["every muscle"], np.zeros(1), "--excitation")
    return ExcitationSeries(f"constant {drive:g}", tuple(muscles), np.zeros(1),
                            np.full((1, len(muscles)), float(drive)), constant=True)


def check_drive_range(values, muscles, time_s, where: str) -> None:
    """VmRosError when a drive in ``values`` (k, n), columns ``muscles``, rows at ``time_s``, is
    outside [0, 1] by more than DRIVE_TOLERANCE: the message names the muscle, the time and the
    likely fix (percent: divide by 100)."""
    values = np.asarray(values, dtype=float)
    low, high = -DRIVE_TOLERANCE, 1.0 + DRIVE_TOLERANCE
    bad = (values < low) | (values > high)
    if not bad.any():
        return
    row, col = np.argwhere(bad)[np.argmax(np.abs(values[bad] - 0.5))]
    value = values[row, col]
    hint = ("; if the values are percent, divide them by 100" if 1.0 < values.max() <= 100.0
            and values.min() >= low else "")
    at = f" at {time_s[row]:.6g} s" if len(time_s) > 1 else ""
    raise VmRosError(f"{where}: drive {value:.6g} for {muscles[col]}{at}: drives are fractions "
                     f"in [0, 1]{hint}")


def excitation_muscle(label: str) -> str | None:
    """The muscle a column label gives the excitation of, or None (module docstring)."""
    text = label.strip()
    for suffix in _SUFFIXES:
        if text.endswith(suffix):
            text = text[: -len(suffix)]
            break
    if "/" not in text:
        return text or None
    parts = [p for p in text.split("/") if p]
    if len(parts) == 2 and parts[0] == "forceset":
        return parts[1]
    if parts and label.strip().endswith("/excitation"):
        return parts[-1]
    return None


def load_excitations(path, muscles, missing_drive: float | None = None) -> ExcitationSeries:
    """The drives of ``muscles`` from a .sto/.mot or .csv file; VmRosError naming the file and
    the problem (unreadable, no time column, times not increasing, a non-number, a muscle without
    a column unless ``missing_drive`` gives its drive, a CSV column that is not a muscle of the
    run, a drive outside [0, 1])."""
    path = Path(path)
    storage = path.suffix.lower() in STORAGE_SUFFIXES
    if not storage and path.suffix.lower() != ".csv":
        raise VmRosError(f"excitations {path}: expected a .sto, .mot or .csv file")
    try:
        text = path.read_text(encoding="utf-8", errors="replace")
    except OSError as exc:
        raise VmRosError(f"excitations {path}: cannot read ({exc.strerror or exc})") from exc
    labels, rows = _storage_table(path, text) if storage else _csv_table(path, text)
    table = numeric_rows(path, labels, rows, "excitations")
    time = table[:, 0]
    if np.any(np.diff(time) <= 0):
        raise VmRosError(f"excitations {path}: times must increase strictly")
    columns: dict[str, int] = {}
    ignored = []
    for i, label in enumerate(labels[1:], start=1):
        name = excitation_muscle(label)
        if name is not None and name in muscles:
            if name in columns:
                raise VmRosError(f"excitations {path}: two columns for muscle {name!r} "
                                 f"({labels[columns[name]]!r}, {label!r})")
            columns[name] = i
        elif storage:
            ignored.append(label)
        else:
            raise VmRosError(f"excitations {path}: column {label!r} is not a muscle of the run "
                             f"({', '.join(muscles)})")
    missing = [m for m in muscles if m not in columns]
    if missing and missing_drive is None:
        raise VmRosError(f"excitations {path}: no column for muscle(s) {', '.join(missing)}")
    values = np.column_stack([table[:, columns[m]] if m in columns
                              else np.full(len(time), float(missing_drive)) for m in muscles])
    check_drive_range(values, muscles, time, f"excitations {path}")
    return ExcitationSeries(str(path), tuple(muscles), time, values, tuple(ignored),
                            absent=tuple(missing))


def _storage_table(path: Path, text: str) -> tuple[list[str], list[list[str]]]:
    table = parse_storage(path, text, "excitations")
    return table.labels, table.rows


def _csv_table(path: Path, text: str) -> tuple[list[str], list[list[str]]]:
    rows = [row for row in csv.reader(text.splitlines()) if row]
    if not rows or rows[0][0].strip() != "time_s":
        raise VmRosError(f"excitations {path}: the first column must be 'time_s'")
    return [label.strip() for label in rows[0]], rows[1:]


__all__ = ["ExcitationSeries", "check_drive_range", "constant_excitation", "excitation_muscle",
           "load_excitations"]
