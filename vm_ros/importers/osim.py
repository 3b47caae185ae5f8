"""``vm-ros import-osim``: an OpenSim model's muscle paths -> polynomial geometry + VM library.

OpenSim (the ``opensim`` extra) is imported here only, inside the functions. Steps:

1. Load the model; classify its coordinates: held ones are no inputs and stay at one value
   (locked: its default value; range min == max: that value; a coupler dependent all of whose
   independent coordinates are held); dependent coordinates of CoordinateCouplerConstraints
   (patella-style) are set from the coupling function at every sample (value = scale_factor *
   f(independent values)) and recorded as CoupledCoordinate; the rest are candidate inputs. A
   model with no candidate left is an error naming the held coordinates and why.
2. Screening: at SCREEN_POSES random poses over every candidate's range, dL/dq of every muscle by
   central differences; a muscle crosses a coordinate where |dL/dq| > CROSSING_THRESHOLD (1 mm per
   rad, or 1 mm per m for translational coordinates) somewhere. Only crossed coordinates are
   inputs.
3. Sampling: poses in the box of the crossed coordinates (the model's ranges, or with ``--motion``
   the motions' range plus a margin, clipped to the model's range; then half of the poses are motion
   frames jittered within the margin): Latin hypercube. At each pose L and dL/dq by central
   differences through the couplers (step STEP). The geometric moment arm r = -dL/dq, not
   OpenSim's computeMomentArm (which differs where a path wraps under a constraint). Held-out poses
   are drawn separately from the fitted ones.
4. Discontinuities: along SWEEP_LINES lines per crossed coordinate (SWEEP_POINTS points each,
   through sampled poses), the secant slope between neighbouring points is compared with the mean
   of the tangent slopes (central differences at STEP) at both ends: two step sizes. Where they
   differ by more than DISCONTINUITY_THRESHOLD (1 mm/rad) the path jumps or kinks (a wrapping
   failure, a ConditionalPathPoint switching): the muscle is flagged ``discontinuous``.
5. Fit each muscle with vm_ros.geometry.fit.fit_path (lowest total degree <= --degree whose
   held-out length RMS is within the tolerance) and write DIR/geometry.yaml, DIR/muscles.yaml,
   DIR/summary.txt (vm_ros.importers.common).
"""

from __future__ import annotations

import math
import os
import sys
import time
import xml.etree.ElementTree as ElementTree
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from vm_ros.errors import VmRosError
from vm_ros.geometry.file import content_hash
from vm_ros.geometry.fit import errors, evaluate_path, fit_path
from vm_ros.geometry.paths import (
    COUPLING_POINTS,
    Coordinate,
    CoupledCoordinate,
    FitReport,
    PolynomialGeometry,
)
from vm_ros.importers.common import (
    LENGTH_WARNING_M,
    FitOptions,
    ImportChoices,
    ImportedMuscle,
    specific_tension_option,
    write_import,
)
from vm_ros.importers.motion import read_motion
from vm_ros.progress import Progress

NEEDS_OPENSIM = 'needs the opensim extra: pip install ".[opensim]"'
STEP = 1e-5                     # central-difference step (rad or m); stable from 1e-3 to 1e-7
CROSSING_THRESHOLD = 1e-3       # |dL/dq| (m/rad, m/m) above which a muscle crosses a coordinate
DISCONTINUITY_THRESHOLD = 1e-3  # m/rad (m/m): secant vs tangent slope along a sweep
SCREEN_POSES = 60
SWEEP_LINES = 3
SWEEP_POINTS = 100
SCREEN_HALF_WIDTH = {"rad": math.pi, "m": 1.0}   # screening box around the default, at most


_ENVIRONMENT_KEPT = ("LD_LIBRARY_PATH", "PATH", "SIMBODY_HOME")


