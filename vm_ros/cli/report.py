"""Tables (CSV) and plots (PNG) of a run log: forces, drive, fascicle kinematics, partitioned
energy per muscle and fibre type, whole-body totals and, for joint-space runs, joint torques.

Files written to --out (default: <log name>-report/ beside the log):
  summary.csv        per muscle and fibre type: peak and mean force (N), energy per component (J:
                     the model's sum over its steps, vm_ros.report.tables.run_energy),
                     mechanical work (J), efficiency; also printed
  forces.csv         time_s, <muscle>.force_N, .fascicle_length_m, .fascicle_velocity_m_per_s
  energy_rate.csv    time_s, <muscle>.<slow|fast|all>.<component>_W
  energy_rate_models.csv  time_s, <muscle>.<model>.<component>_W: the published energetics
                     models (logs with energy_rate_models: simulate/recompute --energetics-models)
  model_totals.csv   per model (Tsianos 2012 first): energy over the run (J, all muscles and
                     each) and relative to Tsianos 2012; also printed
  totals.csv         time_s, energy_rate_total_W, energy_total_J
  telemetry.csv      every muscle_telemetry field (when the log has them)
  joint_efforts.csv  time_s, <joint>.position_rad, .velocity_rad_per_s, .effort_N_m (_m, _m_per_s,
                     _N for translational coordinates): joint_efforts, robot convention (joint-space
                     runs)
  joint_states.csv   time_s, <joint>.position_rad: the joint angles received (before clamping)
  joint_summary.csv  per joint: peak and mean generalized force, joint work (J, the model's sum
                     of tau qdot dt over its steps, logged on joint_work by simulate and
                     recompute; from the published samples for muscle_node's logs),
                     joint_states samples outside the geometry's box; also printed
  summary.png        one page: the run, its totals, force per muscle, the Fig. 7 style energy
                     rate, cumulative energy and partition per muscle, joint torques or drive
                     (more than 9 muscles: the 8 with the most energy by name, the rest as
                     "others")
  force.png, kinematics.png, drive.png, energy_muscles.png   one panel per muscle (more than 4
                     muscles: one lane per muscle, scaled to its range); energy_muscles: the
                     energy rate components of slow and fast fibres, stacked ("not recruited"
                     where a fibre type has none); runs longer than 20 s add their last 5 s as
                     published; at most 40 muscles a file, more in force-2.png, ...
  energy_rate.png    Tsianos 2012 Fig. 7 style: all muscles' activation, cross-bridge, recovery
                     and total energy rate in time bins
  energy_models.png  each published model's total energy rate beside Tsianos 2012's, one panel
                     per muscle and one for all muscles (binned as energy_rate.png)
  energy_models_totals.png  energy per model relative to Tsianos 2012, per muscle and all
  energy_partition.png, totals.png, joint_torque.png (one panel per joint: generalized force,
                     and the joint angle on a twin axis)
Plots of long runs show per time bin the mean (line) and the range (band); the bin comes from
--bin, else the scenario's energy_bin, else the run's length (vm_ros.report.plots).
Times are seconds of model time from the first output. Plots need matplotlib (the [plot]
extra); --no-plots writes the CSV files only.
"""

from __future__ import annotations

import argparse
import csv
from pathlib import Path

import numpy as np

from vm_ros import telemetry as tm
from vm_ros import topics as tp
from vm_ros.errors import VmRosError
from vm_ros.progress import Progress
from vm_ros.recording.messages import TOPIC_TELEMETRY
from vm_ros.recording.run_log import METADATA_NAME, read_run
from vm_ros.report.plots import MAX_BINS, MIN_SCENARIO_BINS, plot_run, report_bin
from vm_ros.report.summary import (
    joint_summary_records,
    joint_summary_table,
    model_totals_records,
    model_totals_table,
    summary_records,
    summary_table,
)
from vm_ros.report.tables import (
    Table,
    energy_models_axes,
    energy_rate_models_table,
    energy_rate_table,
    force_table,
    joint_efforts_table,
    joint_states_table,
    model_totals,
    muscle_names,
    run_joint_summary,
    run_joint_work,
    run_summary,
    telemetry_table,
    totals_table,
)
from vm_ros.report.validity import node_input_losses, node_log_validity


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("log", type=Path, metavar="FILE.mcap", help="run log")
    parser.add_argument("--out", type=Path, metavar="DIR",
                        help="output folder (default: <log name>-report/ beside the log, "
                             "e.g. runs/knee.mcap -> runs/knee-report/)")
    parser.add_argument("--bin", type=float, default=None, metavar="S",
                        help="plot bins of S seconds (0: none). Default: the scenario's "
                             "energy_bin when the log names one (knee_extension: 1 s, as in "
                             "Tsianos 2012 Fig. 7) and the run spans at least "
                             f"{MIN_SCENARIO_BINS} of them, else the smallest 1-2-5 step "
                             f"giving at most {MAX_BINS} bins over the run (180 s: 1 s, "
                             "4 s: 0.02 s); none when that is not longer than the sample "
                             "interval. The choice is printed")
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


