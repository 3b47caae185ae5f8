"""Validation item ``walk``: coordination from motion on the Gait10dof18musc walk of
opensim-models, against its inverse dynamics, OpenSim (StaticOptimization, CMC, the Umberger
probe), indirect calorimetry and walking EMG (config/walk_validation.yaml: references and
criteria, fixed before any result).

What is measured, from a ``WalkSolution`` (drives, forces, joint moments of a forward run of the
full model, metabolic rate):

- tracking: per hip, knee and ankle coordinate, RMS and max of (muscle moment - ID moment) over
  the coordinate's peak |ID moment|; frames where the ID departs from its 5-frame running median
  by more than ``spike_of_peak`` of the peak (heel-strike spikes) are left out of the max and
  reported separately; where the ID's own content above ``smoothness_cutoff_hz`` (RMS over the
  peak, target_content_above) exceeds the RMS bound, that criterion is a known gap naming it;
- a solve on the ID low-passed at ``lowpassed_targets.cutoff_hz``, with a lead-in of
  ``lowpassed_targets.lead_in_s`` (variant_reported): its errors against those targets and
  against the ID as given, reported without a bound;
- EMG timing: each right-leg muscle's drive, normalised over the right gait cycle to
  (u - min) / (max - min), averaged over its active and silent windows;
- smoothness: the share of each drive's variance (mean removed) above ``smoothness_cutoff_hz``;
- forces: per-muscle Pearson correlation with OpenSim SO's and CMC's forces, median over muscles;
- metabolic: the muscles' total rate averaged over the right gait cycle per kg of body mass,
  over each calorimetric reference's net rate (config ``metabolic``).

Without the walk's files (scripts/fetch-gait-data), the opensim extra or a coordination solver,
the item is skipped and says which.
"""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path

import numpy as np
import yaml

from vm_ros.errors import ConfigError
from vm_ros.resources import config_dir
from vm_ros.validation.joint_torque import CheckSkippedError
from vm_ros.validation.results import CheckResult, Criterion

WALK_VALIDATION_FILE = "walk_validation.yaml"
TRACKED = tuple(f"{joint}_{side}" for side in "rl"
                for joint in ("hip_flexion", "knee_angle", "ankle_angle"))
SPIKE_WINDOW = 5  # frames of the running median that heel-strike spikes are measured from
SECONDS_PER_MINUTE = 60.0
M_PER_S_PER_M_PER_MIN = 1.0 / 60.0


@dataclasses.dataclass(frozen=True)
class WalkSolution:
    """A coordination result on the walk.

    | field | shape | unit |
    | --- | --- | --- |
    | times_s | (T,) | s, the walk's time axis (the IK file's) |
    | muscles | (M,) | |
    | drives | (T, M) | 1 |
    | forces_n | (T, M) | N |
    | coordinates | (C,) | |
    | moments_nm | (T, C) | N m, r^T F of the forward run |
    | targets_nm | (T, C) | N m, the inverse-dynamics targets |
    | metabolic_w | (T,) | W, VM's rate summed over the muscles (no basal rate) |
    | metabolic_parts_w | (T, 3) | W, its activation, cross-bridge and recovery parts |
    | model_rates_w | name -> (T,) | W, each published model's rate on the same state |
    | cocontraction | (C,) | opposing share of the muscle moments per coordinate |
    """

    label: str
    times_s: np.ndarray
    muscles: tuple[str, ...]
    drives: np.ndarray
    forces_n: np.ndarray
    coordinates: tuple[str, ...]
    moments_nm: np.ndarray
    targets_nm: np.ndarray
    metabolic_w: np.ndarray
    metabolic_parts_w: np.ndarray | None = None
    model_rates_w: dict | None = None
    cocontraction: np.ndarray | None = None


def load_walk_config(path=None) -> tuple[dict, Path]:
    """config/walk_validation.yaml (or ``path``); ConfigError when unreadable."""
    path = Path(path) if path is not None else config_dir() / WALK_VALIDATION_FILE
    try:
        data = yaml.safe_load(path.read_text(encoding="utf-8"))
    except (OSError, yaml.YAMLError) as exc:
        raise ConfigError(path, "", None, f"cannot read ({exc})") from exc
    for key in ("walk", "metabolic", "emg_timing", "criteria", "lowpassed_targets"):
        if not isinstance(data, dict) or not isinstance(data.get(key), dict):
            raise ConfigError(path, key, None, "missing section")
    return data, path


