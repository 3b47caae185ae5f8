"""Per-muscle summary of a run: force, partitioned energy, mechanical work and efficiency; per
joint (joint-space runs): peak and mean generalized force, joint work and clamping.

    rows = summarize(names, force_samples, energy, work)
    print(summary_table(rows))

energy: (n, 3, 4) J, fibre (slow, fast, all) x component (activation, cross_bridge, recovery,
total), the layout of the energy_rate topic. Efficiency is the net mechanical efficiency,
mechanical work over total energy (work done on the load while shortening counts positive). It
is defined only when the net work is positive (and the energy too): when the muscle did no net
work (isometric) or the load did more work on it while it lengthened than it did on the load, the
ratio would mean nothing, so the efficiency is NaN, printed "n/a" with the reason below the
table, and left empty in CSV records.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vm_ros.telemetry import COMPONENT_LABELS, FIBRE_LABELS


@dataclass(frozen=True)
class MuscleSummary:
    """| field | unit |
    | name | |
    | peak_force, mean_force | N (over the published samples) |
    | energy | J, (3 fibre labels, 4 components) |
    | mechanical_work | J (NaN when the log has no telemetry) |
    | efficiency | 1, mechanical work / total energy (NaN unless both are positive) |
    """

    name: str
    peak_force: float
    mean_force: float
    energy: np.ndarray
    mechanical_work: float

    @property
    def efficiency(self) -> float:
        return net_efficiency(self.mechanical_work, float(self.energy[-1, -1]))


def net_efficiency(work_j: float, energy_j: float) -> float:
    """Mechanical work over total energy (1); NaN unless both are positive (module docstring)."""
    return work_j / energy_j if work_j > 0 and energy_j > 0 else float("nan")


def split_energy(rates, totals) -> np.ndarray:
    """Energy (J, n x 3 fibres x 4 components) from sample 0 to the last: each interval's
    energy is the change of ``totals`` (J, the model's energy_total: its own sum over its steps,
    exact), split in the proportions of the mean of ``rates`` (W, k x n x 3 x 4, energy_rate) at
    its two ends over muscles, the slow and fast fibres and the activation, cross-bridge and
    recovery components. The result adds up to totals[-1] - totals[0]; only the split between
    samples is interpolated."""
    rates = np.asarray(rates, dtype=float)
    parts = rates[:, :, :2, :3]  # (k, n, slow/fast, activation/cross_bridge/recovery)
    mean = 0.5 * (parts[1:] + parts[:-1])
    weight = mean.sum(axis=(1, 2, 3))
    energy_j = np.diff(np.asarray(totals, dtype=float))
    share = np.divide(mean, weight[:, None, None, None],
                      out=np.zeros_like(mean), where=weight[:, None, None, None] != 0)
    cells = np.tensordot(energy_j, share, axes=1)  # (n, 2, 3)
    cells = np.concatenate([cells, cells.sum(axis=1, keepdims=True)], axis=1)  # all fibres
    return np.concatenate([cells, cells.sum(axis=2, keepdims=True)], axis=2)  # total


def run_totals(rows: list[MuscleSummary]) -> tuple[np.ndarray, float, float]:
    """All muscles: (energy per component (4,) J, mechanical work J, net efficiency 1)."""
    energy = sum(row.energy[-1] for row in rows) if rows else np.zeros(4)
    work = float(sum(row.mechanical_work for row in rows))
    return np.asarray(energy, dtype=float), work, net_efficiency(work, float(energy[-1]))


def _efficiency_cell(efficiency: float, width: int) -> str:
    """Percent, or "n/a" when undefined."""
    return f"{100 * efficiency:>{width}.1f}" if np.isfinite(efficiency) else f"{'n/a':>{width}}"


def _work_cell(work_j: float, width: int) -> str:
    """Joules, or "n/a" when the log does not hold it (NaN)."""
    return f"{work_j:>{width}.2f}" if np.isfinite(work_j) else f"{'n/a':>{width}}"


WORK_NOT_LOGGED = ("W mech n/a: the log has no muscle_telemetry, which holds the fibres' "
                   "mechanical work (muscle_node's logs, offline ones with --telemetry-rate 0); "
                   "vm-ros recompute LOG --telemetry-rate 100 --out NEW writes it")


def summarize(names, force_samples, energy, mechanical_work) -> list[MuscleSummary]:
    """force_samples (k, n) N; energy (n, 3, 4) J; mechanical_work (n,) J."""
    force = np.asarray(force_samples, dtype=float).reshape(-1, len(names))
    energy = np.asarray(energy, dtype=float)
    work = np.asarray(mechanical_work, dtype=float)
    rows = []
    for i, name in enumerate(names):
        column = force[:, i]
        peak = float(np.nanmax(column)) if column.size else float("nan")
        mean = float(np.nanmean(column)) if column.size else float("nan")
        rows.append(MuscleSummary(name, peak, mean, energy[i], float(work[i])))
    return rows


def summary_records(rows: list[MuscleSummary]) -> list[dict]:
    """One flat dict per muscle and fibre label (for CSV); force, work and efficiency appear on
    the ``all`` rows."""
    records = []
    for row in rows:
        for j, fibre in enumerate(FIBRE_LABELS):
            record = {"muscle": row.name, "fibre": fibre}
            whole = fibre == "all"
            record["peak_force_N"] = row.peak_force if whole else ""
            record["mean_force_N"] = row.mean_force if whole else ""
            for k, component in enumerate(COMPONENT_LABELS):
                record[f"{component}_energy_J"] = float(row.energy[j, k])
            record["mechanical_work_J"] = row.mechanical_work if whole else ""
            efficiency = row.efficiency
            record["efficiency"] = efficiency if whole and np.isfinite(efficiency) else ""
            records.append(record)
    return records


def name_width(names, minimum: int = 22) -> int:
    """Width of a table's name column: ``minimum``, or the longest name and two spaces."""
    return max([minimum, *(len(name) + 2 for name in names)])