def load_opensim():
    """The opensim module, or VmRosError with the one line saying how to install it."""
    # Importing opensim rewrites this process's LD_LIBRARY_PATH and PATH (and sets SIMBODY_HOME);
    # child processes (muscle_node, other ROS programs) would then fail to load their libraries.
    # Its own libraries are loaded by then: the environment is put back as it was.
    saved = {name: os.environ.get(name) for name in _ENVIRONMENT_KEPT}
    try:
        import opensim
    except ImportError as exc:
        raise VmRosError(NEEDS_OPENSIM) from exc
    finally:
        for name, value in saved.items():
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value
    opensim.Logger.setLevelString("error")
    opensim.Logger.removeFileSink()  # else OpenSim writes opensim.log into the working directory
    return opensim


def check_model_file(path) -> Path:
    """An existing .osim file whose XML root is an OpenSimDocument holding a Model."""
    path = Path(path)
    if not path.is_file():
        raise VmRosError(f"{path}: no such file")
    if path.suffix.lower() != ".osim":
        raise VmRosError(f"{path}: not an .osim file (OpenSim model files end in .osim)")
    try:
        root = ElementTree.parse(path).getroot()
    except (ElementTree.ParseError, OSError) as exc:
        raise VmRosError(f"{path}: not an OpenSim model (not valid XML: {exc})") from None
    if root.tag != "OpenSimDocument" or root.find("Model") is None:
        raise VmRosError(f"{path}: not an OpenSim model (no <OpenSimDocument><Model>)")
    return path


@dataclass(frozen=True)
class OsimOptions(FitOptions):
    """``vm-ros import-osim``'s options: the fit's, and the motions the box follows."""

    motions: tuple = ()
    margin_deg: float = 10.0
    margin_m: float = 0.01


@dataclass
class _Coupler:
    name: str
    dependent: object           # opensim Coordinate
    independent: list           # opensim Coordinates, the function's argument order
    function: object
    scale: float