def spike_frames(targets, fraction: float) -> np.ndarray:
    """(T, C) bool: |target - its running median over SPIKE_WINDOW frames| > fraction x the
    coordinate's peak |target|; T >= 3.

    The window runs past the ends over two slots per end. The slot next to the end holds a
    copy of the end frame (it is also in the second frame's window, which is thus the same as
    with the end frame repeated); the outer slot, which only the end frame's own window holds,
    continues the straight line through the two frames before the end frame. A copy there (the
    end frame three times in its own window of five) made the end frame its own median, so it
    could never be flagged; the line makes an end frame on a straight stretch its own median
    (as a monotone stretch is in the interior) and flags an end frame that turns back from its
    neighbours or stands alone (changed on 2026-12-03 after the walk's results were seen:
    docs/coordination.md, "The hips' max on this walk")."""
    targets = np.asarray(targets, dtype=float)
    half = SPIKE_WINDOW // 2
    padded = np.pad(targets, ((half, half), (0, 0)), mode="edge")
    padded[0] = targets[1] + (half + 1) * (targets[1] - targets[2])
    padded[-1] = targets[-2] + (half + 1) * (targets[-2] - targets[-3])
    windows = np.lib.stride_tricks.sliding_window_view(padded, SPIKE_WINDOW, axis=0)
    median = np.median(windows, axis=-1)
    return np.abs(targets - median) > fraction * np.abs(targets).max(axis=0)


def tracking_errors(solution: WalkSolution, spike_fraction: float) -> dict[str, dict]:
    """Per coordinate: rms_of_peak, max_of_peak (spike frames left out), spikes (frame count),
    spike_max_of_peak (max over the spike frames, 0 without)."""
    spikes = spike_frames(solution.targets_nm, spike_fraction)
    error = np.abs(solution.moments_nm - solution.targets_nm)
    peak = np.maximum(np.abs(solution.targets_nm).max(axis=0), 1e-12)
    out = {}
    for j, name in enumerate(solution.coordinates):
        calm = error[~spikes[:, j], j]
        out[name] = {"rms_of_peak": float(np.sqrt(np.mean(error[:, j] ** 2)) / peak[j]),
                     "max_of_peak": float(calm.max() / peak[j]) if len(calm) else 0.0,
                     "spikes": int(spikes[:, j].sum()),
                     "spike_max_of_peak": float(error[spikes[:, j], j].max() / peak[j])
                     if spikes[:, j].any() else 0.0}
    return out


def target_content_above(solution: WalkSolution, cutoff_hz: float) -> dict[str, float]:
    """Per coordinate: RMS of the targets' content above ``cutoff_hz`` (the targets less their
    zero-phase low-pass, vm_ros.coordination.targets.content_above) over the coordinate's peak;
    empty when the frames allow no low-pass."""
    from vm_ros.coordination.targets import content_above

    rms = content_above(solution.times_s, solution.targets_nm, cutoff_hz)
    if rms is None:
        return {}
    peak = np.maximum(np.abs(solution.targets_nm).max(axis=0), 1e-12)
    return dict(zip(solution.coordinates, (rms / peak).tolist(), strict=True))


def variant_reported(variant: WalkSolution, raw: WalkSolution, config: dict) -> list[Criterion]:
    """Numbers of the solve on low-passed targets (config ``lowpassed_targets``), without a
    bound: per coordinate the RMS and max (no spikes) error against the low-passed targets it
    was solved for and the RMS error against the ID as given (``raw``'s targets, same frames),
    and the largest drive variance share above the smoothness cutoff."""
    crit = config["criteria"]
    own = tracking_errors(variant, crit["spike_of_peak"]["value"])
    against_raw = tracking_errors(dataclasses.replace(variant, targets_nm=raw.targets_nm),
                                  crit["spike_of_peak"]["value"])
    out = []
    for name in (c for c in TRACKED if c in own):
        out += [Criterion(f"{variant.label}: {name} RMS / peak (its ID)",
                          own[name]["rms_of_peak"]),
                Criterion(f"{variant.label}: {name} max / peak (its ID, no spikes)",
                          own[name]["max_of_peak"]),
                Criterion(f"{variant.label}: {name} RMS / peak (ID as given)",
                          against_raw[name]["rms_of_peak"])]
    share = high_frequency_share(variant.times_s, variant.drives,
                                 crit["smoothness_cutoff_hz"]["value"])
    out.append(Criterion(f"{variant.label}: largest drive variance share above "
                         f"{crit['smoothness_cutoff_hz']['value']:g} Hz", float(share.max())))
    return out


