"""``vm-ros import-mjcf``: polynomial geometry and a VM muscle library from a MuJoCo model.

Geometry: poses are sampled uniformly over the coordinate boxes (the dependent joints of joint
equalities set from their polynomials at every pose), MuJoCo gives the exact path lengths and
dL/dq (``ten_length``, ``ten_J`` through vm_ros.geometry.mujoco_backend), and
vm_ros.geometry.fit.fit_path fits one polynomial per muscle over the coordinates it crosses
(|r| > 1 mm at some sampled pose). Errors are reported on held-out poses. A muscle is flagged
``discontinuous`` where central differences of MuJoCo's length at two step sizes disagree with
each other by more than 1 mm/rad (a path jumping between wrapping solutions).

Parameters, the MuJoCo way (``mju_muscleGain``): a MuJoCo muscle stores a normalised operating
range (range0, range1) of fibre length in L0 and a compiled ``lengthrange`` (lr0, lr1) of the
actuator length, not an optimal fibre length and a tendon slack length. MuJoCo derives

    L0 = (lr1 - lr0) / (range1 - range0),      LT = lr0 - range0 * L0   (a rigid tendon),

    F0 = gainprm[2] ("force"), or scale / actuator_acc0 where force < 0,

and so does this importer (divided by the gear, which is 1 in the myo-sim models): LT is taken
as the tendon slack length, L0 as the optimal fibre length. These numbers are often unusable: a
range that is MuJoCo's default (0.75, 1.05) says nothing about the muscle, and the derived tendon
can come out a few mm long or negative (8 of 63 myoarm_r muscles have LT <= 5 mm). Such muscles
are flagged (``tendon <= 5 mm``, ``negative tendon``, ``default range``, ...) and listed loudly;
muscles whose numbers are not even positive are left out of the library. Parameters from
elsewhere (``--library FILE``, a VM muscle library) replace the derived entries by name.
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from vm_ros.errors import VmRosError
from vm_ros.geometry.paths import PolynomialGeometry
from vm_ros.importers.common import (
    FitOptions,
    ImportChoices,
    ImportedMuscle,
    write_library,
)
from vm_ros.importers.pipeline import PathSource, SampleBox, checks_record, import_paths

MUJOCO_DEFAULT_RANGE = (0.75, 1.05)   # MuJoCo's default muscle operating range (L0)
MIN_TENDON_M = 0.005                  # a derived tendon this short (or shorter) is unusable


@dataclass(frozen=True)
class MujocoMuscle:
    """One MuJoCo muscle's parameters derived the MuJoCo way, and what is wrong with them.

    | field | unit | meaning |
    | --- | --- | --- |
    | f0_n | N | gainprm[2], or scale / acc0 where it is < 0 |
    | l0_m | m | (lr1 - lr0) / (range1 - range0) / gear |
    | tendon_m | m | lr0 / gear - range0 * l0_m (MuJoCo's rigid tendon) |
    | operating_range | L0 | (range0, range1) |
    | length_range_m | m | compiled lengthrange / gear |
    | flags | | problems found; empty when usable |
    """

    name: str
    f0_n: float
    f0_rule: str
    l0_m: float
    tendon_m: float
    operating_range: tuple[float, float]
    length_range_m: tuple[float, float]
    flags: tuple[str, ...]

    @property
    def usable(self) -> bool:
        return not self.flags

    @property
    def positive(self) -> bool:
        """Numbers a library entry can be made of (usable or not)."""
        return self.f0_n > 0 and self.l0_m > 0 and self.tendon_m > 0

    def imported(self, path_length_min_m: float, path_length_max_m: float) -> ImportedMuscle:
        note = (f"MuJoCo muscle: range ({self.operating_range[0]:.6g}, "
                f"{self.operating_range[1]:.6g}) L0, lengthrange ({self.length_range_m[0]:.6g}, "
                f"{self.length_range_m[1]:.6g}) m -> L0 {self.l0_m:.6g} m, rigid tendon "
                f"{self.tendon_m:.6g} m (the MuJoCo way); F0 {self.f0_rule}")
        if self.flags:
            note = f"UNUSABLE ({'; '.join(self.flags)}): {note}"
        return ImportedMuscle(self.name, self.f0_n, self.l0_m, self.tendon_m,
                              path_length_min_m, path_length_max_m, 0.0, note)


def mujoco_muscles(model, actuator_names) -> list[MujocoMuscle]:
    """The parameters of the named muscle actuators, derived the MuJoCo way (module docstring)."""
    import mujoco

    out = []
    for name in actuator_names:
        a = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, name)
        prm = model.actuator_gainprm[a]
        gear = float(model.actuator_gear[a, 0]) or 1.0
        range0, range1, force, scale = (float(v) for v in prm[:4])
        lr0, lr1 = (float(v) / gear for v in model.actuator_lengthrange[a])
        flags = []
        if force > 0:
            f0, rule = force, f"= gainprm force {force:.6g} N"
        else:
            acc0 = float(model.actuator_acc0[a])
            f0 = scale / acc0 if acc0 > 0 else float("nan")
            rule = f"= scale {scale:.6g} / acc0 {acc0:.6g} (force < 0)"
        span = range1 - range0
        l0 = (lr1 - lr0) / span if span > 0 else float("nan")
        tendon = lr0 - range0 * l0
        if (range0, range1) == MUJOCO_DEFAULT_RANGE:
            flags.append("default range (0.75, 1.05): L0 and tendon not the muscle's own")
        if not lr1 > lr0:
            flags.append("no lengthrange")
        if not (math.isfinite(l0) and l0 > 0):
            flags.append(f"L0 {l0:.4g} m")
        if not (math.isfinite(f0) and f0 > 0):
            flags.append(f"F0 {f0:.4g} N")
        if not math.isfinite(tendon) or tendon <= 0:
            flags.append(f"negative tendon {tendon * 1e3:.1f} mm")
        elif tendon <= MIN_TENDON_M:
            flags.append(f"tendon <= 5 mm ({tendon * 1e3:.1f} mm)")
        if math.isfinite(l0) and l0 > 0 and math.isfinite(tendon) and tendon > 0 \
                and not 0.02 <= tendon / l0 <= 50:
            flags.append(f"implausible tendon/L0 ratio {tendon / l0:.3g}")
        out.append(MujocoMuscle(name, f0, rule, l0, tendon, (range0, range1), (lr0, lr1),
                                tuple(flags)))
    return out


def sample_poses(geometry, n: int, seed: int = 0) -> np.ndarray:
    """n poses (n, n_q) drawn uniformly over the coordinate boxes."""
    rng = np.random.default_rng(seed)
    lower, upper = geometry.lower, geometry.upper
    return lower + rng.random((int(n), len(lower))) * (upper - lower)


def sample_paths(geometry, poses) -> tuple[np.ndarray, np.ndarray]:
    """MuJoCo's exact (L (P, n_muscles), dL/dq (P, n_muscles, n_q)) at each pose."""
    lengths = np.empty((len(poses), len(geometry.muscle_names)))
    gradients = np.empty((len(poses), len(geometry.muscle_names), len(geometry.coordinates)))
    for p, q in enumerate(poses):
        lengths[p], gradients[p] = geometry.lengths_and_gradients(q)
    return lengths, gradients


def path_extremes(geometry, n_poses: int = 500, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Smallest and largest path length (m) of every muscle over sampled poses."""
    lengths, _ = sample_paths(geometry, sample_poses(geometry, n_poses, seed))
    return lengths.min(axis=0), lengths.max(axis=0)


@dataclass(frozen=True)
class DerivedLibrary:
    """Library entries for a model's muscles: derived the MuJoCo way, then replaced by name from
    a user library. ``excluded``: muscles with no entry (non-positive derived numbers and none
    given); ``overridden``: names taken from the user library; ``flagged``: derived entries in use
    whose MuJoCo numbers are unusable (see MujocoMuscle.flags)."""

    entries: dict
    rows: list
    muscles: tuple
    excluded: tuple
    overridden: tuple
    flagged: tuple


def imported_muscles(model, muscle_names, path_min, path_max
                     ) -> tuple[list[MujocoMuscle], list]:
    """(MuJoCo-way parameters of the named muscles, ImportedMuscle of those with positive
    numbers); path_min/path_max: each muscle's sampled path length extremes (m)."""
    derived = mujoco_muscles(model, muscle_names)
    imported = [d.imported(float(lo), float(hi))
                for d, lo, hi in zip(derived, path_min, path_max, strict=True) if d.positive]
    return derived, imported


def load_user_library(path) -> dict:
    """A VM muscle library given with --library: ``{name: fields}`` (validated when the bank is
    built); ConfigError when the file is unreadable or has no muscles."""
    from vm_ros.model.params import load_muscle_library

    return {str(k): dict(v or {}) for k, v in load_muscle_library(path).items()}


def derive_library(geometry, choices, path_min, path_max, user_entries=None,
                   params=None, fibre_table=None, muscle_names=None) -> DerivedLibrary:
    """Library entries for the muscles of ``geometry`` (a MujocoGeometry; ``muscle_names``: a
    subset, default all, with path_min/path_max in that order): the MuJoCo-way parameters through
    vm_ros.importers.common's rules, entries of ``user_entries`` replacing them by name."""
    from vm_ros.importers import common
    from vm_ros.model.params import load_model_params

    names = tuple(muscle_names or geometry.muscle_names)
    params = params or load_model_params()
    derived, imported = imported_muscles(geometry.model, names, path_min, path_max)
    entries, rows = {}, []
    if imported:
        entries, rows = common.library_entries(
            imported, specific_tension_pa=choices.specific_tension.pa,
            density_kg_per_m3=params.generic.muscle_density,
            fibre_table=fibre_table or common.load_fibre_table(),
            default_fpcsa_slow=choices.default_fpcsa_slow, ur=choices.ur, params=params,
            origin=origin_of(geometry), strength=choices.strength)
    user_entries = user_entries or {}
    overridden = tuple(n for n in names if n in user_entries)
    for name in overridden:
        entries[name] = user_entries[name]
    entries = {n: entries[n] for n in names if n in entries}
    excluded = tuple(n for n in names if n not in entries)
    flagged = tuple(d.name for d in derived if d.flags and d.name in entries
                    and d.name not in overridden)
    return DerivedLibrary(entries, rows, tuple(derived), excluded, overridden, flagged)


def origin_of(geometry) -> str:
    """How library source notes name the model."""
    return f"MuJoCo model {geometry.source.get('model')}"


def parameter_flag_lines(library: DerivedLibrary) -> list[str]:
    """The loud part of the summary: every muscle whose MuJoCo parameters are unusable."""
    bad = [d for d in library.muscles if d.flags]
    if not bad:
        return ["MuJoCo muscle parameters: all usable (derived the MuJoCo way)."]
    lines = [f"WARNING: {len(bad)} of {len(library.muscles)} muscles have unusable MuJoCo "
             "parameters (derived the MuJoCo way: L0 = (lr1 - lr0)/(range1 - range0), tendon = "
             "lr0 - range0*L0):"]
    for d in bad:
        if d.name in library.overridden:
            what = "replaced from --library"
        elif d.name in library.excluded:
            what = "LEFT OUT of the library (give it with --library)"
        else:
            what = "written as derived: REPLACE IT (--library)"
        lines.append(f"  !! {d.name}: L0 {d.l0_m * 1e3:.1f} mm, tendon {d.tendon_m * 1e3:.1f} "
                     f"mm, F0 {d.f0_n:.1f} N: {'; '.join(d.flags)} -> {what}")
    return lines


def print_parameter_flags(library: DerivedLibrary, file=None) -> None:
    """``parameter_flag_lines``, printed (default stdout)."""
    print("\n".join(parameter_flag_lines(library)), file=file or sys.stdout)


# ---------------------------------------------------------------------------- held joints


def held_joints(exact) -> dict[str, dict[str, str]]:
    """Per muscle of ``exact`` (a MujocoGeometry), ``{joint name: why}`` of the joints its
    tendon crosses that stay at one value and are no coordinates: fixed by a joint equality
    without joint2, or driven through joint equalities by such a joint."""
    import mujoco

    from vm_ros.geometry.mujoco_backend import tendon_joints

    m = exact.model
    coupling = {c.joint: c for c in exact.couplings}

    def name(joint):
        return mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, int(joint)) or f"joint{joint}"

    def root(joint):
        while joint in coupling:
            joint = coupling[joint].driver
        return joint

    out = {}
    for muscle, tendon in zip(exact.muscle_names, exact.tendon_ids, strict=True):
        out[muscle] = {}
        for joint in sorted(tendon_joints(m, int(tendon))):
            if joint not in coupling or root(joint) >= 0:
                continue
            c = coupling[joint]
            out[muscle][name(joint)] = (
                f"fixed by joint equality {c.equality!r} (no joint2)" if c.driver < 0 else
                f"follows the held {name(c.driver)} (joint equality {c.equality!r})")
    return out


def held_text(held: dict) -> str:
    """The held joints of every muscle, each once, in one line."""
    joints = {name: why for per_muscle in held.values() for name, why in per_muscle.items()}
    return "; ".join(f"{name}: {why}" for name, why in joints.items())


def check_ranges(exact) -> None:
    """VmRosError for a crossed joint whose range has zero width (min == max, not 0 0):
    MuJoCo reads it as no range, and the import would sample a hinge over [-pi, pi]."""
    import mujoco

    m = exact.model
    for joint in exact.joint_ids:
        lower, upper = (float(v) for v in m.jnt_range[joint])
        if not m.jnt_limited[joint] and lower == upper != 0.0:
            name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, int(joint))
            raise VmRosError(f"model {exact.source['model']!r}: joint {name!r} has the range "
                             f"[{lower:g}, {upper:g}], which MuJoCo reads as no range (it would "
                             "be sampled over [-pi, pi]); give it a range with min < max, or "
                             "fix it with a joint equality without joint2")