def summary_table(rows: list[MuscleSummary]) -> str:
    """A fixed-width text table: one line per muscle and fibre type, then the totals; the name
    column as wide as the longest name (never cut)."""
    w = name_width(row.name for row in rows)
    header = (f"{'muscle':<{w}}{'fibre':<6}{'peak F':>10}{'mean F':>10}{'E act':>11}{'E xb':>11}"
              f"{'E rec':>11}{'E total':>11}{'W mech':>10}{'eff':>7}")
    units = (f"{'':<{w}}{'':<6}{'(N)':>10}{'(N)':>10}{'(J)':>11}{'(J)':>11}{'(J)':>11}"
             f"{'(J)':>11}{'(J)':>10}{'(%)':>7}")
    lines = [header, units, "-" * len(header)]
    for row in rows:
        for j, fibre in enumerate(FIBRE_LABELS):
            whole = fibre == "all"
            name = row.name if j == 0 else ""
            force = f"{row.peak_force:>10.1f}{row.mean_force:>10.1f}" if whole else " " * 20
            energies = "".join(f"{row.energy[j, k]:>11.2f}" for k in range(4))
            tail = (f"{_work_cell(row.mechanical_work, 10)}{_efficiency_cell(row.efficiency, 7)}"
                    if whole else "")
            lines.append(f"{name:<{w}}{fibre:<6}{force}{energies}{tail}")
    total = sum(row.energy for row in rows)
    work = sum(row.mechanical_work for row in rows)
    if len(rows) > 1:
        lines.append("-" * len(header))
        energies = "".join(f"{total[-1, k]:>11.2f}" for k in range(4))
        efficiency = net_efficiency(work, float(total[-1, -1]))
        lines.append(f"{'all muscles':<{w}}{'all':<6}{'':>20}{energies}{_work_cell(work, 10)}"
                     f"{_efficiency_cell(efficiency, 7)}")
    if not np.isfinite(work):
        lines.append(WORK_NOT_LOGGED)
    elif any(row.mechanical_work <= 0 for row in rows) or (len(rows) > 1 and work <= 0):
        lines.append("eff n/a: net mechanical work not positive (isometric, or the muscle was "
                     "stretched by the load more than it shortened), so work / energy is no "
                     "efficiency")
    return "\n".join(lines)


# --- published energetics models (energy_rate_models) ----------------------------------------


@dataclass(frozen=True)
class ModelTotals:
    """One published energetics model over a run (energy_rate_models), beside Tsianos 2012.

    | field | unit |
    | model | name (vm_ros.model.energetics_models.MODEL_NAMES; "tsianos2012" for vm_ros's own) |
    | energy | J, (n muscles,) the model's total rate integrated over the published samples |
    | tsianos | J, (n,) Tsianos 2012's total energy: the model's sum over its steps (the summary
      table's E total) |
    """

    model: str
    energy: np.ndarray
    tsianos: np.ndarray

    @property
    def total(self) -> float:
        return float(np.sum(self.energy))

    @property
    def relative(self) -> float:
        """All muscles' energy over Tsianos 2012's (1); NaN when Tsianos' is not positive."""
        tsianos = float(np.sum(self.tsianos))
        return self.total / tsianos if tsianos > 0 else float("nan")


def model_totals_records(rows: list[ModelTotals], names) -> list[dict]:
    """One flat dict per model (for CSV): all muscles, then each muscle, J and relative to
    Tsianos 2012."""
    records = []
    for row in rows:
        record = {"model": row.model, "energy_J": row.total, "relative_to_tsianos":
                  row.relative if np.isfinite(row.relative) else ""}
        for i, name in enumerate(names):
            ratio = row.energy[i] / row.tsianos[i] if row.tsianos[i] > 0 else float("nan")
            record[f"{name}.energy_J"] = float(row.energy[i])
            record[f"{name}.relative_to_tsianos"] = ratio if np.isfinite(ratio) else ""
        records.append(record)
    return records