@dataclass
class OsimPaths:
    """An OpenSim model opened for sampling: independent coordinates, couplers, muscles, and
    path lengths (with gradients by central differences) at poses of chosen coordinates."""

    osim: object
    path: Path
    model: object = field(init=False)
    state: object = field(init=False)

    def __post_init__(self):
        osim = self.osim
        try:
            self.model = osim.Model(str(self.path))
            self.state = self.model.initSystem()
        except Exception as exc:  # noqa: BLE001 - OpenSim raises RuntimeError with C++ text
            first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
            raise VmRosError(f"{self.path}: OpenSim cannot load the model: {first}") from None
        model, state = self.model, self.state
        coordinates = model.getCoordinateSet()
        all_coords = [coordinates.get(i) for i in range(coordinates.getSize())]
        self.coordinate_names = tuple(c.getName() for c in all_coords)
        self.couplers: list[_Coupler] = []
        self.other_constraints: list[str] = []
        constraints = model.getConstraintSet()
        for i in range(constraints.getSize()):
            constraint = constraints.get(i)
            if not constraint.isEnforced(state):
                continue
            coupler = osim.CoordinateCouplerConstraint.safeDownCast(constraint)
            if coupler is None:
                self.other_constraints.append(
                    f"{constraint.getName()} ({constraint.getConcreteClassName()})")
                continue
            names = coupler.getIndependentCoordinateNames()
            scale = float(coupler.getPropertyByName("scale_factor").toString())
            self.couplers.append(_Coupler(
                coupler.getName(), coordinates.get(coupler.getDependentCoordinateName()),
                [coordinates.get(names.get(j)) for j in range(names.getSize())],
                coupler.getFunction(), scale))
        self._order_couplers()
        dependent = {c.dependent.getName() for c in self.couplers}
        self.locked = tuple(c.getName() for c in all_coords if c.getDefaultLocked())
        self.held = self._held(all_coords, dependent)
        self.independent = [c for c in all_coords
                            if c.getName() not in dependent and c.getName() not in self.held]
        if not self.independent:
            raise VmRosError(f"{self.path}: every coordinate is held, none is left to sample: "
                             f"{self.held_text()}")
        self.units = [self._unit(c) for c in self.independent]
        self.defaults = np.array([c.getDefaultValue() for c in self.independent])
        self.ranges = np.array([[c.getRangeMin(), c.getRangeMax()] for c in self.independent])
        muscles = model.getMuscles()
        self.muscles = [muscles.get(i) for i in range(muscles.getSize())]
        self.muscle_names = tuple(m.getName() for m in self.muscles)
        self.evaluations = 0

    def _held(self, all_coords, dependent) -> dict:
        """{name: why} of the coordinates that are no inputs and stay at one value: locked
        (at its default value, as OpenSim holds it), range min == max (set to that value), and
        coupler dependents whose independent coordinates are all held. Each reason says what to
        change in the model to make the coordinate an input."""
        held = {}
        for c in all_coords:
            name, unit = c.getName(), self._unit(c)
            if name in dependent:
                continue
            if c.getDefaultLocked():
                held[name] = (f"locked at {c.getDefaultValue():g} {unit}, unlock it "
                              "(<locked>false</locked>)")
            elif c.getRangeMin() == c.getRangeMax():
                c.setValue(self.state, c.getRangeMin(), False)
                held[name] = (f"range [{c.getRangeMin():g}, {c.getRangeMax():g}] {unit}, held "
                              "there, give it a range (<range>min max</range>)")
        for c in self.couplers:  # in order: a chain's dependents after their drivers
            drivers = [a.getName() for a in c.independent]
            if all(d in held for d in drivers):
                held[c.dependent.getName()] = (f"follows the held {', '.join(drivers)} through "
                                               f"CoordinateCouplerConstraint {c.name}, free "
                                               f"{' or '.join(drivers)}")
        return held

    def held_text(self) -> str:
        """The held coordinates and why, in one line ('' when none)."""
        return "; ".join(f"{name}: {why}" for name, why in self.held.items())

    def _unit(self, coordinate) -> str:
        translational = int(coordinate.getMotionType()) == int(self.osim.Coordinate.Translational)
        return "m" if translational else "rad"

    def _order_couplers(self) -> None:
        """Couplers ordered so that one whose argument is another's dependent comes after it."""
        ordered, pending = [], list(self.couplers)
        while pending:
            done = {c.dependent.getName() for c in pending}
            ready = [c for c in pending
                     if not any(a.getName() in done for a in c.independent)]
            if not ready:
                raise VmRosError(f"{self.path}: coordinate couplers form a cycle: "
                                 f"{', '.join(c.name for c in pending)}")
            ordered += ready
            pending = [c for c in pending if c not in ready]
        self.couplers = ordered

    def coupled_coordinates(self, coordinates=()) -> list[CoupledCoordinate]:
        """The couplers' dependents; for one whose single argument is among ``coordinates``
        (the geometry's, with their boxes) the coupling function sampled at COUPLING_POINTS
        points over that box, through OpenSim's function."""
        boxes = {c.name: c for c in coordinates}
        out = []
        for c in self.couplers:
            follows = tuple(a.getName() for a in c.independent)
            table = {}
            if len(follows) == 1 and follows[0] in boxes:
                box = boxes[follows[0]]
                grid = np.linspace(box.lower, box.upper, COUPLING_POINTS)
                table = {"unit": self._unit(c.dependent), "follows_values": tuple(grid),
                         "values": tuple(self._coupled_value(c, [x]) for x in grid)}
            out.append(CoupledCoordinate(
                c.dependent.getName(), follows,
                f"OpenSim CoordinateCouplerConstraint {c.name}: {c.dependent.getName()} = "
                f"{c.scale:g} * {c.function.getConcreteClassName()}({', '.join(follows)}); set "
                "from the coupling at every sample, so the fitted paths include its effect",
                **table))
        return out

    def _coupled_value(self, coupler: _Coupler, args) -> float:
        """The dependent's value (rad or m) at its arguments' values: scale * f(args)."""
        return coupler.scale * coupler.function.calcValue(self.osim.Vector(
            [float(a) for a in args]))

    def lengths(self, columns, q) -> np.ndarray:
        """Path lengths (n_muscles,) with independent coordinates ``columns`` (indices into
        ``independent``) at values q; the other coordinates keep their defaults."""
        state = self.state
        for j, value in zip(columns, q, strict=True):
            self.independent[j].setValue(state, float(value), False)
        for c in self.couplers:
            c.dependent.setValue(state, self._coupled_value(
                c, [a.getValue(state) for a in c.independent]), False)
        self.model.realizePosition(state)
        self.evaluations += 1
        return np.array([m.getLength(state) for m in self.muscles])

    def lengths_and_gradients(self, columns, q, wrt=None, step: float = STEP):
        """(L (n_muscles,), dL/dq (n_muscles, len(wrt))) at q by central differences; ``wrt``:
        positions within ``columns`` to differentiate (default all)."""
        q = np.asarray(q, dtype=float)
        wrt = range(len(columns)) if wrt is None else wrt
        base = self.lengths(columns, q)
        gradient = np.empty((len(base), len(wrt)))
        for k, j in enumerate(wrt):
            q_plus, q_minus = q.copy(), q.copy()
            q_plus[j] += step
            q_minus[j] -= step
            gradient[:, k] = (self.lengths(columns, q_plus)
                              - self.lengths(columns, q_minus)) / (2.0 * step)
        self.lengths(columns, q)
        return base, gradient