def window_means(times_s, values, strikes, windows: dict) -> dict[str, float]:
    """``values`` (T,) normalised over the gait cycle from strikes[0] to strikes[1] to
    (v - min) / (max - min), averaged over each window {name: (start %, end %)}; NaN for a window
    with no frame or a cycle the values do not cover."""
    from vm_ros.validation.walk_reference import cycle_percent

    inside, percent = cycle_percent(times_s, strikes)
    values = np.asarray(values, dtype=float)
    if inside.sum() < 2:
        return {name: float("nan") for name in windows}
    cycle = values[inside]
    span = cycle.max() - cycle.min()
    normalised = (cycle - cycle.min()) / span if span > 0 else np.zeros_like(cycle)
    out = {}
    for name, (start, end) in windows.items():
        pick = (percent[inside] >= start) & (percent[inside] <= end)
        out[name] = float(normalised[pick].mean()) if pick.any() else float("nan")
    return out


def high_frequency_share(times_s, values, cutoff_hz: float) -> np.ndarray:
    """Per column of ``values`` (T, k) sampled uniformly at ``times_s``: the share of the
    variance (mean removed) in frequencies above ``cutoff_hz`` (0 for a constant column). The
    content above the cutoff is taken about the straight line from the first to the last
    sample: the FFT treats a column as periodic, and without the line the jump from its last
    sample back to its first counts as content above the cutoff (a drive going from 0.11 to 0
    over the walk would count as rough)."""
    values = np.asarray(values, dtype=float).reshape(len(times_s), -1)
    step = float(np.median(np.diff(times_s)))
    frequency = np.fft.rfftfreq(len(times_s), step)
    along = np.linspace(0.0, 1.0, len(times_s))[:, None]
    about_line = values - (values[:1] + (values[-1:] - values[:1]) * along)
    total = (np.abs(np.fft.rfft(values - values.mean(axis=0), axis=0)) ** 2)[1:].sum(axis=0)
    above = (np.abs(np.fft.rfft(about_line, axis=0)) ** 2)[frequency > cutoff_hz].sum(axis=0)
    # a constant column's residue after removing the mean is rounding, not variance
    moving = values.std(axis=0) > 1e-12 * np.abs(values).max(axis=0)
    return np.divide(above, total, out=np.zeros_like(total), where=moving & (total > 0))


def net_metabolic_references(metabolic: dict, speed_m_per_s: float) -> dict[str, float]:
    """{reference name: net metabolic power (W/kg)} from config ``metabolic``: a net slope per
    m/min of speed is evaluated at ``speed_m_per_s``; a gross rate has the resting rate removed.
    ConfigError for a reference with neither."""
    energy = metabolic["energy_j_per_ml_o2"]["value"]
    resting = metabolic["resting_ml_per_kg_min"]["value"]
    net_ml_per_kg_min = {
        "net_ml_per_kg_min_per_m_per_min": lambda v: v * speed_m_per_s / M_PER_S_PER_M_PER_MIN,
        "gross_ml_per_kg_min": lambda v: v - resting,
    }
    out = {}
    for ref in metabolic["references"]:
        kind = [key for key in net_ml_per_kg_min if key in ref]
        if len(kind) != 1:
            raise ConfigError(WALK_VALIDATION_FILE, "metabolic.references", ref.get("name"),
                              f"give exactly one of {', '.join(net_ml_per_kg_min)}")
        out[ref["name"]] = (net_ml_per_kg_min[kind[0]](ref[kind[0]]) * energy
                            / SECONDS_PER_MINUTE)
    return out


def _bounded(description, value, spec: dict, known_gap: str = "") -> Criterion:
    return Criterion(description, float(value), spec.get("low"), spec.get("high"), known_gap)