def model_totals_table(rows: list[ModelTotals], names) -> str:
    """Fixed-width text: per model its energy over the run (J) for all muscles and each, and
    all muscles' relative to Tsianos 2012."""
    shown = list(names)[:4]  # wider tables wrap; the CSV has every muscle
    c = name_width(shown, 13)  # muscle columns: whole names
    header = (f"{'energetics model':<20}{'E all':>11}{'vs Tsianos':>11}"
              + "".join(f"{name:>{c}}" for name in shown))
    units = f"{'':<20}{'(J)':>11}{'(x)':>11}" + "".join(f"{'(J)':>{c}}" for _ in shown)
    lines = [header, units, "-" * len(header)]
    for row in rows:
        ratio = f"{row.relative:>11.3f}" if np.isfinite(row.relative) else f"{'n/a':>11}"
        lines.append(f"{row.model:<20}{row.total:>11.2f}{ratio}"
                     + "".join(f"{row.energy[i]:>{c}.2f}" for i in range(len(shown))))
    if len(names) > len(shown):
        lines.append(f"(first {len(shown)} of {len(names)} muscles shown; `vm-ros report` of "
                     "the log writes model_totals.csv with every muscle)")
    lines.append("energies: Tsianos 2012 the model's sum over its steps (E total above); the "
                 "published models the trapezoidal integral of their total rates over the "
                 "published samples")
    return "\n".join(lines)


# --- joint space ---------------------------------------------------------------------------

EFFORT_UNITS = {"rad": "N m", "m": "N"}  # generalized force per coordinate unit


@dataclass(frozen=True)
class JointSummary:
    """| field | unit |
    | name | robot joint |
    | unit | the coordinate's: "rad" (effort N m) or "m" (effort N) |
    | peak_effort | N m or N, the sample of largest magnitude (signed) |
    | mean_effort | N m or N (over the published samples) |
    | work | J, joint work sum(tau qdot dt) (positive: the muscles drive the joint) |
    | clamped | joint_states samples in which the coordinate was outside the geometry's box
      (None when not known) |
    """

    name: str
    unit: str
    peak_effort: float
    mean_effort: float
    work: float
    clamped: int | None = None


def summarize_joints(names, units, effort_samples, work, clamped=None) -> list[JointSummary]:
    """effort_samples (k, n_joints) N m or N; work (n_joints,) J; clamped (n_joints,) or None."""
    effort = np.asarray(effort_samples, dtype=float).reshape(-1, len(names))
    rows = []
    for i, name in enumerate(names):
        column = effort[:, i]
        finite = column[np.isfinite(column)]
        peak = float(finite[np.argmax(np.abs(finite))]) if finite.size else float("nan")
        mean = float(finite.mean()) if finite.size else float("nan")
        rows.append(JointSummary(name, units[i], peak, mean, float(work[i]),
                                 None if clamped is None else int(clamped[i])))
    return rows


JOINT_WORK_STEPS = "W joint: sum over the model steps of tau qdot dt"
JOINT_WORK_SAMPLED = ("W joint: sum over the published joint_efforts samples of tau qdot times the "
                      "interval since the previous sample (the log has no joint_work channel; "
                      "the sum over the model steps when they were published at every step)")


def joint_work_increments(time_s, effort, velocity) -> np.ndarray:
    """(k - 1, n_joints) J: the work of each published joint_efforts sample after the first,
    tau qdot (robot convention, NaN as 0) times the interval since the previous sample. Each
    sample holds the step that ended at its time (its force, the velocity that step used), so at
    one sample per model step they are the steps' tau qdot dt."""
    power = np.nan_to_num(np.asarray(effort, dtype=float) * np.asarray(velocity, dtype=float))
    return power[1:] * np.diff(np.asarray(time_s, dtype=float))[:, None]


def joint_summary_records(rows: list[JointSummary]) -> list[dict]:
    """One flat dict per joint (for CSV)."""
    return [{"joint": row.name, "unit": row.unit,
             "effort_unit": EFFORT_UNITS.get(row.unit, ""),
             "peak_effort": row.peak_effort, "mean_effort": row.mean_effort,
             "work_J": row.work, "clamped_samples": "" if row.clamped is None else row.clamped}
            for row in rows]


def joint_summary_table(rows: list[JointSummary], work_note: str = JOINT_WORK_STEPS) -> str:
    """Fixed-width text: per joint peak and mean generalized force, joint work, clamping; then
    ``work_note``, how the joint work was obtained."""
    w = name_width(row.name for row in rows)
    header = (f"{'joint':<{w}}{'peak tau':>12}{'mean tau':>12}{'unit':>6}{'W joint':>11}"
              f"{'clamped':>11}")
    units = f"{'':<{w}}{'':>12}{'':>12}{'':>6}{'(J)':>11}{'(samples)':>11}"
    lines = [header, units, "-" * len(header)]
    for row in rows:
        clamped = "-" if row.clamped is None else str(row.clamped)
        lines.append(f"{row.name:<{w}}{row.peak_effort:>12.3f}{row.mean_effort:>12.3f}"
                     f"{EFFORT_UNITS.get(row.unit, '?'):>6}{row.work:>11.3f}{clamped:>11}")
    return "\n".join([*lines, work_note])