def _progress(label: str, total: int, enabled: bool | None):
    return Progress(label, total, enabled=enabled)


def _latin_hypercube(n: int, lower, upper, rng) -> np.ndarray:
    """n points in the box, one per stratum in every dimension (randomly paired)."""
    d = len(lower)
    u = (np.argsort(rng.random((d, n)), axis=1).T + rng.random((n, d))) / n
    return lower + u * (upper - lower)


def _screen(paths: OsimPaths, rng, progress) -> np.ndarray:
    """max |dL/dq| over SCREEN_POSES random poses: (n_muscles, n_independent)."""
    n = len(paths.independent)
    width = np.array([SCREEN_HALF_WIDTH[u] for u in paths.units])
    lower = np.maximum(paths.ranges[:, 0], paths.defaults - width)
    upper = np.minimum(paths.ranges[:, 1], paths.defaults + width)
    upper = np.maximum(upper, lower)
    columns = list(range(n))
    peak = np.zeros((len(paths.muscles), n))
    with _progress("screening coordinates", SCREEN_POSES, progress) as bar:
        for k, q in enumerate(_latin_hypercube(SCREEN_POSES, lower, upper, rng)):
            _, gradient = paths.lengths_and_gradients(columns, q)
            peak = np.fmax(peak, np.abs(gradient))
            bar.update(k + 1)
    return peak


@dataclass
class _Box:
    lower: np.ndarray
    upper: np.ndarray
    frames: np.ndarray | None     # (n_frames, d) motion frames in the box, or None
    margin: np.ndarray
    note: str


def _motion_box(paths: OsimPaths, columns, motions, options: OsimOptions) -> _Box:
    names = [paths.independent[j].getName() for j in columns]
    units = [paths.units[j] for j in columns]
    lower, upper = paths.ranges[columns, 0].copy(), paths.ranges[columns, 1].copy()
    for name, lo, hi in zip(names, lower, upper, strict=True):
        if not (np.isfinite(lo) and np.isfinite(hi) and lo < hi):
            raise VmRosError(f"coordinate {name}: its range in the model [{lo:g}, {hi:g}] is not "
                             "an interval to sample; give it <range>min max</range> with finite "
                             "min < max")
    margin = np.array([math.radians(options.margin_deg) if u == "rad" else options.margin_m
                       for u in units])
    if not motions:
        return _Box(lower, upper, None, margin, "the model's coordinate ranges")
    rotational = {c.getName() for c, u in zip(paths.independent, paths.units, strict=True)
                  if u == "rad"}
    rotational |= {c.dependent.getName() for c in paths.couplers}
    blocks, seen = [], set()
    for motion in motions:
        unknown = [n for n in motion.names if n not in paths.coordinate_names]
        if unknown:
            raise VmRosError(f"motion {motion.path}: unknown coordinate {unknown[0]!r} (not in "
                             f"the model; it has {len(paths.coordinate_names)} coordinates)")
        values = motion.to_si(rotational)
        block = np.full((len(values), len(names)), np.nan)
        for i, name in enumerate(names):
            if name in motion.names:
                block[:, i] = values[:, motion.names.index(name)]
                seen.add(name)
        blocks.append(block)
    frames = np.vstack(blocks)
    for i, name in enumerate(names):
        if name in seen:
            column = frames[:, i][np.isfinite(frames[:, i])]
            lower[i] = max(lower[i], column.min() - margin[i])
            upper[i] = min(upper[i], column.max() + margin[i])
            if upper[i] <= lower[i]:
                raise VmRosError(f"coordinate {name}: the motions stay outside its model range "
                                 f"[{paths.ranges[columns[i], 0]:g}, "
                                 f"{paths.ranges[columns[i], 1]:g}]")
    missing = [n for n in names if n not in seen]
    note = (f"the motions' range plus a margin of {options.margin_deg:g} deg / "
            f"{options.margin_m:g} m, within the model's range"
            + (f"; model range for {', '.join(missing)} (not in the motions)" if missing else ""))
    return _Box(lower, upper, frames, margin, note)


