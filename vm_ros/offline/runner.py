"""Running a muscle bank offline, logged as muscle_node logs it: `vm-ros simulate` and
`vm-ros recompute` share this loop.

    run = OfflineRun(bank, timing, recorder)
    result = run.run(inputs, n_steps)        # inputs: SampledInputs, RecordedInputs,
                                             # vm_ros.node.replay.NodeReplayInputs or
                                             # motion_inputs.MotionInputs

Step k covers model time [t_k, t_k + dt) with t_k = start + k dt (integer ns). Inputs follow the
run log's zero-order hold: the step uses the latest input with log_time <= t_k. Outputs
(muscle_force, energy_rate, energy_rate_total, energy_total and, for a bank with energetics
models, energy_rate_models) are written every
``timing.steps_per(publish_rate_hz)`` steps and telemetry every
``timing.steps_per(telemetry_rate_hz)`` steps, stamped and logged at the end of the step. The
bank starts at rest (or, with ``steady_start``, with its activation at the steady state of the
first drive), at static equilibrium for the path length held at the start time; with
``publish_start`` (as muscle_node does) that initial state is published too, at the start time.

Inputs with a ``joint_efforts(force)`` method (joint space: NodeReplayInputs, MotionInputs) also
give joint_efforts and joint_effort_commands with every output, the step's tendon forces through
the moment arms of the joint sample the step used; the joint work is summed step by step
(tau . qdot dt, robot convention, with the joint velocities of that sample) and logged with
every output on joint_work (cumulative, J per joint): the one joint work every summary prints.

The run goes by blocks: the inputs of a few thousand steps are taken at once
(SampledInputs.block, RecordedInputs.block and MotionInputs.block take them and build their
messages in bulk; other inputs are advanced step by step with their messages held back), one
MuscleBank.run steps the bank over the block keeping the state at every publish or telemetry
tick (snapshot_every), the joint efforts of every step come at once from the inputs'
``block_efforts`` (joint space: MotionInputs), the messages of the block are built in bulk from
those arrays (vm_ros.recording.bulk) in the order the step-by-step loop writes them, and handed
to the recorder as one block (write_block: whole chunks, no call per message). A block is
built and handed over in parts of PART_STEPS steps (write_block's ``more``: the chunks are those
of the whole block), so that the writer thread compresses a part while the next is built. The
log is the same message for message (``block_steps=0`` runs the step-by-step loop, the reference
kept for the tests and for inputs with joint efforts but no ``block_efforts``: a node log's
replay); a stop request is seen between parts (at most 1e6 muscle-steps), not between steps.
"""

from __future__ import annotations

import itertools
import math
import operator
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from vm_ros import telemetry as tm
from vm_ros import topics as tp
from vm_ros.model import MuscleBank, StepOutput
from vm_ros.recording import bulk
from vm_ros.recording import messages as msgs
from vm_ros.recording.cdr import serialize
from vm_ros.recording.run_log import (
    RunLog,
    RunLogError,
    RunTiming,
    resolve_topic,
)
from vm_ros.recording.writer import McapRecorder

# metadata entry of a run that starts at the steady state of its first drive (value "yes")
STEADY_START = "steady_start"
_RETRY_S = 0.001
_RETRIES = 5000  # an offline run waits up to 5 s for room in the recorder queue, then drops
# messages handed to the recorder and not yet written before another block is handed over (a
# block of BLOCK_STEPS steps of the knee extension holds 12,500): the run steps on while the
# writer thread compresses, and the queue (20 000 entries by default) never fills
_IN_FLIGHT = 40000
# steps whose messages are one block of the log (McapRecorder.write_block: the block's last
# chunk ends with it)
BLOCK_STEPS = 5000
# steps whose inputs are taken, and messages built, at once: a block goes to the writer in parts
# of this many steps (write_block's more), so that the writer thread compresses a part while the
# run builds the next, and only the last part is left to write at the end of the run
PART_STEPS = 1000
# at most this many muscle-steps per block (one MuscleBank.run): a stop request (Ctrl-C) waits
# for the block, about 1 s at 1000 muscles
_BLOCK_MUSCLE_STEPS = 1_000_000
# order of the messages written at one step (stepwise loop): inputs after outputs
INPUT_RANK, _OUTPUT_RANK = 10, 0
_OUTPUT_ORDER = {tm.TOPIC_FORCE: 0, tm.TOPIC_ENERGY_RATE: 1, tm.TOPIC_ENERGY_RATE_TOTAL: 2,
                 tm.TOPIC_ENERGY_TOTAL: 3, tm.TOPIC_ENERGY_RATE_MODELS: 4,
                 tm.TOPIC_JOINT_EFFORTS: 5, tm.TOPIC_JOINT_EFFORT_COMMANDS: 6,
                 tm.TOPIC_JOINT_WORK: 7, msgs.TOPIC_TELEMETRY: 8}
