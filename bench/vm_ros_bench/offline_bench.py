"""The 180 s knee extension logged as `vm-ros simulate` logs it, against the model alone, measured
in one run (issue: performance, "wall time and ratio to the model alone").

Each repeat times, back to back on the same machine state:

| key | what |
| model_s | MuscleBank.run over every step, inputs sampled beforehand (the model alone) |
| simulate_s | vm_ros.cli.simulate.run in this process: bank, inputs, every message of the default
  channels (inputs at 1 kHz, outputs and telemetry at 100 Hz) written to a rosbag2 bag
  directory (one MCAP file and metadata.yaml), closed |
| cli_s | ``python -m vm_ros.cli simulate`` as a child process (adds start-up and imports) |
| recompute_s | vm_ros.cli.recompute.run in this process on the log simulate_s just wrote (read,
  rerun, write a new log), right after it: the pair gives recompute_over_simulate (issue 33:
  <= 2) |

Medians over the repeats; the ratios are of the medians, and ``recompute_over_simulate_paired``
the median of each repeat's own ratio (robust to the load changing between repeats).
"""

from __future__ import annotations

import argparse
import contextlib
import io
import os
import statistics
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np

from vm_ros.child_process import module_command, module_environment

SCENARIO = "knee_extension"
DT = 1e-3


def _model_alone(duration_s: float | None) -> float:
    """Wall time (s) of MuscleBank.run over the scenario, inputs sampled beforehand."""
    from vm_ros.offline.scenarios import load_scenario

    scenario = load_scenario(SCENARIO)
    bank = scenario.make_bank()
    steps = int(round((duration_s or scenario.duration_s) / DT))
    u, lp, vp = scenario.inputs(bank).sample(DT * np.arange(steps))
    bank.reset(lp[0])
    start = time.perf_counter()
    bank.run(DT, u, lp, vp)
    return time.perf_counter() - start


def _simulate_args(out: Path, duration_s: float | None) -> list[str]:
    args = ["--scenario", SCENARIO, "--out", str(out)]
    return args + (["--duration", repr(duration_s)] if duration_s else [])


def _in_process(verb: str, argv: list[str]) -> tuple[float, str]:
    """Wall time (s) of vm_ros.cli.<verb>.run with ``argv``, and its last output line."""
    import importlib

    module = importlib.import_module(f"vm_ros.cli.{verb}")
    parser = argparse.ArgumentParser()
    module.add_arguments(parser)
    args = parser.parse_args(argv)
    text = io.StringIO()
    start = time.perf_counter()
    with contextlib.redirect_stdout(text):
        code = module.run(args)
    wall = time.perf_counter() - start
    if code != 0:
        raise RuntimeError(f"vm-ros {verb} exited with {code}: {text.getvalue()[-300:]}")
    return wall, text.getvalue().strip().splitlines()[-1]


def _simulate_in_process(out: Path, duration_s: float | None) -> tuple[float, str]:
    """Wall time (s) of vm_ros.cli.simulate.run and its last output line."""
    return _in_process("simulate", _simulate_args(out, duration_s))


def _recompute_in_process(log: Path, out: Path) -> float:
    """Wall time (s) of vm_ros.cli.recompute.run of ``log`` into ``out``."""
    return _in_process("recompute", [str(log), "--out", str(out)])[0]


def _simulate_cli(out: Path, duration_s: float | None) -> float:
    command = module_command("vm_ros.cli", "simulate", *_simulate_args(out, duration_s))
    start = time.perf_counter()
    subprocess.run(command, env=module_environment(), check=True, capture_output=True,
                   timeout=600)
    return time.perf_counter() - start


def bench_offline_logged(repeats: int = 3, duration_s: float | None = None, cli: bool = True,
                         progress=None) -> dict:
    """Medians over ``repeats`` of the model alone, simulate in process and (``cli``) as a
    child process; see the module docstring."""
    model, logged, child, again, log_line = [], [], [], [], ""
    with tempfile.TemporaryDirectory(prefix="vm_ros-bench-offline-") as tmp:
        out = Path(tmp) / "knee"  # a bag directory
        _model_alone(1.0)  # warm-up: compilation and caches
        for _ in range(repeats):
            model.append(_model_alone(duration_s))
            wall, log_line = _simulate_in_process(out, duration_s)
            logged.append(wall)
            again.append(_recompute_in_process(out, Path(tmp) / "knee-recomputed.mcap"))
            if cli:
                child.append(_simulate_cli(out, duration_s))
    result = {"scenario": SCENARIO, "duration_s": duration_s or 180.0, "repeats": repeats,
              "model_s": statistics.median(model), "simulate_s": statistics.median(logged),
              "model_s_all": model, "simulate_s_all": logged, "log": log_line}
    result["simulate_over_model"] = result["simulate_s"] / result["model_s"]
    result.update({"recompute_s": statistics.median(again), "recompute_s_all": again,
                   "recompute_over_simulate": statistics.median(again) / result["simulate_s"],
                   "recompute_over_simulate_paired": statistics.median(
                       r / s for r, s in zip(again, logged, strict=True))})
    if child:
        result["cli_s"] = statistics.median(child)
        result["cli_s_all"] = child
        result["cli_over_model"] = result["cli_s"] / result["model_s"]
    if progress:
        progress(f"knee extension logged: simulate {result['simulate_s']:.2f} s, model alone "
                 f"{result['model_s']:.2f} s, ratio {result['simulate_over_model']:.1f}; "
                 f"recompute {result['recompute_s']:.2f} s, "
                 f"{result['recompute_over_simulate_paired']:.2f} x simulate")
    return result