# ---------------------------------------------------------------------------- the import


class MjcfOptions(FitOptions):
    """How ``vm-ros import-mjcf`` samples and fits (its command-line options)."""


@dataclass
class MjcfImport:
    """Result of an import: geometry written, parameters derived, library, files."""

    geometry: PolynomialGeometry
    library: DerivedLibrary
    written: dict
    skipped: dict
    seconds: float
    notes: list = field(default_factory=list)


class MjcfSource(PathSource):
    """A MuJoCo model's exact paths (MujocoGeometry: lengths and ten_J through the joint
    equalities) and its parameters derived the MuJoCo way, for vm_ros.importers.pipeline."""

    def __init__(self, model, options: MjcfOptions, choices: ImportChoices, user_library=None):
        from vm_ros.geometry.mujoco_backend import MujocoGeometry

        self.options, self.choices, self.user_library = options, choices, user_library
        self.user = load_user_library(user_library) if user_library is not None else None
        exact = self.exact = MujocoGeometry(model, muscles=options.muscles or None)
        check_ranges(exact)
        self.held_by_muscle = held_joints(exact)
        self.held = held_text(self.held_by_muscle) if any(self.held_by_muscle.values()) else ""
        if not exact.coordinates:
            raise VmRosError(f"model {exact.source['model']!r}: "
                             + (f"every joint its muscles cross is held, none is left to "
                                f"sample: {self.held}; deactivate (active=\"false\") or remove "
                                "those equalities to make the joints inputs" if self.held
                                else "no muscle crosses a hinge or slide joint"))
        self.muscle_names = exact.muscle_names
        self.origin = origin_of(exact)
        self.library = None

    def box(self, rng) -> SampleBox:
        e = self.exact
        return SampleBox(e.coordinate_names, tuple(c.unit for c in e.coordinates), e.lower,
                         e.upper)

    def poses(self, box, n, rng) -> np.ndarray:
        """Latin hypercube in the coordinate boxes, one pose per stratum of every coordinate."""
        from scipy.stats import qmc

        unit = qmc.LatinHypercube(d=len(box.names), seed=rng).random(int(n))
        return qmc.scale(unit, box.lower, box.upper)

    def lengths_and_gradients(self, q, wrt=None):
        length, gradient = self.exact.lengths_and_gradients(q)
        return length, gradient if wrt is None else gradient[:, wrt]

    def skip_reason(self, name) -> str:
        held = self.held_by_muscle[name]
        return ("crosses no coordinate (|r| <= 1 mm everywhere)"
                + (f"; held: {', '.join(held)}" if held else ""))

    def record(self, skipped, box):
        e = self.exact
        source = {**e.source, "importer": "vm-ros import-mjcf"}
        if skipped:
            source["muscles_skipped"] = skipped
        if e.notes:
            source["notes"] = list(e.notes)
        if self.held:
            source["held_joints"] = self.held
        return source, _options_record(self.options), list(e.coupled)

    def imported(self, names, path_min, path_max) -> list:
        self.library = derive_library(self.exact, self.choices, path_min, path_max, self.user,
                                      muscle_names=names)
        return imported_muscles(self.exact.model, names, path_min, path_max)[1]

    def title(self, geometry, seconds) -> str:
        s = self.exact.source
        return (f"vm-ros import-mjcf {s['model']} (MuJoCo {s['mujoco']}"
                + (f", myo-sim {s['myo_sim']}" if "myo_sim" in s else "")
                + f"): {len(geometry.muscles)} muscles over {len(geometry.coordinates)} "
                f"coordinates, {self.options.samples + self.options.n_held_out} poses in "
                f"{seconds:.1f} s")

    def finish(self, written) -> list[str]:
        library = self.library
        if library.overridden:
            _replace_library(written["library"], library)
        lines = parameter_flag_lines(library)
        if library.overridden:
            lines.append(f"replaced from {self.user_library}: {', '.join(library.overridden)}")
        return lines