# with published energetics models a block holds their rates, M x 5 values per muscle-step
# (MuscleBank.run): blocks of at most this many muscle-step-values of them (about 80 MB)
_BLOCK_MODEL_VALUES = 10_000_000


class LogSink:
    """Serialises field dicts and hands them (or recorded bytes) to a recorder. Offline nothing
    is real time, so a full queue is waited for instead of dropping. While ``pending`` is set
    (OfflineRun's blocks) messages are held there, at the current ``slot``, instead."""

    def __init__(self, recorder: McapRecorder | None,
                 log_topic: Callable[[str], str] = resolve_topic):
        self.recorder = recorder
        self.log_topic = log_topic
        self.pending: _Pending | None = None
        self.slot = 0
        self._topics: dict[str, str] = {}
        self._sent = 0

    def write_fields(self, topic: str, type_name: str, fields: dict, time_ns: int) -> None:
        if self.recorder is not None:
            self.write_bytes(topic, serialize(type_name, fields), time_ns)

    def write_bytes(self, topic: str, data: bytes, time_ns: int) -> None:
        if self.pending is not None:
            self.pending.add_one(self.slot * 16 + INPUT_RANK, topic, data, time_ns)
            return
        if self.recorder is None:
            return
        self._write(self._full(topic), data, time_ns)

    def write_many(self, topics, data, times_ns, more: bool = False) -> None:
        """Write messages in the given order (topics: base names) as one block of the recorder
        (McapRecorder.write_block; ``more``: a part of a block, the next part to come), once
        fewer than _IN_FLIGHT messages wait for it."""
        if self.recorder is None or not len(data):
            return
        names = {topic: self._full(topic) for topic in set(topics)}
        full = list(map(names.__getitem__, topics))
        self._wait_for_room()
        for _ in range(_RETRIES):
            if self.recorder.write_block(full, data, times_ns, more=more):
                self._sent += len(data)
                return
            if not self.recorder.status.ok:
                return
            time.sleep(_RETRY_S)

    def _full(self, topic: str) -> str:
        name = self._topics.get(topic)
        if name is None:
            name = self._topics[topic] = self.log_topic(topic)
        return name

    def _wait_for_room(self) -> None:
        for _ in range(_RETRIES):
            status = self.recorder.status
            if not status.ok or self._sent - status.written <= _IN_FLIGHT:
                return
            time.sleep(_RETRY_S)

    def _write(self, full: str, data: bytes, time_ns: int) -> None:
        for _ in range(_RETRIES):
            if self.recorder.write(full, data, time_ns):
                self._sent += 1
                return
            if not self.recorder.status.ok:
                return
            time.sleep(_RETRY_S)


class _Pending:
    """Messages of one block with their sort keys (slot * 16 + rank + order in the slot), held
    as groups in the order added (a group: keys, topics, data and times of its messages), so
    that ``flush`` puts them in key order with a few whole-list operations instead of Python
    work per message."""

    def __init__(self):
        self._groups: list = []  # (keys (k,) int64, topics [k], data [k], times (k,) int64)
        self._loose: tuple = ([], [], [], [])  # messages added one by one, not yet a group

    def add_one(self, key: int, topic: str, data: bytes, time_ns: int) -> None:
        for items, item in zip(self._loose, (key, topic, data, time_ns), strict=True):
            items.append(item)

    def add_each(self, keys, topics: list, data: list, times_ns) -> None:
        """Messages each with its own topic."""
        self._close_loose()
        self._groups.append((np.asarray(keys, dtype=np.int64), list(topics), list(data),
                             np.asarray(times_ns, dtype=np.int64)))

    def add(self, keys, topic: str, data: list, times_ns) -> None:
        self.add_each(keys, [topic] * len(data), data, times_ns)

    def _close_loose(self) -> None:
        if self._loose[0]:
            keys, topics, data, times = self._loose
            self._loose = ([], [], [], [])
            self.add_each(keys, topics, data, times)

    def _joined(self, part: int) -> list:
        self._close_loose()
        return list(itertools.chain.from_iterable(group[part] for group in self._groups))

    @property
    def keys(self) -> list:
        return np.asarray(self._joined(0), dtype=np.int64).tolist()

    @property
    def topics(self) -> list:
        return self._joined(1)

    @property
    def data(self) -> list:
        return self._joined(2)

    @property
    def times(self) -> list:
        return np.asarray(self._joined(3), dtype=np.int64).tolist()

    def flush(self, sink: LogSink, steps: int, more: bool = False) -> None:
        """Write in key order (stable) what the stepwise loop writes in ``steps`` steps (the
        outputs at the end of the last one, not the inputs of the next), drop the rest;
        ``more``: a part of a log block (LogSink.write_many)."""
        self._close_loose()
        if self._groups:
            keys = np.concatenate([group[0] for group in self._groups])
            order = np.argsort(keys, kind="stable")
            order = order[keys[order] < steps * 16 + INPUT_RANK]
            times = np.concatenate([group[3] for group in self._groups])[order]
            sink.write_many(_pick(self._joined(1), order), _pick(self._joined(2), order), times,
                            more)
        self.__init__()