def evaluate_walk(solution: WalkSolution, context: dict, config: dict
                  ) -> tuple[list[Criterion], dict]:
    """The item's criteria and plot data for ``solution``; ``context``: ``strikes`` (right heel
    strikes, s), ``mass_kg``, ``speed_m_per_s``, and optionally ``so_forces`` and
    ``cmc_forces`` (MuscleSeries)."""
    from vm_ros.validation.walk_reference import MuscleSeries, compare, cycle_percent

    crit = config["criteria"]
    criteria, data = [], {"label": solution.label}
    tracking = tracking_errors(solution, crit["spike_of_peak"]["value"])
    data["tracking"] = tracking
    above = target_content_above(solution, crit["smoothness_cutoff_hz"]["value"])
    data["target_above_cutoff"] = above
    bound = crit["tracking_rms_of_peak"]["high"]
    for name in (c for c in TRACKED if c in tracking):
        floor = above.get(name, 0.0)
        gap = (f"the ID's own content above {crit['smoothness_cutoff_hz']['value']:g} Hz is "
               f"{100 * floor:.2f} % of its peak RMS, above the bound: drives smooth at that "
               "cutoff cannot follow it (docs/coordination.md)") if floor > bound else ""
        criteria.append(_bounded(f"{solution.label}: {name} RMS error / peak",
                                 tracking[name]["rms_of_peak"], crit["tracking_rms_of_peak"],
                                 gap))
        criteria.append(_bounded(f"{solution.label}: {name} max error / peak (no spikes)",
                                 tracking[name]["max_of_peak"], crit["tracking_max_of_peak"]))
    strikes = context["strikes"]
    timing = {}
    for key, windows in config["emg_timing"].items():
        name = f"{key}_r"
        if name not in solution.muscles:
            continue
        means = window_means(solution.times_s, solution.drives[:, solution.muscles.index(name)],
                             strikes, {"active": windows["active"],
                                       "silent": windows["silent"]})
        timing[name] = means
        criteria.append(_bounded(f"{solution.label}: {name} drive in {windows['active']} % "
                                 "(active)", means["active"], crit["emg_on_mean"]))
        criteria.append(_bounded(f"{solution.label}: {name} drive in {windows['silent']} % "
                                 "(silent)", means["silent"], crit["emg_off_mean"]))
    data["timing"] = timing
    share = high_frequency_share(solution.times_s, solution.drives,
                                 crit["smoothness_cutoff_hz"]["value"])
    data["smoothness"] = dict(zip(solution.muscles, share.tolist(), strict=True))
    criteria.append(_bounded(f"{solution.label}: largest drive variance share above "
                             f"{crit['smoothness_cutoff_hz']['value']:g} Hz", share.max(),
                             crit["smoothness_share_above_cutoff"]))
    ours = MuscleSeries(solution.label, solution.times_s, solution.muscles, solution.forces_n, "N")
    for key in ("so", "cmc"):
        reference = context.get(f"{key}_forces")
        if reference is None:
            continue
        per_muscle = compare(ours, reference)
        data[f"forces_vs_{key}"] = per_muscle
        median = float(np.median([v["r"] for v in per_muscle.values()]))
        criteria.append(_bounded(f"{solution.label}: median force correlation with "
                                 f"{reference.source}", median,
                                 crit[f"force_correlation_median_{key}"]))
    inside, _ = cycle_percent(solution.times_s, strikes)
    rate = _cycle_mean(solution.metabolic_w, solution.times_s, inside) / context["mass_kg"]
    references = net_metabolic_references(config["metabolic"], context["speed_m_per_s"])
    data["metabolic_w_per_kg"] = rate
    data.update(_metabolic_breakdown(solution, inside, context["mass_kg"]))
    criteria.extend(_reported(solution.label, data))
    data["metabolic_references"] = references
    for name, value in references.items():
        criteria.append(Criterion(f"{solution.label}: net metabolic power / {name} "
                                  f"({value:.2f} W/kg)", rate / value,
                                  crit["metabolic_ratio_low"]["low"],
                                  crit["metabolic_ratio_high"]["high"]))
    return criteria, data


def _cycle_mean(values, times_s, inside) -> float:
    from scipy import integrate

    t = times_s[inside]
    return float(integrate.trapezoid(values[inside], t) / (t[-1] - t[0])) if inside.sum() > 1 \
        else float("nan")


