r"""The floor that rclpy sets under muscle_node's traffic: a bare rclpy node with muscle_node's
endpoints, timers, executor and main, and nothing of the model.

    python -P -m vm_ros_bench.rclpy_floor --params node_bench_params.yaml --level mcap
    # measured as muscle_node is (inside scripts/netns-run):
    PYTHONPATH=bench python -m vm_ros_bench.node_bench --muscles 1 --floor mcap --duration 20
    PYTHONPATH=bench python -m vm_ros_bench.node_bench --geometry geometry.yaml \
        --library muscles.yaml --floor mcap --duration 20  # the joint-space node's traffic

It reads the params file that vm_ros_bench.node_bench writes for muscle_node (muscles,
publish_rate_hz, diagnostics_period_s, mcap.enabled, mcap.path, geometry, and if given
executor, qos_depth, joint_map and joints, else muscle_node's defaults: vm_ros.node.params) and
builds what muscle_node builds from it (vm_ros.node.shell), up to ``level``, each level adding
to the one before. With a ``geometry`` (the joint-space node) the input topics include
joint_states and the outputs joint_efforts and joint_effort_commands for the node's output
joints (vm_ros.joint_space.JointSpace of the same parameters: its output_names):

| level | what the node has |
| subscriptions | the input subscriptions (vm_ros.node.interface.input_topics: excitation,
  excitation_array, muscle_kinematics) as muscle_node makes them: raw, the message info asked
  for, QoS shell.stream_qos(qos_depth); with a geometry also joint_states; the callback takes
  the bytes and does nothing else |
| timer | the model timer (ROS clock, a tick per publish period: 1 / publish_rate_hz, muscle_node's
  default batching), the diagnostics timer and the publisher-type check timer (steady clock,
  diagnostics_period_s and shell.GRAPH_CHECK_PERIOD_S; the check asks the graph for the input
  topics' publishers as muscle_node does); the model tick does nothing |
| publishers | the output publishers (interface.OUTPUT_TOPICS); each tick publishes muscle_force,
  energy_rate, energy_rate_total and energy_total, bytes serialised at start-up with
  muscle_node's layouts for its muscles (vm_ros.recording.bulk.OutputLayouts: the same sizes),
  with a geometry also joint_efforts and joint_effort_commands (bulk.JointLayouts of the output
  joints), OUTPUT_STEPS different steps in turn (output_bytes), and the diagnostics timer a
  DiagnosticArray of DIAGNOSTICS_KEYS key-value pairs |
| mcap | with mcap.enabled: a McapRecorder (vm_ros.recording.writer, muscle_node's writer with its
  defaults) at mcap.path writing every input message's bytes as they arrive and every published
  message's bytes, as muscle_node logs them (without the run metadata and attachments) |

The main is muscle_node's (shell.run_node: vm_ros's signal handling, the node, the executor of
shell.make_executor(executor), gc.freeze of the start-up objects, shell.spin until SIGINT or
SIGTERM, the log finished when the node is destroyed). What muscle_node does beyond this is the
model and its inputs and outputs: placing, sampling and conditioning the inputs, the steps,
encoding the outputs, its health counters.
"""

from __future__ import annotations

import argparse
import inspect
import sys
import time
from pathlib import Path

import numpy as np
import yaml
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rclpy.serialization import serialize_message
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64, Float64MultiArray

from vm_ros import telemetry as tm
from vm_ros.joint_space import JointEfforts, JointSpace
from vm_ros.node import interface
from vm_ros.node.params import PARAMS
from vm_ros.node.shell import (
    GRAPH_CHECK_PERIOD_S,
    make_executor,
    run_node,
    stream_qos,
)
from vm_ros.recording import bulk
from vm_ros.recording.qos import offered_qos_profiles_yaml
from vm_ros.recording.run_log import resolve_topic
from vm_ros.recording.writer import McapRecorder
from vm_ros_bench.node_bench import FLOOR_LEVELS as LEVELS

NODE_NAME = "rclpy_floor"
DIAGNOSTICS_KEYS = 30  # about muscle_node's /diagnostics keys (vm_ros.node.shell, health)
OUTPUT_STEPS = 100  # distinct published steps, sent in turn (a second at 100 Hz)
DEFAULTS = {spec.name: spec.default for spec in PARAMS}  # muscle_node's
# the signature that makes rclpy hand a subscription callback the message info (as the node's)
_WITH_MESSAGE_INFO = inspect.Signature(
    [inspect.Parameter(name, inspect.Parameter.POSITIONAL_OR_KEYWORD) for name in ("data", "info")])
