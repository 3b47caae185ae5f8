"""Whether the numbers of a real-time run are valid: the model ran on every step of its time, with
inputs that kept up.

A run of muscle_node in real time is not valid when

- it skipped model time: it fell behind by more than max_catch_up_steps and jumped ahead (its
  /diagnostics ``skipped model time (s)``; or a gap between two consecutive output stamps longer
  than 1.5 publish periods, counted beyond one period, which catches a skip the last diagnostics
  did not report yet); the state then jumps with no steps between, and the forces and torques
  after the jump are not the model's response to the motion;
- an input was applied off its own time by more than INPUT_JITTER_BOUND_S: muscle_node logs each
  input at the model time from which its steps use it (vm_ros.node.input_timeline: its header
  stamp when that is on the node's clock, else its arrival, never before the model time reached),
  so its log time minus its header stamp is how far the model's input timeline sat from the
  publisher's. A constant offset is harmless (a publisher whose stamps are its transport delay
  early); the jitter is its largest departure from the run's median. It grows when samples come
  after the model has passed their stamps (a late publisher, a late delivery, or the node's own
  callbacks held up by a long tick): a drive switch moved by a few ms moves the steep force decay
  after it by hundreds of newtons (path lengths are extrapolated from the stamp, so a late
  kinematics sample costs less). The bound, 20 ms, is two publish periods of the default 100 Hz;
  it was set when the node placed inputs up to a period early, and is kept;
- an input arrived more than ``extrapolation_max_s`` after the previous one (muscle_node's
  parameter, 0.05 s by default) while the model ran: for that long the node extrapolated the
  last sample, then held it, so the model's input left the motion.

How many samples of each input the node placed at their arrival rather than at their stamps
(stamps it could not use: 0, later than the arrival, or older than its input_timeout_s, as a
replayed log's own stamps are) is counted from the log and printed with a note, not as a
failure: such samples carry their delivery delay into the model, and the jitter above measures
that delay's spread, not the samples' departure from their true time (README example 3 printed
a vasti peak 21 % above the offline run's in a run found valid this way; `vm-ros replay
--restamp` stamps them on the replay's clock).

``vm-ros report`` of a muscle_node log prints the same check (node_log_validity) over the time
the node had inputs: from its first output to the last message of its inputs that ended first;
the time after it, when the node ran on stale inputs until it was stopped, is named apart.

Both are facts of the run log (output stamps on model time, inputs on their receipt time) or of
the node's diagnostics, never of when a message reached a monitor. A run that is not valid ends
its command with EXIT_NOT_VALID unless the caller accepts it (``vm-ros demo --accept-skips``),
and its summary says so in either case. Offline runs (``vm-ros simulate``, ``recompute``,
``closed-loop``) step every dt of model time by construction and have no arrival times: there is
nothing to check.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vm_ros import telemetry as tm
from vm_ros import topics as tp
from vm_ros.recording.run_log import (
    INPUT_TIME_KEY,
    INPUT_TIME_STAMPED,
    NODE_SOURCE,
    logged_node_parameters,
    stamp_on_clock,
)

EXIT_NOT_VALID = 3  # exit status of a real-time command whose run is not valid
GAP_PERIODS = 1.5  # an output gap longer than this many publish periods is skipped model time
DEFAULT_INPUT_BOUND_S = 0.05  # muscle_node's default extrapolation_max_s
INPUT_JITTER_BOUND_S = 0.02  # s, two default publish periods (module docstring)


def skipped_from_stamps(stamps_ns) -> float:
    """Model time (s) missing between consecutive output stamps: each gap longer than
    GAP_PERIODS times the median gap counts beyond one median gap."""
    stamps = np.asarray(stamps_ns, dtype=np.int64)
    if len(stamps) < 3:
        return 0.0
    gaps = np.diff(stamps)
    period = float(np.median(gaps))
    late = gaps[gaps > GAP_PERIODS * period]
    return float((late - period).sum() * 1e-9)


@dataclass(frozen=True)
class InputTiming:
    """One input of a run while the model ran: its largest interval between two messages and
    its jitter (module docstring), s, NaN when not known; of its ``messages``, how many the node
    placed at their arrival (-1: not known)."""

    topic: str
    gap_s: float
    jitter_s: float
    messages: int = 0
    at_arrival: int = -1


def input_timing(topic: str, log_ns, stamp_ns, start_ns: int, end_ns: int,
                 stamp_timeout_ns: int | None = None) -> InputTiming:
    """InputTiming of the messages of ``topic`` logged (``log_ns``, the model time that applied
    them) from ``start_ns`` to ``end_ns``, with header stamps ``stamp_ns`` (None or all zero:
    jitter not known); the interval before the first and after the last count as gaps. With
    the node's input_timeout_s (``stamp_timeout_ns``), the messages placed at their arrival are
    counted (recording.run_log.stamp_on_clock)."""
    log = np.asarray(log_ns, dtype=np.int64)
    inside = (log >= start_ns) & (log <= end_ns)
    if not inside.any():
        return InputTiming(topic, float("nan"), float("nan"))
    edges = np.concatenate([[start_ns], log[inside], [end_ns]])
    gap = float(np.diff(edges).max() * 1e-9)
    jitter, at_arrival = float("nan"), -1
    if stamp_ns is not None:
        stamps = np.asarray(stamp_ns, dtype=np.int64)[inside]
        if np.all(stamps > 0):
            lag = (log[inside] - stamps) * 1e-9
            jitter = float(np.abs(lag - np.median(lag)).max())
        if stamp_timeout_ns is not None:
            at_arrival = int(np.count_nonzero(~stamp_on_clock(stamps, log[inside],
                                                               stamp_timeout_ns)))
    return InputTiming(topic, gap, jitter, int(np.count_nonzero(inside)), at_arrival)


@dataclass(frozen=True)
class Validity:
    """| field | unit |
    | skipped_s | s, model time skipped (the larger of the node's count and the stamp gaps) |
    | inputs | InputTiming per input checked (() when the run's inputs are not known) |
    | gap_bound_s | s, bound on an input's gap (muscle_node's extrapolation_max_s) |
    """

    skipped_s: float
    inputs: tuple = ()
    gap_bound_s: float = DEFAULT_INPUT_BOUND_S

    @property
    def problems(self) -> list[str]:
        found = []
        if self.skipped_s > 0:
            found.append(f"muscle_node skipped {self.skipped_s:.3g} s of model time")
        for timing in self.inputs:
            if timing.jitter_s > INPUT_JITTER_BOUND_S:
                found.append(f"{timing.topic} applied up to {1e3 * timing.jitter_s:.0f} ms off "
                             f"its time (bound {1e3 * INPUT_JITTER_BOUND_S:.0f} ms)")
            if timing.gap_s > self.gap_bound_s:
                found.append(f"{timing.topic} arrived {timing.gap_s:.3g} s apart (bound: "
                             f"muscle_node's extrapolation_max_s, {self.gap_bound_s:g} s)")
        return found

    @property
    def valid(self) -> bool:
        return not self.problems

    def lines(self, accepted: bool | None) -> list[str]:
        """The summary's closing lines: what was checked, and a verdict when not valid
        (``accepted``: --accept-skips; None: a report of a finished log, no exit status)."""
        checked = [f"{t.topic} jitter {1e3 * t.jitter_s:.0f} ms (bound "
                   f"{1e3 * INPUT_JITTER_BOUND_S:.0f}), largest gap {1e3 * t.gap_s:.0f} ms "
                   f"(bound {1e3 * self.gap_bound_s:.0f})" for t in self.inputs]
        lines = [f"validity: skipped model time {self.skipped_s:.3g} s; "
                 + ("; ".join(checked) if checked else
                    "input timing not checked (no log of the inputs: --no-mcap)")]
        arrival = [f"{t.topic} {t.at_arrival} of {t.messages}" for t in self.inputs
                   if t.at_arrival > 0]
        if arrival:
            lines.append("note: placed at their arrival, not at their stamps (0, later than the "
                         "arrival or older than the node's input_timeout_s): "
                         + ", ".join(arrival) + "; they carry their delivery delay into the "
                         "model, which the jitter does not show (a path length a few ms off "
                         "its time moves the tendon force by up to hundreds of newtons): stamp "
                         "inputs on the node's clock (a replay: vm-ros replay --restamp)")
        if not self.valid:
            lines.append("NOT VALID: " + "; ".join(self.problems) + ". The numbers above are "
                         "not the model's response to the intended inputs (CPU starved: rerun "
                         "on an idle machine)"
                         + ("" if accepted is None else "; accepted (--accept-skips)"
                            if accepted else
                            f"; exit status {EXIT_NOT_VALID} (--accept-skips: 0)"))
        return lines

    def exit_status(self, accepted: bool) -> int:
        return 0 if self.valid or accepted else EXIT_NOT_VALID


def run_validity(stamps_ns, diagnostics_skipped_s: float, inputs=(),
                 gap_bound_s: float = DEFAULT_INPUT_BOUND_S,
                 stamp_timeout_ns: int | None = None) -> Validity:
    """Validity of a run from its output stamps (ns, model time), the node's own count of
    skipped time (s; NaN when not known) and its inputs: (topic, log times ns, header stamps ns
    or None) each, checked over the span of the outputs; ``stamp_timeout_ns``: input_time's
    timeout (input_timing)."""
    stamps = np.asarray(stamps_ns, dtype=np.int64)
    skipped = max(skipped_from_stamps(stamps), np.nan_to_num(diagnostics_skipped_s, nan=0.0))
    timings = tuple(input_timing(topic, log, stamp, int(stamps[0]), int(stamps[-1]),
                                 stamp_timeout_ns)
                    for topic, log, stamp in inputs) if len(stamps) else ()
    return Validity(float(skipped), timings, float(gap_bound_s))


def node_diagnostics(run) -> list[dict]:
    """muscle_node's /diagnostics values (key -> text) logged in ``run``, in order."""
    series = run.get(tm.TOPIC_DIAGNOSTICS)
    return [{kv.key: kv.value for kv in status.values}
            for msg in ((series.messages or []) if series is not None else [])
            for status in msg.status if status.hardware_id == "vm_ros"]


def node_input_losses(run) -> dict:
    """Input topic -> messages muscle_node counted lost on it (its last /diagnostics; topics
    with none left out)."""
    diagnostics = node_diagnostics(run)
    if not diagnostics:
        return {}
    lost = {row.name: diagnostics_number(diagnostics[-1], tp.lost_key(row.name))
            for row in tp.INPUT_TOPICS}
    return {topic: int(n) for topic, n in lost.items() if n > 0}


def diagnostics_number(diagnostics: dict, key: str) -> float:
    """A /diagnostics value as a number (NaN when missing or not a number)."""
    try:
        return float(diagnostics.get(key, "nan"))
    except ValueError:
        return float("nan")


def logged_inputs(run) -> list:
    """(topic, log times ns, header stamps ns or None) of each input topic
    (vm_ros.topics.INPUT_TOPICS) that ``run`` holds messages of: run_validity's inputs."""
    return [(row.name, s.time_ns, s.fields.get("stamp_ns")) for row in tp.INPUT_TOPICS
            if (s := run.get(row.name)) is not None and len(s)]


def logged_gap_bound(run) -> float:
    """The input gap bound of a muscle_node log: its extrapolation_max_s (s), else the
    default's."""
    return float((logged_node_parameters(run) or {}).get("extrapolation_max_s",
                                                          DEFAULT_INPUT_BOUND_S))


def logged_stamp_timeout_ns(run) -> int | None:
    """The input_timeout_s (ns) with which a muscle_node log placed its inputs at their stamps
    (its INPUT_TIME_KEY), None for a log that did not (written before) or holds no such
    parameter."""
    timeout = (logged_node_parameters(run) or {}).get("input_timeout_s")
    if run.info.extra.get(INPUT_TIME_KEY) != INPUT_TIME_STAMPED or timeout is None:
        return None
    return int(round(float(timeout) * 1e9))


def node_log_validity(run) -> tuple[Validity, float] | None:
    """(Validity, s the node ran after its inputs ended) of a muscle_node run log, checked
    over its muscle_force stamps up to the last message of the input that ended first
    (module docstring); None for a log muscle_node did not write (offline runs step every dt,
    and those that condition their inputs as the node does, `simulate --motion` and `recompute`
    of a node log, hold its parameters too) or one with fewer than 2 outputs or no inputs."""
    forces = run.get(tm.TOPIC_FORCE)
    inputs = logged_inputs(run)
    written_by_node = run.info is not None and run.info.source == NODE_SOURCE
    if not written_by_node or forces is None or len(forces) < 2 or not inputs:
        return None
    stamps = np.sort(np.asarray(forces.time_ns, dtype=np.int64))
    inputs_end = min(int(np.max(log)) for _, log, _ in inputs)
    live = stamps[stamps <= inputs_end]
    if len(live) < 2:
        return None
    diagnostics = node_diagnostics(run)
    skipped = (diagnostics_number(diagnostics[-1], "skipped model time (s)") if diagnostics
               else float("nan"))
    return (run_validity(live, skipped, inputs, logged_gap_bound(run),
                         logged_stamp_timeout_ns(run)),
            float((stamps[-1] - live[-1]) * 1e-9))


__all__ = ["DEFAULT_INPUT_BOUND_S", "EXIT_NOT_VALID", "INPUT_JITTER_BOUND_S", "InputTiming",
           "Validity", "diagnostics_number", "input_timing", "logged_gap_bound", "logged_inputs",
           "logged_stamp_timeout_ns",
           "node_diagnostics", "node_input_losses", "node_log_validity", "run_validity",
           "skipped_from_stamps"]
