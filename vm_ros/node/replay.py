"""Recorded inputs of a muscle_node run log, conditioned as the node conditioned them (no rclpy).

muscle_node logs every input message (exact bytes) at the model time from which its steps use it
(vm_ros.node.recording; with the time it gave the sample, its header stamp or that placement:
``input_time``), and its parameters as JSON in the ``vm_ros.run`` metadata key ``node_parameters``
(vm_ros.node.recording). Feeding those messages, in log-time order, into a
:class:`~vm_ros.node.inputs.NodeInputs` built from those parameters, and taking
``NodeInputs.sample(t)`` for the step at model time t, gives the inputs the node used step by step
(clipping, rejected messages, stale_input_policy, path-length extrapolation bounded by
extrapolation_max_s). With a ``geometry`` parameter, joint_states go through
:class:`~vm_ros.node.joint_inputs.JointInputs` with the logged ``joint_map`` and ``joints`` and the
attached ``geometry.yaml``, and each step's joint efforts use the moment arms of the joint sample
that step used, as in the node. `vm-ros recompute`, `vm-ros simulate --motion` (which conditions
its inputs as the node would and logs the parameters used in ``node_parameters``) and the node
tests use this one implementation (:class:`NodeConditioning`).

    inputs = NodeReplayInputs(run, bank, sink)   # run read with raw=input_topic_names()
    u, lp, vp = inputs.advance_to(t_ns)          # same interface as offline.RecordedInputs
    inputs.joint_efforts(force)                  # JointEfforts of that step's forces, or None

With ``coordination.enabled`` (live coordination) the joint-driven muscles' drives are those
the node logged on ``coordination_drive`` at the start of each publish period (the drives its
coordinator applied, held over the period), not their excitation; the target topics are copied
as data (the recompute does not solve again).

Exact only while the node's model time ran on one grid: time it skipped (max_catch_up_steps),
paused (stale_input_policy "pause"), a backward clock jump or a model reset after a non-finite
output are not in the inputs; :func:`model_time_irregularities` finds them in the output stamps.
Parameters changed at run time are not logged either (the log holds those at the model start).
"""

from __future__ import annotations

from collections import Counter
from pathlib import Path

import numpy as np

from vm_ros import telemetry as tm
from vm_ros import topics as tp
from vm_ros.errors import ConfigError
from vm_ros.geometry import load_geometry
from vm_ros.geometry.file import loads as load_geometry_text
from vm_ros.joint_space import JointEfforts, JointMap, JointSpace
from vm_ros.node.inputs import HeldInputs, InputLimits, NodeInputs, input_time_ns, node_receivers
from vm_ros.node.joint_inputs import JointInputs
from vm_ros.node.params import NodeConfig
from vm_ros.recording.cdr import input_decoder
from vm_ros.recording.run_log import (
    ATTACHMENT_GEOMETRY,
    COORDINATION_INPUT_TOPICS,
    INPUT_TIME_KEY,
    INPUT_TIME_STAMPED,
    METADATA_NAME,
    NODE_PARAMETERS_KEY,
    RunLog,
    RunLogError,
    logged_node_parameters,
)


def node_config(run: RunLog) -> NodeConfig | None:
    """The muscle_node parameters logged with ``run`` (None when it holds none). Raises
    ConfigError naming the log and the parameter when they cannot be used."""
    values = logged_node_parameters(run)
    if values is None:
        return None
    try:
        return NodeConfig.from_values(values)
    except ConfigError as exc:
        raise ConfigError(f"{run.path}: '{METADATA_NAME}' metadata",
                          f"{NODE_PARAMETERS_KEY}.{exc.field}", exc.value, exc.reason) from None


def is_node_log(run: RunLog) -> bool:
    """True for a log whose inputs were conditioned by muscle_node (its own log, a recompute of
    one: the parameters and the input times are carried over, or a `vm-ros simulate --motion`
    log, conditioned offline as the node would)."""
    return node_config(run) is not None


