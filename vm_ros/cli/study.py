"""Batch studies: many offline runs (inputs x parameter changes) on Dask distributed, one
results table. docs/studies.md has the study file's format and the cluster set-ups.

  vm-ros study check STUDY.yaml              validate the file and list its runs (nothing runs)
  vm-ros study run STUDY.yaml --out DIR      run it: by default on an embedded LocalCluster of
                                             one worker process per core (loopback only);
                                             --scheduler ADDRESS uses a running Dask cluster
                                             (SLURM through dask-jobqueue, Kubernetes, ...)
  vm-ros study report DIR                    print the table, plot energy against each varied
                                             parameter (main effects, per muscle)

DIR holds runs/<run id>.mcap (each run's log, as `vm-ros simulate` or `recompute` writes it)
and runs/<run id>.txt (what it printed), rows/<run id>.json (the record of each finished run),
results.parquet and results.csv (one row per run and muscle), runs.csv (status, error, wall
time, worker per run), params/ (model files of model.* changes) and study.yaml (a copy).

A run's id is a content hash of its input and parameters: `study run` again on the same DIR
skips the runs that finished and reruns failed or missing ones, and those whose log is missing
from runs/. The table is the same bit for bit whatever the number of workers. A run that fails
is recorded with its one-line error and the study goes on; a lost worker's runs are rerun on
another; Ctrl-C stops, keeping every finished run and the table of them (exit 130); a file of
DIR that cannot be written (disk full) stops the study with one line naming it, keeping the runs
recorded before (exit 1). A bad study file, --out naming a file or a --scheduler address Dask
cannot connect to is one line naming the field or option, exit 2.

Needs the study extra: pip install "vm_ros[study]" (dask[distributed], pyarrow); the report's
plots need matplotlib (the plot extra).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from vm_ros.errors import VmRosError


def offline_verbs() -> dict:
    """The verbs a study runs, by name (vm_ros.study.task.Verb)."""
    from vm_ros.cli import coordinate, recompute, simulate
    from vm_ros.study.task import Verb

    return {name: Verb(name, module.add_arguments, module.run)
            for name, module in (("simulate", simulate), ("recompute", recompute),
                                 ("coordinate", coordinate))}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="action", metavar="ACTION", required=True)
    check = sub.add_parser("check", help="validate a study file and list its runs")
    check.add_argument("study", type=Path, metavar="STUDY.yaml")
    run = sub.add_parser("run", help="run a study (resumes in an existing DIR)")
    run.add_argument("study", type=Path, metavar="STUDY.yaml")
    run.add_argument("--out", type=Path, required=True, metavar="DIR",
                     help="study folder: logs, records, results table")
    where = run.add_mutually_exclusive_group()
    where.add_argument("--scheduler", metavar="ADDRESS",
                       help="address of a running Dask scheduler (tcp://host:8786) instead of "
                            "the embedded LocalCluster")
    where.add_argument("--workers", type=int, metavar="N",
                       help="worker processes of the embedded LocalCluster (default: one per "
                            "core)")
    report = sub.add_parser("report", help="print a study's table and plot its main effects")
    report.add_argument("dir", type=Path, metavar="DIR")
    report.add_argument("--no-plots", action="store_true", help="print the table only")
    report.add_argument("--energy", default="all.total_energy_J", metavar="COLUMN",
                        help="the energy column plotted (default all.total_energy_J, Tsianos "
                             "2012's total; a published model's: <model>.energy_J)")
    report.add_argument("--by", metavar="PARAMETER",
                        help="one line per value of this varied parameter (interaction)")


def run(args) -> int:
    from vm_ros.study import require_extra
    from vm_ros.study.study_file import load_study

    if args.action == "check":
        study = load_study(args.study)
        for spec in study.runs:
            changes = ", ".join(f"{k}={v}" for k, v in spec.changes.items())
            print(f"{spec.run_id}  {spec.verb:9} {spec.input}  {changes}")
        print(f"{study.name}: {len(study.runs)} runs, varied: {', '.join(study.varied) or 'none'}")
        return 0
    require_extra()
    if args.action == "report":
        from vm_ros.study.report import report

        return report(args.dir, plots=not args.no_plots, energy=args.energy, by=args.by)
    from vm_ros.study.engine import Engine, StudyWriteError, close, run_study

    study = load_study(args.study)
    if args.workers is not None and args.workers < 1:
        raise VmRosError(f"--workers must be >= 1, got {args.workers}")
    if args.out.exists() and not args.out.is_dir():
        raise VmRosError(f"--out {args.out} is a file: give a folder (a new one, or the folder "
                         "of this study to resume it)")
    try:
        client, cluster = Engine(args.scheduler, args.workers).open()
    except OSError as error:
        raise VmRosError(f"cannot reach the Dask scheduler {args.scheduler}: {error}") from None
    try:
        print(f"Dask: {len(client.scheduler_info()['workers'])} workers at "
              f"{client.scheduler.address}")
        summary = run_study(study, args.out, client, offline_verbs())
    except StudyWriteError as error:  # the records written before it are kept
        print(f"vm-ros study: error: {error}; the study stopped, the runs recorded before "
              f"are kept in {args.out / 'rows'}", file=sys.stderr)
        return 1
    finally:
        close(client, cluster)
    print(summary.line())
    print(f"table: {args.out / 'results.parquet'}, {args.out / 'results.csv'}")
    return 1 if summary.failed else 0