def _pick(items: list, order: np.ndarray) -> list:
    """``[items[i] for i in order]`` in one call."""
    if len(order) < 2:
        return [items[i] for i in order.tolist()]
    return list(operator.itemgetter(*order.tolist())(items))


class SampledInputs:
    """Inputs from functions of time (s) -> (n,) arrays, sampled every ``period_ns`` from
    ``start_ns`` and logged as the excitation and muscle_kinematics messages."""

    def __init__(self, names, excitation, path_length, path_velocity, period_ns: int,
                 start_ns: int, sink: LogSink):
        self.names = tuple(names)
        self._functions = (excitation, path_length, path_velocity)
        self.period_ns = int(period_ns)
        self._next_ns = int(start_ns)
        self._start_ns = int(start_ns)
        self._sink = sink
        self._held = None

    def _sample(self, time_ns: int):
        return tuple(array[0] for array in self._sample_many([time_ns]))

    def _sample_many(self, times_ns) -> list:
        """[U, path length, path velocity] at each of ``times_ns``, (k, n) each. A function
        called with the array of times (s) that gives (k, n) is taken at once (the built-in
        scenarios and input files do); otherwise it is called at each time, and a value of
        shape () or (n,) is the same for every muscle."""
        n = len(self.names)
        times_s = (np.asarray(times_ns, dtype=np.int64) - self._start_ns) * 1e-9
        arrays = []
        for function in self._functions:
            try:
                at_once = np.asarray(function(times_s), dtype=float)
            except (TypeError, ValueError):  # a function of one time only
                at_once = None
            if at_once is not None and at_once.shape == (len(times_s), n):
                arrays.append(np.ascontiguousarray(at_once))
                continue
            values = [function(t) for t in times_s.tolist()]
            try:
                stacked = np.array(values, dtype=float)
            except ValueError:  # values of different shapes: each broadcast to the muscles
                stacked = np.array([np.asarray(v, dtype=float) * np.ones(n) for v in values])
            if stacked.ndim == 1:
                stacked = stacked[:, None]
            # times ones (exact), broadcast to the muscles
            arrays.append(np.ascontiguousarray(np.broadcast_to(stacked, (len(values), n))))
        return arrays

    def advance_to(self, time_ns: int):
        """(U, path length, path velocity) held at ``time_ns``; logs the samples taken."""
        while self._next_ns <= time_ns:
            u, lp, vp = self._sample(self._next_ns)
            self._sink.write_fields(tm.TOPIC_EXCITATION, tm.TYPE_JOINT_STATE,
                                    msgs.excitation_fields(self.names, u, self._next_ns),
                                    self._next_ns)
            self._sink.write_fields(tm.TOPIC_KINEMATICS, tm.TYPE_JOINT_STATE,
                                    msgs.kinematics_fields(self.names, lp, vp, self._next_ns),
                                    self._next_ns)
            self._held = (u, lp, vp)
            self._next_ns += self.period_ns
        return self._held

    def block(self, step_starts_ns: np.ndarray, first_step: int, pending: _Pending):
        """advance_to for every step start of ``step_starts_ns`` (increasing), at once: the
        inputs held over each step, (k, n) each; the samples' messages go to ``pending`` at the
        step that takes them (``first_step`` + index)."""
        samples = np.zeros(0, dtype=np.int64)
        rows = [np.array([held]) for held in self._held]
        last = int(step_starts_ns[-1])
        if self._next_ns <= last:
            count = (last - self._next_ns) // self.period_ns + 1
            samples = self._next_ns + self.period_ns * np.arange(count, dtype=np.int64)
            taken = self._sample_many(samples)
            slots = first_step + np.searchsorted(step_starts_ns, samples, side="left")
            n = len(self.names)
            excitation = bulk.joint_state_layout(self.names, position=n)
            kinematics = bulk.joint_state_layout(self.names, position=n, velocity=n)
            pending.add(slots * 16 + INPUT_RANK, tm.TOPIC_EXCITATION,
                        excitation.encode(samples, position=taken[0]), samples)
            pending.add(slots * 16 + INPUT_RANK + 1, tm.TOPIC_KINEMATICS,
                        kinematics.encode(samples, position=taken[1], velocity=taken[2]),
                        samples)
            rows = [np.concatenate([row, array]) for row, array in zip(rows, taken,
                                                                       strict=True)]
            self._held = tuple(array[-1] for array in taken)
            self._next_ns += count * self.period_ns
        index = np.searchsorted(samples, step_starts_ns, side="right")  # 0: held before
        return tuple(row[index] for row in rows)


