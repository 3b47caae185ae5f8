"""Run the model offline (no ROS needed) on a built-in scenario, on input time series or on an
OpenSim motion through a joint-space geometry, write an MCAP log with the channels muscle_node
writes, and print a per-muscle (and per-joint) summary. Without --scenario, --inputs or --motion
it runs the DEFAULT_SCENARIO (knee_extension, Tsianos 2012 Fig. 7, 180 s of model time), and
says so.

The log holds the inputs (excitation, muscle_kinematics or joint_states, sampled every
--input-rate), the outputs (muscle_force, energy_rate, energy_rate_total, energy_total, and
joint_efforts, joint_effort_commands with --motion, at --publish-rate), the muscle_telemetry record
(--telemetry-rate), the run's metadata and the model, muscle and geometry files used; `vm-ros
recompute` reruns it, `vm-ros report` plots it, `vm-ros replay` republishes it. Every log time
and header stamp is the start time plus the model time, in ns: the start time is the wall clock
when the run starts (--start-time NS sets it; 0 puts the log on model time from 0), recorded as
start_time_ns in the log's metadata, so that timeline tools (Foxglove) show the date of the run
and model time = log time - start_time_ns. With no input log to sit beside, the log goes to
out/ under the current directory unless --out says otherwise.

Input CSV (--inputs): a header row, then one row per sample:
  time_s                  time (s), strictly increasing
  <muscle>.excitation     drive U in [0, 1]
  <muscle>.path_length    musculotendon path length (m)
  <muscle>.path_velocity  path lengthening velocity (m/s), optional (default: derivative of the
                          path length)
Values are interpolated linearly between rows; the muscles are those with columns (or
--muscles), taken from the muscle library.

Joint space (--motion FILE.mot|.sto --geometry GEOMETRY.yaml):
  coordinates   the geometry's coordinates from the motion's columns by name (coordinate names
                or /jointset/<joint>/<coordinate>/value; degrees when its header says
                inDegrees=yes; a file saying inDegrees=no with angles beyond a full turn is an
                error); a coordinate crossed by a muscle of the run that the motion lacks is an
                error unless --hold COORDINATE=VALUE gives it a constant value with its unit
                (30deg, 0.5rad, 0.9m; inside the geometry's box)
  muscles       the geometry's muscles that are in the muscle library (--library, e.g. the
                muscles.yaml of `vm-ros import-osim`), or --muscles (each needs a path)
  drive         --excitations FILE (.sto/.mot: columns NAME, /forceset/NAME, NAME|excitation,
                .../NAME/excitation, other columns ignored; .csv: time_s and one column per
                muscle), on the motion's time axis (a file that does not overlap the run is an
                error); or a constant --excitation U; default 0: passive (the torques come from
                the muscles' passive elasticity only). Drives are fractions in [0, 1]: a value
                outside is an error (percent: divide by 100)
Input warnings (printed when found and repeated after the summary; --strict makes them errors):
an excitation or input table that covers only part of the run (its first or last row is held),
a run longer than its motion, motion frames outside the geometry's box (clamped), a motion whose
header says degrees but whose angles all stay within +-3.14.
  joints        joint_states and joint_efforts name the coordinates through --joint-map (YAML
                text or file, as muscle_node's joint_map: robot q = sign (q - offset)); the
                joint outputs are the coordinates crossed by the run's muscles
Inputs are conditioned as muscle_node conditions them (vm_ros.node.joint_inputs.JointInputs and
vm_ros.node.inputs.NodeInputs with the node's default input parameters, recorded in the log's
node_parameters): coordinates outside the geometry's box are clamped (counted per coordinate in
the summary), joint_states giving non-physical path lengths are dropped (counted); the initial
state is published at model time 0 as the node does. The summary adds per joint the peak and mean
generalized force (N m or N), the joint work (sum of tau qdot dt over the steps) and the clamping.

Published energetics models (--energetics-models A,B or all; vm_ros.model.energetics_models,
docs/energetics_models.md): the bank runs them beside Tsianos 2012 and the log gains the
energy_rate_models channel (W, muscle x model x component, at --publish-rate) and their names in
the metadata; `vm-ros report` plots them and prints their totals.

SIGINT or SIGTERM stops the run between two steps; the log is finished cleanly and the summary
covers the time simulated.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path

from vm_ros.cli.runs import (
    InputWarnings,
    RunOutcome,
    StopOnSignal,
    add_model_options,
    add_output_options,
    add_strict_option,
    apply_model_options,
    default_log_path,
    recorder_options,
)
from vm_ros.errors import InputError, VmRosError
from vm_ros.geometry import load_geometry
from vm_ros.importers.motion import read_motion
from vm_ros.joint_space import JointMap, JointSpace
from vm_ros.model.energetics_models.in_bank import model_names
from vm_ros.model.energetics_models.vm_state import MODEL_NAMES, RENAMED
from vm_ros.model.params import load_muscle_library
from vm_ros.model.run_config import RunConfig
from vm_ros.node.motion_inputs import (
    JointMotion,
    MotionInputs,
    motion_checks,
    parse_hold,
)
from vm_ros.node.params import NodeConfig
from vm_ros.node.recording import INPUT_RULE as NODE_INPUT_RULE
from vm_ros.node.replay import NODE_PARAMETERS_KEY, NodeConditioning
from vm_ros.offline.excitations import (
    COVERAGE_TOLERANCE_S,
    constant_excitation,
    load_excitations,
)
from vm_ros.offline.input_series import load_input_series
from vm_ros.offline.runner import STEADY_START, OfflineResult, OfflineRun, SampledInputs
from vm_ros.offline.scenarios import load_scenario, scenario_names
from vm_ros.progress import Progress
from vm_ros.recording.bag import shown_log_path
from vm_ros.recording.run_log import RunInfo, RunTiming, open_run_log, run_attachments
from vm_ros.report.summary import (
    joint_summary_table,
    model_totals_table,
    summarize,
    summarize_joints,
    summary_table,
)
from vm_ros.report.tables import logged_model_totals
from vm_ros.telemetry import energy_partition

JOINT_OPTIONS = ("geometry", "excitations", "excitation", "joint_map", "hold")
DEFAULT_SCENARIO = "knee_extension"  # the paper's headline run (Fig. 7), also the demo's
# metadata time_base of a simulate log
OFFLINE_TIME_BASE = "start_time_ns (wall clock at the start) + model time (offline)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    source = parser.add_mutually_exclusive_group()
    source.add_argument("--scenario", choices=scenario_names(),
                        help=f"built-in scenario (default {DEFAULT_SCENARIO} when neither "
                             "--inputs nor --motion is given)")
    source.add_argument("--inputs", metavar="FILE.csv", help="input time series (see above)")
    source.add_argument("--motion", type=Path, metavar="FILE.mot|.sto",
                        help="OpenSim motion or states file, with --geometry (see above)")
    parser.add_argument("--duration", type=float, metavar="S",
                        help="simulated time (default: the scenario's, the CSV's or the "
                             "motion's)")
    parser.add_argument("--muscles", metavar="A,B", help="comma-separated muscles instead of "
                        "the scenario's (the CSV's, the geometry's)")
    parser.add_argument("--dt", type=float, default=0.001, metavar="S",
                        help="model step (default 0.001 s)")
    parser.add_argument("--input-rate", type=float, metavar="HZ",
                        help="input sampling rate (default: the model rate, 1/dt)")
    parser.add_argument("--start-time", type=start_time_ns, metavar="NS",
                        help="log time of model time 0, integer ns since the Unix epoch "
                             "(default: the wall clock when the run starts; 0: the log on model "
                             "time from 0)")
    joint = parser.add_argument_group("joint space (with --motion)")
    joint.add_argument("--geometry", type=Path, metavar="GEOMETRY.yaml",
                       help="vm_ros.geometry file (e.g. from vm-ros import-osim); required")
    joint.add_argument("--excitations", type=Path, metavar="FILE.sto|.csv",
                       help="drive per muscle over time (see above)")
    joint.add_argument("--excitation", type=float, metavar="U",
                       help="constant drive of every muscle, in [0, 1] (default 0: passive)")
    joint.add_argument("--joint-map", metavar="YAML",
                       help="robot joints -> coordinates, YAML text or file (muscle_node's "
                            "joint_map; default: coordinates under their own names)")
    joint.add_argument("--hold", action="append", default=[], metavar="COORDINATE=VALUE",
                       help="hold a coordinate at VALUE, with its unit (30deg, 0.5rad, 0.9m), "
                            "instead of the motion (repeatable)")
    add_strict_option(parser)
    add_model_options(parser, "the scenario's settings, lumped recruitment")
    add_energetics_option(parser, "none")
    add_output_options(parser, "default out/<scenario or file>-<date>-<time>.mcap under the "
                               "current directory: there is no input log to write beside")


@dataclass
class _Source:
    """Where the inputs come from: a scenario, a CSV file or a motion; ``config`` before the
    command line's model options."""

    name: str
    config: RunConfig
    duration_s: float
    extra: dict
    # (bank, offline run, input period ns) -> inputs for OfflineRun.run
    make_inputs: Callable
    publish_start: bool = False
    # (inputs, result) -> summary lines after the muscles'
    report: Callable = field(default=lambda inputs, result: [])
    # run duration (s) -> input warnings (InputWarnings) for that span; VmRosError when unusable
    check: Callable = field(default=lambda duration_s: [])