MESSAGE_CLASSES = {tm.TYPE_JOINT_STATE: JointState, tm.TYPE_FLOAT64_MULTI_ARRAY: Float64MultiArray,
                   tm.TYPE_FLOAT64: Float64, tm.TYPE_DIAGNOSTIC_ARRAY: DiagnosticArray}


def output_joints(params: dict) -> tuple[str, ...]:
    """The joints muscle_node publishes efforts for with the params YAML's ``ros__parameters``
    dict ``params`` (JointSpace.output_names of its geometry, joint_map, muscles and joints;
    the geometry read with the NumPy back end): () without a geometry."""
    if not params.get("geometry"):
        return ()
    return JointSpace.load(params["geometry"], params.get("joint_map", DEFAULTS["joint_map"]),
                           params["muscles"], params.get("joints", DEFAULTS["joints"]),
                           NODE_NAME, backend="numpy").output_names


def output_bytes(names, steps: int = 1, joints=()) -> list[list[tuple[str, bytes]]]:
    """[[(topic, bytes)] per step] of ``steps`` published steps of muscle_node for the muscles
    ``names`` (and with ``joints``, its output joints, the joint topics for them): its layouts
    (vm_ros.recording.bulk.OutputLayouts and JointLayouts), so the sizes are the node's.
    The values are sines of the step, of the muscle's kind and of the value's place in the
    muscle's block: muscles named ``<kind>_<k>`` (vm_ros_bench.node_bench's copies of the
    shipped muscles, which the bench drives alike) get the same values, as they do from the
    node, so that the log compresses about as the node's does (distinct values for every muscle
    made the 100-muscle log 23 MiB against the node's 4.1 MiB, zeros 1.0 MiB)."""
    layouts = bulk.OutputLayouts(names)
    kinds = {}
    kind = np.array([kinds.setdefault(name.rsplit("_", 1)[0], len(kinds)) for name in names])
    phase = 2.0 * np.pi * np.arange(steps) / steps

    def values(per_muscle: int = 1) -> np.ndarray:
        """(steps, n_muscles * per_muscle)."""
        offset = (kind[:, None] + 0.1 * np.arange(per_muscle)[None, :]).ravel()
        return np.sin(phase[:, None] + offset[None, :])

    rates = values(int(np.prod(layouts.energy_rate.fields["data"][1])) // len(names))
    total = np.sin(phase)
    encoded = layouts.encode_many(np.zeros(steps, np.int64), values(), values(), values(),
                                  rates, total, total)
    out = [[(topic, data[k]) for topic, data in encoded] for k in range(steps)]
    if joints:
        joint_layouts = bulk.JointLayouts(joints)
        angle = np.sin(phase[:, None] + np.arange(len(joints))[None, :])
        for k, step in enumerate(out):
            step += joint_layouts.encode(JointEfforts(tuple(joints), angle[k], angle[k],
                                                      angle[k]), 0)
    return out


def diagnostics_bytes(keys: int = DIAGNOSTICS_KEYS) -> bytes:
    """A serialised DiagnosticArray of one status with ``keys`` key-value pairs."""
    values = [KeyValue(key=f"floor value {k} (s)", value="0.000000") for k in range(keys)]
    status = DiagnosticStatus(level=DiagnosticStatus.OK, name=f"{NODE_NAME}: floor",
                              message="running", hardware_id=NODE_NAME, values=values)
    return serialize_message(DiagnosticArray(status=[status]))


class FloorNode(Node):
    """muscle_node's endpoints and timers up to ``level`` (module docstring), from the params
    YAML's ``ros__parameters`` dict ``params``."""

    def __init__(self, params: dict, level: str):
        super().__init__(NODE_NAME)
        parts = LEVELS[:LEVELS.index(level) + 1]
        qos = stream_qos(int(params.get("qos_depth", DEFAULTS["qos_depth"])))
        mcap = params.get("mcap", {})
        joints = output_joints(params)
        inputs = interface.input_topics(geometry=bool(joints))
        outputs = interface.OUTPUT_TOPICS + (interface.JOINT_OUTPUT_TOPICS if joints else ())
        self.recorder = None
        if "mcap" in parts and mcap.get("enabled"):
            self.recorder = McapRecorder(Path(mcap["path"]))
            for topic, type_name, _ in (*inputs, *outputs):
                self.recorder.add_channel(resolve_topic(topic), type_name,
                                          offered_qos_profiles_yaml(qos))
        self._inputs = [(topic, MESSAGE_CLASSES[type_name]) for topic, type_name, _ in inputs]
        self._subscriptions = [
            self.create_subscription(msg_type, topic, self._receiver(topic), qos, raw=True)
            for topic, msg_type in self._inputs]
        self._timers = []
        if "timer" in parts:
            steady = Clock(clock_type=ClockType.STEADY_TIME)
            self._timers = [
                self.create_timer(1.0 / float(params["publish_rate_hz"]), self._on_tick),
                self.create_timer(float(params["diagnostics_period_s"]),
                                  self._publish_diagnostics, clock=steady),
                self.create_timer(GRAPH_CHECK_PERIOD_S, self._check_publishers, clock=steady)]
        self._outputs, self._diagnostics, self._ticks = [[]], None, 0
        if "publishers" in parts:
            publishers = {topic: self.create_publisher(MESSAGE_CLASSES[type_name], topic, qos)
                          for topic, type_name, _ in outputs}
            self._outputs = [[(publishers[topic], resolve_topic(topic), data)
                              for topic, data in step]
                             for step in output_bytes(params["muscles"], OUTPUT_STEPS, joints)]
            self._diagnostics = (publishers[tm.TOPIC_DIAGNOSTICS],
                                 resolve_topic(tm.TOPIC_DIAGNOSTICS), diagnostics_bytes())

    def _receiver(self, topic: str):
        recorder, full = self.recorder, resolve_topic(topic)

        def receive(data, info=None) -> None:
            if info is None:  # the EventsExecutor's call: one (data, info) tuple
                data, info = data
            if recorder is not None:
                now_ns = time.time_ns()
                recorder.write(full, data, now_ns, now_ns)

        receive.__signature__ = _WITH_MESSAGE_INFO
        return receive

    def _send(self, outputs) -> None:
        now_ns = time.time_ns()
        for publisher, full, data in outputs:
            publisher.publish(data)
            if self.recorder is not None:
                self.recorder.write(full, data, now_ns, now_ns)

    def _on_tick(self) -> None:
        self._send(self._outputs[self._ticks % len(self._outputs)])
        self._ticks += 1

    def _publish_diagnostics(self) -> None:
        if self._diagnostics is not None:
            self._send([self._diagnostics])

    def _check_publishers(self) -> None:
        if not self.context.ok():
            return
        for topic, _ in self._inputs:
            self.get_publishers_info_by_topic(self.resolve_topic_name(topic))

    def destroy_node(self):
        if self.recorder is not None:
            self.recorder.close()
        return super().destroy_node()


def argument_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="python -m vm_ros_bench.rclpy_floor",
        description="A bare rclpy node with muscle_node's traffic (run inside "
                    "scripts/netns-run; vm_ros_bench.node_bench --floor starts it).")
    parser.add_argument("--params", type=Path, required=True,
                        help="muscle_node's params YAML (vm_ros_bench.node_bench writes it)")
    parser.add_argument("--level", choices=LEVELS, default=LEVELS[-1],
                        help="how much of muscle_node's traffic (module docstring)")
    return parser


def main(args=None) -> int:
    """python -m vm_ros_bench.rclpy_floor --params FILE [--level LEVEL]: spin until SIGINT."""
    from rclpy.utilities import remove_ros_args

    argv = sys.argv if args is None else list(args)
    parser = argument_parser()
    options = parser.parse_args(remove_ros_args(argv)[1:])
    document = yaml.safe_load(options.params.read_text(encoding="utf-8"))
    params = document["/**"]["ros__parameters"]
    executor = params.get("executor", DEFAULTS["executor"])
    return run_node(NODE_NAME, parser, lambda: FloorNode(params, options.level),
                    lambda _node: make_executor(executor), argv)


if __name__ == "__main__":
    sys.exit(main())