def node_joint_space(run: RunLog, muscles, config: NodeConfig) -> tuple[JointSpace | None,
                                                                         str | None]:
    """(The JointSpace the node built from its logged geometry, joint_map and joints parameters,
    or None without a geometry; a note when the geometry is not attached to the log and is read
    from the recorded path instead). The attached ``geometry.yaml`` is used when there is one.
    Raises RunLogError when neither exists, ConfigError when they do not fit together."""
    if not config.geometry:
        return None, None
    source = f"{run.path}: '{METADATA_NAME}' metadata {NODE_PARAMETERS_KEY}"
    note = None
    attached = run.attachments.get(ATTACHMENT_GEOMETRY)
    if attached is not None:
        geometry = load_geometry_text(attached.decode("utf-8", errors="replace"),
                                      f"{run.path}: {ATTACHMENT_GEOMETRY}")
    elif Path(config.geometry).is_file():
        geometry = load_geometry(config.geometry)
        note = (f"no {ATTACHMENT_GEOMETRY} attached: geometry read from {config.geometry} as "
                "recorded (exact only if that file is unchanged)")
    else:
        raise RunLogError(run.path, f"no {ATTACHMENT_GEOMETRY} attached and the recorded "
                                    f"geometry {config.geometry} is not a file")
    space = JointSpace(geometry, JointMap.build(config.joint_map, geometry, source), muscles,
                       config.joints, source)
    return space, note


