"""Run the model offline (no ROS needed) on a built-in scenario or on input time series, write an
MCAP log with the channels muscle_node writes, and print a per-muscle summary.

The log holds the inputs (excitation, muscle_kinematics, sampled every --input-rate), the outputs
(muscle_force, energy_rate, energy_rate_total, energy_total at --publish-rate), the
muscle_telemetry record (--telemetry-rate), the run's metadata and the model and muscle files
used; `vm-ros recompute` reruns it, `vm-ros report` plots it, `vm-ros replay` republishes it.
Offline, every log time and header stamp is the model time in ns, starting at 0.

Input CSV (--inputs): a header row, then one row per sample:
  time_s                  time (s), strictly increasing
  <muscle>.excitation     drive U in [0, 1]
  <muscle>.path_length    musculotendon path length (m)
  <muscle>.path_velocity  path lengthening velocity (m/s), optional (default: derivative of the
                          path length)
Values are interpolated linearly between rows; the muscles are those with columns (or
--muscles), taken from the muscle library.

SIGINT or SIGTERM stops the run between two steps; the log is finished cleanly and the summary
covers the time simulated.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from dataclasses import dataclass

from vm_ros.cli.progress import Progress
from vm_ros.cli.runs import (
    StopOnSignal,
    add_model_options,
    add_output_options,
    apply_model_options,
    default_log_path,
)
from vm_ros.errors import VmRosError
from vm_ros.recording.input_series import load_input_series
from vm_ros.recording.offline import OfflineRun, SampledInputs
from vm_ros.recording.run_config import RunConfig
from vm_ros.recording.run_log import RunInfo, RunTiming, open_run_log
from vm_ros.recording.summary import summarize, summary_table
from vm_ros.scenarios import load_scenario, scenario_names
from vm_ros.telemetry import energy_partition

HELP = "run the model offline on a scenario or CSV inputs; write MCAP and print a summary"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    source = parser.add_mutually_exclusive_group(required=True)
    source.add_argument("--scenario", choices=scenario_names(), help="built-in scenario")
    source.add_argument("--inputs", metavar="FILE.csv", help="input time series (see above)")
    parser.add_argument("--duration", type=float, metavar="S",
                        help="simulated time (default: the scenario's or the CSV's)")
    parser.add_argument("--muscles", metavar="A,B", help="comma-separated muscles instead of "
                        "the scenario's (or the CSV's)")
    parser.add_argument("--dt", type=float, default=0.001, metavar="S",
                        help="model step (default 0.001 s)")
    parser.add_argument("--input-rate", type=float, metavar="HZ",
                        help="input sampling rate (default: the model rate, 1/dt)")
    add_model_options(parser, "the scenario's settings, lumped recruitment")
    add_output_options(parser, "default out/<scenario>-<date>-<time>.mcap")


@dataclass(frozen=True)
class _Source:
    """Where the inputs come from: a scenario or a CSV file."""

    name: str
    muscles: tuple
    make_inputs: Callable  # bank -> object with excitation/path_length/path_velocity(t)
    duration_s: float
    recovery_mode: str | None
    extra: dict


def _source(args) -> _Source:
    muscles = tuple(m.strip() for m in (args.muscles or "").split(",") if m.strip())
    if args.scenario:
        scenario = load_scenario(args.scenario)
        return _Source(scenario.name, muscles or scenario.muscles, scenario.inputs,
                       scenario.duration_s, scenario.recovery_mode, {"scenario": scenario.name})
    series = load_input_series(args.inputs)
    series = series.select(muscles or series.muscles)
    return _Source(series.path.stem, series.muscles, lambda bank: series, series.duration_s,
                   None, {"inputs_file": str(series.path)})


def _positive(name: str, value: float) -> float:
    if not value > 0:
        raise VmRosError(f"{name} must be > 0 (got {value})")
    return value


def run(args) -> int:
    source = _source(args)
    duration = _positive("--duration", source.duration_s if args.duration is None
                         else args.duration)
    timing = RunTiming(
        dt_s=_positive("--dt", args.dt),
        publish_rate_hz=_positive("--publish-rate", args.publish_rate or 100.0),
        telemetry_rate_hz=100.0 if args.telemetry_rate is None else max(args.telemetry_rate, 0),
    )
    config = apply_model_options(RunConfig(source.muscles, recovery_mode=source.recovery_mode),
                                 args)
    bank = config.make_bank()
    inputs = source.make_inputs(bank)
    input_period_ns = timing.dt_ns * timing.steps_per(args.input_rate or timing.model_rate_hz)
    out_path = args.out or default_log_path(source.name)
    info = RunInfo(config, timing, "simulate", time_base="model time from 0 (offline)",
                   extra={**source.extra, "duration_s": repr(duration)})
    n_steps = round(duration / timing.dt_s)
    # signals stay caught until the log is closed, so that SIGTERM cannot cut the file short
    with StopOnSignal() as stop, open_run_log(
            out_path, info, bank, chunk_size=args.chunk_size) as recorder, Progress(
            f"simulate {source.name}", n_steps, enabled=True if args.progress else None) \
            as progress:
        offline = OfflineRun(bank, timing, recorder)
        sampled = SampledInputs(bank.names, inputs.excitation, inputs.path_length,
                                inputs.path_velocity, input_period_ns, 0, offline.sink)
        result = offline.run(sampled, n_steps, should_stop=stop, progress=progress.update)
    status = recorder.status
    print(f"simulated {result.steps * timing.dt_s:.3f} s of {', '.join(bank.names)} "
          f"({config.recruitment} recruitment, {bank.recovery_mode} recovery, dt "
          f"{timing.dt_s * 1e3:g} ms)")
    if result.last is not None:
        last = result.last
        rows = summarize(bank.names, result.force_samples,
                         energy_partition(last.energy_by_fiber, last.energy),
                         last.mechanical_work)
        print(summary_table(rows))
    print(f"log: {status.path} ({status.written} messages, {status.bytes_written / 1e6:.2f} MB"
          f"{f', {status.dropped} dropped' if status.dropped else ''})")
    if stop.signum:
        print(f"vm-ros simulate: stopped by signal {stop.signum} at t = "
              f"{result.steps * timing.dt_s:.3f} s; the log is complete up to there",
              file=sys.stderr)
        return stop.exit_code
    if not status.ok:
        print(f"vm-ros simulate: error: {status.error}", file=sys.stderr)
        return 1
    return 0