def _poses(box: _Box, n: int, rng) -> np.ndarray:
    """n poses: Latin hypercube in the box; with motions, half of them motion frames jittered
    uniformly within the margin (coordinates the motions lack: uniform in the box)."""
    poses = _latin_hypercube(n, box.lower, box.upper, rng)
    if box.frames is not None:
        k = n // 2
        picks = box.frames[rng.integers(0, len(box.frames), k)]
        jitter = rng.uniform(-1.0, 1.0, picks.shape) * box.margin
        near = np.where(np.isfinite(picks), picks + jitter, poses[:k])
        poses[:k] = np.clip(near, box.lower, box.upper)
    return poses


def _sample(paths: OsimPaths, columns, poses, label: str, progress):
    n_m = len(paths.muscles)
    length = np.empty((len(poses), n_m))
    gradient = np.empty((len(poses), n_m, len(columns)))
    with _progress(label, len(poses), progress) as bar:
        for k, q in enumerate(poses):
            length[k], gradient[k] = paths.lengths_and_gradients(columns, q)
            bar.update(k + 1)
    return length, gradient


def _sweeps(paths: OsimPaths, columns, box: _Box, bases, progress):
    """Largest secant-vs-tangent disagreement per (muscle, coordinate), and the lengths seen."""
    n_m, d = len(paths.muscles), len(columns)
    worst = np.zeros((n_m, d))
    seen = [np.full(n_m, np.inf), np.full(n_m, -np.inf)]
    total = d * len(bases)
    with _progress("discontinuity sweeps", total, progress) as bar:
        for j in range(d):
            grid = np.linspace(box.lower[j] + STEP, box.upper[j] - STEP, SWEEP_POINTS)
            spacing = grid[1] - grid[0]
            for b, base in enumerate(bases):
                lengths = np.empty((SWEEP_POINTS, n_m))
                slopes = np.empty((SWEEP_POINTS, n_m))
                for i, value in enumerate(grid):
                    q = base.copy()
                    q[j] = value
                    lengths[i], g = paths.lengths_and_gradients(columns, q, wrt=[j])
                    slopes[i] = g[:, 0]
                secant = np.diff(lengths, axis=0) / spacing
                tangent = (slopes[1:] + slopes[:-1]) / 2.0
                worst[:, j] = np.fmax(worst[:, j], np.abs(secant - tangent).max(axis=0))
                seen[0] = np.fmin(seen[0], lengths.min(axis=0))
                seen[1] = np.fmax(seen[1], lengths.max(axis=0))
                bar.update(j * len(bases) + b + 1)
    return worst, seen


@dataclass
class OsimImport:
    """Result of an import: the geometry, the muscles' parameters, what was written."""

    geometry: PolynomialGeometry
    muscles: list
    written: dict
    skipped: dict
    seconds: float
    evaluations: int


def _source(osim, paths: OsimPaths, model_path: Path, motions, extra=None) -> dict:
    source = {
        "model": paths.model.getName(), "file": model_path.name,
        "sha256": content_hash(model_path), "importer": "vm-ros import-osim",
        "opensim_version": osim.GetVersion(),
        "locked_coordinates": list(paths.locked),
    }
    if paths.held:
        source["held_coordinates"] = dict(paths.held)
    if motions:
        source["motions"] = [{"file": Path(m.path).name, "sha256": content_hash(m.path),
                              "in_degrees": m.in_degrees} for m in motions]
    if paths.other_constraints:
        source["constraints_not_enforced_while_sampling"] = list(paths.other_constraints)
    return {**source, **(extra or {})}


