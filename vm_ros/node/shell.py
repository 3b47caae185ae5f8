"""muscle_node: the ROS 2 shell around MuscleBank.

Messages in -> arrays (vm_ros.node.inputs) -> MuscleBank.step on a timer, in fixed steps of
1/model_rate_hz by elapsed ROS time (vm_ros.node.timing) -> messages out (vm_ros.telemetry
layouts). Parameters: vm_ros.node.params; bad-input behaviours and diagnostics counters:
vm_ros.node.health. Topics (relative names, so namespaces and remapping apply):

- in ``excitation`` (JointState), ``excitation_array`` (Float64MultiArray), ``muscle_kinematics``
  (JointState), and with a ``geometry`` ``joint_states`` (JointState): reliable, keep last
  qos_depth, volatile. A drive sent once must arrive (best effort lost messages on a loaded
  machine); a best-effort (sensor-data) publisher needs
  ``qos_overrides./<topic>.subscription.reliability: best_effort``.
- out ``muscle_force`` (JointState), ``energy_rate`` (Float64MultiArray), ``energy_rate_total``
  and ``energy_total`` (Float64), and with a ``geometry`` ``joint_efforts`` (JointState) and
  ``joint_effort_commands`` (Float64MultiArray): reliable, keep last qos_depth, volatile.
- out ``/diagnostics`` (DiagnosticArray): reliable, keep last qos_depth, volatile; on a
  steady-clock timer, so it keeps coming while a simulated clock is paused.

Every publisher and subscription accepts the standard ``qos_overrides`` parameters (history,
depth, reliability).

Live coordination (``coordination.enabled``, vm_ros.node.live_coordination): in
``joint_effort_trajectory`` (JointTrajectory), ``joint_effort_targets`` (JointState),
``joint_effort_targets_array`` (Float64MultiArray); out ``muscle_drive`` and ``joint_reserves``
(JointState); the joint-driven muscles' drives solved each publish period.

Joint space (vm_ros.joint_space): node muscles that the geometry covers are driven from
joint_states; each published step's tendon forces go back through the moment arms of the joint
sample that step used, as generalized forces in the robot's convention.

Outgoing messages are serialised once; the same bytes are published and logged. Inputs are
subscribed raw, logged as received, then deserialised.
"""

from __future__ import annotations

import argparse
import contextlib
import faulthandler
import gc
import importlib
import inspect
import math
import re
import sys
import time
from datetime import datetime

import numpy as np
import rclpy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rcl_interfaces.msg import (
    FloatingPointRange,
    IntegerRange,
    ParameterDescriptor,
    ParameterType,
    SetParametersResult,
)
from rclpy.clock import Clock, ClockType
from rclpy.exceptions import (
    InvalidParameterTypeException,
    InvalidParameterValueException,
    ParameterUninitializedException,
)
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.qos_overriding_options import InvalidQosOverridesError, QoSOverridingOptions
from rclpy.serialization import deserialize_message, serialize_message
from rclpy.signals import SignalHandlerOptions
from rclpy.task import Future
from rclpy.utilities import remove_ros_args
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64, Float64MultiArray
from trajectory_msgs.msg import JointTrajectory

from vm_ros import telemetry as tm
from vm_ros import topics as tp
from vm_ros.errors import ConfigError, VmRosError
from vm_ros.joint_space import JointEfforts
from vm_ros.node import interface
from vm_ros.node.health import (
    ISSUE_KINDS,
    QUIET_KINDS,
    DurationWindow,
    Issue,
    IssueLog,
    SequenceGaps,
    format_seconds,
    format_value,
    lost_key,
)
from vm_ros.node.input_timeline import InputTimeline
from vm_ros.node.inputs import InputLimits, NodeInputs, input_time_ns, node_receivers
from vm_ros.node.joint_inputs import JointInputs
from vm_ros.node.live_coordination import LiveCoordination
from vm_ros.node.params import PARAMS, PARAMS_SOURCE, NodeConfig, ParamSpec
from vm_ros.node.params import runtime_parameter_names as _runtime_names
from vm_ros.node.recording import NodeRunLog, node_run_extra
from vm_ros.node.signals import ShutdownRequest
from vm_ros.node.startup import EXIT_BAD_PARAMETER, build_model, error_line
from vm_ros.node.timing import StepScheduler
from vm_ros.recording import bulk
from vm_ros.recording.cdr import input_decoder
from vm_ros.recording.qos import offered_qos_profiles_yaml
from vm_ros.recording.run_log import COORDINATION_TOPICS, NODE_SOURCE, RunInfo, RunTiming

NODE_NAME = "muscle_node"
RCLError = _rclpy.RCLError
LOG_THROTTLE_S = 2.0
GRAPH_CHECK_PERIOD_S = 1.0  # steady clock: how often input topics' publishers are type-checked
# the signature that makes rclpy hand a subscription callback the message info (_receiver)
_WITH_MESSAGE_INFO = inspect.Signature(
    [inspect.Parameter(name, inspect.Parameter.POSITIONAL_OR_KEYWORD) for name in ("data", "info")])

# (topic, message class, description) from vm_ros.node.interface (type names there)
_MESSAGE_CLASSES = {tm.TYPE_JOINT_STATE: JointState, tm.TYPE_FLOAT64_MULTI_ARRAY: Float64MultiArray,
                    tm.TYPE_FLOAT64: Float64, tm.TYPE_DIAGNOSTIC_ARRAY: DiagnosticArray,
                    tm.TYPE_JOINT_TRAJECTORY: JointTrajectory}
(OUTPUT_TOPICS, MODEL_OUTPUT_TOPICS, JOINT_OUTPUT_TOPICS, COORDINATION_INPUT_TOPICS,
 COORDINATION_OUTPUT_TOPICS) = (
    tuple((topic, _MESSAGE_CLASSES[type_name], text) for topic, type_name, text in table)
    for table in (interface.OUTPUT_TOPICS, interface.MODEL_OUTPUT_TOPICS,
                  interface.JOINT_OUTPUT_TOPICS, interface.COORDINATION_INPUT_TOPICS,
                  interface.COORDINATION_OUTPUT_TOPICS))