def _metabolic_breakdown(solution: WalkSolution, inside, mass_kg: float) -> dict:
    """What the metabolic rate is made of, over the cycle: the parts' shares (activation,
    cross-bridge, recovery), each published model's W/kg on the same state, the rate per
    newton of summed muscle force (W/N), and the co-contraction share per coordinate."""
    t = solution.times_s
    out = {"w_per_newton": _cycle_mean(solution.metabolic_w, t, inside)
           / max(_cycle_mean(solution.forces_n.sum(axis=1), t, inside), 1e-12)}
    if solution.metabolic_parts_w is not None:
        total = _cycle_mean(solution.metabolic_w, t, inside)
        out["metabolic_parts_share"] = {
            part: _cycle_mean(solution.metabolic_parts_w[:, j], t, inside) / total
            for j, part in enumerate(("activation", "cross-bridge", "recovery"))}
    if solution.model_rates_w is not None:
        out["model_w_per_kg"] = {name: _cycle_mean(rate, t, inside) / mass_kg
                                 for name, rate in solution.model_rates_w.items()}
    if solution.cocontraction is not None:
        out["cocontraction"] = dict(zip(solution.coordinates, solution.cocontraction.tolist(),
                                        strict=True))
    return out


def _reported(label: str, data: dict) -> list[Criterion]:
    """Numbers shown beside the criteria, without a bound (Criterion 'reported')."""
    out = [Criterion(f"{label}: net metabolic power (W/kg), right cycle",
                     data["metabolic_w_per_kg"]),
           Criterion(f"{label}: metabolic rate per newton of muscle force (W/N)",
                     data["w_per_newton"])]
    out += [Criterion(f"{label}: {part} share of VM's rate", share)
            for part, share in data.get("metabolic_parts_share", {}).items()]
    out += [Criterion(f"{label}: {name} on the same state (W/kg)", value)
            for name, value in data.get("model_w_per_kg", {}).items()]
    out += [Criterion(f"{label}: co-contraction share, {name}", value)
            for name, value in data.get("cocontraction", {}).items()]
    out += [Criterion(f"{label}: {name} max error / peak on {t['spikes']} spike frames",
                      t["spike_max_of_peak"])
            for name, t in data["tracking"].items() if t["spikes"]]
    return out


def context_reported(context: dict) -> list[Criterion]:
    """The references' own numbers, shown once: belt speed, OpenSim's Umberger probe over the
    CMC walk, and OpenSim SO against CMC (median force correlation)."""
    from vm_ros.validation.walk_reference import compare

    so_cmc = compare(context["so_forces"], context["cmc_forces"])
    return [Criterion("walk: treadmill belt speed (m/s)", context["speed_m_per_s"]),
            Criterion("OpenSim Umberger 2010 probe over CMC (W/kg)",
                      context["umberger"]["per_kg"]),
            Criterion("OpenSim SO against CMC: median force correlation",
                      float(np.median([v["r"] for v in so_cmc.values()])))]


def _walk_context(files, config) -> dict:
    from vm_ros.validation import walk_reference as wr

    walk = config["walk"]
    events = wr.gait_events(files, walk["contact_threshold_n"]["value"])
    strikes = events["r"]["strike"]
    so = wr.static_optimization(files)
    return {"strikes": strikes, "events": events,
            "mass_kg": wr.body_mass_kg(files["model"]),
            "speed_m_per_s": wr.walking_speed(files, strikes, walk["speed_window"]["value"]),
            "so_forces": so["force"], "so_reserves": so["reserve"],
            "cmc_forces": wr.cmc_forces(files), "umberger": wr.umberger_probe(files)}


# the walk's strengths (import-osim --specific-tension, --strength): the model's own F0 with the
# masses of measured volumes (60 N/cm^2), and the import's default (VM's 31.8 N/cm^2 on those
# masses: 0.53 x the model's F0), reported beside it (issue 30). Not `--specific-tension vm`: it
# keeps F0 by making every mass 60 / 31.8 = 1.89 x larger, and VM's metabolic rate scales with
# mass (the same drives and forces on the walk: 6.85 against 3.63 W/kg)
STRENGTHS = {"model F0": ("60", "model"), "default import": ("60", "vm")}
COSTS = ("drive2", "tsianos2012")   # the classic and VM's own energy (vm_ros.coordination.costs)
VARIANT_COST = "tsianos2012"        # the cost of the solve on low-passed targets


