"""The one import pipeline: a source model's exact paths -> fitted polynomial geometry + VM library.

An importer supplies a ``PathSource``: its exact paths (a back end of vm_ros.geometry:
``mujoco_backend.MujocoGeometry`` or ``opensim_backend.OsimPaths``), the box it samples, and its
parameter mapping (source muscle -> ImportedMuscle). ``import_paths`` does the rest, the same way
for every source:

1. ``source.box(rng)``: the coordinates to sample and their box (a source may screen which
   coordinates its muscles cross first, and give the largest |dL/dq| it saw as ``prior``).
2. Fitted and held-out poses (``source.poses``), drawn separately; L and dL/dq at each.
3. Discontinuities: along SWEEP_LINES lines per coordinate (SWEEP_POINTS points each, through the
   first fitted poses), the secant slope between neighbouring points against the mean of the
   tangent slopes at both ends. Where they differ by more than DISCONTINUITY_M the path jumps or
   kinks (a wrapping failure, a conditional path point): the muscle is flagged ``discontinuous``.
4. A muscle crosses a coordinate where |dL/dq| > CROSSING_M (1 mm per rad, or per m) at a
   screened or sampled pose; a muscle that crosses none is skipped, with the source's reason.
5. Each muscle is fitted over the coordinates it crosses (vm_ros.geometry.fit.fit_path) on its
   finite samples (``invalid_samples`` flag where some were not), flagged ``poor_fit`` above
   LENGTH_WARNING_M held-out length RMS, and its sampled path length extremes feed the library
   rules; geometry.yaml, muscles.yaml and summary.txt are written (common.write_import), then
   what the source adds (``source.finish``) and the held and skipped lines.
"""

from __future__ import annotations

import sys
import time
from abc import ABC, abstractmethod
from dataclasses import dataclass, replace

import numpy as np

from vm_ros.errors import VmRosError
from vm_ros.geometry.fit import fit_path
from vm_ros.geometry.paths import Coordinate, PolynomialGeometry
from vm_ros.importers.common import LENGTH_WARNING_M, write_import
from vm_ros.progress import Progress

CROSSING_M = 1e-3         # |dL/dq| (m/rad, m/m) above which a muscle crosses a coordinate
DISCONTINUITY_M = 1e-3    # m/rad (m/m): secant vs tangent slope along a sweep
SWEEP_LINES = 3           # sweeps per coordinate, through the first fitted poses
SWEEP_POINTS = 100        # points per sweep


@dataclass
class SampleBox:
    """The coordinates an import samples (names, units 'rad' or 'm', box), and ``prior``: the
    largest |dL/dq| (n_muscles, n_coordinates) a source saw before sampling, or None."""

    names: tuple
    units: tuple
    lower: np.ndarray
    upper: np.ndarray
    prior: np.ndarray | None = None


class PathSource(ABC):
    """What an importer supplies to ``import_paths``: exact paths of the muscles to import
    (``muscle_names``, in order) and their parameter mapping.

    ``gradient_step``: the finite-difference step of the gradients (0 where they are exact);
    sweeps stay that far inside the box. ``sweep_extremes``: the path lengths seen along the
    sweeps count toward each muscle's path length extremes (else the sampled poses' only).
    """

    muscle_names: tuple
    gradient_step: float = 0.0
    sweep_extremes: bool = False

    @abstractmethod
    def box(self, rng) -> SampleBox:
        """The coordinates to sample (VmRosError when nothing is left to sample)."""

    @abstractmethod
    def poses(self, box: SampleBox, n: int, rng) -> np.ndarray:
        """n poses (n, n_coordinates) in the box."""

    @abstractmethod
    def lengths_and_gradients(self, q, wrt=None) -> tuple[np.ndarray, np.ndarray]:
        """(L (n_muscles,), dL/dq (n_muscles, len(wrt))) at the pose q of the box's coordinates;
        ``wrt``: the coordinates (positions in the box) to differentiate, default all."""

    @abstractmethod
    def skip_reason(self, name: str) -> str:
        """Why a muscle crossing no sampled coordinate is skipped (recorded and printed)."""

    @abstractmethod
    def record(self, skipped: dict, box: SampleBox) -> tuple[dict, dict, list]:
        """The geometry file's (``source``, ``options``) records and the coupled coordinates
        (CoupledCoordinate) of the source."""

    @abstractmethod
    def imported(self, names, path_min, path_max) -> list:
        """The parameter mapping: ImportedMuscle of the named muscles (m: sampled path length
        extremes, in that order); a source may leave out muscles with unusable numbers."""

    @abstractmethod
    def title(self, geometry, seconds: float) -> str:
        """First line of the library header and summary: which model, which importer."""

    origin: str = "the source model"   # how library source notes name the model
    held: str = ""                     # the held coordinates and why, in one line
    skip_word: str = "coordinate"      # "skipped N muscle(s) that cross no <skip_word>"

    def finish(self, written: dict) -> list[str]:
        """After the files are written: changes to them and lines for the summary."""
        return []


