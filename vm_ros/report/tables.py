"""Tables (column names and rows) of a run log, for CSV files and plots, and its summary.

Times are seconds from the first output stamp (model time). Column names carry units. Joint
topics are in the robot's convention (the run's joint map); each joint's unit (rad or m) comes
from the attached geometry (rad when the log has none).
"""

from __future__ import annotations

import numpy as np

from vm_ros import telemetry as tm
from vm_ros.errors import VmRosError
from vm_ros.geometry.file import loads as load_geometry_text
from vm_ros.joint_space import JointMap
from vm_ros.recording.messages import TOPIC_TELEMETRY
from vm_ros.recording.run_log import (
    ATTACHMENT_GEOMETRY,
    RunLog,
    TopicSeries,
    logged_node_parameters,
    read_run,
)
from vm_ros.report.summary import (
    JOINT_WORK_SAMPLED,
    JOINT_WORK_STEPS,
    JointSummary,
    ModelTotals,
    MuscleSummary,
    joint_work_increments,
    split_energy,
    summarize,
    summarize_joints,
)

# MuscleTelemetry fields per muscle and per fibre type, with their units (msg_defs/)
TELEMETRY_PER_MUSCLE = {
    "excitation": "1", "effective_drive": "1", "path_length": "m", "path_velocity": "m_per_s",
    "force": "N", "contractile_force": "N", "fascicle_length": "m",
    "fascicle_velocity": "m_per_s", "mechanical_power": "W", "mechanical_work": "J",
}
TELEMETRY_PER_FIBRE = {"firing_rate": "f05", "recruited_fraction": "1",
                       "effective_activation": "1"}
FIBRE_TYPES = tm.FIBRE_LABELS[:2]


class Table:
    """A named table: ``columns`` (names with units) and ``data`` (rows x columns array)."""

    def __init__(self, name: str, columns: list[str], data: np.ndarray):
        self.name, self.columns, self.data = name, columns, data

    def column(self, name: str) -> np.ndarray:
        return self.data[:, self.columns.index(name)]


def muscle_names(run: RunLog) -> tuple:
    if run.info is not None:
        return tuple(run.info.config.muscles)
    force = run.get(tm.TOPIC_FORCE)
    return tuple(force.names or ()) if force is not None else ()


def time_origin_ns(run: RunLog) -> int:
    """Model time of the first output (or of the first message): time zero of the tables."""
    force = run.get(tm.TOPIC_FORCE)
    if force is not None and len(force):
        return int(force.fields["stamp_ns"][0])
    firsts = [int(s.time_ns[0]) for s in run.series.values() if len(s)]
    return min(firsts) if firsts else 0


def _times(run: RunLog, series: TopicSeries) -> np.ndarray:
    stamps = series.fields.get("stamp_ns")
    times = stamps if stamps is not None else series.time_ns
    return (np.asarray(times, dtype=np.int64) - time_origin_ns(run)) * 1e-9


def force_table(run: RunLog) -> Table | None:
    series = run.get(tm.TOPIC_FORCE)
    if series is None or not len(series):
        return None
    columns, blocks = ["time_s"], [_times(run, series)[:, None]]
    for key, label in (("effort", "force_N"), ("position", "fascicle_length_m"),
                       ("velocity", "fascicle_velocity_m_per_s")):
        columns += [f"{m}.{label}" for m in muscle_names(run)]
        blocks.append(series.fields[key])
    return Table("forces", columns, np.hstack(blocks))


def energy_rate_table(run: RunLog) -> Table | None:
    series = run.get(tm.TOPIC_ENERGY_RATE)
    if series is None or not len(series):
        return None
    columns = ["time_s"] + [f"{m}.{f}.{c}_W" for m in muscle_names(run) for f in tm.FIBRE_LABELS
                            for c in tm.COMPONENT_LABELS]
    data = series.fields["data"]
    if data.shape[1] != len(columns) - 1:
        return None
    return Table("energy_rate", columns, np.hstack([_times(run, series)[:, None], data]))


