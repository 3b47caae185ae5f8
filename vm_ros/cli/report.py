"""Tables (CSV) and plots (PNG) of a run log: forces, drive, fascicle kinematics, partitioned
energy per muscle and fibre type, whole-body totals and, for joint-space runs, joint torques.

Files written to --out (default: <log name>-report/ beside the log):
  summary.csv        per muscle and fibre type: peak and mean force (N), energy per component (J),
                     mechanical work (J), efficiency; also printed
  forces.csv         time_s, <muscle>.force_N, .fascicle_length_m, .fascicle_velocity_m_per_s
  energy_rate.csv    time_s, <muscle>.<slow|fast|all>.<component>_W
  totals.csv         time_s, energy_rate_total_W, energy_total_J
  telemetry.csv      every muscle_telemetry field (when the log has them)
  joint_efforts.csv  time_s, <joint>.position_rad, .velocity_rad_per_s, .effort_N_m (_m, _m_per_s,
                     _N for translational coordinates): joint_efforts, robot convention (joint-space
                     runs)
  joint_states.csv   time_s, <joint>.position_rad: the joint angles received (before clamping)
  joint_summary.csv  per joint: peak and mean generalized force, joint work (J, trapezoidal
                     integral of tau qdot over the published samples), joint_states samples
                     outside the geometry's box; also printed
  force.png, drive.png, kinematics.png, energy_<muscle>.png, energy_partition.png, totals.png,
  joint_torque.png (one panel per joint: generalized force, and the joint angle on a twin axis)
Times are seconds of model time from the first output. Plots need matplotlib (the [plot]
extra); --no-plots writes the CSV files only.
"""

from __future__ import annotations

import argparse
import csv
from pathlib import Path

import numpy as np

from vm_ros import telemetry as tm
from vm_ros.errors import VmRosError
from vm_ros.progress import Progress
from vm_ros.recording.messages import TOPIC_TELEMETRY
from vm_ros.recording.run_log import METADATA_NAME, RunLog, read_run
from vm_ros.recording.summary import (
    EFFORT_UNITS,
    joint_summary_records,
    joint_summary_table,
    summary_records,
    summary_table,
)
from vm_ros.recording.tables import (
    FIBRE_TYPES,
    JOINT_UNITS,
    Table,
    bin_means,
    energy_rate_table,
    force_table,
    joint_efforts_table,
    joint_states_table,
    joint_units,
    muscle_names,
    run_joint_summary,
    run_summary,
    telemetry_table,
    time_origin_ns,
    totals_table,
)

HELP = "CSV tables and PNG plots of forces and partitioned energy from a run log"
COMPONENTS = tm.COMPONENT_LABELS[:3]  # the parts of the total


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("log", type=Path, metavar="FILE.mcap", help="run log")
    parser.add_argument("--out", type=Path, metavar="DIR",
                        help="output folder (default: <log name>-report/ beside the log)")
    parser.add_argument("--bin", type=float, default=0.0, metavar="S",
                        help="average energy rates over bins of S seconds in the plots "
                             "(e.g. 1 as in Tsianos 2012 Fig. 7; default: no binning)")
    parser.add_argument("--no-plots", action="store_true", help="CSV files only")
    parser.add_argument("--progress", action="store_true",
                        help="show progress on stderr even when it is not a terminal")


def _pyplot():
    try:
        import matplotlib
    except ImportError as exc:
        raise VmRosError("vm-ros report needs matplotlib for its plots: pip install matplotlib "
                         "(or vm_ros[plot]); --no-plots writes the CSV files only") from exc
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def write_csv(path: Path, columns: list, rows) -> None:
    with open(path, "w", newline="", encoding="utf-8") as handle:
        writer = csv.writer(handle)
        writer.writerow(columns)
        writer.writerows(rows)


def _save(plt, fig, path: Path, written: list) -> None:
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    written.append(path)


def _per_muscle_figure(plt, rows: int, ylabels: list, title: str):
    fig, axes = plt.subplots(rows, 1, figsize=(9, 2.6 * rows), sharex=True, squeeze=False)
    for ax, label in zip(axes[:, 0], ylabels, strict=True):
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    axes[-1, 0].set_xlabel("time (s)")
    fig.suptitle(title)
    return fig, axes[:, 0]