@dataclass
class ImportResult:
    """What ``import_paths`` made: the geometry, the imported muscles' parameters, the files
    written, the skipped muscles with the reason, and the seconds taken."""

    geometry: PolynomialGeometry
    muscles: list
    written: dict
    skipped: dict
    seconds: float


def sample(source: PathSource, poses, label: str, progress=None, wrt=None):
    """(L (P, n_muscles), dL/dq (P, n_muscles, len(wrt))) at each pose, with a progress bar."""
    n_m, n_g = len(source.muscle_names), len(poses[0]) if wrt is None else len(wrt)
    length, gradient = np.empty((len(poses), n_m)), np.empty((len(poses), n_m, n_g))
    with Progress(label, len(poses), enabled=progress) as bar:
        for k, q in enumerate(poses):
            length[k], gradient[k] = source.lengths_and_gradients(q, wrt)
            bar.update(k + 1)
    return length, gradient


def sweeps(source: PathSource, box: SampleBox, bases, progress=None):
    """(largest secant-vs-tangent disagreement (n_muscles, n_coordinates), smallest and largest
    length seen (n_muscles,) each) along sweeps of each coordinate through the ``bases`` poses."""
    n_m, d = len(source.muscle_names), len(box.names)
    worst = np.zeros((n_m, d))
    seen = [np.full(n_m, np.inf), np.full(n_m, -np.inf)]
    inset = source.gradient_step
    with Progress("discontinuity sweeps", d * len(bases), enabled=progress) as bar:
        for j in range(d):
            grid = np.linspace(box.lower[j] + inset, box.upper[j] - inset, SWEEP_POINTS)
            spacing = grid[1] - grid[0]
            for b, base in enumerate(bases):
                lengths = np.empty((SWEEP_POINTS, n_m))
                slopes = np.empty((SWEEP_POINTS, n_m))
                for i, value in enumerate(grid):
                    q = base.copy()
                    q[j] = value
                    lengths[i], g = source.lengths_and_gradients(q, [j])
                    slopes[i] = g[:, 0]
                secant = np.diff(lengths, axis=0) / spacing
                tangent = (slopes[1:] + slopes[:-1]) / 2.0
                worst[:, j] = np.fmax(worst[:, j], np.abs(secant - tangent).max(axis=0))
                seen[0] = np.fmin(seen[0], lengths.min(axis=0))
                seen[1] = np.fmax(seen[1], lengths.max(axis=0))
                bar.update(j * len(bases) + b + 1)
    return worst, seen


def checks_record(crossing_where: str, slope: str) -> dict:
    """The geometry file's ``options`` entries for the crossing, discontinuity and poor-fit
    rules; ``crossing_where``: the poses screened, ``slope``: which tangent the sweeps use."""
    return {
        "crossing_threshold": f"|dL/dq| > {CROSSING_M:g} m/rad (m/m) {crossing_where}",
        "discontinuity_check": f"{SWEEP_LINES} sweeps of {SWEEP_POINTS} points per coordinate: "
                               f"secant vs {slope} slope > {DISCONTINUITY_M:g} m/rad",
        "poor_fit_flag": f"held-out length RMS > {LENGTH_WARNING_M:g} m",
    }


def with_flag(path, flag: str):
    """The MusclePath with ``flag`` added to its fit report."""
    return replace(path, fit=replace(path.fit, flags=tuple(path.fit.flags) + (flag,)))