def import_mjcf(model, out_dir, options: MjcfOptions | None = None,
                choices: ImportChoices | None = None, user_library=None, file=None,
                progress: bool | None = None) -> MjcfImport:
    """Import a MuJoCo model's muscle paths and parameters into ``out_dir``: DIR/geometry.yaml,
    DIR/muscles.yaml, DIR/summary.txt (module docstring). ``user_library``: a muscle-library
    YAML whose entries replace the derived ones by name."""
    from vm_ros.importers.common import specific_tension_option

    options = options or MjcfOptions()
    choices = choices or ImportChoices(specific_tension_option("rajagopal"))
    source = MjcfSource(model, options, choices, user_library)
    result = import_paths(source, out_dir, options, choices, progress=progress, file=file,
                          label=f"model {source.exact.source['model']!r}")
    return MjcfImport(result.geometry, source.library, result.written, result.skipped,
                      result.seconds, list(source.exact.notes))


def _replace_library(path, library: DerivedLibrary) -> None:
    """Rewrite the library write_import wrote with the user's entries in place of the derived
    ones (same derivation, so the other entries are unchanged); the header says which."""
    path = Path(path)
    header = "\n".join(line[2:] if line.startswith("# ") else line.lstrip("#")
                       for line in path.read_text(encoding="utf-8").splitlines()
                       if line.startswith("#"))
    header += ("\n\nEntries replaced from the user library (--library): "
               f"{', '.join(library.overridden)}")
    write_library(path, library.entries, header)


def _options_record(options: MjcfOptions) -> dict:
    return {
        **options.recorded(),
        "box": "joint ranges (jnt_range); unlimited hinges [-pi, pi]",
        "sampling": "Latin hypercube in the box; joint-equality dependents from their "
                    "polynomials",
        "gradient": "exact: MuJoCo ten_J (mj_kinematics, mj_comPos, mj_tendon) through the "
                    "joint equalities",
        **checks_record("at a sampled pose", "exact"),
    }
