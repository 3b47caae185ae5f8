"""OpenSim motion files (.mot, .sto) without OpenSim: a time column and coordinate columns.

Format: header lines up to ``endheader`` (among them ``inDegrees=yes|no``, required here because
it decides the units; any other value is an error: OpenSim's Storage reads ``yes`` in any case as
degrees and every other word, ``true`` included, silently as radians), then a tab- or
space-separated line of column labels starting with ``time``, then one row of numbers per frame.
Labels are coordinate names (IK output) or state paths (``/jointset/knee_r/knee_angle_r/value``);
a states file's ``.../speed`` columns are kept as the coordinates' speeds (``Motion.speeds``), its
other columns skipped. Values stay as written; ``Motion.to_si`` converts the rotational columns
from degrees when the header says so.

The declared unit is checked where the values cannot be in it (``Motion.unit_warnings``): a
rotational column beyond RADIAN_LIMIT (2 pi, a full turn) in a file that says ``inDegrees=no`` is
an error (the file is in degrees); a file that says ``inDegrees=yes`` whose rotational columns all
stay within +-DEGREE_SUSPECT (pi degrees, about 3 deg) while moving is a warning (the file may be
in radians).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from vm_ros.errors import VmRosError
from vm_ros.storage import check_increasing, numeric_rows, read_storage

IN_DEGREES = {"yes": True, "no": False}  # the header's inDegrees values (case-insensitive)
RADIAN_LIMIT = 2.0 * np.pi   # rad: no joint angle in radians is beyond a full turn
DEGREE_SUSPECT = np.pi       # deg: a moving motion that stays within +-pi "degrees" is in radians


@dataclass(frozen=True)
class Motion:
    """One motion file: ``names`` (coordinate per column), ``time`` (n_frames,) s, ``values``
    (n_frames, n_columns) as written, ``in_degrees`` from the header."""

    path: str
    names: tuple[str, ...]
    time: np.ndarray
    values: np.ndarray
    in_degrees: bool
    speeds: dict = field(default_factory=dict)

    def to_si(self, rotational) -> np.ndarray:
        """Values in rad (rotational columns, converted when the file is in degrees) and m."""
        return self.values * self._factors(self.names, rotational)

    def speeds_to_si(self, rotational) -> dict[str, np.ndarray]:
        """``speeds`` in rad/s (rotational, converted when the file is in degrees) or m/s."""
        names = tuple(self.speeds)
        factors = self._factors(names, rotational)
        return {name: self.speeds[name] * factor for name, factor in zip(names, factors,
                                                                          strict=True)}

    def _factors(self, names, rotational) -> np.ndarray:
        convert = np.pi / 180.0 if self.in_degrees else 1.0
        return np.array([convert if n in rotational else 1.0 for n in names])

    def unit_warnings(self, rotational) -> list[str]:
        """Check the declared unit of the ``rotational`` columns (module docstring): VmRosError
        when the values cannot be radians, a warning when they look like radians in a file
        that says degrees."""
        columns = [i for i, name in enumerate(self.names) if name in rotational]
        if not columns:
            return []
        values = self.values[:, columns]
        peak = np.abs(values).max(axis=0)
        if not self.in_degrees and peak.max() > RADIAN_LIMIT:
            worst = int(np.argmax(peak))
            value = values[int(np.argmax(np.abs(values[:, worst]))), worst]
            raise VmRosError(f"motion {self.path}: the header says inDegrees=no but "
                             f"{self.names[columns[worst]]} reaches {value:.6g}, beyond a "
                             "full turn in radians: the file is in degrees; set inDegrees=yes")
        moving = np.ptp(values, axis=0).max() > 0.0
        if self.in_degrees and moving and peak.max() <= DEGREE_SUSPECT:
            return [f"motion {self.path}: the header says inDegrees=yes but every rotational "
                    f"column stays within +-{peak.max():.3g} deg; if the file is in radians, "
                    "set inDegrees=no"]
        return []


def _label(label: str, kind: str = "value") -> str | None:
    """Coordinate name of a column label holding the coordinate's ``kind`` (value or speed),
    or None. A bare name is a value."""
    if "/" not in label:
        return label if kind == "value" else None
    parts = [p for p in label.split("/") if p]
    if len(parts) >= 3 and parts[0] == "jointset" and parts[-1] == kind:
        return parts[-2]
    return None


def read_motion(path) -> Motion:
    """Read a .mot/.sto file; VmRosError naming the file and the problem."""
    path = Path(path)
    table = read_storage(path, "motion")
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
    check_increasing(path, data[:, 0], "motion")
    keep = [(i, name) for i, name in enumerate(map(_label, labels)) if i > 0 and name]
    if not keep:
        raise VmRosError(f"motion {path}: no coordinate columns")
    speeds = {name: data[:, i] for i, label in enumerate(labels)
              if i > 0 and (name := _label(label, "speed"))}
    return Motion(str(path), tuple(n for _, n in keep), data[:, 0],
                  data[:, [i for i, _ in keep]], in_degrees, speeds)


__all__ = ["Motion", "read_motion"]


SPLINE_DEGREE = 5  # quintic: its velocity is smooth to the third derivative


def velocity_from_positions(time_s, q) -> np.ndarray:
    """dq/dt at the frames: the derivative of FITPACK's quintic smoothing spline of ``q``
    (scipy.interpolate.UnivariateSpline, k = 5) with the smoothing s = n sigma^2, sigma the noise
    estimated from the fourth differences (var(diff4) = 70 sigma^2 for white noise). End
    conditions: none imposed, the ends are fitted like the rest (no natural or clamped
    condition; numpy.gradient's one-sided difference is first order there). With fewer frames
    than the spline needs (6), numpy.gradient. For 30 (1 - cos(2 pi t)) deg at 100 Hz, which
    starts at rest, test/test_simulate_joint_space.py holds the velocity at t = 0 within
    0.2 deg/s of 0 (numpy.gradient's one-sided difference: 5.9 deg/s)."""
    from scipy.interpolate import UnivariateSpline, make_interp_spline

    time_s, q = np.asarray(time_s, dtype=float), np.asarray(q, dtype=float)
    if len(time_s) <= SPLINE_DEGREE:
        return np.gradient(q, time_s) if len(time_s) > 1 else np.zeros_like(q)
    sigma = float(np.std(np.diff(q, 4))) / np.sqrt(70.0)
    if sigma == 0.0:  # a polynomial of degree < 4: the interpolating spline is exact
        return make_interp_spline(time_s, q, k=SPLINE_DEGREE).derivative()(time_s)
    with warnings.catch_warnings():  # FITPACK's "fp not within tol of s": the fit is returned
        warnings.simplefilter("ignore", UserWarning)
        spline = UnivariateSpline(time_s, q, k=SPLINE_DEGREE, s=len(q) * sigma ** 2)
    return spline.derivative()(time_s)