class RecordedInputs:
    """The input messages of a run log, applied in log-time order under the zero-order hold and
    copied verbatim (same bytes and times) to ``sink``; messages that did not decode are copied
    but not applied.

    Per muscle, by name (or by position for excitation_array and name-less messages): a finite
    drive replaces the held drive; a finite positive path length replaces the held length and
    its velocity (0 when the message has none). Other values leave the held input as it was.
    Before the first excitation the drive is 0. The run needs a kinematics message; if none is
    at or before the start time, the first one is used from the start. joint_states need the
    node's conditioning (vm_ros.node.replay): a log with them is a RunLogError here.
    """

    def __init__(self, run: RunLog, n_muscles: int, sink: LogSink):
        self._sink = sink
        self.u = np.zeros(n_muscles)
        self.lp = np.full(n_muscles, np.nan)
        self.vp = np.zeros(n_muscles)
        # how each role's values are held: one message (_apply) and a block of them (block);
        # joint inputs need the node's conditioning (vm_ros.node.replay)
        self._hold = {tp.DRIVE: self._hold_drive, tp.PATH: self._hold_path}
        self._hold_block = {tp.DRIVE: self._drive_block, tp.PATH: self._path_block}
        for row in tp.INPUT_TOPICS:
            series = run.get(row.name)
            if row.role not in self._hold and series is not None and len(series):
                raise RunLogError(run.path, f"{row.name} without node_parameters: the joint "
                                            "conditioning of this log is not known")
        self._events = run.event_table(tp.input_topic_names())
        self._next = 0
        kinematics = run.get(tm.TOPIC_KINEMATICS)
        if kinematics is None or len(kinematics) == 0:
            raise RunLogError(run.path, f"no {tm.TOPIC_KINEMATICS} messages to run from")
        self._first_kinematics = kinematics

    @property
    def last_time_ns(self) -> int:
        return int(self._events.time_ns[-1]) if len(self._events) else 0

    def _apply(self, topic: str, series, i: int) -> None:
        row = tp.input_topic(topic)
        self._hold[row.role](*(series.fields[field][i] for field in row.fields))

    def _hold_drive(self, u) -> None:
        if u.shape == self.u.shape:
            ok = np.isfinite(u)
            self.u[ok] = u[ok]

    def _hold_path(self, lp, vp) -> None:
        ok = np.isfinite(lp) & (lp > 0)
        self.lp[ok] = lp[ok]
        self.vp[ok] = np.where(np.isfinite(vp[ok]), vp[ok], 0.0)

    def advance_to(self, time_ns: int):
        while (self._next < len(self._events)
               and self._events.time_ns[self._next] <= time_ns):
            event = self._events.event(self._next)
            if event.series is not None:  # a message that did not decode changes nothing
                self._apply(event.topic, event.series, event.index)
            if event.data is not None:
                self._sink.write_bytes(event.topic, event.data, event.time_ns)
            self._next += 1
        if np.any(np.isnan(self.lp)):
            first = self._first_kinematics.fields["position"][0]
            self.lp = np.where(np.isnan(self.lp), first, self.lp)
        return self.u.copy(), self.lp.copy(), self.vp.copy()


    def block(self, step_starts_ns: np.ndarray, first_step: int, pending: _Pending):
        """advance_to for every step start of ``step_starts_ns`` (increasing), at once: the
        inputs held over each step, (k, n) each; the messages applied by each step go to
        ``pending`` at that step (``first_step`` + index), in event order. The updates of
        each muscle are carried forward over the events (the latest one that applies wins)."""
        table, begin = self._events, self._next
        end = int(np.searchsorted(table.time_ns, step_starts_ns[-1], side="right"))
        times = table.time_ns[begin:end]
        topic, index = table.topic[begin:end], table.index[begin:end]
        slots = first_step + np.searchsorted(step_starts_ns, times, side="left")
        data = table.data[begin:end]
        kept = [k for k, item in enumerate(data) if item is not None]
        pending.add_each(slots[kept] * 16 + INPUT_RANK, [table.names[t] for t in
                                                          topic[kept].tolist()],
                         [data[k] for k in kept], times[kept])
        applied = np.searchsorted(times, step_starts_ns, side="right")  # events per step
        n, count = len(self.u), end - begin
        u_new, lp_new, vp_new = (np.full((count, n), np.nan) for _ in range(3))
        for order, name in enumerate(table.names):
            chosen = np.flatnonzero((topic == order) & (index >= 0))
            if not len(chosen):
                continue
            row = tp.input_topic(name)
            series = table.series[order]
            self._hold_block[row.role]((u_new, lp_new, vp_new), chosen,
                                       *(series.fields[field][index[chosen]]
                                         for field in row.fields))
        u = _carried(u_new, ~np.isnan(u_new), applied, self.u)
        updated = ~np.isnan(lp_new)
        lp = _carried(lp_new, updated, applied, self.lp)
        vp = _carried(vp_new, updated, applied, self.vp)
        if np.any(np.isnan(lp)):
            lp = np.where(np.isnan(lp), self._first_kinematics.fields["position"][0], lp)
        self._next = end
        self.u, self.lp, self.vp = u[-1].copy(), lp[-1].copy(), vp[-1].copy()
        return u, lp, vp

    def _drive_block(self, new, chosen, drive) -> None:
        """block's _hold_drive: the drives of the messages ``chosen`` into their rows of new[0]
        (NaN: not updated); drives of another size are ignored, as _hold_drive ignores them."""
        if drive.shape[1:] == (len(self.u),):
            new[0][chosen] = np.where(np.isfinite(drive), drive, np.nan)

    def _path_block(self, new, chosen, length, velocity) -> None:
        """block's _hold_path: path lengths and velocities into new[1] and new[2]."""
        ok = np.isfinite(length) & (length > 0)
        new[1][chosen] = np.where(ok, length, np.nan)
        new[2][chosen] = np.where(ok, np.where(np.isfinite(velocity), velocity, 0.0), np.nan)


