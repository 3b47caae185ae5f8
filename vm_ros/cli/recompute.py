"""Re-run the model from a run log's recorded inputs, optionally with other parameters, into a
new MCAP log (same channels; inputs copied verbatim, outputs recomputed).

The model files attached to the log (model.yaml, muscles.yaml) and its recorded settings are the
starting point; the options below replace them. Inputs are applied by the rule the log was made
with:

- `vm-ros simulate` logs: zero-order hold, the model step [t, t + dt) uses the latest input with
  log time <= t;
- muscle_node logs and `vm-ros simulate --motion` logs (``node_parameters`` in the metadata):
  node conditioning, the recorded messages at their log times (the model time of the first step
  that used them) through vm_ros.node.inputs.NodeInputs with the logged node parameters
  (vm_ros.node.replay), and the initial state published at the start time as the node
  does. With a geometry, joint_states go through vm_ros.node.joint_inputs.JointInputs with the
  logged joint_map and joints and the attached geometry.yaml, and joint_efforts and
  joint_effort_commands are recomputed (each step's forces through the moment arms of the joint
  sample it used). With live coordination (``coordination.enabled``) the joint-driven muscles
  take the drives the node logged on coordination_drive at each publish period's start; the
  target topics are copied as data, the coordination is not solved again.

A recorded input that does not decode (muscle_node records inputs as received) is copied to the
new log but not applied, as the node dropped it; a line on stderr counts them per topic.

Without changes either is reproduced to floating-point precision, except where a node's model time
left its step grid (skipped or paused time, a backward clock jump): the summary then says the
result is approximate and why.

At the end the recomputed tendon forces (and joint efforts) are compared with the recorded ones
at equal model time (header stamps), once: the printed max |difference| and the verdict come from
that one comparison. "exact" when they are equal at every common stamp (equal NaNs count as
equal) and the recorded model time stayed on the step grid; else "not exact" and which of these
failed, with the same numbers.

Times: the new log keeps the original's start time (start_time_ns) and time line: inputs are
copied at their recorded log times, outputs logged and stamped at start + model time, so the two
logs line up in a timeline tool and model time = log time - start_time_ns in both. The
original's metadata entries that vm_ros does not interpret (scenario, inputs_file, ...) are
carried over, so that `vm-ros report` of the new log bins it as the original.

Published energetics models: as the log ran them (its ``energetics_models``), or those of
--energetics-models A,B|all|none: any log, however old, gains (or loses) the energy_rate_models
channel.

Output: by default beside the input log, <log folder>/<log name>-recomputed-<date>-<time>.mcap
(runs/knee.mcap -> runs/knee-recomputed-20250101-120000.mcap), as `vm-ros report` writes
<log name>-report/ beside it; --out elsewhere.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from vm_ros import telemetry as tm
from vm_ros.cli.runs import (
    RunOutcome,
    StopOnSignal,
    add_model_options,
    add_output_options,
    apply_model_options,
    beside,
    default_log_path,
    recorder_options,
)
from vm_ros.cli.simulate import add_energetics_option, energetics_models_option
from vm_ros.errors import ConfigError, VmRosError
from vm_ros.node.recording import INPUT_RULE as NODE_INPUT_RULE
from vm_ros.node.replay import (
    NodeReplayInputs,
    model_time_irregularities,
    node_config,
    node_joint_space,
)
from vm_ros.offline.runner import STEADY_START, OfflineRun, RecordedInputs
from vm_ros.progress import Progress
from vm_ros.recording.bag import shown_log_path
from vm_ros.recording.run_log import (
    ATTACHMENT_GEOMETRY,
    COORDINATION_INPUT_TOPICS,
    INPUT_TOPICS,
    RunInfo,
    RunLog,
    RunTiming,
    default_log_topics,
    open_run_log,
    read_run,
)
from vm_ros.report.summary import (
    joint_summary_table,
    model_totals_table,
    summarize,
    summarize_joints,
    summary_table,
)
from vm_ros.report.tables import logged_model_totals
from vm_ros.telemetry import energy_partition


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("log", type=Path, metavar="FILE.mcap", help="run log to recompute")
    parser.add_argument("--dt", type=float, metavar="S", help="model step (default: recorded)")
    add_model_options(parser, "as recorded, with the attached model files")
    add_energetics_option(parser, "as recorded")
    add_output_options(parser, "default beside the input log: <log folder>/<log name>-"
                               "recomputed-<date>-<time>.mcap")


def _start_and_end_ns(run: RunLog, timing: RunTiming) -> tuple[int, int]:
    """Model time of the reset (recorded, else the first force stamp, else the first input) and
    of the last recorded output (else the last input)."""
    force = run.get(tm.TOPIC_FORCE)
    stamps = force.fields["stamp_ns"] if force is not None and len(force) else None
    inputs = [s.time_ns for s in map(run.get, INPUT_TOPICS) if s is not None and len(s)]
    if not inputs:
        raise VmRosError(f"{run.path}: no recorded inputs to recompute from")
    first_input = min(int(t[0]) for t in inputs)
    last_input = max(int(t[-1]) for t in inputs)
    start = timing.start_time_ns
    if start is None:
        start = int(stamps[0]) if stamps is not None else first_input
    end = int(stamps[-1]) if stamps is not None else last_input + timing.dt_ns
    return int(start), end


@dataclass(frozen=True)
class Comparison:
    """One recomputed output against the recorded one at equal model time (header stamps); the
    printed line and the verdict are both made from it.

    | field | meaning |
    | --- | --- |
    | what, unit | e.g. "tendon force", "N" |
    | max_abs | max |recomputed - recorded| over the common stamps (equal NaNs count as equal;
      NaN where they cannot be compared: a NaN on one side, other columns) |
    | common | stamps in both |
    | recorded | recorded stamps |
    """

    what: str
    unit: str
    max_abs: float
    common: int
    recorded: int

    @property
    def equal(self) -> bool:
        return self.common > 0 and self.max_abs == 0.0

    def unequal(self) -> str:
        """Why it is not equal, in words and the same number as ``line``."""
        if not self.common:
            return f"recorded and recomputed {self.what}s share no model time"
        if np.isnan(self.max_abs):
            return f"the {self.what}s cannot be compared (NaN on one side, or other columns)"
        return f"the {self.what}s differ by up to {self.max_abs:.3g} {self.unit}"

    def line(self) -> str:
        if not self.common:
            return self.unequal()
        of = f" (of {self.recorded} recorded)" if self.common < self.recorded else ""
        return (f"{self.what} vs recorded: max |difference| {self.max_abs:.3g} {self.unit} over "
                f"{self.common} samples{of}")


def _difference(run: RunLog, topic: str, what: str, unit: str, sample_times_ns, values,
                names=None) -> Comparison | None:
    """Recomputed ``values`` (n_samples, n) at ``sample_times_ns`` against the efforts recorded
    on ``topic`` at equal stamps (joint columns by ``names``), or None when either is empty."""
    recorded = run.get(topic)
    if recorded is None or not len(recorded) or not len(sample_times_ns):
        return None
    common, mine, theirs = np.intersect1d(sample_times_ns, recorded.fields["stamp_ns"],
                                          return_indices=True)
    found = Comparison(what, unit, float("nan"), len(common), len(recorded))
    theirs_values = recorded.fields["effort"][theirs]
    if names is not None:  # joint columns by name
        if not all(n in (recorded.names or ()) for n in names):
            return found
        theirs_values = theirs_values[:, [recorded.names.index(n) for n in names]]
    if not len(common) or theirs_values.shape != values[mine].shape:
        return found
    difference = np.abs(values[mine] - theirs_values)
    difference[np.isnan(values[mine]) & np.isnan(theirs_values)] = 0.0
    return replace(found, max_abs=float(np.max(difference)))


def compare_outputs(run: RunLog, result) -> list[Comparison]:
    """The recomputed tendon forces (and joint efforts) against the recorded ones."""
    found = [_difference(run, tm.TOPIC_FORCE, "tendon force", "N", result.sample_times_ns,
                         result.force_samples)]
    if len(result.joints):
        found.append(_difference(run, tm.TOPIC_JOINT_EFFORTS, "joint effort", "(N m or N)",
                                 result.sample_times_ns, result.joint_samples[:, 2, :],
                                 result.joints))
    return [f for f in found if f is not None]


def verdict(comparisons: list[Comparison], irregular: list) -> str | None:
    """'exact' when every comparison is equal at every common stamp and the recorded model time
    stayed on the step grid; else 'not exact' and why, from the same comparisons."""
    if not comparisons:
        return None
    unequal = [c for c in comparisons if not c.equal]
    if unequal:
        return "not exact: " + "; ".join(c.unequal() for c in unequal)
    if irregular:
        return ("not exact: equal at every common stamp, but the recorded model time left the "
                "step grid (approximate, above)")
    return "exact: the recomputed outputs equal the recorded ones at every common stamp"


def _joint_geometry(recorded: RunLog, config, node, bank, tmp: Path):
    """(config, joint space or None) of a node-conditioned log with a geometry; the geometry is
    attached to the new log (written to ``tmp`` when the original log named it only in its node
    parameters). Prints a note on stderr when the geometry is read from the recorded path."""
    if node is None:
        return config, None
    space, note = node_joint_space(recorded, bank.names, node)
    if note:
        print(f"vm-ros recompute: {note}", file=sys.stderr)
    if space is not None and config.geometry is None:
        path = tmp / ATTACHMENT_GEOMETRY
        data = recorded.attachments.get(ATTACHMENT_GEOMETRY)
        path.write_bytes(data if data is not None else Path(node.geometry).read_bytes())
        config = config.replace(geometry=path, joint_map=node.joint_map, joints=node.joints)
    return config, space


def _bank_of(config, log_path, attached_dir):
    """The bank of ``config``; a model file attached by an older vm_ros that lacks a field this
    one needs gives a ConfigError that says how to recompute with today's file."""
    try:
        return config.make_bank()
    except ConfigError as error:
        if error.reason != "missing" or not error.path.startswith(str(attached_dir)):
            raise
        raise ConfigError(
            log_path, error.field, None,
            "missing from the model file this log attached (written by an older vm_ros); "
            "--params config/model.yaml recomputes with today's file (add --drive-law "
            "tsianos2012 for a log from before the drive laws, to keep the law it ran with)",
        ) from None