REPORT_PLOT_TARGET_S = 5.0  # issue 27: the report's plotting for the 18-muscle walk under 5 s


def _timed_report(log: Path, out: Path, plots: bool) -> tuple[float, float]:
    """(wall s, CPU s of this process) of vm_ros.cli.report.run on ``log``."""
    cpu = time.process_time()
    wall, _ = _in_process("report", [str(log), "--out", str(out)] + ([] if plots else
                                                                     ["--no-plots"]))
    return wall, time.process_time() - cpu


def bench_report_walk(repeats: int = 3, progress=None) -> dict:
    """`vm-ros report` of opensim-models' Gait10dof18musc walk (18 muscles): the model imported
    at its own F0, `vm-ros simulate --motion IK --excitations CMC controls` (0.03-2.494 s of the
    run's 0-2.5 s: simulate warns that the first and last rows are held), then the report with
    and without plots, alternately in this process (the load average before the first). The
    plotting time is the difference of the medians, in wall time and in this process's CPU time;
    the target (< REPORT_PLOT_TARGET_S) is held on the CPU time, which a busy machine does not
    inflate as it does the wall time (the plotting is single-threaded). ``skipped`` with the
    reason when the walk is not fetched (scripts/fetch-gait-data)."""
    from vm_ros.validation.walk import STRENGTHS, import_walk
    from vm_ros.validation.walk_data import WalkDataError, walk_files

    try:
        files = walk_files()
    except WalkDataError as error:
        return {"skipped": str(error)}
    times: dict = {True: [], False: []}  # plots: [(wall, cpu), ...]
    with tempfile.TemporaryDirectory(prefix="vm_ros-bench-report-") as tmp:
        folder = Path(tmp)
        _, library = import_walk(files, STRENGTHS["model F0"], folder / "model")
        log = folder / "walk.mcap"
        _in_process("simulate", ["--motion", str(files["motion"]), "--geometry",
                                 str(folder / "model" / "geometry.yaml"), "--library",
                                 str(library), "--excitations", str(files["cmc_controls"]),
                                 "--out", str(log)])
        load = os.getloadavg()[0]
        for k in range(repeats):
            for plots in (False, True):
                times[plots].append(_timed_report(log, folder / f"{plots}{k}", plots))
    result = {"muscles": 18, "repeats": repeats, "load_average_start": load,
              "target_s": REPORT_PLOT_TARGET_S}
    for key, plots in (("report", True), ("no_plots", False)):
        for column, unit in enumerate(("s", "cpu_s")):
            values = [row[column] for row in times[plots]]
            result[f"{key}_{unit}"] = statistics.median(values)
            result[f"{key}_{unit}_all"] = values
    result["plotting_s"] = result["report_s"] - result["no_plots_s"]
    result["plotting_cpu_s"] = result["report_cpu_s"] - result["no_plots_cpu_s"]
    if progress:
        progress(f"report of the walk: {result['report_s']:.1f} s, --no-plots "
                 f"{result['no_plots_s']:.1f} s: plotting {result['plotting_s']:.1f} s "
                 f"({result['plotting_cpu_s']:.1f} s of CPU)")
    return result


HELP_COMMANDS = ("vm-ros", "muscle_node")  # console scripts beside this Python
HELP_TARGET_S = 0.5  # issue 27: `vm-ros --help` and `muscle_node --help` under 0.5 s


def bench_help(repeats: int = 5, progress=None) -> list[dict]:
    """`COMMAND --help` of each console script of HELP_COMMANDS as a child process, ``repeats``
    times: median wall time and CPU time (user + system, from the children's resource usage);
    the target (< HELP_TARGET_S) is held on the CPU time. ``skipped`` for a script not installed
    beside this Python."""
    import resource
    import sys

    rows = []
    for name in HELP_COMMANDS:
        script = Path(sys.executable).parent / name
        if not script.is_file():
            rows.append({"command": name, "skipped": f"{script} is not installed"})
            continue
        walls, cpus = [], []
        for _ in range(repeats):
            before = resource.getrusage(resource.RUSAGE_CHILDREN)
            start = time.perf_counter()
            subprocess.run([str(script), "--help"], check=True, capture_output=True, timeout=120)
            walls.append(time.perf_counter() - start)
            after = resource.getrusage(resource.RUSAGE_CHILDREN)
            cpus.append(after.ru_utime - before.ru_utime + after.ru_stime - before.ru_stime)
        rows.append({"command": name, "wall_s": statistics.median(walls), "wall_s_all": walls,
                     "cpu_s": statistics.median(cpus), "cpu_s_all": cpus,
                     "load_average": os.getloadavg()[0], "target_s": HELP_TARGET_S})
        if progress:
            progress(f"{name} --help: {rows[-1]['wall_s']:.2f} s wall, "
                     f"{rows[-1]['cpu_s']:.2f} s CPU")
    return rows
