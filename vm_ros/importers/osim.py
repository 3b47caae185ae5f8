"""``vm-ros import-osim``: an OpenSim model's muscle paths -> polynomial geometry + VM library.

``OsimSource`` is what this importer gives vm_ros.importers.pipeline (which samples, screens,
fits, flags and writes): OpenSim's paths (vm_ros.geometry.opensim_backend.OsimPaths; the
``opensim`` extra, imported inside the functions), the box and the parameter mapping.

1. Load the model; classify its coordinates: held ones are no inputs and stay at one value
   (locked: its default value; range min == max: that value; a coupler dependent all of whose
   independent coordinates are held); dependent coordinates of CoordinateCouplerConstraints
   (patella-style) are set from the coupling function at every sample (value = scale_factor *
   f(independent values)) and recorded as CoupledCoordinate; the rest are candidate inputs. A
   model with no candidate left is an error naming the held coordinates and why.
2. Screening: at SCREEN_POSES random poses over every candidate's range, dL/dq of every muscle by
   central differences; a muscle crosses a coordinate where |dL/dq| > CROSSING_M (1 mm per rad,
   or 1 mm per m for translational coordinates) somewhere. Only crossed coordinates are inputs.
3. The box of the crossed coordinates: the model's ranges, or with ``--motion`` the motions' range
   plus a margin, clipped to the model's range; poses are a Latin hypercube in it, half of them
   motion frames jittered within the margin when motions are given. At each pose L and dL/dq by
   central differences through the couplers (step STEP): the geometric moment arm r = -dL/dq, not
   OpenSim's computeMomentArm (which differs where a path wraps under a constraint).
4. Parameters: F0, optimal fibre length, tendon slack length and pennation of each muscle as
   OpenSim gives them (ImportedMuscle); the path length extremes include the sweeps' lengths.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from vm_ros.errors import VmRosError
from vm_ros.geometry.file import content_hash
from vm_ros.geometry.fit import errors, evaluate_path
from vm_ros.geometry.opensim_backend import (
    NEEDS_OPENSIM,
    STEP,
    OsimPaths,
    check_model_file,
    load_opensim,
)
from vm_ros.geometry.paths import Coordinate, FitReport, PolynomialGeometry
from vm_ros.importers.common import (
    LENGTH_WARNING_M,
    FitOptions,
    ImportChoices,
    ImportedMuscle,
    specific_tension_option,
    write_import,
)
from vm_ros.importers.motion import read_motion
from vm_ros.importers.pipeline import (
    CROSSING_M,
    PathSource,
    SampleBox,
    checks_record,
    import_paths,
    sample,
)
from vm_ros.progress import Progress

SCREEN_POSES = 60
SCREEN_HALF_WIDTH = {"rad": math.pi, "m": 1.0}   # screening box around the default, at most


@dataclass(frozen=True)
class OsimOptions(FitOptions):
    """``vm-ros import-osim``'s options: the fit's, and the motions the box follows."""

    motions: tuple = ()
    margin_deg: float = 10.0
    margin_m: float = 0.01


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
    with Progress("screening coordinates", SCREEN_POSES, enabled=progress) as bar:
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


@dataclass
class OsimImport:
    """Result of an import: the geometry, the muscles' parameters, what was written."""

    geometry: PolynomialGeometry
    muscles: list
    written: dict
    skipped: dict
    seconds: float
    evaluations: int