def _imported(paths: OsimPaths, index: int, lo: float, hi: float) -> ImportedMuscle:
    m = paths.muscles[index]
    return ImportedMuscle(m.getName(), float(m.getMaxIsometricForce()),
                          float(m.getOptimalFiberLength()), float(m.getTendonSlackLength()),
                          float(lo), float(hi), float(m.getPennationAngleAtOptimalFiberLength()),
                          f"{m.getConcreteClassName()} of OpenSim model {paths.model.getName()}")


def _selected(paths: OsimPaths, wanted) -> list[int]:
    if not wanted:
        return list(range(len(paths.muscles)))
    unknown = [n for n in wanted if n not in paths.muscle_names]
    if unknown:
        raise VmRosError(f"muscle {unknown[0]!r} is not in the model (it has "
                         f"{', '.join(paths.muscle_names[:12])}"
                         f"{', ...' if len(paths.muscle_names) > 12 else ''})")
    return [paths.muscle_names.index(n) for n in wanted]


def import_osim(model_path, out_dir, options: OsimOptions | None = None,
                choices: ImportChoices | None = None, *, progress: bool | None = None,
                file=None) -> OsimImport:
    """Import an .osim model's muscle paths and parameters into ``out_dir`` (see the module
    docstring). ``progress``: progress lines on stderr (default: when stderr is a terminal)."""
    options = options or OsimOptions()
    choices = choices or ImportChoices(specific_tension_option("60"))
    model_path = check_model_file(model_path)
    motions = [read_motion(p) for p in options.motions]
    osim = load_opensim()
    started = time.monotonic()
    paths = OsimPaths(osim, model_path)
    chosen = _selected(paths, options.muscles)
    if not paths.muscles:
        raise VmRosError(f"{model_path}: the model has no muscles")
    rng = np.random.default_rng(options.seed)
    peak = _screen(paths, rng, progress)[chosen]
    columns = [j for j in range(len(paths.independent))
               if np.any(peak[:, j] > CROSSING_THRESHOLD)]
    free = "free " if paths.held else ""
    held = f" with {', '.join(paths.held)} held" if paths.held else ""
    constant = f"crosses no {free}coordinate (constant length{held})"
    skipped = {paths.muscle_names[i]: constant
               for i, row in zip(chosen, peak, strict=True) if not np.any(row > CROSSING_THRESHOLD)}
    if not columns:
        raise VmRosError(f"{model_path}: no muscle crosses a free coordinate"
                         + (f" (held: {paths.held_text()})" if paths.held else ""))
    box = _motion_box(paths, columns, motions, options)
    q_fit = _poses(box, options.samples, rng)
    q_test = _poses(box, options.n_held_out, rng)
    l_fit, g_fit = _sample(paths, columns, q_fit, "sampling poses", progress)
    l_test, g_test = _sample(paths, columns, q_test, "sampling held-out poses", progress)
    worst, seen = _sweeps(paths, columns, box, q_fit[:SWEEP_LINES], progress)

    names = [paths.independent[j].getName() for j in columns]
    crossing = np.fmax(peak[:, columns], np.abs(g_fit[:, chosen]).max(axis=0))
    muscles, imported = [], []
    for row, i in enumerate(chosen):
        name = paths.muscle_names[i]
        if name in skipped:
            continue
        cols = [k for k in range(len(columns)) if crossing[row, k] > CROSSING_THRESHOLD]
        flags = []
        if np.any(worst[i, cols] > DISCONTINUITY_THRESHOLD):
            flags.append("discontinuous")
        good_fit = np.isfinite(l_fit[:, i]) & np.all(np.isfinite(g_fit[:, i][:, cols]), axis=1)
        good_test = np.isfinite(l_test[:, i]) & np.all(np.isfinite(g_test[:, i][:, cols]),
                                                       axis=1)
        if not (good_fit.all() and good_test.all()):
            flags.append("invalid_samples")
        path = fit_path(name, [names[k] for k in cols], box.lower[cols], box.upper[cols],
                        q_fit[good_fit][:, cols], l_fit[good_fit, i],
                        g_fit[good_fit, i][:, cols], q_test[good_test][:, cols],
                        l_test[good_test, i], g_test[good_test, i][:, cols],
                        degrees=options.degrees(len(cols)),
                        length_tolerance_m=options.length_tolerance_m, flags=flags)
        if path.fit.length_rms_m > LENGTH_WARNING_M:
            path = _with_flag(path, "poor_fit")
        muscles.append(path)
        lengths = np.concatenate([l_fit[:, i], l_test[:, i]])
        lengths = lengths[np.isfinite(lengths)]
        imported.append(_imported(paths, i, min(lengths.min(), seen[0][i]),
                                  max(lengths.max(), seen[1][i])))
    if not muscles:
        raise VmRosError(f"{model_path}: none of the selected muscles crosses a coordinate")
    used = {c for m in muscles for c in m.coordinates}
    coordinates = [Coordinate(n, paths.units[columns[k]], float(box.lower[k]),
                              float(box.upper[k])) for k, n in enumerate(names) if n in used]
    coupled = [c for c in paths.coupled_coordinates(coordinates) if set(c.follows) <= used]
    source = _source(osim, paths, model_path, motions,
                     {"muscles_skipped": skipped} if skipped else None)
    geometry = PolynomialGeometry(coordinates, muscles, coupled, source=source,
                                  options=_options_record(options, box))
    result = _finish(osim, paths, model_path, "", geometry, imported, out_dir, choices, started,
                     file)
    if paths.held:
        print(f"held at one value, not inputs: {paths.held_text()}", file=file or sys.stdout)
    if skipped:
        print(f"skipped {len(skipped)} muscle(s) that cross no {free}coordinate: "
              f"{', '.join(skipped)}", file=file or sys.stdout)
    result.skipped.update(skipped)
    return result