def plot_run(plt, run: RunLog, tables: dict, out: Path, bin_s: float) -> list:
    names = muscle_names(run)
    written: list = []
    force = tables.get("forces")
    if force is not None:
        t = force.column("time_s")
        fig, axes = _per_muscle_figure(plt, 1, ["tendon force (N)"], "force")
        for m in names:
            axes[0].plot(t, force.column(f"{m}.force_N"), label=m)
        axes[0].legend(fontsize=8)
        _save(plt, fig, out / "force.png", written)
        fig, axes = _per_muscle_figure(plt, 2, ["fascicle length (m)", "fascicle velocity (m/s)"],
                                       "fascicle kinematics (velocity < 0: shortening)")
        for m in names:
            axes[0].plot(t, force.column(f"{m}.fascicle_length_m"), label=m)
            axes[1].plot(t, force.column(f"{m}.fascicle_velocity_m_per_s"), label=m)
        axes[0].legend(fontsize=8)
        _save(plt, fig, out / "kinematics.png", written)
    telemetry = tables.get("telemetry")
    excitation = run.get(tm.TOPIC_EXCITATION)
    if telemetry is not None or (excitation is not None and len(excitation)):
        fig, axes = _per_muscle_figure(plt, 2, ["drive (1)", "effective activation (1)"],
                                       "drive U, filtered drive Ueff, and Acteff per fibre type")
        for m in names:
            if telemetry is not None:
                t = telemetry.column("time_s")
                axes[0].plot(t, telemetry.column(f"{m}.excitation_1"), label=f"{m} U")
                axes[0].plot(t, telemetry.column(f"{m}.effective_drive_1"), "--",
                             label=f"{m} Ueff")
                for f in FIBRE_TYPES:
                    axes[1].plot(t, telemetry.column(f"{m}.{f}.effective_activation_1"),
                                 label=f"{m} {f}")
            else:
                t = (excitation.time_ns - time_origin_ns(run)) * 1e-9
                axes[0].plot(t, excitation.fields["position"][:, names.index(m)], label=f"{m} U")
        for ax in axes:
            if ax.get_lines():
                ax.legend(fontsize=7)
        _save(plt, fig, out / "drive.png", written)
    rates = tables.get("energy_rate")
    if rates is not None:
        t_all = rates.column("time_s")
        for m in names:
            fig, axes = _per_muscle_figure(plt, 2, [f"{f} fibres (W)" for f in FIBRE_TYPES],
                                           f"{m}: energy rate by component")
            for ax, f in zip(axes, FIBRE_TYPES, strict=True):
                parts = np.column_stack([rates.column(f"{m}.{f}.{c}_W") for c in COMPONENTS])
                t, parts = bin_means(t_all, parts, bin_s)
                ax.stackplot(t, parts.T, labels=COMPONENTS, alpha=0.8)
                ax.legend(fontsize=7, loc="upper left")
            _save(plt, fig, out / f"energy_{m}.png", written)
    summary = run_summary(run)
    if summary:
        fig, ax = plt.subplots(figsize=(max(5, 1.6 * len(summary) * 2), 4))
        labels = [f"{row.name}\n{f}" for row in summary for f in FIBRE_TYPES]
        bottom = np.zeros(len(labels))
        for k, component in enumerate(COMPONENTS):
            values = np.array([row.energy[j, k] for row in summary for j in range(2)])
            ax.bar(labels, values, bottom=bottom, label=component)
            bottom += values
        ax.set_ylabel("energy (J)")
        ax.set_title("energy partition per muscle and fibre type")
        ax.legend(fontsize=8)
        _save(plt, fig, out / "energy_partition.png", written)
    totals = tables.get("totals")
    if totals is not None:
        fig, axes = _per_muscle_figure(plt, 2, ["energy rate (W)", "energy (J)"],
                                       "whole body")
        t, rate = bin_means(totals.column("time_s"), totals.column("energy_rate_total_W"), bin_s)
        axes[0].plot(t, rate)
        axes[1].plot(totals.column("time_s"), totals.column("energy_total_J"))
        _save(plt, fig, out / "totals.png", written)
    efforts = tables.get("joint_efforts")
    if efforts is not None:
        _plot_joints(plt, run, efforts, tables.get("joint_states"), out / "joint_torque.png",
                     written)
    return written