def import_paths(source: PathSource, out_dir, options, choices, *, progress=None, file=None,
                 label: str = "the model") -> ImportResult:
    """Sample, screen, fit, flag and write (module docstring). ``options``: FitOptions;
    ``choices``: ImportChoices; ``label`` names the model in errors."""
    file = file or sys.stdout
    started = time.monotonic()
    rng = np.random.default_rng(options.seed)
    box = source.box(rng)
    q_fit = source.poses(box, options.samples, rng)
    q_test = source.poses(box, options.n_held_out, rng)
    l_fit, g_fit = sample(source, q_fit, "sampling poses", progress)
    l_test, g_test = sample(source, q_test, "sampling held-out poses", progress)
    worst, seen = sweeps(source, box, q_fit[:SWEEP_LINES], progress)
    crossing = np.fmax(np.abs(g_fit).max(axis=0), np.abs(g_test).max(axis=0))
    if box.prior is not None:
        crossing = np.fmax(box.prior, crossing)
    muscles, skipped, extremes = [], {}, []
    for i, name in enumerate(source.muscle_names):
        cols = np.flatnonzero(crossing[i] > CROSSING_M)
        if not len(cols):
            skipped[name] = source.skip_reason(name)
            continue
        flags = ["discontinuous"] if np.any(worst[i, cols] > DISCONTINUITY_M) else []
        good_fit = np.isfinite(l_fit[:, i]) & np.all(np.isfinite(g_fit[:, i][:, cols]), axis=1)
        good_test = np.isfinite(l_test[:, i]) & np.all(np.isfinite(g_test[:, i][:, cols]),
                                                       axis=1)
        if not (good_fit.all() and good_test.all()):
            flags.append("invalid_samples")
        path = fit_path(name, [box.names[k] for k in cols], box.lower[cols], box.upper[cols],
                        q_fit[good_fit][:, cols], l_fit[good_fit, i],
                        g_fit[good_fit, i][:, cols], q_test[good_test][:, cols],
                        l_test[good_test, i], g_test[good_test, i][:, cols],
                        degrees=options.degrees(len(cols)),
                        length_tolerance_m=options.length_tolerance_m, flags=flags)
        if path.fit.length_rms_m > LENGTH_WARNING_M:
            path = with_flag(path, "poor_fit")
        muscles.append(path)
        lengths = np.concatenate([l_fit[:, i], l_test[:, i]])
        lengths = lengths[np.isfinite(lengths)]
        low, high = lengths.min(), lengths.max()
        if source.sweep_extremes:
            low, high = min(low, seen[0][i]), max(high, seen[1][i])
        extremes.append((low, high))
    if not muscles:
        raise VmRosError(f"{label}: none of the selected muscles crosses a coordinate")
    used = {c for m in muscles for c in m.coordinates}
    coordinates = [Coordinate(n, box.units[k], float(box.lower[k]), float(box.upper[k]))
                   for k, n in enumerate(box.names) if n in used]
    record, options_record, coupled = source.record(skipped, box)
    coupled = [c for c in coupled if set(c.follows) <= used]
    geometry = PolynomialGeometry(coordinates, muscles, coupled, source=record,
                                  options=options_record)
    imported = source.imported([m.name for m in muscles], *zip(*extremes, strict=True))
    seconds = time.monotonic() - started
    written = write_import(out_dir, geometry, imported, choices,
                           title=source.title(geometry, seconds), origin=source.origin,
                           file=file)
    lines = source.finish(written)
    if source.held:
        lines.append(f"held at one value, not inputs: {source.held}")
    if skipped:
        lines.append(f"skipped {len(skipped)} muscle(s) that cross no {source.skip_word}: "
                     f"{', '.join(skipped)}")
    if lines:
        with open(written["summary"], "a", encoding="utf-8") as summary:
            for stream in (summary, file):
                print("\n" + "\n".join(lines), file=stream)
    return ImportResult(geometry, imported, written, skipped, seconds)


__all__ = ["CROSSING_M", "DISCONTINUITY_M", "ImportResult", "PathSource", "SWEEP_LINES",
           "SWEEP_POINTS", "SampleBox", "checks_record", "import_paths", "sample", "sweeps",
           "with_flag"]