def import_walk(files, strength: tuple[str, str], out_dir):
    """The walk's model imported as `vm-ros import-osim --motion IK --specific-tension S
    --strength F` does for ``strength`` (S, F), into ``out_dir``: (geometry, library path)."""
    import io

    from vm_ros.importers.common import ImportChoices, specific_tension_option, strength_option
    from vm_ros.importers.osim import OsimOptions, import_osim

    tension, factor = strength
    done = import_osim(files["model"], out_dir, OsimOptions(motions=(str(files["motion"]),)),
                       ImportChoices(specific_tension_option(tension),
                                     strength=strength_option(factor)),
                       progress=False, file=io.StringIO())
    return done.geometry, Path(out_dir) / "muscles.yaml"



@dataclasses.dataclass(frozen=True)
class WalkProblem:
    """The walk imported at one strength: its geometry, motion (JointMotion), the ID's target
    moments as given, the muscles' specs and the coordination problem on those targets."""

    geometry: object
    motion: object
    targets: object
    specs: list
    problem: object


def walk_problem(files, strength: tuple[str, str], out_dir, params) -> WalkProblem:
    """The walk's coordination problem at ``strength`` (:func:`import_walk` into ``out_dir``),
    as the item solves it: every muscle of the geometry, the ID's hip, knee and ankle moments
    as given."""
    from vm_ros.coordination.problem import build_problem
    from vm_ros.coordination.targets import load_targets
    from vm_ros.importers.motion import read_motion
    from vm_ros.model.params import resolve_muscles
    from vm_ros.node.motion_inputs import JointMotion

    geometry, library = import_walk(files, strength, out_dir)
    motion = JointMotion.from_motion(read_motion(files["motion"]), geometry,
                                     geometry.coordinate_names, {})
    targets = load_targets(str(files["inverse_dynamics"]), geometry=geometry, motion=motion)
    muscles = geometry.muscle_names
    specs = resolve_muscles(muscles, library, None, params.generic.ur_default)
    return WalkProblem(geometry, motion, targets, specs,
                       build_problem(geometry, motion, targets, muscles))

TARGET_PERTURBATION = 1e-9  # relative change of target moments that shows what their last digits do


def perturbed_moments(moments, seed: int, relative: float = TARGET_PERTURBATION) -> np.ndarray:
    """``moments`` each times 1 + ``relative`` N(0, 1), drawn from NumPy's default_rng(``seed``):
    the same targets to their last digits, for measuring how far such a change carries through
    a coordination (docs/coordination.md, "Repeatable on one machine")."""
    moments = np.asarray(moments, dtype=float)
    return moments * (1.0 + relative * np.random.default_rng(seed).standard_normal(moments.shape))


def cocontraction_share(moment_arm, forces) -> np.ndarray:
    """(C,): per coordinate, sum over frames of the moment muscles spend against each other,
    (sum_i |r_i F_i| - |sum_i r_i F_i|) / 2, over the sum of sum_i |r_i F_i| (0: no muscle
    works against another; 0.5: all moment cancels). ``moment_arm`` (T, n, C), ``forces``
    (T, n)."""
    each = moment_arm * forces[:, :, None]
    gross = np.abs(each).sum(axis=1)
    opposing = (gross - np.abs(each.sum(axis=1))) / 2.0
    return opposing.sum(axis=0) / np.maximum(gross.sum(axis=0), 1e-12)


def solution_from_result(label: str, result, motion, specs, params) -> WalkSolution:
    """A WalkSolution from a vm_ros.coordination solve: drives, forces and moments at the
    target frames; the forward run replayed with every published energetics model
    (MuscleBank energetics_models='all') for VM's rate, its parts and the models' rates,
    summed over the muscles and interpolated from the model steps to the frames."""
    from vm_ros.coordination.costs import MODEL_TOTAL
    from vm_ros.coordination.forward import replay as forward_replay
    from vm_ros.model.bank import MuscleBank

    problem = result.problem
    frames = problem.frame_times_s
    drives = np.column_stack([np.interp(frames, result.node_times_s, result.drives[:, i])
                              for i in range(result.drives.shape[1])])
    drive_steps = result.forward.drive_steps
    bank = MuscleBank(specs, params, "lumped", energetics_models="all")
    replay = forward_replay(bank, problem, result.forward)   # through the lead-in
    steps = np.arange(drive_steps.shape[0]) * problem.dt_s

    def at_frames(per_step):
        return np.interp(frames, steps, per_step)

    parts = replay.record.energy_rates.sum(axis=1)   # (k, 4): activation, cross-bridge, ...
    models = {name: at_frames(replay.energy_rate_models[:, :, m, MODEL_TOTAL].sum(axis=1))
              for m, name in enumerate(bank.energetics_models)}
    return WalkSolution(label, frames + motion.start_s, tuple(problem.muscles), drives,
                        result.forward.force_frames, tuple(problem.coordinates), result.moments,
                        problem.target, at_frames(parts[:, 3]),
                        np.column_stack([at_frames(parts[:, j]) for j in range(3)]), models,
                        cocontraction_share(problem.moment_arm, result.forward.force_frames))