def _finish(osim, paths, model_path, how, geometry, imported, out_dir, choices, started,
            file) -> OsimImport:
    """Write geometry + library + summary (common.write_import) under a title saying what ran."""
    seconds = time.monotonic() - started
    title = (f"vm-ros import-osim {model_path.name}{how} (OpenSim model "
             f"{paths.model.getName()}, OpenSim {osim.GetVersion()}): {len(geometry.muscles)} "
             f"muscles over {len(geometry.coordinates)} coordinates, {paths.evaluations} path "
             f"evaluations in {seconds:.1f} s")
    written = write_import(out_dir, geometry, imported, choices, title=title,
                           origin=f"OpenSim model {paths.model.getName()} ({model_path.name})",
                           file=file)
    return OsimImport(geometry, imported, written, {}, seconds, paths.evaluations)


def _with_flag(path, flag: str):
    return replace(path, fit=replace(path.fit, flags=tuple(path.fit.flags) + (flag,)))


def _options_record(options: OsimOptions, box: _Box) -> dict:
    return {
        **options.recorded(), "box": box.note,
        "sampling": "Latin hypercube in the box" + ("; half of the poses motion frames jittered "
                                                     "within the margin" if box.frames is not None
                                                     else ""),
        "gradient": f"central differences, step {STEP:g} (rad or m), through the couplers",
        "crossing_threshold": f"|dL/dq| > {CROSSING_THRESHOLD:g} m/rad (m/m) at one of "
                              f"{SCREEN_POSES} screening poses or any sampled pose",
        "discontinuity_check": f"{SWEEP_LINES} sweeps of {SWEEP_POINTS} points per coordinate: "
                               f"secant vs tangent slope > {DISCONTINUITY_THRESHOLD:g} m/rad",
        "poor_fit_flag": f"held-out length RMS > {LENGTH_WARNING_M:g} m",
    }