class NodeConditioning:
    """muscle_node's input conditioning without rclpy: NodeInputs and, with a JointSpace,
    JointInputs, fed with decoded messages as the node's subscriptions feed them.

    Counts what the node would report: ``issues`` (Counter of vm_ros.node.health issue kinds,
    weighted by each issue's count; ``issue_text()`` quotes the first of each kind) and
    ``clamped`` (per coordinate of ``space``, the accepted joint_states messages in which that
    coordinate, named in the message, was outside the geometry's box and clamped).
    """

    def __init__(self, bank, config: NodeConfig, space: JointSpace | None = None,
                 stamped: bool = False):
        self.config = config
        self.space = space
        self.stamped = stamped  # inputs timed by their header stamps (a log's input_time)
        initial = np.array(config.initial_path_length_m) if config.initial_path_length_m else None
        self.inputs = NodeInputs(bank.names, InputLimits.for_bank(bank, config), initial,
                                 joint_driven=space.driven if space is not None else ())
        self.joints = JointInputs(space, self.inputs) if space is not None else None
        self.issues: Counter = Counter()
        self._texts: dict[str, str] = {}
        self.clamped = np.zeros(space.n_coordinates if space is not None else 0, dtype=int)
        self._receivers = node_receivers(self.inputs, self._joint_states)
        # live coordination: the joint-driven muscles' drives come from coordination_drive
        self.coordinated = (space.driven_index if space is not None and config.coordination_enabled
                            else np.zeros(0, dtype=int))
        self.inputs.exempt_drive(self.coordinated)
        self._coordinated_at = {bank.names[i]: k for k, i in enumerate(self.coordinated)}
        self.coordination_drive = np.zeros(len(self.coordinated))

    def _count(self, issues) -> None:
        for issue in issues:
            self.issues[issue.kind] += issue.count
            self._texts.setdefault(issue.kind, issue.text)

    def issue_text(self) -> str:
        """The first issue of each kind met so far, in one line ('' when none)."""
        return "; ".join(self._texts.values())

    def on_message(self, topic: str, msg, time_ns: int) -> None:
        """A decoded message on one of the input topics (vm_ros.topics.INPUT_TOPICS), placed
        at ``time_ns`` (its log time), of the time the node gave it there (its header stamp when
        on the node's clock: input_time_ns); joint topics without a geometry are not subscribed:
        nothing happens."""
        sample_ns = (input_time_ns(tp.header_stamp_ns(msg), time_ns, self.inputs.limits.timeout_ns)
                     if self.stamped else time_ns)
        self._count(tp.apply_input(tp.input_topic(topic), msg, self._receivers, sample_ns))

    def on_coordination_drive(self, names, drive) -> None:
        """A coordination_drive record: the drives of the named joint-driven muscles from now
        on (names that are not joint-driven muscles are ignored)."""
        for name, value in zip(names, drive, strict=True):
            k = self._coordinated_at.get(name)
            if k is not None:
                self.coordination_drive[k] = value

    def on_excitation(self, names, drive, time_ns: int) -> None:
        self._count(self.inputs.on_excitation(names, drive, time_ns))

    def on_joint_states(self, names, position, velocity, time_ns: int) -> None:
        self._count(self._joint_states(names, position, velocity, time_ns))

    def _joint_states(self, names, position, velocity, time_ns: int) -> list:
        if self.joints is None:  # no geometry: the node does not subscribe joint topics
            return []
        before = self.joints.sample
        issues = self.joints.on_joint_states(names, position, velocity, time_ns)
        sample = self.joints.sample
        if sample is not before:  # accepted: count the named coordinates that were clamped
            named = self._named(names)
            self.clamped[named[self.joints.q[named] != sample.q[named]]] += 1
        return issues

    def _named(self, names) -> np.ndarray:
        """Coordinate indices of the joints a joint_states message names (positional: joints)."""
        if len(names) == 0:
            return self.space.output
        index = (self.space.map.index_of(name) for name in names)
        return np.array([j for j in index if j is not None], dtype=int)

    def block(self, muscles: tuple, drives, joints: tuple, positions, velocities, times_ns,
              steps_ns):
        """An excitation naming ``muscles`` and a joint_states naming ``joints`` at each of
        ``times_ns`` (rows of ``drives``, ``positions``, ``velocities``), then the steps starting
        at ``steps_ns``, as arrays: what on_excitation and on_joint_states message by message,
        with ``sample`` at each step start in between, give (the same bits, the same counts):
        (U, path length, path velocity) (k, n) each and the joint sample each step used
        (JointSamples, a row per step). None
        (nothing applied) when a message is not the usual accepted one, a step would find the
        inputs not ready or live coordination is on: the caller then goes message by message."""
        if self.joints is None or len(self.coordinated) or not len(times_ns):
            return None
        drive = self.inputs.drive_many("excitation", muscles, drives, times_ns)
        if drive is None:
            return None
        block = self.joints.on_joint_states_many(joints, positions, velocities, times_ns)
        if block is None:
            return None
        applied = np.searchsorted(times_ns, steps_ns, side="right")  # messages before each step
        # held before each step, then after the last message
        held = self.inputs.hold_rows(times_ns, drive, block.path,
                                     np.append(applied, len(times_ns)))
        at_steps = HeldInputs(*(rows[:-1] for rows in held))
        if not np.isfinite(at_steps.length_m).all():
            return None  # a step not ready: message by message, which says so
        u, length, velocity = self.inputs.sample_held(steps_ns, at_steps)
        previous = self.joints.sample
        self.inputs.keep(held, times_ns[-1])
        self.joints.keep(block)
        self._count(block.issues)
        named = self._named(joints)
        self.clamped[named] += (block.q[:, named] != block.samples.q[:, named]).sum(axis=0)
        return u, length, velocity, block.samples.take(applied - 1, before=previous)

    @property
    def ready(self) -> bool:
        return self.inputs.ready

    def sample(self, time_ns: int):
        """(U, path length, path velocity) for the step starting at ``time_ns``; the coordinated
        muscles' U the latest coordination_drive."""
        u, length, velocity = self.inputs.sample(time_ns)
        if len(self.coordinated):
            u = np.array(u, dtype=float)
            u[self.coordinated] = self.coordination_drive
        return u, length, velocity

    def joint_efforts(self, force) -> JointEfforts | None:
        """The joint efforts of a step's tendon forces through the latest joint sample (the one
        the step used), or None without a geometry."""
        if self.joints is None or self.joints.sample is None:
            return None
        return self.joints.efforts(self.joints.sample, force)