def solve_walk(files, config, params) -> tuple[list[WalkSolution], WalkSolution]:
    """One solution per strength (STRENGTHS) and cost (COSTS) of the walk's hip, knee and ankle
    ID moments, and the variant on low-passed targets with a lead-in (config
    ``lowpassed_targets``: the first strength, VARIANT_COST); CheckSkippedError when
    vm_ros.coordination has no solver in this build."""
    import tempfile

    try:
        from vm_ros.coordination.problem import build_problem
        from vm_ros.coordination.solver import SolverOptions, solve
    except ImportError as exc:
        raise CheckSkippedError("vm_ros.coordination has no solver in this build: the walk "
                                f"item needs one ({exc})") from exc
    from vm_ros.coordination.targets import lowpass_targets
    from vm_ros.model.bank import MuscleBank
    from vm_ros.model.params import load_model_params

    params = params or load_model_params()
    solutions, variant = [], None
    for strength_label, strength in STRENGTHS.items():
        with tempfile.TemporaryDirectory(prefix="vm_ros_walk_") as out:
            w = walk_problem(files, strength, out, params)
            for cost in COSTS:
                result = solve(MuscleBank(w.specs, params, "lumped"), w.problem,
                               SolverOptions(cost=cost))
                solutions.append(solution_from_result(f"{cost}, {strength_label}", result,
                                                      w.motion, w.specs, params))
            if variant is None:
                cutoff = config["lowpassed_targets"]["cutoff_hz"]["value"]
                smooth = lowpass_targets(w.targets, cutoff)
                lead_in = config["lowpassed_targets"]["lead_in_s"]["value"]
                result = solve(MuscleBank(w.specs, params, "lumped"),
                               build_problem(w.geometry, w.motion, smooth,
                                             w.geometry.muscle_names),
                               SolverOptions(cost=VARIANT_COST, lead_in_s=lead_in))
                variant = solution_from_result(f"ID at {cutoff:g} Hz, lead-in {lead_in:g} s",
                                               result, w.motion, w.specs, params)
    return solutions, variant


def check_walk(params=None) -> CheckResult:
    """The ``walk`` item (module docstring); CheckSkippedError when it cannot run here."""
    from vm_ros.errors import VmRosError
    from vm_ros.importers.osim import load_opensim
    from vm_ros.validation.walk_data import WalkDataError, walk_files

    start = time.monotonic()
    config, _ = load_walk_config()
    try:
        files = walk_files()
    except WalkDataError as exc:
        raise CheckSkippedError(str(exc)) from exc
    try:
        load_opensim()
    except VmRosError as exc:
        raise CheckSkippedError(f"OpenSim is needed for the walk's references ({exc})") from exc
    solutions, variant = solve_walk(files, config, params)
    context = _walk_context(files, config)
    result = CheckResult("walk", "Coordination from motion: the Gait10dof18musc walk",
                         "muscles alone reproduce the walk's inverse-dynamics moments from a "
                         "forward run of the full model, with drives timed like walking EMG, "
                         "forces like OpenSim's, and a metabolic rate comparable with "
                         "calorimetry (issue 30)")
    result.criteria.extend(context_reported(context))
    for solution in solutions:
        criteria, data = evaluate_walk(solution, context, config)
        result.criteria.extend(criteria)
        result.data[solution.label] = {"solution": solution, **data}
    result.criteria.extend(variant_reported(variant, solutions[COSTS.index(VARIANT_COST)],
                                            config))
    result.data["variant"] = variant
    result.data["context"] = context
    result.seconds = time.monotonic() - start
    return result


__all__ = ["TARGET_PERTURBATION", "TRACKED", "WalkSolution", "check_walk",
           "cocontraction_share", "evaluate_walk", "perturbed_moments",
           "target_content_above", "variant_reported",
           "high_frequency_share", "load_walk_config", "net_metabolic_references",
           "spike_frames", "tracking_errors", "window_means"]