def import_function_based_paths(model_path, xml_path, out_dir, options: OsimOptions | None = None,
                                choices: ImportChoices | None = None, *,
                                progress: bool | None = None, file=None) -> OsimImport:
    """Turn OpenSim's own PolynomialPathFitter output (a FunctionBasedPath set XML) into a
    geometry file and library. The model gives coordinates (units, ranges, couplers) and muscle
    parameters; the polynomials are taken as they are (offset 0, scale 1). Their box is the
    model's range (or the motions' range plus a margin). Each path is compared with the model's
    own path (if it is still a geometric path) at ``options.n_held_out`` poses in that box: the fit
    report; its path length extremes over those poses feed the library rules."""
    from vm_ros.geometry.opensim_xml import (
        function_based_paths_geometry,
        parse_function_based_paths,
    )

    options = options or OsimOptions()
    choices = choices or ImportChoices(specific_tension_option("60"))
    model_path = check_model_file(model_path)
    xml_path = Path(xml_path)
    if not xml_path.is_file():
        raise VmRosError(f"{xml_path}: no such file")
    motions = [read_motion(p) for p in options.motions]
    osim = load_opensim()
    started = time.monotonic()
    paths = OsimPaths(osim, model_path)
    columns = list(range(len(paths.independent)))
    box = _motion_box(paths, columns, motions, options)
    coordinates = [Coordinate(c.getName(), u, float(lo), float(hi)) for c, u, lo, hi in
                   zip(paths.independent, paths.units, box.lower, box.upper, strict=True)]
    dependent = {c.dependent.getName() for c in paths.couplers}
    for path in parse_function_based_paths(xml_path).paths:
        odd = [c for c in path.coordinates if c in dependent or c in paths.held]
        if odd:
            raise VmRosError(f"{xml_path}: path {path.name!r} takes the coupled or held "
                             f"coordinate {odd[0]!r} as an argument; vm_ros inputs are the "
                             "independent coordinates only")
    raw = function_based_paths_geometry(xml_path, coordinates,
                                        paths.coupled_coordinates(coordinates))
    unknown = [m.name for m in raw.muscles if m.name not in paths.muscle_names]
    if unknown:
        raise VmRosError(f"{xml_path}: path {unknown[0]!r} names no muscle of the model")
    wanted = set(options.muscles) or set(raw.muscle_names)
    _selected(paths, sorted(wanted))
    index = {c.getName(): j for j, c in enumerate(paths.independent)}
    cols = [index[c.name] for c in raw.coordinates]
    rng = np.random.default_rng(options.seed)
    sub = _Box(box.lower[cols], box.upper[cols],
               None if box.frames is None else box.frames[:, cols], box.margin[cols], box.note)
    poses = _poses(sub, options.n_held_out, rng)
    length, gradient = _sample(paths, cols, poses, "evaluating the model's paths", progress)
    muscles, imported = [], []
    for path in raw.muscles:
        if path.name not in wanted:
            continue
        i = paths.muscle_names.index(path.name)
        k = [raw.coordinate_names.index(c) for c in path.coordinates]
        q = poses[:, k]
        err = errors(path, q, length[:, i], gradient[:, i][:, k])
        flags = ("poor_fit",) if err[0] > LENGTH_WARNING_M else ()
        muscles.append(replace(path, fit=FitReport(*err, poses_fit=0,
                                                   poses_held_out=len(poses), flags=flags)))
        fitted, _ = evaluate_path(path, q)
        imported.append(_imported(paths, i, fitted.min(), fitted.max()))
    geometry = PolynomialGeometry(raw.coordinates, muscles, raw.coupled,
                                  source=_source(osim, paths, model_path, motions, raw.source),
                                  options={"from": "OpenSim PolynomialPathFitter output "
                                                   "(FunctionBasedPath set), polynomials as "
                                                   "written", "box": box.note,
                                           "fit_report": f"against the model's own paths at "
                                                         f"{len(poses)} poses in the box",
                                           "seed": options.seed})
    return _finish(osim, paths, model_path, f" --function-based-paths {xml_path.name}",
                   geometry, imported, out_dir, choices, started, file)


__all__ = ["CROSSING_THRESHOLD", "DISCONTINUITY_THRESHOLD", "NEEDS_OPENSIM", "OsimImport",
           "OsimOptions", "OsimPaths", "STEP", "check_model_file", "import_function_based_paths",
           "import_osim", "load_opensim"]