class NodeReplayInputs:
    """The input messages of a muscle_node log through NodeConditioning, copied verbatim (same
    bytes and log times) to ``sink`` (a LogSink, or None). ``run`` must be read with the input
    topics raw (read_run(..., raw=INPUT_TOPICS)); messages are decoded from those bytes, as the
    node did, and those that do not decode are dropped, as the node dropped them (and still
    copied). ``space``: the joint space (default: node_joint_space of the log).
    """

    def __init__(self, run: RunLog, bank, sink=None, config: NodeConfig | None = None,
                 space: JointSpace | None = None):
        config = config or node_config(run)
        if config is None:
            raise RunLogError(run.path, f"no {NODE_PARAMETERS_KEY!r} in the run metadata "
                                        "(not a muscle_node log)")
        if space is None:
            space, _ = node_joint_space(run, bank.names, config)
        self.config = config
        self._sink = sink
        self._path = run.path
        stamped = run.info is not None and \
            run.info.extra.get(INPUT_TIME_KEY) == INPUT_TIME_STAMPED
        self.conditioning = NodeConditioning(bank, config, space, stamped)
        self.inputs = self.conditioning.inputs
        self._events = run.events(tp.input_topic_names() + (COORDINATION_INPUT_TOPICS
                                                            if config.coordination_enabled
                                                            else ()))
        # the node's decoders (one per topic: a JointState decoder remembers its names); the
        # target topics are copied, not decoded
        self._decoders = {row.name: input_decoder(row.type_name) for row in tp.INPUT_TOPICS}
        self._decoders[tm.TOPIC_COORDINATION_DRIVE] = input_decoder(tm.TYPE_JOINT_STATE)
        if any(event.data is None for event in self._events):
            raise ValueError(f"{run.path}: inputs read without their raw bytes")
        self._next = 0

    @property
    def last_time_ns(self) -> int:
        return self._events[-1].time_ns if self._events else 0

    def _apply(self, topic: str, data: bytes, time_ns: int) -> None:
        decode = self._decoders.get(topic)
        if decode is None:  # a coordination target: data only
            return
        try:
            msg = decode(data)
        except Exception:  # the node drops undecodable bytes too
            return
        if topic == tm.TOPIC_COORDINATION_DRIVE:
            self.conditioning.on_coordination_drive(msg.name, msg.position)
        else:
            self.conditioning.on_message(topic, msg, time_ns)

    def advance_to(self, time_ns: int):
        """Apply the messages logged at or before ``time_ns``; (U, path length, path velocity)
        for the step starting there (NodeInputs.sample)."""
        while self._next < len(self._events) and self._events[self._next].time_ns <= time_ns:
            event = self._events[self._next]
            self._apply(event.topic, event.data, event.time_ns)
            if self._sink is not None:
                self._sink.write_bytes(event.topic, event.data, event.time_ns)
            self._next += 1
        if not self.conditioning.ready:
            raise RunLogError(self._path, f"no valid {_path_source(self.conditioning)} for every "
                                          f"muscle by model time {time_ns * 1e-9:.6f} s")
        return self.conditioning.sample(time_ns)

    def joint_efforts(self, force) -> JointEfforts | None:
        return self.conditioning.joint_efforts(force)


def _path_source(conditioning: NodeConditioning) -> str:
    if conditioning.space is None:
        return tm.TOPIC_KINEMATICS
    if np.all(conditioning.inputs.joint_driven):
        return tm.TOPIC_JOINT_STATES
    return f"{tm.TOPIC_KINEMATICS} or {tm.TOPIC_JOINT_STATES}"


def model_time_irregularities(run: RunLog, dt_ns: int, every_steps: int) -> list[str]:
    """Where the recorded output stamps leave the grid start + k * every_steps * dt: model time
    the node skipped or paused (a gap), or a backward clock jump. Empty when the run is on the
    grid, i.e. when recomputing it is exact."""
    force = run.get(tm.TOPIC_FORCE)
    if force is None or len(force) < 2:
        return []
    steps = np.diff(force.fields["stamp_ns"].astype(np.int64))
    period = dt_ns * every_steps
    notes = []
    gaps, back = steps > period, steps <= 0
    if np.any(gaps):
        notes.append(f"{int(np.sum(gaps))} gap(s) in model time "
                     f"({np.sum(steps[gaps] - period) * 1e-9:.6g} s skipped or paused)")
    if np.any(back):
        notes.append(f"{int(np.sum(back))} backward jump(s) of model time")
    off = ~gaps & ~back & (steps != period)
    if np.any(off):
        notes.append(f"{int(np.sum(off))} output interval(s) off the publish period")
    return notes


__all__ = ["NodeConditioning", "NodeReplayInputs", "is_node_log", "model_time_irregularities",
           "node_config", "node_joint_space"]