def _plot_joints(plt, run: RunLog, efforts: Table, states: Table | None, path: Path,
                 written: list) -> None:
    """One panel per joint: generalized force (N m or N), and on a twin axis the joint angle
    received (joint_states; deg for rotational joints) or, without them, the one used."""
    joints = [c.split(".effort_")[0] for c in efforts.columns if ".effort_" in c]
    units = joint_units(run, joints)
    labels = [f"{j} ({EFFORT_UNITS[u]})" for j, u in zip(joints, units, strict=True)]
    fig, axes = _per_muscle_figure(plt, len(joints), labels,
                                   "joint torques (robot convention) and joint angles")
    for ax, joint, unit in zip(axes, joints, units, strict=True):
        position, _, effort = (f"{joint}.{q}_{s}" for q, s in zip(
            ("position", "velocity", "effort"), JOINT_UNITS[unit], strict=True))
        ax.plot(efforts.column("time_s"), efforts.column(effort), color="C0", label="torque")
        source = states if states is not None and position in states.columns else efforts
        scale, angle_unit = (180.0 / np.pi, "deg") if unit == "rad" else (1.0, "m")
        twin = ax.twinx()
        twin.plot(source.column("time_s"), scale * source.column(position), color="C1",
                  alpha=0.8, label="angle")
        twin.set_ylabel(f"angle ({angle_unit})" if unit == "rad" else "position (m)",
                        color="C1")
    _save(plt, fig, path, written)


def run(args) -> int:
    log_path = args.log
    plt = None if args.no_plots else _pyplot()  # fail before the (long) read
    with Progress(f"read {log_path.name}", 1.0, enabled=True if args.progress else None) as p:
        log = read_run(log_path, topics=(tm.TOPIC_FORCE, tm.TOPIC_ENERGY_RATE,
                                         tm.TOPIC_ENERGY_RATE_TOTAL, tm.TOPIC_ENERGY_TOTAL,
                                         tm.TOPIC_EXCITATION, TOPIC_TELEMETRY,
                                         tm.TOPIC_JOINT_EFFORTS, tm.TOPIC_JOINT_STATES),
                       progress=lambda done, size: p.update(done / max(size, 1)))
    if not muscle_names(log):
        raise VmRosError(f"{log_path}: not a vm_ros run log (no '{METADATA_NAME}' metadata "
                         f"record and no decodable {tm.TOPIC_FORCE} messages)")
    out = args.out or log_path.with_name(f"{log_path.stem}-report")
    out.mkdir(parents=True, exist_ok=True)
    builders = (force_table, energy_rate_table, totals_table, telemetry_table,
                joint_efforts_table, joint_states_table)
    tables: dict[str, Table] = {}
    for build in builders:
        table = build(log)
        if table is not None:
            tables[table.name] = table
            write_csv(out / f"{table.name}.csv", table.columns, table.data.tolist())
    summary = run_summary(log)
    records = summary_records(summary)
    if records:
        write_csv(out / "summary.csv", list(records[0]), [r.values() for r in records])
    print(summary_table(summary))
    joint_summary = run_joint_summary(log)
    joint_rows = joint_summary_records(joint_summary)
    if joint_rows:
        write_csv(out / "joint_summary.csv", list(joint_rows[0]), [r.values() for r in joint_rows])
        print(joint_summary_table(joint_summary))
    if not log.complete:
        print(f"note: {log_path} is cut short ({log.stop_reason}); the report covers what it "
              "holds")
    if log.skipped:
        print(f"note: {log.skipped_note()}")
    written = plot_run(plt, log, tables, out, args.bin) if plt is not None else []
    files = len(tables) + bool(records) + bool(joint_rows) + len(written)
    print(f"report: {out} ({files} files)")
    return 0