def run(args, on_outcome: Callable[[RunOutcome], None] | None = None) -> int:
    """The verb; ``on_outcome`` (vm_ros.study) gets what the run computed when it succeeded."""
    models = energetics_models_option(args.energetics_models)
    log_path = args.log
    with Progress(f"read {log_path.name}", 1.0, enabled=True if args.progress else None) as p:
        recorded = read_run(log_path, topics=(*INPUT_TOPICS, *COORDINATION_INPUT_TOPICS,
                                              tm.TOPIC_FORCE, tm.TOPIC_JOINT_EFFORTS),
                            raw=(*INPUT_TOPICS, *COORDINATION_INPUT_TOPICS),
                            progress=lambda done, size: p.update(done / max(size, 1)))
    if recorded.info is None:
        raise VmRosError(f"{log_path}: not a vm_ros run log (no 'vm_ros.run' metadata record)")
    info = recorded.info
    if not recorded.complete:
        print(f"vm-ros recompute: {log_path} is cut short ({recorded.stop_reason}); using "
              "what it holds", file=sys.stderr)
    if recorded.skipped:  # copied, not applied: the node dropped them too
        print(f"vm-ros recompute: {recorded.skipped_note()}", file=sys.stderr)
    if recorded.unlisted_note:
        print(f"vm-ros recompute: {recorded.unlisted_note}", file=sys.stderr)
    timing = RunTiming(
        dt_s=args.dt or info.timing.dt_s,
        publish_rate_hz=args.publish_rate or info.timing.publish_rate_hz,
        telemetry_rate_hz=info.timing.telemetry_rate_hz if args.telemetry_rate is None
        else max(args.telemetry_rate, 0.0),
        start_time_ns=info.timing.start_time_ns)
    start_ns, end_ns = _start_and_end_ns(recorded, timing)
    timing = RunTiming(timing.dt_s, timing.publish_rate_hz, timing.telemetry_rate_hz, start_ns)
    n_steps = max(0, (end_ns - start_ns) // timing.dt_ns)
    node = node_config(recorded)
    # the original's other entries (scenario...), but the versions of this run (RunInfo)
    extra = {**{k: v for k, v in info.extra.items() if k != "versions"},
             "recomputed_from": str(log_path)}
    irregular: list = []
    if node is not None:
        extra["input_hold"] = NODE_INPUT_RULE
        irregular = model_time_irregularities(recorded, info.timing.dt_ns,
                                              info.timing.steps_per(info.timing.publish_rate_hz))
    folder, stem = beside(log_path)
    out_path = args.out or default_log_path(f"{stem}-recomputed", folder)
    with tempfile.TemporaryDirectory(prefix="vm_ros-recompute-") as tmp:
        config = apply_model_options(recorded.config(tmp), args)
        if models is not None:
            config = config.replace(energetics_models=models)
        bank = _bank_of(config, log_path, tmp)
        config, space = _joint_geometry(recorded, config, node, bank, Path(tmp))
        new_info = RunInfo(config, timing, "recompute", info.namespace, info.time_base, extra,
                           info.topics)
        # open while the attached files exist: the new log attaches them again
        coordinated = node is not None and node.coordination_enabled
        recorder = open_run_log(out_path, new_info, bank, attachment_time_ns=start_ns,
                                topics=default_log_topics(new_info)
                                + list(COORDINATION_INPUT_TOPICS if coordinated else ()),
                                **recorder_options(args))
    with StopOnSignal() as stop, recorder, Progress(
            f"recompute {log_path.name}", n_steps, enabled=True if args.progress else None) \
            as progress:
        offline = OfflineRun(bank, timing, recorder, new_info.log_topic)
        if node is not None:
            inputs = NodeReplayInputs(recorded, bank, offline.sink, node, space)
        else:
            inputs = RecordedInputs(recorded, bank.n, offline.sink)
        result = offline.run(inputs, n_steps, should_stop=stop, progress=progress.update,
                             publish_start=node is not None,
                             steady_start=info.extra.get(STEADY_START) == "yes")
    status = recorder.status
    print(f"recomputed {result.steps * timing.dt_s:.3f} s of {', '.join(bank.names)} "
          f"({config.recruitment} recruitment, {bank.recovery_mode} recovery)")
    if node is None:
        print("inputs: zero-order hold (the step [t, t + dt) uses the latest input with log "
              "time <= t)")
    else:
        print("inputs: muscle_node conditioning (NodeInputs with the logged node_parameters: "
              f"{node.stale_input_policy} stale policy, extrapolation at most "
              f"{node.extrapolation_max_s:g} s)")
        if irregular:
            print("approximate: the node's model time left its step grid ("
                  + "; ".join(irregular) + "); recomputed on one continuous grid")
    rows = []
    if result.last is not None:
        last = result.last
        rows = summarize(bank.names, result.force_samples,
                         energy_partition(last.energy_by_fibre, last.energy),
                         last.mechanical_work)
        print(summary_table(rows))
    if len(result.joints):
        conditioning = inputs.conditioning
        units = [space.geometry.coordinates[j].unit for j in space.output]
        print(joint_summary_table(summarize_joints(
            result.joints, units, result.joint_samples[:, 2, :], result.joint_work,
            conditioning.clamped[space.output])))
    comparisons = compare_outputs(recorded, result)
    for line in [c.line() for c in comparisons] + [verdict(comparisons, irregular)]:
        if line:
            print(line)
    totals = []
    if bank.energetics_models and status.ok and status.written:
        totals = logged_model_totals(out_path)
        print(model_totals_table(totals, bank.names))
    print(f"log: {shown_log_path(out_path, status.path)} ({status.written} messages, "
          f"{status.bytes_written / 1e6:.2f} MB)")
    if stop.signum:
        print(f"vm-ros recompute: stopped by signal {stop.signum}", file=sys.stderr)
        return stop.exit_code
    if not status.ok:
        print(f"vm-ros recompute: error: {status.error}", file=sys.stderr)
        return 1
    if on_outcome is not None:
        on_outcome(RunOutcome(rows, totals, result.steps * timing.dt_s))
    return 0
