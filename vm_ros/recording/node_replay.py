"""Recorded inputs of a muscle_node run log, conditioned as the node conditioned them (no rclpy).

muscle_node logs every input message (exact bytes) at the model time of the first step that uses
it, and its parameters as JSON in the ``vm_ros.run`` metadata key ``node_parameters``
(vm_ros.node_recording). Feeding those messages, in log-time order, into a
:class:`~vm_ros.node_inputs.NodeInputs` built from those parameters, and taking
``NodeInputs.sample(t)`` for the step at model time t, gives the inputs the node used step by step
(clipping, rejected messages, stale_input_policy, path-length extrapolation bounded by
extrapolation_max_s). `vm-ros recompute` and the node tests use this one implementation.

    inputs = NodeReplayInputs(run, bank, sink)   # run read with raw=INPUT_TOPICS
    u, lp, vp = inputs.advance_to(t_ns)          # same interface as offline.RecordedInputs

Exact only while the node's model time ran on one grid: time it skipped (max_catch_up_steps),
paused (stale_input_policy "pause"), a backward clock jump or a model reset after a non-finite
output are not in the inputs; :func:`model_time_irregularities` finds them in the output stamps.
Parameters changed at run time are not logged either (the log holds those at the model start).
"""

from __future__ import annotations

import json

import numpy as np

from vm_ros import telemetry as tm
from vm_ros.errors import ConfigError
from vm_ros.node_inputs import InputLimits, NodeInputs
from vm_ros.node_params import NodeConfig
from vm_ros.recording.cdr import deserialize
from vm_ros.recording.run_log import INPUT_TOPICS, METADATA_NAME, RunLog, RunLogError

NODE_PARAMETERS_KEY = "node_parameters"


def node_config(run: RunLog) -> NodeConfig | None:
    """The muscle_node parameters logged with ``run`` (None when it holds none). Raises
    ConfigError naming the log and the parameter when they cannot be used."""
    if run.info is None or NODE_PARAMETERS_KEY not in run.info.extra:
        return None
    text = run.info.extra[NODE_PARAMETERS_KEY]
    source = f"{run.path}: '{METADATA_NAME}' metadata"
    try:
        values = json.loads(text)
    except ValueError as exc:
        raise ConfigError(source, NODE_PARAMETERS_KEY, text, f"not JSON: {exc}") from None
    if not isinstance(values, dict):
        raise ConfigError(source, NODE_PARAMETERS_KEY, text, "expected a JSON object")
    try:
        return NodeConfig.from_values(values)
    except ConfigError as exc:
        raise ConfigError(source, f"{NODE_PARAMETERS_KEY}.{exc.field}", exc.value,
                          exc.reason) from None


def is_node_log(run: RunLog) -> bool:
    """True for a log whose inputs were conditioned by muscle_node (its own log, or a recompute
    of one: the parameters and the input times are carried over)."""
    return node_config(run) is not None


class NodeReplayInputs:
    """The input messages of a muscle_node log through NodeInputs, copied verbatim (same bytes
    and log times) to ``sink`` (a LogSink, or None). ``run`` must be read with the input topics
    raw (read_run(..., raw=INPUT_TOPICS)); messages are decoded from those bytes, as the node did,
    and those that do not decode are dropped, as the node dropped them (and still copied).
    """

    def __init__(self, run: RunLog, bank, sink=None, config: NodeConfig | None = None):
        config = config or node_config(run)
        if config is None:
            raise RunLogError(run.path, f"no {NODE_PARAMETERS_KEY!r} in the run metadata "
                                        "(not a muscle_node log)")
        self.config = config
        self._sink = sink
        self._path = run.path
        initial = np.array(config.initial_path_length_m) if config.initial_path_length_m else None
        self.inputs = NodeInputs(bank.names, InputLimits.for_bank(bank, config), initial)
        self._events = run.events(INPUT_TOPICS)
        if any(event.data is None for event in self._events):
            raise ValueError(f"{run.path}: inputs read without their raw bytes")
        self._next = 0

    @property
    def last_time_ns(self) -> int:
        return self._events[-1].time_ns if self._events else 0

    def _apply(self, topic: str, data: bytes, time_ns: int) -> None:
        try:
            msg = deserialize(tm.TOPIC_TYPES[topic], data)
        except Exception:  # the node drops undecodable bytes too
            return
        if topic == tm.TOPIC_EXCITATION_ARRAY:
            self.inputs.on_excitation_array(msg.data, time_ns)
        elif topic == tm.TOPIC_EXCITATION:
            self.inputs.on_excitation(msg.name, msg.position, time_ns)
        else:
            self.inputs.on_kinematics(msg.name, msg.position, msg.velocity, time_ns)

    def advance_to(self, time_ns: int):
        """Apply the messages logged at or before ``time_ns``; (U, path length, path velocity)
        for the step starting there (NodeInputs.sample)."""
        while self._next < len(self._events) and self._events[self._next].time_ns <= time_ns:
            event = self._events[self._next]
            self._apply(event.topic, event.data, event.time_ns)
            if self._sink is not None:
                self._sink.write_bytes(event.topic, event.data, event.time_ns)
            self._next += 1
        if not self.inputs.ready:
            raise RunLogError(self._path, f"no valid {tm.TOPIC_KINEMATICS} for every muscle by "
                                          f"model time {time_ns * 1e-9:.6f} s")
        return self.inputs.sample(time_ns)


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


__all__ = ["NodeReplayInputs", "is_node_log", "model_time_irregularities", "node_config"]