_ROS_TYPES = {"bool": ParameterType.PARAMETER_BOOL, "integer": ParameterType.PARAMETER_INTEGER,
              "double": ParameterType.PARAMETER_DOUBLE, "string": ParameterType.PARAMETER_STRING,
              "string_array": ParameterType.PARAMETER_STRING_ARRAY,
              "double_array": ParameterType.PARAMETER_DOUBLE_ARRAY}
_EMPTY_ARRAY_TYPES = {"string_array": Parameter.Type.STRING_ARRAY,
                      "double_array": Parameter.Type.DOUBLE_ARRAY}


def parameter_descriptor(spec: ParamSpec) -> ParameterDescriptor:
    """The ROS descriptor of one ParamSpec. Doubles are dynamically typed so that a params file
    may write 1000 for 1000.0; NodeConfig checks the type."""
    descriptor = ParameterDescriptor(
        description=spec.describe(), read_only=not spec.runtime,
        dynamic_typing=spec.kind == "double", type=_ROS_TYPES[spec.kind],
        additional_constraints=f"one of: {', '.join(spec.choices)}" if spec.choices else "")
    if spec.kind == "double" and spec.low is not None:
        descriptor.floating_point_range = [
            FloatingPointRange(from_value=float(spec.low), to_value=float(spec.high), step=0.0)]
    if spec.kind == "integer" and spec.low is not None:
        descriptor.integer_range = [
            IntegerRange(from_value=int(spec.low), to_value=int(spec.high), step=0)]
    return descriptor


def stream_qos(depth: int) -> QoSProfile:
    """Every stream, in and out: reliable, keep last ``depth``, volatile. Reliable inputs because
    a drive sent once (on change) must arrive: best effort lost such messages on a loaded
    machine. Best-effort (sensor-data) peers need the qos_overrides parameters."""
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=depth,
                      reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.VOLATILE)


def fill_message(msg, fields: dict):
    """Set a ROS message's fields from vm_ros.telemetry's nested dicts; returns ``msg``."""
    slot_types = dict(zip(msg.get_fields_and_field_types(), msg.SLOT_TYPES, strict=True))
    for key, value in fields.items():
        if isinstance(value, dict):
            fill_message(getattr(msg, key), value)
        elif value and isinstance(value, list) and isinstance(value[0], dict):
            element = slot_types[key].value_type  # a NamespacedType of a message
            module = importlib.import_module(".".join(element.namespaces))
            setattr(msg, key, [fill_message(getattr(module, element.name)(), v) for v in value])
        else:
            setattr(msg, key, value)
    return msg


_TYPE_CLASH = re.compile(r"parameter '(?P<name>[^']*)' to '(?P<value>.*)' of type '(?P<given>\w+)'"
                         r", expecting type '(?:Type\.)?(?P<expected>\w+)'", re.DOTALL)


def _parameter_error(exc: Exception, overrides: dict) -> ConfigError:
    """rclpy's parameter exception (a value of the wrong type for a typed declaration, e.g.
    use_sim_time:=maybe) as a ConfigError naming the parameter and the value given."""
    match = _TYPE_CLASH.search(str(exc))
    if match is None:
        name = str(exc).rsplit(": ", 1)[-1]  # ParameterException: "<message>: <name>"
        given = overrides[name].value if name in overrides else None
        return ConfigError(PARAMS_SOURCE, name, given, str(exc))
    name = match["name"]
    given = overrides[name].value if name in overrides else match["value"]
    return ConfigError(PARAMS_SOURCE, match["name"], given,
                       f"expected {match['expected'].lower()}, got {match['given'].lower()}")


def _type_name(msg_type) -> str:
    """'sensor_msgs/msg/JointState' of the JointState class (the graph's type names)."""
    return f"{msg_type.__module__.split('.')[0]}/msg/{msg_type.__name__}"


def _finite(outputs) -> bool:
    """Tendon force (from the fascicle length), contractile force (length and velocity) and
    energy rate all finite (a NaN or inf makes the sum so), of a StepOutput or of every step of
    a Trajectory."""
    return math.isfinite(float(outputs.force.sum() + outputs.contractile_force.sum()
                               + outputs.record.energy_rates[..., 3].sum()))


