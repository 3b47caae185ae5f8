"""Running a muscle bank offline, logged as muscle_node logs it: `vm-ros simulate` and
`vm-ros recompute` share this loop.

    run = OfflineRun(bank, timing, recorder)
    result = run.run(inputs, n_steps)        # inputs: SampledInputs, RecordedInputs,
                                             # vm_ros.node.replay.NodeReplayInputs or
                                             # motion_inputs.MotionInputs

Step k covers model time [t_k, t_k + dt) with t_k = start + k dt (integer ns). Inputs follow the
run log's zero-order hold: the step uses the latest input with log_time <= t_k. Outputs
(muscle_force, energy_rate, energy_rate_total, energy_total) are written every
``timing.steps_per(publish_rate_hz)`` steps and telemetry every
``timing.steps_per(telemetry_rate_hz)`` steps, stamped and logged at the end of the step. The
bank starts at rest, at static equilibrium for the path length held at the start time; with
``publish_start`` (as muscle_node does) that initial state is published too, at the start time.

Inputs with a ``joint_efforts(force)`` method (joint space: NodeReplayInputs, MotionInputs) also
give joint_efforts and joint_effort_commands with every output, the step's tendon forces through
the moment arms of the joint sample the step used; the joint work is summed step by step
(tau . qdot dt, robot convention, with the joint velocities of that sample).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from vm_ros import telemetry as tm
from vm_ros.model import MuscleBank, StepOutput
from vm_ros.recording import messages as msgs
from vm_ros.recording.cdr import serialize
from vm_ros.recording.run_log import (
    INPUT_TOPICS,
    RunLog,
    RunLogError,
    RunTiming,
    resolve_topic,
)
from vm_ros.recording.writer import McapRecorder

_RETRY_S = 0.001
_RETRIES = 5000  # an offline run waits up to 5 s for room in the recorder queue, then drops


class LogSink:
    """Serialises field dicts and hands them (or recorded bytes) to a recorder. Offline nothing
    is real time, so a full queue is waited for instead of dropping."""

    def __init__(self, recorder: McapRecorder | None,
                 log_topic: Callable[[str], str] = resolve_topic):
        self.recorder = recorder
        self.log_topic = log_topic

    def write_fields(self, topic: str, type_name: str, fields: dict, time_ns: int) -> None:
        if self.recorder is not None:
            self.write_bytes(topic, serialize(type_name, fields), time_ns)

    def write_bytes(self, topic: str, data: bytes, time_ns: int) -> None:
        if self.recorder is None:
            return
        full = self.log_topic(topic)
        for _ in range(_RETRIES):
            if self.recorder.write(full, data, time_ns) or not self.recorder.status.ok:
                return
            time.sleep(_RETRY_S)


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

    def advance_to(self, time_ns: int):
        """(U, path length, path velocity) held at ``time_ns``; logs the samples taken."""
        while self._next_ns <= time_ns:
            t_s = (self._next_ns - self._start_ns) * 1e-9
            u, lp, vp = (np.asarray(f(t_s), dtype=float) * np.ones(len(self.names))
                         for f in self._functions)
            self._sink.write_fields(tm.TOPIC_EXCITATION, tm.TYPE_JOINT_STATE,
                                    msgs.excitation_fields(self.names, u, self._next_ns),
                                    self._next_ns)
            self._sink.write_fields(tm.TOPIC_KINEMATICS, tm.TYPE_JOINT_STATE,
                                    msgs.kinematics_fields(self.names, lp, vp, self._next_ns),
                                    self._next_ns)
            self._held = (u, lp, vp)
            self._next_ns += self.period_ns
        return self._held


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
        joint_states = run.get(tm.TOPIC_JOINT_STATES)
        if joint_states is not None and len(joint_states):
            raise RunLogError(run.path, f"{tm.TOPIC_JOINT_STATES} without node_parameters: the "
                                        "joint conditioning of this log is not known")
        self._events = run.events(INPUT_TOPICS)
        self._next = 0
        kinematics = run.get(tm.TOPIC_KINEMATICS)
        if kinematics is None or len(kinematics) == 0:
            raise RunLogError(run.path, f"no {tm.TOPIC_KINEMATICS} messages to run from")
        self._first_kinematics = kinematics

    @property
    def last_time_ns(self) -> int:
        return self._events[-1].time_ns if self._events else 0

    def _apply(self, topic: str, series, i: int) -> None:
        if topic == tm.TOPIC_KINEMATICS:
            lp, vp = series.fields["position"][i], series.fields["velocity"][i]
            ok = np.isfinite(lp) & (lp > 0)
            self.lp[ok] = lp[ok]
            self.vp[ok] = np.where(np.isfinite(vp[ok]), vp[ok], 0.0)
            return
        key = "position" if topic == tm.TOPIC_EXCITATION else "data"
        u = series.fields[key][i]
        if u.shape == self.u.shape:
            ok = np.isfinite(u)
            self.u[ok] = u[ok]

    def advance_to(self, time_ns: int):
        while self._next < len(self._events) and self._events[self._next].time_ns <= time_ns:
            event = self._events[self._next]
            if event.series is not None:  # a message that did not decode changes nothing
                self._apply(event.topic, event.series, event.index)
            if event.data is not None:
                self._sink.write_bytes(event.topic, event.data, event.time_ns)
            self._next += 1
        if np.any(np.isnan(self.lp)):
            first = self._first_kinematics.fields["position"][0]
            self.lp = np.where(np.isnan(self.lp), first, self.lp)
        return self.u.copy(), self.lp.copy(), self.vp.copy()


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

    def _publish(self, out: StepOutput, time_ns: int, efforts=None) -> None:
        names, write = self.bank.names, self.sink.write_fields
        write(tm.TOPIC_FORCE, tm.TYPE_JOINT_STATE, tm.force_fields(out, names, time_ns), time_ns)
        write(tm.TOPIC_ENERGY_RATE, tm.TYPE_FLOAT64_MULTI_ARRAY, tm.energy_rate_fields(out),
              time_ns)
        write(tm.TOPIC_ENERGY_RATE_TOTAL, tm.TYPE_FLOAT64,
              msgs.float64_fields(out.total_energy_rate), time_ns)
        write(tm.TOPIC_ENERGY_TOTAL, tm.TYPE_FLOAT64, msgs.float64_fields(out.total_energy),
              time_ns)
        if efforts is not None:
            write(tm.TOPIC_JOINT_EFFORTS, tm.TYPE_JOINT_STATE,
                  tm.joint_efforts_fields(efforts, time_ns), time_ns)
            write(tm.TOPIC_JOINT_EFFORT_COMMANDS, tm.TYPE_FLOAT64_MULTI_ARRAY,
                  tm.joint_effort_commands_fields(efforts), time_ns)

    def run(self, inputs, n_steps: int, should_stop: Callable[[], bool] = lambda: False,
            progress: Callable[[int, int], None] | None = None,
            publish_start: bool = False) -> OfflineResult:
        t = self.timing
        dt_ns, start = t.dt_ns, int(t.start_time_ns or 0)
        per_publish, per_telemetry = t.steps_per(t.publish_rate_hz), t.steps_per(
            t.telemetry_rate_hz)
        _, lp, _ = inputs.advance_to(start)
        initial = self.bank.reset(path_length=lp, time_s=start * 1e-9)
        joint_efforts = getattr(inputs, "joint_efforts", None)
        joints = _JointRecord(t.dt_s)
        forces, times, out, k = [], [], None, 0
        if publish_start and per_publish:
            efforts = joint_efforts(initial.force) if joint_efforts is not None else None
            self._publish(initial, start, efforts)
            joints.sample(efforts)
            forces.append(initial.force.copy())
            times.append(start)
        interrupted = False
        for k in range(n_steps):
            if should_stop():
                interrupted = True
                break
            u, lp, vp = inputs.advance_to(start + k * dt_ns)
            out = self.bank.step(t.dt_s, u, lp, vp)
            end_ns = start + (k + 1) * dt_ns
            efforts = joint_efforts(out.force) if joint_efforts is not None else None
            joints.step(efforts)
            if per_publish and (k + 1) % per_publish == 0:
                self._publish(out, end_ns, efforts)
                joints.sample(efforts)
                forces.append(out.force.copy())
                times.append(end_ns)
            if per_telemetry and (k + 1) % per_telemetry == 0:
                self.sink.write_fields(msgs.TOPIC_TELEMETRY, msgs.TYPE_MUSCLE_TELEMETRY,
                                       msgs.telemetry_fields(out, self.bank.names, end_ns, lp,
                                                             vp), end_ns)
            if progress is not None and k % 500 == 0:
                progress(k, n_steps)
        else:
            k = n_steps
        steps = k
        force_samples = np.array(forces) if forces else np.zeros((0, self.bank.n))
        return OfflineResult(steps, start + steps * dt_ns, out, np.array(times, dtype=np.int64),
                             force_samples, interrupted, *joints.result())


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

    def sample(self, efforts) -> None:
        if efforts is not None:
            self.names = tuple(efforts.names)
            self.samples.append(np.stack([efforts.position, efforts.velocity, efforts.effort]))

    def result(self) -> tuple:
        n = len(self.names)
        samples = np.array(self.samples) if self.samples else np.zeros((0, 3, n))
        work = self.work if self.work is not None else np.zeros(n)
        return self.names, samples, work