class OsimSource(PathSource):
    """An OpenSim model's exact paths (OsimPaths: central differences through the couplers,
    screened over every free coordinate first) and its muscles' parameters, for
    vm_ros.importers.pipeline. ``how``: added to the title after the model file's name."""

    gradient_step = STEP
    sweep_extremes = True

    def __init__(self, osim, model_path: Path, options: OsimOptions, motions=(),
                 progress: bool | None = None, how: str = ""):
        self.osim, self.model_path, self.options = osim, model_path, options
        self.motions, self.progress, self.how = list(motions), progress, how
        paths = self.paths = OsimPaths(osim, model_path)
        self.chosen = _selected(paths, options.muscles)
        if not paths.muscles:
            raise VmRosError(f"{model_path}: the model has no muscles")
        self.muscle_names = tuple(paths.muscle_names[i] for i in self.chosen)
        self.columns = list(range(len(paths.independent)))
        self.held = paths.held_text()
        self.skip_word = f"{'free ' if paths.held else ''}coordinate"
        self.origin = f"OpenSim model {paths.model.getName()} ({model_path.name})"
        self.motion_box = None

    def box(self, rng) -> SampleBox:
        """Screening (every free coordinate, SCREEN_POSES poses), then the box of the crossed
        coordinates: the model's ranges or the motions' (_motion_box)."""
        paths = self.paths
        peak = _screen(paths, rng, self.progress)[self.chosen]
        self.columns = [j for j in range(len(paths.independent))
                        if np.any(peak[:, j] > CROSSING_M)]
        if not self.columns:
            raise VmRosError(f"{self.model_path}: no muscle crosses a free coordinate"
                             + (f" (held: {paths.held_text()})" if paths.held else ""))
        self.motion_box = box = _motion_box(paths, self.columns, self.motions, self.options)
        return SampleBox(tuple(paths.independent[j].getName() for j in self.columns),
                         tuple(paths.units[j] for j in self.columns), box.lower, box.upper,
                         peak[:, self.columns])

    def poses(self, box, n, rng) -> np.ndarray:
        return _poses(self.motion_box, n, rng)

    def lengths_and_gradients(self, q, wrt=None):
        length, gradient = self.paths.lengths_and_gradients(self.columns, q, wrt)
        return length[self.chosen], gradient[self.chosen]

    def skip_reason(self, name) -> str:
        held = f" with {', '.join(self.paths.held)} held" if self.paths.held else ""
        return f"crosses no {self.skip_word} (constant length{held})"

    def record(self, skipped, box):
        coordinates = [Coordinate(n, u, float(lo), float(hi)) for n, u, lo, hi in
                       zip(box.names, box.units, box.lower, box.upper, strict=True)]
        return (_source(self.osim, self.paths, self.model_path, self.motions,
                        {"muscles_skipped": skipped} if skipped else None),
                _options_record(self.options, self.motion_box),
                self.paths.coupled_coordinates(coordinates))

    def imported(self, names, path_min, path_max) -> list:
        return [_imported(self.paths, self.paths.muscle_names.index(n), lo, hi)
                for n, lo, hi in zip(names, path_min, path_max, strict=True)]

    def title(self, geometry, seconds) -> str:
        return (f"vm-ros import-osim {self.model_path.name}{self.how} (OpenSim model "
                f"{self.paths.model.getName()}, OpenSim {self.osim.GetVersion()}): "
                f"{len(geometry.muscles)} muscles over {len(geometry.coordinates)} coordinates, "
                f"{self.paths.evaluations} path evaluations in {seconds:.1f} s")


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
    source = OsimSource(load_opensim(), model_path, options, motions, progress)
    result = import_paths(source, out_dir, options, choices, progress=progress, file=file,
                          label=str(model_path))
    return OsimImport(result.geometry, result.muscles, result.written, result.skipped,
                      result.seconds, source.paths.evaluations)


def _options_record(options: OsimOptions, box: _Box) -> dict:
    return {
        **options.recorded(), "box": box.note,
        "sampling": "Latin hypercube in the box" + ("; half of the poses motion frames jittered "
                                                     "within the margin" if box.frames is not None
                                                     else ""),
        "gradient": f"central differences, step {STEP:g} (rad or m), through the couplers",
        **checks_record(f"at one of {SCREEN_POSES} screening poses or any sampled pose",
                        "tangent"),
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
    started = time.monotonic()
    source = OsimSource(load_opensim(), model_path, replace(options, muscles=()), motions,
                        progress, how=f" --function-based-paths {xml_path.name}")
    paths = source.paths
    box = _motion_box(paths, source.columns, motions, options)
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
    cols = source.columns = [index[c.name] for c in raw.coordinates]
    rng = np.random.default_rng(options.seed)
    sub = _Box(box.lower[cols], box.upper[cols],
               None if box.frames is None else box.frames[:, cols], box.margin[cols], box.note)
    poses = _poses(sub, options.n_held_out, rng)
    length, gradient = sample(source, poses, "evaluating the model's paths", progress)
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
                                  source=_source(source.osim, paths, model_path, motions,
                                                 raw.source),
                                  options={"from": "OpenSim PolynomialPathFitter output "
                                                   "(FunctionBasedPath set), polynomials as "
                                                   "written", "box": box.note,
                                           "fit_report": f"against the model's own paths at "
                                                         f"{len(poses)} poses in the box",
                                           "seed": options.seed})
    seconds = time.monotonic() - started
    written = write_import(out_dir, geometry, imported, choices,
                           title=source.title(geometry, seconds), origin=source.origin,
                           file=file)
    return OsimImport(geometry, imported, written, {}, seconds, paths.evaluations)


__all__ = ["NEEDS_OPENSIM", "OsimImport", "OsimOptions", "OsimSource", "check_model_file",
           "import_function_based_paths", "import_osim", "load_opensim"]