def totals_table(run: RunLog) -> Table | None:
    rate, total = run.get(tm.TOPIC_ENERGY_RATE_TOTAL), run.get(tm.TOPIC_ENERGY_TOTAL)
    if rate is None or total is None or not len(rate):
        return None
    common, i, j = np.intersect1d(rate.time_ns, total.time_ns, return_indices=True)
    times = (common - common[0]) * 1e-9 if len(common) else common * 1.0
    return Table("totals", ["time_s", "energy_rate_total_W", "energy_total_J"],
                 np.column_stack([times, rate.fields["data"][i], total.fields["data"][j]]))


def energy_models_axes(run: RunLog) -> tuple[tuple, tuple, tuple] | None:
    """(muscles, models, components) of the log's energy_rate_models channel, from its layout
    labels (vm_ros.telemetry), or None when the log has no such channel or its layout does not
    fit its data."""
    series = run.get(tm.TOPIC_ENERGY_RATE_MODELS)
    if series is None or not len(series) or not series.layout or len(series.layout) != 3:
        return None
    axes = [tm.split_dim_label(dim["label"])[1] for dim in series.layout]
    sizes = [int(dim["size"]) for dim in series.layout]
    if [len(a) for a in axes] != sizes or series.fields["data"].shape[1] != np.prod(sizes):
        return None
    return tuple(axes)


def energy_rate_models_table(run: RunLog) -> Table | None:
    """time_s and <muscle>.<model>.<component>_W of energy_rate_models (None without it)."""
    axes = energy_models_axes(run)
    if axes is None:
        return None
    series = run.get(tm.TOPIC_ENERGY_RATE_MODELS)
    muscles, models, components = axes
    columns = ["time_s"] + [f"{m}.{model}.{c}_W" for m in muscles for model in models
                            for c in components]
    return Table("energy_rate_models", columns,
                 np.hstack([_times(run, series)[:, None], series.fields["data"]]))