def _carried(new, updated, applied, held) -> np.ndarray:
    """Per step (k, n): the latest of the first ``applied[j]`` rows of ``new`` where
    ``updated``, per column, else ``held``."""
    count, n = new.shape
    if count == 0:
        return np.tile(held, (len(applied), 1))
    latest = np.where(updated, np.arange(count)[:, None], -1)
    latest = np.maximum.accumulate(latest, axis=0)
    rows = latest[np.maximum(applied - 1, 0)]  # (k, n)
    rows[applied == 0] = -1
    values = new[np.maximum(rows, 0), np.arange(n)[None, :]]
    return np.where(rows >= 0, values, held[None, :])


@dataclass
class OfflineResult:
    """| field | meaning |
    | steps | model steps taken |
    | end_time_ns | model time after the last step |
    | last | StepOutput of the last step (None if none) |
    | sample_times_ns | (k,) model times of the publish ticks |
    | force_samples | (k, n) tendon force (N) at the publish ticks |
    | interrupted | True when should_stop ended the run early |
    | joints | robot joint names of joint_efforts (() without a geometry) |
    | joint_samples | (k, 3, n_joints) position, velocity and effort of joint_efforts at the
      publish ticks (rad or m, rad/s or m/s, N m or N) |
    | joint_work | (n_joints,) J, sum over the steps of tau qdot dt |
    """

    steps: int
    end_time_ns: int
    last: StepOutput | None
    sample_times_ns: np.ndarray
    force_samples: np.ndarray
    interrupted: bool
    joints: tuple = ()
    joint_samples: np.ndarray = field(default_factory=lambda: np.zeros((0, 3, 0)))
    joint_work: np.ndarray = field(default_factory=lambda: np.zeros(0))