def add_energetics_option(parser: argparse.ArgumentParser, default: str) -> None:
    """--energetics-models A,B|all (simulate and recompute)."""
    parser.add_argument("--energetics-models", metavar="A,B|all",
                        help="published energetics models to run beside Tsianos 2012 and log "
                             f"(energy_rate_models): {', '.join(MODEL_NAMES)}, all, or none "
                             f"(default {default})")


def energetics_models_option(text: str | None) -> tuple | None:
    """The models of --energetics-models (None when not given, () for "none"); VmRosError
    naming the known models for an unknown name."""
    if text is None:
        return None
    if text.strip() == "none":
        return ()
    try:
        names = model_names(text)
    except InputError as error:
        raise VmRosError(f"--energetics-models: {error.value!r}: {error.reason}") from None
    if not names:
        raise VmRosError(f"--energetics-models: no model named; known: {', '.join(MODEL_NAMES)}"
                         ", all or none")
    for former in (part.strip() for part in text.split(",")):
        if former in RENAMED:
            print(f"vm-ros: --energetics-models {former} is now {RENAMED[former]}; the former "
                  "name goes in the next release", file=sys.stderr)
    return names


def start_time_ns(text: str) -> int:
    """argparse type of --start-time: an integer number of ns >= 0."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer number of ns, got {text!r}") \
            from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be >= 0, got {text!r}")
    return value


def _muscle_list(args) -> tuple:
    return tuple(m.strip() for m in (args.muscles or "").split(",") if m.strip())


def _sampled(functions):
    """make_inputs of functions of time: excitation, path_length, path_velocity."""

    def make(bank, offline, period_ns):
        inputs = functions(bank)
        return SampledInputs(bank.names, inputs.excitation, inputs.path_length,
                             inputs.path_velocity, period_ns, offline.timing.start_time_ns,
                             offline.sink)

    return make


def _source(args) -> _Source:
    muscles = _muscle_list(args)
    if not args.scenario and not args.inputs:
        args.scenario = DEFAULT_SCENARIO
        print(f"vm-ros simulate: no --scenario, --inputs or --motion: running the default "
              f"scenario, {DEFAULT_SCENARIO}", file=sys.stderr)
    if args.scenario:
        scenario = load_scenario(args.scenario)
        config = RunConfig(muscles or scenario.muscles, recovery_mode=scenario.recovery_mode)
        return _Source(scenario.name, config, scenario.duration_s, {"scenario": scenario.name},
                       _sampled(scenario.inputs))
    series = load_input_series(args.inputs)
    series = series.select(muscles or series.muscles)
    return _Source(series.path.stem, RunConfig(series.muscles), series.duration_s,
                   {"inputs_file": str(series.path)}, _sampled(lambda bank: series),
                   check=lambda duration_s: held_after(f"inputs {series.path}",
                                                        series.duration_s, duration_s))


def held_after(what: str, table_s: float, duration_s: float) -> list[str]:
    """A warning when the run goes on past the end of a table of inputs (its last row held)."""
    if duration_s - table_s <= COVERAGE_TOLERANCE_S:
        return []
    return [f"{what} span {table_s:.6g} s, the run {duration_s:.6g} s: their last row is held "
            f"for the last {duration_s - table_s:.6g} s"]


def _check_options(args) -> None:
    """Joint-space options only with --motion, --motion only with a geometry."""
    if not args.motion:
        given = [name for name in JOINT_OPTIONS if getattr(args, name)]
        if given:
            raise VmRosError(f"--{given[0].replace('_', '-')} is for joint-space runs: use it "
                             "with --motion")
        return
    if args.geometry is None:
        raise VmRosError("--motion needs --geometry GEOMETRY.yaml (a vm_ros.geometry file, "
                         "e.g. from vm-ros import-osim)")
    if args.excitations is not None and args.excitation is not None:
        raise VmRosError("give --excitations FILE or --excitation U, not both")


def _joint_map_text(value: str | None) -> str:
    """--joint-map: YAML text, or the text of the YAML file it names."""
    if not value:
        return ""
    path = Path(value)
    try:
        return path.read_text() if path.is_file() else value
    except OSError as exc:
        raise VmRosError(f"--joint-map {value}: cannot read ({exc.strerror or exc})") from exc


def _motion_muscles(args, geometry) -> tuple:
    """--muscles (each with a path in the geometry), else the geometry's muscles in the
    library."""
    chosen = _muscle_list(args)
    if chosen:
        unknown = [m for m in chosen if m not in geometry.muscle_names]
        if unknown:
            raise VmRosError(f"--muscles: {unknown[0]!r} has no path in the geometry "
                             f"{args.geometry} (it has: {', '.join(geometry.muscle_names)})")
        return chosen
    library = load_muscle_library(args.library)
    muscles = tuple(m for m in geometry.muscle_names if m in library)
    if not muscles:
        raise VmRosError(f"none of the geometry's muscles ({', '.join(geometry.muscle_names)}) "
                         f"is in the muscle library {args.library or 'shipped with vm_ros'}: "
                         "give --library (e.g. the muscles.yaml of vm-ros import-osim)")
    return muscles


def _motion_source(args, motion_checked: bool = False) -> _Source:
    """The joint-space source; ``motion_checked``: the caller has run ``motion_checks`` on the
    motion and has their warnings and notes (`vm-ros coordinate`, on the motion it solved)."""
    geometry = load_geometry(args.geometry)
    motion = read_motion(args.motion)
    hold = parse_hold(args.hold, geometry)
    text = _joint_map_text(args.joint_map)
    joint_map = JointMap.build(text, geometry, "--joint-map")
    muscles = _motion_muscles(args, geometry)
    crossed = {c for m in geometry.muscles if m.name in muscles for c in m.coordinates}
    joints = tuple(robot for robot, name in zip(joint_map.robot_names, joint_map.coordinates,
                                                strict=True) if name in crossed)
    node_values = {"muscles": list(muscles), "geometry": str(args.geometry), "joint_map": text,
                   "joints": list(joints)}
    node = NodeConfig.from_values(node_values)
    needed = [name for name in geometry.coordinate_names if name in crossed]
    joint_motion = JointMotion.from_motion(motion, geometry, needed, hold)
    warnings, coupled_notes = (([], []) if motion_checked
                               else motion_checks(motion, joint_motion, geometry))
    excitations = (load_excitations(args.excitations, muscles) if args.excitations else
                   constant_excitation(muscles, 0.0 if args.excitation is None
                                       else args.excitation))

    def check(duration_s: float) -> list[str]:
        start = joint_motion.start_s
        return [*warnings, *held_after(f"motion {args.motion}", joint_motion.duration_s,
                                       duration_s),
                *excitations.coverage(start, start + duration_s)]

    def make_inputs(bank, offline, period_ns):
        space = JointSpace(geometry, joint_map, bank.names, joints, "--geometry")
        return MotionInputs(bank.names, excitations, joint_motion, joint_map,
                            NodeConditioning(bank, node, space), period_ns, offline.sink,
                            start_ns=offline.timing.start_time_ns)

    def report(inputs: MotionInputs, result: OfflineResult) -> list[str]:
        conditioning = inputs.conditioning
        output = conditioning.space.output
        units = [geometry.coordinates[j].unit for j in output]
        rows = summarize_joints(result.joints, units, result.joint_samples[:, 2, :],
                                result.joint_work, conditioning.clamped[output])
        lines = [joint_summary_table(rows)] if len(result.joints) else []
        if conditioning.issues:
            counts = ", ".join(f"{kind} {n}" for kind, n in sorted(conditioning.issues.items()))
            lines.append(f"inputs conditioned as muscle_node: {counts} "
                         f"({conditioning.issue_text()})")
        if excitations.ignored:
            shown = ", ".join(excitations.ignored[:5])
            more = f" (+{len(excitations.ignored) - 5} more)" if len(excitations.ignored) > 5 \
                else ""
            lines.append(f"excitations {excitations.source}: columns not used: {shown}{more}")
        return lines + coupled_notes

    config = RunConfig(muscles, geometry=args.geometry, joint_map=text, joints=joints)
    extra = {"motion_file": str(args.motion), "excitations": excitations.source,
             "hold": json.dumps(hold, sort_keys=True),
             NODE_PARAMETERS_KEY: json.dumps(node_values, sort_keys=True),
             "input_hold": NODE_INPUT_RULE}
    return _Source(args.motion.stem, config, joint_motion.duration_s, extra, make_inputs,
                   publish_start=True, report=report, check=check)


def _positive(name: str, value: float) -> float:
    if not value > 0:
        raise VmRosError(f"{name} must be > 0 (got {value})")
    return value


def run(args, on_outcome: Callable[[RunOutcome], None] | None = None,
        verb: str = "simulate", extra: dict | None = None,
        checked: InputWarnings | None = None,
        attachments: Mapping[str, bytes] | None = None) -> int:
    """The verb; ``on_outcome`` (vm_ros.study) gets what the run computed when it succeeded;
    ``verb``, ``extra`` (metadata entries; STEADY_START "yes" starts the activation at the
    steady state of the first drive) and ``checked`` for a verb that runs its drives through
    this one (`vm-ros coordinate`): the InputWarnings of a caller that has checked the motion
    (``motion_checks``) before its own work; the run leaves the motion's checks out, adds its
    own warnings to it, and the caller prints the closing lines; ``attachments`` (name ->
    bytes): files the caller attaches to the log beside the run's own (model, library,
    geometry)."""
    extra = dict(extra or {})
    models = energetics_models_option(args.energetics_models)
    _check_options(args)
    source = (_motion_source(args, motion_checked=checked is not None) if args.motion
              else _source(args))
    if args.duration is None and not source.duration_s > 0:
        raise VmRosError(f"the inputs ({source.name}) span {source.duration_s:g} s, a single "
                         "time: give --duration S, or inputs with at least two times")
    duration = _positive("--duration", source.duration_s if args.duration is None
                         else args.duration)
    warnings = InputWarnings(verb, args.strict) if checked is None else checked
    warnings.extend(source.check(duration))
    timing = RunTiming(
        dt_s=_positive("--dt", args.dt),
        publish_rate_hz=_positive("--publish-rate", args.publish_rate or 100.0),
        telemetry_rate_hz=100.0 if args.telemetry_rate is None else max(args.telemetry_rate, 0),
        start_time_ns=time.time_ns() if args.start_time is None else args.start_time,
    )
    config = apply_model_options(source.config, args)
    if models:
        config = config.replace(energetics_models=models)
    bank = config.make_bank()
    input_period_ns = timing.dt_ns * timing.steps_per(args.input_rate or timing.model_rate_hz)
    out_path = args.out or default_log_path(source.name)
    info = RunInfo(config, timing, verb, time_base=OFFLINE_TIME_BASE,
                   extra={**source.extra, **extra, "duration_s": repr(duration)})
    n_steps = round(duration / timing.dt_s)
    # signals stay caught until the log is closed, so that SIGTERM cannot cut the file short
    with StopOnSignal() as stop, open_run_log(
            out_path, info, bank, attachment_time_ns=timing.start_time_ns,
            attachments=None if attachments is None else {
                **run_attachments(info.config), **attachments},
            **recorder_options(args)) as recorder, Progress(
            f"simulate {source.name}", n_steps, enabled=True if args.progress else None) \
            as progress:
        offline = OfflineRun(bank, timing, recorder)
        inputs = source.make_inputs(bank, offline, input_period_ns)
        result = offline.run(inputs, n_steps, should_stop=stop, progress=progress.update,
                             publish_start=source.publish_start,
                             steady_start=extra.get(STEADY_START) == "yes")
    status = recorder.status
    print(f"simulated {result.steps * timing.dt_s:.3f} s of {', '.join(bank.names)} "
          f"({config.recruitment} recruitment, {bank.recovery_mode} recovery, dt "
          f"{timing.dt_s * 1e3:g} ms)")
    rows = []
    if result.last is not None:
        last = result.last
        rows = summarize(bank.names, result.force_samples,
                         energy_partition(last.energy_by_fibre, last.energy),
                         last.mechanical_work)
        print(summary_table(rows))
    for line in source.report(inputs, result):
        print(line)
    totals = []
    if bank.energetics_models and status.ok and status.written:
        totals = logged_model_totals(out_path)
        print(model_totals_table(totals, bank.names))
    print(f"log: {shown_log_path(out_path, status.path)} ({status.written} messages, "
          f"{status.bytes_written / 1e6:.2f} MB"
          f"{f', {status.dropped} dropped' if status.dropped else ''})")
    for line in warnings.closing_lines() if checked is None else ():
        print(line)
    if stop.signum:
        print(f"vm-ros {verb}: stopped by signal {stop.signum} at t = "
              f"{result.steps * timing.dt_s:.3f} s; the log is complete up to there",
              file=sys.stderr)
        return stop.exit_code
    if not status.ok:
        print(f"vm-ros {verb}: error: {status.error}", file=sys.stderr)
        return 1
    if on_outcome is not None:
        on_outcome(RunOutcome(rows, totals, result.steps * timing.dt_s))
    return 0