def _span_and_interval(tables: dict) -> tuple[float, float]:
    """(span, median sample interval) in s of the first time-series table the log has."""
    for name in ("forces", "energy_rate", "totals", "telemetry"):
        table = tables.get(name)
        if table is not None and len(table.data) > 1:
            t = table.column("time_s")
            return float(t[-1] - t[0]), float(np.median(np.diff(t)))
    return 0.0, 0.0


def run(args) -> int:
    log_path = args.log
    plt = None if args.no_plots else _pyplot()  # fail before the (long) read
    with Progress(f"read {log_path.name}", 1.0, enabled=True if args.progress else None) as p:
        log = read_run(log_path, topics=(tm.TOPIC_FORCE, tm.TOPIC_ENERGY_RATE,
                                         tm.TOPIC_ENERGY_RATE_TOTAL, tm.TOPIC_ENERGY_TOTAL,
                                         tm.TOPIC_EXCITATION, TOPIC_TELEMETRY,
                                         tm.TOPIC_JOINT_EFFORTS, tm.TOPIC_JOINT_STATES,
                                         tm.TOPIC_JOINT_WORK, tm.TOPIC_ENERGY_RATE_MODELS,
                                         *(row.name for row in tp.INPUT_TOPICS),
                                         tm.TOPIC_DIAGNOSTICS),
                       progress=lambda done, size: p.update(done / max(size, 1)))
    if not muscle_names(log):
        raise VmRosError(f"{log_path}: not a vm_ros run log (no '{METADATA_NAME}' metadata "
                         f"record and no decodable {tm.TOPIC_FORCE} messages)")
    out = args.out or log_path.with_name(f"{log_path.stem}-report")
    out.mkdir(parents=True, exist_ok=True)
    builders = (force_table, energy_rate_table, totals_table, telemetry_table,
                joint_efforts_table, joint_states_table, energy_rate_models_table)
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
    if not len(log.get(TOPIC_TELEMETRY) or ()) and summary:
        print("energy: totals are the model's own; the split into fibre types and components "
              "follows the logged energy_rate samples (vm_ros.report.tables.run_energy), so a "
              "component may differ a little from the run's own summary; its totals do not")
    joint_summary = run_joint_summary(log)
    joint_rows = joint_summary_records(joint_summary)
    if joint_rows:
        write_csv(out / "joint_summary.csv", list(joint_rows[0]), [r.values() for r in joint_rows])
        print(joint_summary_table(joint_summary, run_joint_work(log)[1]))
    totals, model_rows = model_totals(log), []
    if totals:
        model_muscles = energy_models_axes(log)[0]
        model_rows = model_totals_records(totals, model_muscles)
        write_csv(out / "model_totals.csv", list(model_rows[0]), [r.values() for r in model_rows])
        print(model_totals_table(totals, model_muscles))
    if not log.complete:
        print(f"note: {log_path} is cut short ({log.stop_reason}); the report covers what it "
              "holds")
    if log.skipped:
        print(f"note: {log.skipped_note()}")
    if log.unlisted_note:
        print(f"note: {log.unlisted_note}")
    checked = node_log_validity(log)
    if checked is not None:  # a muscle_node log: did its inputs keep up (vm_ros.report.validity)
        validity, stale_s = checked
        print("\n".join(validity.lines(accepted=None)))
        if stale_s > 0:
            print(f"note: muscle_node ran {stale_s:.2f} s after its inputs ended (until it was "
                  "stopped, on stale inputs: its stale_input_policy); the tables include that "
                  "time, the validity check does not")
        lost = node_input_losses(log)
        if lost:
            counts = ", ".join(f"{n} {topic}" for topic, n in lost.items())
            print(f"note: muscle_node lost {counts} message(s) before taking them (publisher "
                  "sequence gaps; the model held the inputs before each: its qos_depth, "
                  "docs/node.md section 4)")
    written = []
    if plt is not None:
        bin_s, reason = report_bin(log, *_span_and_interval(tables), args.bin)
        print(f"plot bins: {reason}")
        written = plot_run(plt, log, tables, out, bin_s, reason)
    files = len(tables) + bool(records) + bool(joint_rows) + bool(model_rows) + len(written)
    print(f"report: {out} ({files} files)")
    return 0