def trapezoid(time_s: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Trapezoidal integral of ``values`` (k, ...) over ``time_s`` (k,); 0 for k < 2."""
    if len(time_s) < 2:
        return np.zeros(np.shape(values)[1:])
    return (0.5 * (values[1:] + values[:-1]) * np.diff(time_s).reshape(
        (-1,) + (1,) * (np.ndim(values) - 1))).sum(axis=0)


TSIANOS = "tsianos2012"  # vm_ros's own energetics in tables beside the published models


def logged_model_totals(path) -> list[ModelTotals]:
    """:func:`model_totals` of a finished log, reading only the channels it needs ([] without
    energy_rate_models)."""
    return model_totals(read_run(path, topics=[tm.TOPIC_ENERGY_RATE, tm.TOPIC_ENERGY_TOTAL,
                                               TOPIC_TELEMETRY, tm.TOPIC_ENERGY_RATE_MODELS]))


def model_totals(run: RunLog) -> list[ModelTotals]:
    """Tsianos 2012 (first row, the reference): run_energy's total per muscle, the number the
    summary table prints; then per published model of energy_rate_models its total rate
    integrated per muscle over the published samples (trapezoid; the log has no running sum of
    theirs) ([] without the channel)."""
    axes = energy_models_axes(run)
    if axes is None:
        return []
    muscles, models, components = axes
    energy_all = run_energy(run)[:, -1, -1]
    own = dict(zip(muscle_names(run), energy_all, strict=True))
    tsianos = np.array([own.get(m, np.nan) for m in muscles])
    table = energy_rate_models_table(run)
    t = table.column("time_s")
    data = table.data[:, 1:].reshape(len(t), len(muscles), len(models), len(components))
    energy = trapezoid(t, data[..., components.index("total")])  # (n, M)
    return [ModelTotals(TSIANOS, tsianos, tsianos)] + [
        ModelTotals(model, energy[:, j], tsianos) for j, model in enumerate(models)]


def telemetry_table(run: RunLog) -> Table | None:
    series = run.get(TOPIC_TELEMETRY)
    if series is None or not len(series):
        return None
    names = series.names or muscle_names(run)
    columns, blocks = ["time_s"], [_times(run, series)[:, None]]
    for key, unit in TELEMETRY_PER_MUSCLE.items():
        columns += [f"{m}.{key}_{unit}" for m in names]
        blocks.append(series.fields[key])
    for key, unit in TELEMETRY_PER_FIBRE.items():
        columns += [f"{m}.{f}.{key}_{unit}" for m in names for f in FIBRE_TYPES]
        blocks.append(series.fields[key])
    for key, unit in (("energy_rate", "W"), ("energy", "J")):
        columns += [f"{m}.{f}.{c}_{key}_{unit}" for m in names for f in tm.FIBRE_LABELS
                    for c in tm.COMPONENT_LABELS]
        blocks.append(series.fields[key])
    return Table("telemetry", columns, np.hstack(blocks))


def run_energy(run: RunLog) -> np.ndarray:
    """Energy per muscle over the run (J, n x 3 fibres x 4 components): the model's own sum over
    its steps, as the summary of the run that wrote the log printed it. From the last
    muscle_telemetry record (cumulative per muscle); without telemetry (muscle_node's logs) the
    last energy_total (cumulative, whole bank) split over muscles, fibres and components by
    energy_rate (split_energy; the energy before the first sample in the proportions of the first
    rate), NaN without those channels."""
    n = len(muscle_names(run))
    telemetry = run.get(TOPIC_TELEMETRY)
    if telemetry is not None and len(telemetry):
        return telemetry.fields["energy"][-1].reshape(n, 3, 4)
    rate, total = run.get(tm.TOPIC_ENERGY_RATE), run.get(tm.TOPIC_ENERGY_TOTAL)
    if rate is None or total is None or not len(rate) or rate.fields["data"].shape[1] != n * 12:
        return np.full((n, 3, 4), np.nan)
    common, i, j = np.intersect1d(rate.time_ns, total.time_ns, return_indices=True)
    if not len(common):
        return np.full((n, 3, 4), np.nan)
    rates = rate.fields["data"][i].reshape(len(common), n, 3, 4)
    return split_energy(np.concatenate([rates[:1], rates]),
                        np.concatenate([[0.0], total.fields["data"][j]]))


def run_summary(run: RunLog) -> list[MuscleSummary]:
    """Per-muscle summary: force over the published samples, energy from run_energy, work from
    the last telemetry record (unknown, NaN, without telemetry)."""
    names = muscle_names(run)
    n = len(names)
    force = run.get(tm.TOPIC_FORCE)
    forces = force.fields["effort"] if force is not None and len(force) else np.zeros((0, n))
    telemetry = run.get(TOPIC_TELEMETRY)
    work = (telemetry.fields["mechanical_work"][-1] if telemetry is not None and len(telemetry)
            else np.full(n, np.nan))
    return summarize(names, forces, run_energy(run), work)


def bin_means(time_s: np.ndarray, values: np.ndarray, bin_s: float):
    """Means of ``values`` (k, ...) over consecutive ``bin_s`` windows: (bin centres, means)."""
    if bin_s <= 0 or len(time_s) == 0:
        return time_s, values
    index = np.floor((time_s - time_s[0]) / bin_s).astype(int)
    bins = np.unique(index)
    means = np.array([values[index == b].mean(axis=0) for b in bins])
    return time_s[0] + (bins + 0.5) * bin_s, means


# --- joint space ---------------------------------------------------------------------------

JOINT_UNITS = {"rad": ("rad", "rad_per_s", "N_m"), "m": ("m", "m_per_s", "N")}


def joint_geometry(run: RunLog):
    """(geometry, JointMap) of a joint-space log from its attached geometry and its joint map
    (the node parameters' for a node-conditioned log, else the run's), or None when the log has
    no usable geometry."""
    data = run.attachments.get(ATTACHMENT_GEOMETRY)
    if data is None:
        return None
    try:
        geometry = load_geometry_text(data.decode("utf-8", errors="replace"),
                                      f"{run.path}: {ATTACHMENT_GEOMETRY}", backend="numpy")
        node = logged_node_parameters(run)
        text = str(node.get("joint_map", "")) if node is not None else (
            run.info.config.joint_map if run.info is not None else "")
        return geometry, JointMap.build(text, geometry, str(run.path))
    except VmRosError:
        return None


def joint_units(run: RunLog, names) -> list[str]:
    """Per robot joint of ``names``: "rad" or "m" (rad when not known)."""
    found = joint_geometry(run)
    if found is None:
        return ["rad"] * len(names)
    geometry, joint_map = found
    units = {robot: c.unit for robot, c in zip(joint_map.robot_names, geometry.coordinates,
                                               strict=True)}
    return [units.get(name, "rad") for name in names]


def joint_efforts_table(run: RunLog) -> Table | None:
    """time_s, then per joint <joint>.position_<rad|m>, .velocity_<rad|m>_per_s and
    .effort_<N_m|N> of joint_efforts (robot convention, after clamping)."""
    series = run.get(tm.TOPIC_JOINT_EFFORTS)
    if series is None or not len(series) or not series.names:
        return None
    names = series.names
    units = joint_units(run, names)
    columns, blocks = ["time_s"], [_times(run, series)[:, None]]
    for k, key in enumerate(("position", "velocity", "effort")):
        columns += [f"{j}.{key}_{JOINT_UNITS[u][k]}" for j, u in zip(names, units, strict=True)]
        blocks.append(series.fields[key])
    return Table("joint_efforts", columns, np.hstack(blocks))


def joint_states_table(run: RunLog) -> Table | None:
    """time_s and <joint>.position_<rad|m> of the joint_states received (robot convention,
    before clamping): the motion's joint angles."""
    series = run.get(tm.TOPIC_JOINT_STATES)
    if series is None or not len(series) or not series.names:
        return None
    names = series.names
    units = joint_units(run, names)
    columns = ["time_s"] + [f"{j}.position_{JOINT_UNITS[u][0]}" for j, u in zip(
        names, units, strict=True)]
    return Table("joint_states", columns, np.hstack([_times(run, series)[:, None],
                                                     series.fields["position"]]))


def run_joint_work(run: RunLog) -> tuple[np.ndarray, str]:
    """Per joint of joint_efforts (J) and how it was obtained (JOINT_WORK_STEPS or
    JOINT_WORK_SAMPLED): the joint_work channel's last value, the model's own sum over its steps
    (offline runs log it), else the sum of joint_work_increments over the published samples
    (muscle_node's logs). Empty for a log without joint_efforts."""
    series = run.get(tm.TOPIC_JOINT_EFFORTS)
    if series is None or not len(series) or not series.names:
        return np.zeros(0), JOINT_WORK_STEPS
    logged = run.get(tm.TOPIC_JOINT_WORK)
    if logged is not None and len(logged) and logged.fields["data"].shape[1] == len(series.names):
        return np.asarray(logged.fields["data"][-1], dtype=float), JOINT_WORK_STEPS
    increments = joint_work_increments(_times(run, series), series.fields["effort"],
                                       series.fields["velocity"])
    return increments.sum(axis=0), JOINT_WORK_SAMPLED


def run_joint_summary(run: RunLog) -> list[JointSummary]:
    """Per joint of joint_efforts: peak and mean generalized force, joint work (run_joint_work)
    and the joint_states samples outside the geometry's box. Empty for a log without
    joint_efforts."""
    series = run.get(tm.TOPIC_JOINT_EFFORTS)
    if series is None or not len(series) or not series.names:
        return []
    names = series.names
    return summarize_joints(names, joint_units(run, names), series.fields["effort"],
                            run_joint_work(run)[0], _clamped_samples(run, names))


def _clamped_samples(run: RunLog, names) -> np.ndarray | None:
    """Per robot joint of ``names``: joint_states samples whose position, in model
    coordinates, is outside the geometry's box (None without a geometry or joint_states)."""
    found = joint_geometry(run)
    states = run.get(tm.TOPIC_JOINT_STATES)
    if found is None or states is None or not states.names:
        return None
    geometry, joint_map = found
    counts = np.zeros(len(names), dtype=int)
    for i, name in enumerate(names):
        j = joint_map.index_of(name)
        if j is None or name not in states.names:
            continue
        robot_q = states.fields["position"][:, states.names.index(name)]
        q = joint_map.sign[j] * robot_q + joint_map.offset[j]
        coordinate = geometry.coordinates[j]
        counts[i] = int(np.sum((q < coordinate.lower) | (q > coordinate.upper)))
    return counts
