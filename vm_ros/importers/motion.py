"""OpenSim motion files (.mot, .sto) without OpenSim: a time column and coordinate columns.

Format: header lines up to ``endheader`` (among them ``inDegrees=yes|no``, required here because
it decides the units; any other value is an error: OpenSim's Storage reads ``yes`` in any case as
degrees and every other word, ``true`` included, silently as radians), then a tab- or
space-separated line of column labels starting with ``time``, then one row of numbers per frame.
Labels are coordinate names (IK output) or state paths (``/jointset/knee_r/knee_angle_r/value``;
``.../speed`` and non-coordinate columns of a states file are skipped). Values stay as written;
``Motion.to_si`` converts the rotational columns from degrees when the header says so.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from vm_ros.errors import VmRosError
from vm_ros.storage import numeric_rows, parse_storage

IN_DEGREES = {"yes": True, "no": False}  # the header's inDegrees values (case-insensitive)


@dataclass(frozen=True)
class Motion:
    """One motion file: ``names`` (coordinate per column), ``time`` (n_frames,) s, ``values``
    (n_frames, n_columns) as written, ``in_degrees`` from the header."""

    path: str
    names: tuple[str, ...]
    time: np.ndarray
    values: np.ndarray
    in_degrees: bool

    def to_si(self, rotational) -> np.ndarray:
        """Values in rad (rotational columns, converted when the file is in degrees) and m."""
        if not self.in_degrees:
            return self.values.copy()
        factor = np.array([np.pi / 180.0 if n in rotational else 1.0 for n in self.names])
        return self.values * factor


def _label(label: str) -> str | None:
    """Coordinate name of a column label, or None for a column that is not a coordinate value."""
    if "/" not in label:
        return label
    parts = [p for p in label.split("/") if p]
    if len(parts) >= 3 and parts[0] == "jointset" and parts[-1] == "value":
        return parts[-2]
    return None


def read_motion(path) -> Motion:
    """Read a .mot/.sto file; VmRosError naming the file and the problem."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8", errors="replace")
    except OSError as exc:
        raise VmRosError(f"motion {path}: cannot read ({exc.strerror or exc})") from exc
    table = parse_storage(path, text, "motion")
    in_degrees = table.header.get("indegrees")
    if in_degrees is None:
        raise VmRosError(f"motion {path}: the header has no 'inDegrees=yes|no' line, so the "
                         "units are unknown; add it")
    if in_degrees.lower() not in IN_DEGREES:
        raise VmRosError(f"motion {path}: header 'inDegrees={in_degrees}' is neither yes "
                         "(degrees) nor no (radians); write one of them")
    in_degrees = IN_DEGREES[in_degrees.lower()]
    labels = table.labels
    data = numeric_rows(path, labels, table.rows, "motion")
    if np.any(np.diff(data[:, 0]) <= 0):
        raise VmRosError(f"motion {path}: times must increase strictly (row "
                         f"{int(np.argmax(np.diff(data[:, 0]) <= 0)) + 2} does not)")
    keep = [(i, name) for i, name in enumerate(map(_label, labels)) if i > 0 and name]
    if not keep:
        raise VmRosError(f"motion {path}: no coordinate columns")
    return Motion(str(path), tuple(n for _, n in keep), data[:, 0],
                  data[:, [i for i, _ in keep]], in_degrees)


__all__ = ["Motion", "read_motion"]