class MuscleNode(Node):
    """The muscle model as a ROS 2 node (see the module docstring and vm_ros.node.params).

    Raises ConfigError (naming the parameter or file field) for bad parameters; the partly
    built node is destroyed first.
    """

    def __init__(self, node_name: str = NODE_NAME, **kwargs):
        try:
            super().__init__(node_name, **kwargs)
        except (InvalidParameterTypeException, InvalidParameterValueException) as exc:
            raise _parameter_error(exc, {}) from exc  # e.g. use_sim_time:=maybe
        self.run_log: NodeRunLog | None = None
        try:
            self._setup()
        except BaseException:
            self.destroy_node()
            raise

    # --- set-up -----------------------------------------------------------------------------

    def _setup(self) -> None:
        self.config = self._declare_parameters()
        c = self.config
        model = build_model(c)  # vm_ros.node.startup: the same path without ROS
        self.run_config, self.bank, self.joint_space = model.run_config, model.bank, \
            model.joint_space
        initial = model.initial_path_length_m
        driven = self.joint_space.driven if self.joint_space is not None else ()
        self.inputs = NodeInputs(self.bank.names, model.limits, initial, joint_driven=driven)
        self.joint_inputs = (JointInputs(self.joint_space, self.inputs)
                             if self.joint_space is not None else None)
        # the inputs held after each message, by arrival, for the steps (vm_ros.node.input_timeline)
        self.timeline = InputTimeline(self.inputs, self.joint_inputs)
        self.scheduler = StepScheduler(c.step_ns, c.max_catch_up_steps, c.steps_per_tick)
        # on the system clock a tick woken late holds back the steps past its last publish step
        # (StepScheduler.due); a simulated clock's jumps are meant: their steps all run at once
        self._steps_end_on = (0 if self.get_parameter("use_sim_time").value
                              else c.publish_every_steps)
        self.coordination = (LiveCoordination(self.bank, self.joint_space, self.inputs, c,
                                              c.step_ns * 1e-9 * c.publish_every_steps)
                             if c.coordination_enabled else None)
        self.issues = IssueLog(LOG_THROTTLE_S)
        self._gaps: dict[str, SequenceGaps] = {}  # input topic -> publication sequence gaps
        self._wrong_type_publishers: set = set()  # (topic, endpoint gid) seen
        self._reported_counts = dict(self.issues.counts)
        self._dt_s = c.step_ns * 1e-9
        self._step_times = DurationWindow()
        self._tick_times = DurationWindow()
        self.ticks = self._overruns = self._window_ticks = self._window_steps = 0
        self._window_start_s = time.monotonic()
        self._energy_offset_j = 0.0
        self._last_output = None
        self._reset_pending = False  # started, state not yet set (_reset_at_start)

        self._create_endpoints(c.qos_depth)
        self._check_no_unknown_parameters()
        self.run_log = self._open_run_log()
        self._model_timer = self.create_timer(self._dt_s * c.steps_per_tick, self._on_tick)
        self._layouts = bulk.OutputLayouts(self.bank.names, self.bank.energetics_models)
        self._joint_layouts = (bulk.JointLayouts(self.joint_space.output_names)
                               if self.joint_space is not None else None)
        self._diagnostics_timer = self.create_timer(
            c.diagnostics_period_s, self._publish_diagnostics,
            clock=Clock(clock_type=ClockType.STEADY_TIME))
        self._graph_timer = self.create_timer(
            GRAPH_CHECK_PERIOD_S, self._check_publisher_types,
            clock=Clock(clock_type=ClockType.STEADY_TIME))
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self._log_joint_space(initial is not None)
        self.get_logger().info(
            f"{self.bank.n} muscles ({', '.join(self.bank.names)}), {c.recruitment} recruitment, "
            f"{c.recovery_mode} recovery, model {c.model_rate_hz:g} Hz, publish every "
            f"{c.publish_every_steps} steps; "
            + (self._state_text() if not self.inputs.ready else "starting"))

    def _log_joint_space(self, initial_given: bool) -> None:
        space = self.joint_space
        if space is None:
            return
        log = self.get_logger()
        log.info(f"{space.summary()} (geometry {self.config.geometry})")
        if space.ignored:
            log.info(f"geometry muscles not in the muscles parameter, ignored: "
                     f"{', '.join(space.ignored)}")
        if initial_given:
            log.info(f"initial_path_length_m not used for the joint-driven muscles "
                     f"({', '.join(space.driven)}): they wait for joint_states")

    def _create_endpoints(self, depth: int) -> None:
        """Publishers and raw subscriptions, each with its own QoS profile that the standard
        ``qos_overrides.<topic>.<publisher|subscription>.<history|depth|reliability>``
        parameters may change."""
        overridable = QoSOverridingOptions.with_default_policies()
        outputs = list(OUTPUT_TOPICS)
        inputs = [(topic, _MESSAGE_CLASSES[type_name], text) for topic, type_name, text
                  in interface.input_topics(geometry=self.joint_space is not None)]
        if self.joint_space is not None:
            outputs += JOINT_OUTPUT_TOPICS
        if self.bank.energetics_models:
            outputs += MODEL_OUTPUT_TOPICS
        targets = COORDINATION_INPUT_TOPICS if self.coordination is not None else ()
        if self.coordination is not None:
            outputs += COORDINATION_OUTPUT_TOPICS
        self._input_types = {topic: msg_type for topic, msg_type, _ in inputs + list(targets)}
        qos_values = {name: p.value for name, p in self._parameter_overrides.items()
                      if name.startswith("qos_overrides.")}
        for name, value in qos_values.items():  # rcl prints an rcutils warning block for these
            if name.endswith(".depth") and (not isinstance(value, int) or value < 0):
                raise ConfigError(PARAMS_SOURCE, name, value, "depth must be an integer >= 0")
        try:
            self._publishers_by_topic = {
                topic: self.create_publisher(msg_type, topic, stream_qos(depth),
                                             qos_overriding_options=overridable)
                for topic, msg_type, _ in outputs}
            self._subscriptions_by_topic = {
                topic: self.create_subscription(
                    msg_type, topic, self._receiver(topic, msg_type), stream_qos(depth),
                    qos_overriding_options=overridable, raw=True)
                for topic, msg_type, _ in inputs}
            self._subscriptions_by_topic.update({
                topic: self.create_subscription(
                    msg_type, topic, self._target_receiver(topic, msg_type), stream_qos(depth),
                    qos_overriding_options=overridable, raw=True)
                for topic, msg_type, _ in targets})
        except (RuntimeError, InvalidQosOverridesError, InvalidParameterTypeException) as exc:
            named = {k: v for k, v in qos_values.items()
                     if k in str(exc) or str(v) in str(exc)} or qos_values
            name, value = (next(iter(named.items())) if len(named) == 1
                           else ("qos_overrides", named))
            raise ConfigError(PARAMS_SOURCE, name, value, str(exc)) from exc

    def _declare_parameters(self) -> NodeConfig:
        values = {}
        for spec in PARAMS:
            try:
                if spec.kind in _EMPTY_ARRAY_TYPES and not spec.default:
                    # an empty list has no type for rclpy: declare typed, unset
                    self.declare_parameter(spec.name, _EMPTY_ARRAY_TYPES[spec.kind],
                                           parameter_descriptor(spec))
                    try:
                        values[spec.name] = list(self.get_parameter(spec.name).value)
                    except ParameterUninitializedException:
                        values[spec.name] = []
                else:
                    values[spec.name] = self.declare_parameter(
                        spec.name, spec.default, parameter_descriptor(spec)).value
            except (InvalidParameterTypeException, InvalidParameterValueException) as exc:
                raise _parameter_error(exc, self._parameter_overrides) from exc
            if values[spec.name] is None and spec.kind in _EMPTY_ARRAY_TYPES:
                values[spec.name] = []  # '[]' given: rcl reads an empty list as not set
        return NodeConfig.from_values(values)

    def _check_no_unknown_parameters(self) -> None:
        """A misspelt name in a params file or -p would otherwise be ignored silently."""
        unknown = sorted(name for name in self._parameter_overrides if not self.has_parameter(name))
        if unknown:
            value = self._parameter_overrides[unknown[0]].value
            known = ", ".join(p.name for p in PARAMS)
            raise ConfigError(PARAMS_SOURCE, unknown[0], value,
                              f"unknown parameter of {self.get_name()} (known: {known}, "
                              "use_sim_time and qos_overrides.<topic>.<publisher|subscription>."
                              "<history|depth|reliability>)")

    def _on_set_parameters(self, parameters) -> SetParametersResult:
        runtime = set(_runtime_names())
        changes = {p.name: p.value for p in parameters if p.name in runtime}
        if not changes:
            return SetParametersResult(successful=True)
        try:
            config = self.config.with_values(changes)
        except ConfigError as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        self.config = config
        self.inputs.limits = InputLimits.for_bank(self.bank, config)
        return SetParametersResult(successful=True)

    def _open_run_log(self) -> NodeRunLog | None:
        """The MCAP run log (vm_ros.node.recording); inputs' offered QoS is not known here."""
        if not self.config.mcap_enabled:
            return None
        path = self.config.mcap_path or datetime.now().strftime(
            "muscle_node-%Y%m%d-%H%M%S.mcap")
        offered = {topic: offered_qos_profiles_yaml(publisher.qos_profile)
                   for topic, publisher in self._publishers_by_topic.items()}
        run_log = NodeRunLog(path, self._run_info, namespace=self.get_namespace(), qos=offered,
                            on_error=self.get_logger().error,
                            extra_topics=COORDINATION_TOPICS if self.config.coordination_enabled
                            else ())
        self.get_logger().info(f"recording to {run_log.path.resolve()}")
        return run_log

    def _run_info(self, start_time_ns: int | None) -> RunInfo:
        """The log's vm_ros.run record: what `vm-ros recompute` needs to redo this run."""
        c = self.config
        extra = node_run_extra(self.get_fully_qualified_name(), c.as_parameters())
        if start_time_ns is None:
            extra["started"] = "false"
        timing = RunTiming(dt_s=self._dt_s, publish_rate_hz=c.publish_rate_hz,
                           telemetry_rate_hz=0.0, start_time_ns=start_time_ns or 0)
        return RunInfo(self.run_config, timing, source=NODE_SOURCE,
                       namespace=self.get_namespace(),
                       time_base="ROS time (simulated with use_sim_time)", extra=extra)

    # --- inputs -----------------------------------------------------------------------------

    def _receiver(self, topic: str, msg_type):
        row = tp.input_topic(topic)
        receivers = node_receivers(self.inputs, self._on_joint_states)
        gaps = self._gaps[topic] = SequenceGaps()
        # the decoder a recompute uses (vm_ros.recording.cdr.input_decoder), so that the node
        # and its replay agree on what is undecodable; rclpy's deserialiser printed a stderr line
        # per oversized payload and then returned a garbage message
        decode = input_decoder(_type_name(msg_type))
        timeout_ns = self.inputs.limits.timeout_ns

        def receive(data, info=None) -> None:
            if info is None:  # the EventsExecutor's call: one (data, info) tuple, see below
                data, info = data
            lost = gaps.add(info.get("publication_sequence_number"))
            if lost:
                self._report([Issue("input_lost", f"{topic}: {lost} message(s) lost before "
                                    "the node took them", count=lost)])
            now_ns = self.get_clock().now().nanoseconds
            try:
                msg = decode(data)
            except Exception as exc:  # corrupt bytes: never let them stop the node
                msg = None
                self._report([Issue("undecodable", f"{topic}: {type(exc).__name__}: {exc}")])
            # placed at its header stamp when the stamp is on this clock, else at its arrival,
            # never before the model time reached; the steps from there on use it
            # (vm_ros.node.input_timeline); logged there (vm_ros.node.recording)
            stamp_ns = tp.header_stamp_ns(msg) if msg is not None else 0
            started = self.scheduler.started
            placed_ns = (self.timeline.place(input_time_ns(stamp_ns, now_ns, timeout_ns),
                                             self.scheduler.model_time_ns)
                         if started else now_ns)
            if self.run_log is not None:
                self.run_log.write(topic, data, placed_ns, now_ns)
            if msg is None:
                return
            self._report(tp.apply_input(row, msg, receivers,
                                        input_time_ns(stamp_ns, placed_ns, timeout_ns)))
            if started:
                self.timeline.record(placed_ns)

        # rclpy passes the message info (its publication sequence number) to a callback whose
        # signature takes two arguments: SingleThreadedExecutor as receive(data, info), rclpy
        # 7.1.6's EventsExecutor as receive((data, info)) (a callback that needs both arguments
        # failed there: SystemError). receive takes either; its declared signature makes rclpy
        # pass the info.
        receive.__signature__ = _WITH_MESSAGE_INFO
        return receive

    def _on_joint_states(self, names, position, velocity, now_ns: int):
        return self.joint_inputs.on_joint_states(names, position, velocity, now_ns)

    def _target_receiver(self, topic: str, msg_type):
        """The receiver of a live-coordination target topic (vm_ros.node.effort_targets):
        deserialised by rclpy, an undecodable message counted; losses counted as for the other
        inputs; logged at the model time reached when it arrived (the coordinator takes the
        targets at the start of each publish period; a recompute copies them, and applies the
        coordination_drive records)."""
        targets = self.coordination.targets
        handle = {
            tm.TOPIC_JOINT_EFFORT_TRAJECTORY: lambda msg, now_ns: targets.on_trajectory(
                msg.joint_names, msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec,
                [p.time_from_start.sec * 1_000_000_000 + p.time_from_start.nanosec
                 for p in msg.points], [p.effort for p in msg.points], now_ns,
                [p.positions for p in msg.points]),
            tm.TOPIC_JOINT_EFFORT_TARGETS: lambda msg, now_ns: targets.on_stream(
                topic, msg.name, msg.effort, now_ns),
            tm.TOPIC_JOINT_EFFORT_TARGETS_ARRAY: lambda msg, now_ns: targets.on_stream(
                topic, None, msg.data, now_ns),
        }[topic]
        gaps = self._gaps[topic] = SequenceGaps()

        def receive(data, info=None) -> None:
            if info is None:  # the EventsExecutor's call (see _receiver)
                data, info = data
            lost = gaps.add(info.get("publication_sequence_number"))
            if lost:
                self._report([Issue("input_lost", f"{topic}: {lost} message(s) lost before "
                                    "the node took them", count=lost)])
            now_ns = self.get_clock().now().nanoseconds
            if self.run_log is not None:
                self.run_log.write(topic, data, self.scheduler.model_time_ns
                                   if self.scheduler.started else now_ns, now_ns)
            try:
                msg = deserialize_message(data, msg_type)
            except Exception as exc:  # corrupt bytes: never let them stop the node
                self._report([Issue("undecodable", f"{topic}: {type(exc).__name__}: {exc}")])
                return
            self._report(handle(msg, now_ns))

        receive.__signature__ = _WITH_MESSAGE_INFO
        return receive

    def _check_publisher_types(self) -> None:
        """Publishers of another message type on an input topic are never matched, so nothing
        of theirs arrives: count each one once and say so (rmw_fastrtps accepts the
        INCOMPATIBLE_TYPE event but never raises it; the graph is asked instead)."""
        if not self.context.ok():
            return
        for topic, msg_type in self._input_types.items():
            expected = _type_name(msg_type)
            name = self.resolve_topic_name(topic)
            for info in self.get_publishers_info_by_topic(name):
                key = (name, bytes(info.endpoint_gid))
                if info.topic_type == expected or key in self._wrong_type_publishers:
                    continue
                self._wrong_type_publishers.add(key)
                node = f"{info.node_namespace.rstrip('/')}/{info.node_name}"
                self._report([Issue("wrong_type_publisher", f"{name}: publisher {node} offers "
                                    f"{info.topic_type}, this node takes {expected}")])

    def _report(self, issues) -> None:
        for issue in issues:
            line = self.issues.record(issue, time.monotonic())
            if line is None:
                continue
            # rclpy ties a severity to the calling line: one call site per severity
            if issue.kind in QUIET_KINDS:
                self.get_logger().info(line)
            else:
                self.get_logger().warning(line)

    # --- the model loop ---------------------------------------------------------------------

    def _on_tick(self) -> None:
        if not self.context.ok():  # shutting down (a signal): publishing would fail
            return
        tick_start_ns = time.perf_counter_ns()
        now_ns = self.get_clock().now().nanoseconds
        self.ticks += 1  # timer callbacks so far
        self._window_ticks += 1
        if self.scheduler.went_backwards(now_ns):
            self.inputs.rebase(now_ns)
            if self.scheduler.started:  # re-anchored at now_ns: the ticks follow (_start)
                self._model_timer.reset()
            if self.joint_inputs is not None:
                self.joint_inputs.rebase(now_ns)
            self.timeline.restart()  # the rows' times are of the old time base
            self._report([Issue("time_backwards", f"ROS time went back to {now_ns * 1e-9:.6f} s")])
        self._report(self.inputs.update_staleness(now_ns))
        if not self.scheduler.started:
            if self.inputs.ready:
                self._start(now_ns)
        elif self.config.stale_input_policy == "pause" and self.inputs.any_stale:
            self.scheduler.hold(now_ns, self._steps_end_on)
            self.timeline.consume(self.scheduler.model_time_ns)
        else:
            self._run_steps(now_ns)
        tick_ns = time.perf_counter_ns() - tick_start_ns
        self._tick_times.add(tick_ns)
        if tick_ns > self.scheduler.step_ns * self.scheduler.steps_per_tick:
            self._overruns += 1

    def _start(self, now_ns: int) -> None:
        """Start the model's clock at ``now_ns``; the state is set at the next tick
        (_reset_at_start). The model timer restarts at ``now_ns`` too, so that its ticks
        fall just after whole periods of model time (their wake-up delay, which is never
        negative, added): each tick's steps end at a publish step and run in one MuscleBank.run.
        Left in the phase of its creation, every tick that fired earlier in its period than the
        start tick ran 9 steps, and the next one split its 11 at the publish step into two
        calls (docs/performance.md)."""
        self.scheduler.start(now_ns)
        self.timeline.restart()
        self._model_timer.reset()
        if self.run_log is not None:
            self.run_log.start(now_ns)
        self._reset_pending = True

    def _reset_at_start(self) -> None:
        """The equilibrium at the start time from the inputs held then, at the first tick after
        the start (inputs that arrive in between are placed at their arrival, after the start),
        as `vm-ros recompute` does."""
        self._reset_pending = False
        start_ns = self.scheduler.model_time_ns
        _, lp, _, rows = self.timeline.sample_many([start_ns])
        lp = lp[0]
        out = self.bank.reset(path_length=lp)
        self.get_logger().info(f"model started at {start_ns * 1e-9:.6f} s, path lengths "
                               f"{np.round(lp, 5).tolist()} m")
        self._publish(out, self.timeline.joint_sample(rows[0]))

    def _run_steps(self, now_ns: int) -> None:
        if self._reset_pending:
            self._reset_at_start()
        stalls = self.scheduler.stalls
        due = self.scheduler.due(now_ns, self._steps_end_on)
        if self.scheduler.stalls != stalls:
            self._report([Issue("skipped_time", f"model fell behind by more than "
                                f"{self.scheduler.max_catch_up_steps} steps at "
                                f"{now_ns * 1e-9:.6f} s")])
        if due == 0:
            return
        every = self.config.publish_every_steps
        # every step's inputs: those held after the last message that arrived at or before its
        # start (InputTimeline), at once
        t0, step_ns = self.scheduler.model_time_ns, self.scheduler.step_ns
        u, lp, vp, rows = self.timeline.sample_many(
            t0 + step_ns * np.arange(due, dtype=np.int64))
        done = 0
        while done < due:  # batches that end at a publish step or at the last step due
            count = min(due - done, every - self.scheduler.total_steps % every)
            # the moment arms of the batch's forces: the joint sample its last step used
            joints = self.timeline.joint_sample(rows[done + count - 1])
            if self.coordination is not None:  # the joint-driven muscles' drives: solved at
                # the start of each publish period, held over it
                if self.scheduler.total_steps % every == 0:
                    self._report(self.coordination.solve(self.bank.restore_point(),
                                                         self.scheduler.model_time_ns, joints))
                    self._publish_coordination_drive(now_ns)
                u[done:done + count, self.coordination.index] = self.coordination.drive
            self._run_batch(u[done:done + count], lp[done:done + count],
                            vp[done:done + count], joints)
            done += count
        self.timeline.consume(self.scheduler.model_time_ns)
        self._window_steps += due

    def _run_batch(self, u, lp, vp, joints) -> None:
        """The steps of the inputs (k, n) each in one MuscleBank.run; published if the last one
        is a publish step. A non-finite output anywhere in the batch: the batch again, step by
        step from its start (_run_stepwise)."""
        count = len(u)
        start_state = self.bank.restore_point() if count > 1 else None
        started_ns = time.perf_counter_ns()
        if count == 1:
            out = self.bank.step(self._dt_s, u[0], lp[0], vp[0])
            finite = _finite(out)
        else:
            run = self.bank.run(self._dt_s, u, lp, vp)
            out = run.last
            finite = _finite(run)
        self._step_times.add((time.perf_counter_ns() - started_ns) // count)
        if not finite and count > 1:
            self.bank.set_state(start_state)
            self._run_stepwise(u, lp, vp, joints)
            return
        for _ in range(count):
            self.scheduler.advance()
        if not finite:
            out = self._reset_model(lp[-1])
        if self.scheduler.total_steps % self.config.publish_every_steps == 0:
            self._publish(out, joints)

    def _run_stepwise(self, u, lp, vp, joints) -> None:
        """Steps one by one (a batch that gave a non-finite output): the model is reset at the
        step that did, as a tick per step does."""
        for j in range(len(u)):
            out = self.bank.step(self._dt_s, u[j], lp[j], vp[j])
            self.scheduler.advance()
            if not _finite(out):
                out = self._reset_model(lp[j])
            if self.scheduler.total_steps % self.config.publish_every_steps == 0:
                self._publish(out, joints)

    def _reset_model(self, lp):
        """Recover from a non-finite model output: equilibrium at the current path lengths."""
        if self._last_output is not None:
            self._energy_offset_j += self._last_output.total_energy
        self._report([Issue("model_reset", "model output not finite at "
                            f"{self.scheduler.model_time_ns * 1e-9:.6f} s")])
        return self.bank.reset(path_length=lp, time_s=self.bank.time_s)

    # --- outputs ----------------------------------------------------------------------------

    def _send_bytes(self, topic: str, data: bytes, log_time_ns: int,
                    publish_time_ns: int) -> None:
        """Publish and log the same serialised bytes."""
        try:
            self._publishers_by_topic[topic].publish(data)
        except RCLError:
            if self.context.ok():
                raise
            return  # the context was shut down during this callback (a signal)
        if self.run_log is not None:
            self.run_log.write(topic, data, log_time_ns, publish_time_ns)

    def _publish(self, out, joint_sample=None) -> None:
        """The outputs, stamped and logged at the model time; with a geometry also the joint
        efforts of ``out``'s forces through ``joint_sample``'s moment arms. The muscle and joint
        topics' bytes come from fixed layouts (vm_ros.recording.bulk, the bytes rclpy would
        serialise), without a message object."""
        self._last_output = out
        now_ns = self.get_clock().now().nanoseconds
        stamp_ns = self.scheduler.model_time_ns
        for topic, data in self._layouts.encode(out, stamp_ns, self._energy_offset_j):
            self._send_bytes(topic, data, stamp_ns, now_ns)
        if joint_sample is not None:
            efforts = self.joint_inputs.efforts(joint_sample, out.force)
            for topic, data in self._joint_layouts.encode(efforts, stamp_ns):
                self._send_bytes(topic, data, stamp_ns, now_ns)
            if self.coordination is not None:
                self._publish_coordination(out, efforts, stamp_ns, now_ns)

    def _publish_coordination_drive(self, now_ns: int) -> None:
        """coordination_drive: the joint-driven muscles' drives of the period starting now in
        model time, stamped and logged at that time (the drives a recompute applies)."""
        start_ns = self.scheduler.model_time_ns
        fields = tm.muscle_drive_fields(self.coordination.names, self.coordination.drive,
                                        start_ns)
        self._send_bytes(tm.TOPIC_COORDINATION_DRIVE,
                         serialize_message(fill_message(JointState(), fields)), start_ns, now_ns)

    def _publish_coordination(self, out, efforts, stamp_ns: int, now_ns: int) -> None:
        """muscle_drive (the drive every muscle used) and joint_reserves (target - effort)."""
        reserves = JointEfforts(efforts.names, efforts.position, efforts.velocity,
                                self.coordination.reserves(stamp_ns, efforts))
        for topic, fields in (
                (tm.TOPIC_MUSCLE_DRIVE, tm.muscle_drive_fields(self.bank.names, out.excitation,
                                                               stamp_ns)),
                (tm.TOPIC_JOINT_RESERVES, tm.joint_efforts_fields(reserves, stamp_ns))):
            self._send_bytes(topic, serialize_message(fill_message(JointState(), fields)),
                             stamp_ns, now_ns)

    # --- diagnostics ------------------------------------------------------------------------

    def health(self) -> tuple[int, str, list]:
        """(level, message, [(key, value)]) of the node's state since the last report."""
        now_ns = self.get_clock().now().nanoseconds
        wall_s = max(time.monotonic() - self._window_start_s, 1e-9)
        s, c = self.scheduler, self.config
        step_p50, step_p99, step_max = self._step_times.percentiles_ms()
        _, tick_p99, _ = self._tick_times.percentiles_ms()
        ages = self.inputs.ages_s(now_ns)
        stale = self.inputs.stale_names()
        values = [
            ("state", self._state_text()),
            ("model time (s)", f"{s.model_time_ns * 1e-9:.6f}" if s.started else None),
            ("model rate (Hz)", c.model_rate_hz),
            ("tick rate (Hz)", self._window_ticks / wall_s),
            ("step rate (Hz)", self._window_steps / wall_s),
            ("step time p50 (ms)", step_p50),
            ("step time p99 (ms)", step_p99),
            ("step time max (ms)", step_max),
            ("tick time p99 (ms)", tick_p99),
            ("overruns (ticks longer than their period)", self._overruns),
            ("catch-up ticks", s.catch_up_ticks),
            ("skipped model time (s)", format_seconds(s.skipped_ns)),
            ("paused model time (s)", format_seconds(s.paused_ns)),
            ("excitation age (s)", ages["excitation"]),
            ("kinematics age (s)", ages["kinematics"]),
            ("stale excitation", ", ".join(stale["excitation"]) or "-"),
            ("stale kinematics", ", ".join(stale["kinematics"]) or "-"),
        ]
        if self.joint_inputs is not None:
            values += [("joint_states age (s)", self.joint_inputs.age_s(now_ns))]
        if self.coordination is not None:
            values += self.coordination.diagnostics(now_ns)
        values += [(lost_key(topic), gaps.lost if gaps.supported is not False else
                    "not counted: the rmw gives no sequence numbers")
                   for topic, gaps in self._gaps.items()]
        values += [(ISSUE_KINDS[kind][0], count) for kind, count in self.issues.counts.items()]
        values += self._recorder_values()
        level, message = self._level(stale)
        return level, message, [(key, format_value(value)) for key, value in values]

    def _state_text(self) -> str:
        if not self.scheduler.started:
            have = np.isfinite(self.inputs.length_m) | self.inputs.joint_driven
            missing = [n for n, ok in zip(self.bank.names, have, strict=True) if not ok]
            waiting = [f"muscle_kinematics ({', '.join(missing)})"] if missing else []
            if self.joint_inputs is not None and not self.joint_inputs.ready:
                joints = self.joint_inputs.missing()
                waiting.append(f"joint_states ({', '.join(joints)})" if joints else
                               "joint_states (a message giving physical path lengths)")
            return f"waiting for {' and '.join(waiting)}" if waiting else "starting"
        if self.config.stale_input_policy == "pause" and self.inputs.any_stale:
            return "paused (stale inputs, stale_input_policy pause)"
        return "running"

    def _recorder_values(self) -> list:
        if self.run_log is None:
            return [("mcap", "off")]
        st = self.run_log.status
        state = "ok" if self.run_log.started else "waiting for the model start (buffering)"
        return [("mcap", state if st.ok else f"error: {st.error}"), ("mcap path", st.path),
                ("mcap messages written", st.written), ("mcap messages dropped", st.dropped),
                ("mcap bytes written", st.bytes_written)]

    def _level(self, stale) -> tuple[int, str]:
        """ERROR: recording failed, or a model reset since the last report; WARN: not started,
        stale inputs, or issues since the last report; else OK."""
        new = {k: v - self._reported_counts[k] for k, v in self.issues.counts.items()
               if k not in QUIET_KINDS}
        if self.run_log is not None and not self.run_log.status.ok:
            return DiagnosticStatus.ERROR, "MCAP recording failed"
        if new["model_reset"]:
            return DiagnosticStatus.ERROR, "model output was not finite (model reset)"
        if not self.scheduler.started:
            return DiagnosticStatus.WARN, self._state_text()
        if stale["excitation"] or stale["kinematics"]:
            which = " and ".join(k for k in ("excitation", "kinematics") if stale[k])
            return DiagnosticStatus.WARN, (f"stale inputs ({which}; stale_input_policy "
                                           f"{self.config.stale_input_policy})")
        if any(new.values()):
            kinds = ", ".join(k for k, v in new.items() if v)
            return DiagnosticStatus.WARN, f"input or timing issues: {kinds}"
        return DiagnosticStatus.OK, "running"

    def _diagnostics(self, now) -> bytes:
        """The serialised /diagnostics message of health() stamped ``now`` (an rclpy Time)."""
        level, message, values = self.health()
        status = DiagnosticStatus(level=level, name=f"{self.get_name()}: muscle model",
                                  message=message, hardware_id="vm_ros",
                                  values=[KeyValue(key=k, value=v) for k, v in values])
        array = DiagnosticArray(status=[status])
        array.header.stamp = now.to_msg()
        return serialize_message(array)

    def _publish_diagnostics(self) -> None:
        now = self.get_clock().now()
        self._send_bytes(tm.TOPIC_DIAGNOSTICS, self._diagnostics(now), now.nanoseconds,
                         now.nanoseconds)
        self._reported_counts = dict(self.issues.counts)
        self._step_times.clear()
        self._tick_times.clear()
        self._window_ticks = self._window_steps = 0
        self._window_start_s = time.monotonic()

    # --- shutdown ---------------------------------------------------------------------------

    def close_run_log(self) -> None:
        """Finish the MCAP file (idempotent), its last record a /diagnostics message with the
        final counters (not published: the context may be shut down already); log the
        messages written and dropped, and the input messages lost."""
        if self.run_log is not None and not self.run_log.closed:
            now = self.get_clock().now()
            self.run_log.write(tm.TOPIC_DIAGNOSTICS, self._diagnostics(now), now.nanoseconds,
                               now.nanoseconds)
            self.run_log.close()
            st = self.run_log.status
            lost = ", ".join(f"{topic} {gaps.lost}" for topic, gaps in self._gaps.items()
                             if gaps.lost)
            log = self.get_logger().info if st.ok else self.get_logger().error
            log(f"MCAP {st.path}: {st.written} messages, {st.dropped} dropped"
                + ("" if st.ok else f", {st.error}")
                + (f"; input messages lost before the node took them: {lost}" if lost else ""))

    def destroy_node(self):
        self.close_run_log()
        return super().destroy_node()


# --- main --------------------------------------------------------------------------------------


def make_executor(kind: str, context=None):
    """'events' (rclpy.experimental.EventsExecutor) or 'single_threaded'."""
    if kind == "events":
        from rclpy.experimental import EventsExecutor

        return EventsExecutor(context=context)
    return SingleThreadedExecutor(context=context)


def freeze_startup_objects() -> None:
    """Move every object alive now (imports, the compiled model: about 140,000 in muscle_node;
    run_node calls it for each vm_ros node once built) to the garbage collector's permanent
    generation, so that its full collections stop walking them: each stalled the spinning
    thread for several publish periods (docs/performance.md)."""
    gc.collect()
    gc.freeze()


SPIN_CHECK_S = 1.0  # the longest a stop request can wait when no callback runs (see spin)


def spin(executor, context, stop: ShutdownRequest) -> None:
    """Spin until a shutdown is requested or the context is shut down, in the executor's own
    loop: spin_until_future_complete on a future that the stop request completes. Python runs
    the signal handler at the next callback (the model timer's, every publish period), and the
    spin returns from it; without any callback, at the next SPIN_CHECK_S. A Python loop of
    spin_once calls, one per callback, cost the node more (docs/performance.md)."""
    requested = Future()
    stop.when_requested(lambda: requested.done() or requested.set_result(True))
    while not stop.requested and context.ok():
        executor.spin_until_future_complete(requested, timeout_sec=SPIN_CHECK_S)


# the longest the DDS teardown at exit (executor shutdown, node destruction, context shutdown)
# may take before the process gives up on it: Fast DDS 2.14's participant destruction can spin
# forever waiting for a discovery callback of a peer that stops at the same moment (seen once:
# mujoco_sim_node busy at 53 % of a core in DomainParticipant::set_listener for over an hour;
# eProsima/Fast-DDS#6513); a normal teardown takes well under a second
TEARDOWN_LIMIT_S = 30.0


@contextlib.contextmanager
def teardown_limit(limit_s: float):
    """Within the block, a process still in it after ``limit_s`` prints every thread's stack to
    stderr and exits with status 1 (faulthandler's watchdog: a C thread, which fires also while a
    native call holds the GIL, as the hung DDS teardown does). Without a usable stderr the
    block runs unbounded."""
    try:
        faulthandler.dump_traceback_later(limit_s, exit=True, file=sys.__stderr__)
        armed = True
    except (AttributeError, ValueError, OSError):  # no stderr, or one without a descriptor
        armed = False
    try:
        yield
    finally:
        if armed:
            faulthandler.cancel_dump_traceback_later()


def run_node(name: str, parser: argparse.ArgumentParser, make_node, executor_for,
             args=None, finish=None) -> int:
    """The Jazzy-style main of a vm_ros node program: --help (ROS arguments stripped), init with
    vm_ros's signal handling, ``make_node()``, spin on ``executor_for(node)`` until SIGINT or
    SIGTERM, ``finish(node)`` (the node's own outputs, e.g. its run log, closed before any DDS
    teardown), then destroy and shutdown within TEARDOWN_LIMIT_S (teardown_limit). Exit status 2
    with one line (vm_ros.node.startup.error_line) for a VmRosError (a bad parameter) or an rcl
    error at init (an unparsable --params-file); 1 with the threads' stacks on stderr when the
    teardown did not end in time; 0 otherwise, also when a signal came before the node was
    built (then nothing was started)."""
    argv = sys.argv if args is None else list(args)
    stop = ShutdownRequest.install()  # vm_ros.node.main installs it before rclpy's import
    try:
        parser.parse_args(remove_ros_args(argv)[1:])
        rclpy.init(args=argv, signal_handler_options=SignalHandlerOptions.NO)
    except RCLError as exc:  # e.g. an unparsable --params-file or -p: rcl's message names it
        print(error_line(name, exc), file=sys.stderr)
        return EXIT_BAD_PARAMETER
    node = executor = None
    try:
        if stop.requested:
            return 0
        node = make_node()
        executor = executor_for(node)
        executor.add_node(node)
        freeze_startup_objects()
        spin(executor, node.context, stop)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except VmRosError as exc:
        print(error_line(name, exc), file=sys.stderr)
        return EXIT_BAD_PARAMETER
    finally:
        if node is not None and finish is not None:
            finish(node)
        with teardown_limit(TEARDOWN_LIMIT_S):
            if executor is not None:
                executor.shutdown()
            if node is not None:
                node.destroy_node()
            rclpy.try_shutdown()
    return 0


def main(args=None) -> int:
    """muscle_node [--help] [--ros-args ...]: init, node, spin, destroy, shutdown."""
    return run_node(NODE_NAME, interface.argument_parser(), MuscleNode,
                    lambda node: make_executor(node.config.executor), args,
                    finish=MuscleNode.close_run_log)


if __name__ == "__main__":
    sys.exit(main())