class OfflineRun:
    """Steps ``bank`` with ``timing`` and logs its outputs to ``recorder`` (None: no log) under
    the topic names ``log_topic`` gives (RunInfo.log_topic)."""

    def __init__(self, bank: MuscleBank, timing: RunTiming, recorder: McapRecorder | None,
                 log_topic: Callable[[str], str] = resolve_topic):
        self.bank = bank
        self.timing = timing
        self.sink = LogSink(recorder, log_topic)

    def _publish(self, out: StepOutput, time_ns: int, efforts=None, joint_work=None) -> None:
        names, write = self.bank.names, self.sink.write_fields
        write(tm.TOPIC_FORCE, tm.TYPE_JOINT_STATE, tm.force_fields(out, names, time_ns), time_ns)
        write(tm.TOPIC_ENERGY_RATE, tm.TYPE_FLOAT64_MULTI_ARRAY, tm.energy_rate_fields(out),
              time_ns)
        write(tm.TOPIC_ENERGY_RATE_TOTAL, tm.TYPE_FLOAT64,
              msgs.float64_fields(out.total_energy_rate), time_ns)
        write(tm.TOPIC_ENERGY_TOTAL, tm.TYPE_FLOAT64, msgs.float64_fields(out.total_energy),
              time_ns)
        if self.bank.energetics_models:
            write(tm.TOPIC_ENERGY_RATE_MODELS, tm.TYPE_FLOAT64_MULTI_ARRAY,
                  tm.energy_rate_models_fields(out, names, self.bank.energetics_models), time_ns)
        if efforts is not None:
            write(tm.TOPIC_JOINT_EFFORTS, tm.TYPE_JOINT_STATE,
                  tm.joint_efforts_fields(efforts, time_ns), time_ns)
            write(tm.TOPIC_JOINT_EFFORT_COMMANDS, tm.TYPE_FLOAT64_MULTI_ARRAY,
                  tm.joint_effort_commands_fields(efforts), time_ns)
            write(tm.TOPIC_JOINT_WORK, tm.TYPE_FLOAT64_MULTI_ARRAY,
                  tm.joint_work_fields(joint_work), time_ns)

    def run(self, inputs, n_steps: int, should_stop: Callable[[], bool] = lambda: False,
            progress: Callable[[int, int], None] | None = None,
            publish_start: bool = False, block_steps: int = BLOCK_STEPS,
            steady_start: bool = False) -> OfflineResult:
        """Step ``n_steps`` from the timing's start; ``block_steps`` 0 runs the step-by-step
        loop (also used for inputs with joint efforts but no ``block_efforts``), else blocks of
        about that many steps;
        ``steady_start``: the activation starts at the steady state of the first drive instead
        of at rest (STEADY_START in a log's metadata; `vm-ros coordinate`'s runs)."""
        t = self.timing
        start = int(t.start_time_ns or 0)
        u, lp, _ = inputs.advance_to(start)
        initial = self.bank.reset(path_length=lp, time_s=start * 1e-9,
                                  excitation=u if steady_start else None)
        joint_efforts = getattr(inputs, "joint_efforts", None)
        joints = _JointRecord(t.dt_s)
        forces, times = [], []
        if publish_start and t.steps_per(t.publish_rate_hz):
            efforts = joint_efforts(initial.force) if joint_efforts is not None else None
            self._publish(initial, start, efforts, joints.work_so_far(efforts))
            joints.sample(efforts)
            forces.append(initial.force.copy())
            times.append(start)
        if block_steps > 0 and (joint_efforts is None or hasattr(inputs, "block_efforts")):
            steps, out, interrupted = self._run_blocks(inputs, n_steps, should_stop, progress,
                                                       block_steps, forces, times,
                                                       joints if joint_efforts else None)
        else:
            steps, out, interrupted = self._run_stepwise(inputs, n_steps, should_stop, progress,
                                                         joint_efforts, joints, forces, times)
        force_samples = np.array(forces) if forces else np.zeros((0, self.bank.n))
        return OfflineResult(steps, start + steps * t.dt_ns, out,
                             np.array(times, dtype=np.int64), force_samples, interrupted,
                             *joints.result())

    def _run_stepwise(self, inputs, n_steps, should_stop, progress, joint_efforts, joints,
                      forces, times):
        t = self.timing
        dt_ns, start = t.dt_ns, int(t.start_time_ns or 0)
        per_publish, per_telemetry = t.steps_per(t.publish_rate_hz), t.steps_per(
            t.telemetry_rate_hz)
        out, k = None, 0
        for k in range(n_steps):
            if should_stop():
                return k, out, True
            u, lp, vp = inputs.advance_to(start + k * dt_ns)
            out = self.bank.step(t.dt_s, u, lp, vp)
            end_ns = start + (k + 1) * dt_ns
            efforts = joint_efforts(out.force) if joint_efforts is not None else None
            joints.step(efforts)
            if per_publish and (k + 1) % per_publish == 0:
                self._publish(out, end_ns, efforts, joints.work_so_far(efforts))
                joints.sample(efforts)
                forces.append(out.force.copy())
                times.append(end_ns)
            if per_telemetry and (k + 1) % per_telemetry == 0:
                self.sink.write_fields(msgs.TOPIC_TELEMETRY, msgs.TYPE_MUSCLE_TELEMETRY,
                                       msgs.telemetry_fields(out, self.bank.names, end_ns, lp,
                                                             vp), end_ns)
            if progress is not None and k % 500 == 0:
                progress(k, n_steps)
        return n_steps, out, False

    def _block_inputs(self, inputs, step_starts_ns, first_step: int, pending: _Pending):
        """(U, path length, path velocity) of each step, (k, n) each; the inputs' messages go
        to ``pending``."""
        block = getattr(inputs, "block", None)
        if block is not None:
            return block(step_starts_ns, first_step, pending)
        rows = []
        self.sink.pending = pending
        try:
            for j, time_ns in enumerate(step_starts_ns.tolist()):
                self.sink.slot = first_step + j
                u, lp, vp = inputs.advance_to(time_ns)
                rows.append((u, lp, np.zeros(self.bank.n) if vp is None else vp))
        finally:
            self.sink.pending = None
        return tuple(np.array([row[i] for row in rows], dtype=float) for i in range(3))

    def _run_blocks(self, inputs, n_steps, should_stop, progress, block_steps, forces, times,
                    joints=None):
        """The run by blocks (module docstring): one MuscleBank.run per block, with the state
        kept at every tick (snapshot_every); with ``joints`` (a _JointRecord) the joint efforts
        of every step from the inputs' block_efforts."""
        t = self.timing
        dt_ns, start = t.dt_ns, int(t.start_time_ns or 0)
        per_publish, per_telemetry = t.steps_per(t.publish_rate_hz), t.steps_per(
            t.telemetry_rate_hz)
        every = [p for p in (per_publish, per_telemetry) if p]
        tick = math.gcd(*every) if every else block_steps
        muscle_steps = _BLOCK_MUSCLE_STEPS
        if self.bank.energetics_models:
            values = len(self.bank.energetics_models) * len(tm.MODEL_COMPONENT_LABELS)
            muscle_steps = min(muscle_steps, _BLOCK_MODEL_VALUES // values)
        steps_per_block = min(block_steps, max(1, muscle_steps // self.bank.n))
        chunk = max(tick, steps_per_block // tick * tick)
        part = min(chunk, max(tick, PART_STEPS // tick * tick))
        ticks = _Ticks(self.bank)
        pending = _Pending()
        out, k = None, 0
        while k < n_steps:
            if should_stop():
                return k, out, True
            count = min(part, chunk - k % chunk, n_steps - k)
            step_starts = start + (k + np.arange(count, dtype=np.int64)) * dt_ns
            u, lp, vp = self._block_inputs(inputs, step_starts, k, pending)
            run = self.bank.run(t.dt_s, u, lp, vp, snapshot_every=tick)
            out = run.last
            steps = k + tick * (1 + np.arange(count // tick, dtype=np.int64))  # at each tick
            published = steps % per_publish == 0 if per_publish else steps < 0
            recorded = steps % per_telemetry == 0 if per_telemetry else steps < 0
            rows = steps[published] - k - 1
            joint = None
            if joints is not None:
                efforts = inputs.block_efforts(run.force)
                work = joints.steps(efforts)
                joint = {"joint_position": efforts.position, "joint_velocity": efforts.velocity,
                         "joint_effort": efforts.effort, "joint_work": work}
                joints.sample_many(efforts, rows)
                ticks.joint_names = joints.names
            ticks.add(run, steps - k - 1, start + steps * dt_ns, steps, published, recorded,
                      lp, vp, joint)
            forces.extend(run.force[rows])
            times.extend((start + steps[published] * dt_ns).tolist())
            k += count
            ticks.flush(pending, self.sink)
            pending.flush(self.sink, k, more=k % chunk != 0 and k < n_steps)
            if progress is not None:
                progress(k, n_steps)
        return n_steps, out, False


class _Ticks:
    """The outputs and telemetry at a block's ticks, from the run's arrays and state snapshots,
    encoded in bulk by ``flush``: the values StepOutput reports at those steps, computed as it
    computes them (sums per message, over the same axes)."""

    def __init__(self, bank: MuscleBank):
        self.equations = bank.equations
        self.outputs = bulk.OutputLayouts(bank.names, bank.energetics_models)
        self.record = bulk.telemetry_layout(bank.names)
        self.joint_names: tuple = ()
        self._clear()

    def _clear(self) -> None:
        self.published: list[dict] = []
        self.recorded: list[dict] = []

    def add(self, run, rows, times_ns, slots, published, recorded, path_length,
            path_velocity, joint: dict | None = None) -> None:
        """The ticks of one MuscleBank.run: ``rows`` (m,) its rows at the ticks (one per
        snapshot), their end times and slots (step counts), and which of them publish and
        record telemetry; path_length, path_velocity: the run's inputs (k, n); ``joint``: the
        joint efforts' position, velocity, effort and cumulative work of every step (k, J)."""
        record, snap = run.record, run.snapshots
        energy_rates: dict = {}  # the energy_rate rows of each set of ticks, built once (ticks
        # that both publish and record telemetry share them: the default rates)

        def energy_rate(at) -> np.ndarray:
            key = at.tobytes()
            if key not in energy_rates:
                energy_rates[key] = tm.energy_rate_rows(record.energy_components[at],
                                                        record.energy_rates[at])
            return energy_rates[key]

        energy_totals = _row_sums(snap.energy_j)
        rate_totals = _row_sums(record.energy_rates[rows][:, :, 3])
        if np.any(published):
            at, j = rows[published], np.flatnonzero(published)
            self.published.append({
                "time": times_ns[published], "slot": slots[published],
                "position": run.fascicle_length[at], "velocity": run.fascicle_velocity[at],
                "effort": record.force[at],
                "energy_rate": energy_rate(at),
                "rate_total": rate_totals[j], "energy_total": energy_totals[j],
                **({} if self.outputs.models is None else {"models": run.energy_rate_models[at]}),
                **{key: values[at] for key, values in (joint or {}).items()}})
        if np.any(recorded):
            at, j = rows[recorded], np.flatnonzero(recorded)
            eq, excitation = self.equations, record.excitation[at]
            effective_drive = snap.effective_drive[j]
            recruited = eq.recruitment.recruited_fraction(excitation, effective_drive)
            self.recorded.append({
                "time": times_ns[recorded], "slot": slots[recorded],
                "excitation": excitation, "path_length": path_length[at],
                "path_velocity": path_velocity[at], "effective_drive": effective_drive[..., 0],
                "force": record.force[at], "contractile_force": record.contractile_force[at],
                "fascicle_length": run.fascicle_length[at],
                "fascicle_velocity": run.fascicle_velocity[at],
                "mechanical_power": record.mechanical_power[at],
                "mechanical_work": snap.mechanical_work_j[j],
                "firing_rate": eq.per_type_mean(snap.firing_rate_effective[j]),
                "recruited_fraction": recruited @ eq.membership,
                "effective_activation": record.effective_activation[at],
                "energy_rate": energy_rate(at),
                "energy": _energies(snap.energy_j[j]),
                "total_energy_rate": rate_totals[j], "total_energy": energy_totals[j]})

    def flush(self, pending: _Pending, sink: LogSink) -> None:
        if sink.recorder is None:
            self._clear()
            return
        if self.published:
            p = {key: np.concatenate([part[key] for part in self.published])
                 for key in self.published[0]}
            keys = p["slot"] * 16 + _OUTPUT_RANK
            stamps = p["time"]
            encoded = self.outputs.encode_many(
                stamps, p["position"], p["velocity"], p["effort"], p["energy_rate"],
                p["rate_total"], p["energy_total"], p.get("models"))
            if "joint_effort" in p:
                encoded += _joint_messages(self.joint_names, p, stamps)
            for topic, messages in encoded:
                pending.add(keys + _OUTPUT_ORDER[topic], topic, messages, stamps)
        if self.recorded:
            r = {key: np.concatenate([part[key] for part in self.recorded])
                 for key in self.recorded[0]}
            keys = r.pop("slot") * 16 + _OUTPUT_RANK + _OUTPUT_ORDER[msgs.TOPIC_TELEMETRY]
            stamps = r.pop("time")
            pending.add(keys, msgs.TOPIC_TELEMETRY, self.record.encode(stamps, **r), stamps)
        self._clear()


def _row_sums(values: np.ndarray) -> np.ndarray:
    """The sum of each row (first axis) of ``values``, as ``row.sum()`` sums it (pairwise, in C
    order): one reduction along the last axis of a C-contiguous (rows, -1) copy."""
    return np.ascontiguousarray(values).reshape(len(values), -1).sum(axis=1)


def _joint_messages(names, published: dict, stamps_ns) -> list:
    """[(topic, [bytes])] of joint_efforts (joints ``names``), joint_effort_commands and
    joint_work at the ticks (telemetry.joint_efforts_fields, joint_effort_commands_fields and
    joint_work_fields, in bulk)."""
    layouts = bulk.JointLayouts(names)
    state, array = layouts.state, layouts.array
    return [(tm.TOPIC_JOINT_EFFORTS, state.encode(
                stamps_ns, position=published["joint_position"],
                velocity=published["joint_velocity"], effort=published["joint_effort"])),
            (tm.TOPIC_JOINT_EFFORT_COMMANDS, array.encode(data=published["joint_effort"])),
            (tm.TOPIC_JOINT_WORK, array.encode(data=published["joint_work"]))]


def _energies(by_fibre) -> np.ndarray:
    """telemetry.energy_partition(out.energy_by_fibre, out.energy) of each step, (k, n, 3, 4),
    from the energies per fibre type and component (k, n, 2, 3), computed as StepOutput
    computes them for one step (per muscle: the two fibre types summed)."""
    per_muscle = by_fibre.sum(axis=2)[:, :, None, :]
    parts = np.concatenate([by_fibre, per_muscle], axis=2)
    return np.concatenate([parts, parts.sum(axis=-1)[..., None]], axis=-1)


class _JointRecord:
    """Joint efforts of a run: the published samples and the work summed over the steps."""

    def __init__(self, dt_s: float):
        self.dt_s = dt_s
        self.names: tuple = ()
        self.samples: list = []
        self.work: np.ndarray | None = None

    def step(self, efforts) -> None:
        if efforts is None:
            return
        self.names = tuple(efforts.names)
        power = efforts.effort * efforts.velocity
        self.work = power * self.dt_s if self.work is None else self.work + power * self.dt_s

    def steps(self, efforts) -> np.ndarray:
        """``step`` for each row of ``efforts`` (k, J arrays): the work summed after each step,
        (k, J), added step by step as ``step`` adds it."""
        self.names = tuple(efforts.names)
        added = efforts.effort * efforts.velocity * self.dt_s
        if self.work is None:
            work = np.cumsum(added, axis=0)
        else:
            work = np.cumsum(np.concatenate([self.work[None, :], added]), axis=0)[1:]
        self.work = work[-1].copy()
        return work

    def sample_many(self, efforts, rows) -> None:
        """``sample`` of the rows ``rows`` of ``efforts`` (k, J arrays)."""
        self.samples.extend(np.stack([efforts.position[rows], efforts.velocity[rows],
                                      efforts.effort[rows]], axis=1))

    def work_so_far(self, efforts) -> np.ndarray | None:
        """The work summed over the steps so far (J per joint; zeros before any step), None
        without joint efforts."""
        if efforts is None:
            return None
        return np.zeros(len(efforts.names)) if self.work is None else self.work.copy()

    def sample(self, efforts) -> None:
        if efforts is not None:
            self.names = tuple(efforts.names)
            self.samples.append(np.stack([efforts.position, efforts.velocity, efforts.effort]))

    def result(self) -> tuple:
        n = len(self.names)
        samples = np.array(self.samples) if self.samples else np.zeros((0, 3, n))
        work = self.work if self.work is not None else np.zeros(n)
        return self.names, samples, work
