"""The demos' ROS nodes: a driver that plays a scenario's inputs in real time, a monitor that
collects what muscle_node publishes (the demo's summary comes from these messages, never from the
model's internals), and the closed-loop demo's driver, which only sends drive (the simulator
sends joint_states).

    driver = DemoDriver("knee_extension", context=ctx)   # excitation + muscle_kinematics
    monitor = DemoMonitor(context=ctx)                   # muscle_force, energy_rate, energy_total
    ...spin until monitor.stamps_ns...; driver.start(monitor.stamps_ns[0]); ...spin...

    loop = LoopDriver(names, pulses, context=ctx)        # excitation; counts joint_efforts
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64, Float64MultiArray

from vm_ros import telemetry as tm
from vm_ros.offline.scenarios import load_scenario

_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1000,
                  reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE)


class DemoDriver(Node):
    """Publishes a scenario's drive and path kinematics at ``rate_hz``. Scenario time is 0 until
    :meth:`start` is given the model's start time (muscle_node starts its model on the first
    kinematics, so it starts from the scenario's t = 0), then runs on the ROS clock from there,
    wrapped at the scenario's duration: the model sees the same scenario whenever it starts."""

    def __init__(self, scenario: str = "knee_extension", rate_hz: float = 200.0, **kwargs):
        super().__init__("vm_ros_demo_driver", **kwargs)
        self.scenario = load_scenario(scenario)
        bank = self.scenario.make_bank()  # the scenario's path lengths follow the muscles' geometry
        self.names = list(bank.names)
        self.inputs = self.scenario.inputs(bank)
        self._excitation = self.create_publisher(JointState, tm.TOPIC_EXCITATION, _QOS)
        self._kinematics = self.create_publisher(JointState, tm.TOPIC_KINEMATICS, _QOS)
        self.start_ns: int | None = None
        self.create_timer(1.0 / rate_hz, self._tick)

    def start(self, start_ns: int) -> None:
        """Scenario time 0 is ROS time ``start_ns`` (the model's first output stamp)."""
        self.start_ns = int(start_ns)

    def _tick(self) -> None:
        now = self.get_clock().now()
        t = 0.0
        if self.start_ns is not None:
            t = (max(now.nanoseconds - self.start_ns, 0) * 1e-9) % self.scenario.duration_s
        for publisher, position, velocity in (
                (self._excitation, self.inputs.excitation(t), ()),
                (self._kinematics, self.inputs.path_length(t), self.inputs.path_velocity(t))):
            msg = JointState(name=self.names, position=np.asarray(position, float).tolist(),
                             velocity=np.asarray(velocity, float).tolist())
            msg.header.stamp = now.to_msg()
            publisher.publish(msg)


class LoopDriver(Node):
    """Publishes ``excitation`` (name[] ``names``, position[] ``drive(t)``) at ``rate_hz`` for
    the closed loop, and counts muscle_node's joint_efforts. The drive's time t is 0 until the
    first joint_efforts arrives (the loop is closed: muscle_node has joint_states and runs), then
    runs on the ROS clock from that message's arrival. ``sent_to_subscriber``: drive messages
    published while some subscriber (muscle_node) was matched. ``stop_listening()`` ends the
    joint_efforts subscription once the loop is closed: counting every message of a 1 kHz
    stream in a Python callback cost this process about a fifth of a core, taken from
    muscle_node and the simulator on a two-core machine."""

    def __init__(self, names: Sequence[str], drive: Callable[[float], np.ndarray],
                 rate_hz: float = 100.0, **kwargs):
        super().__init__("vm_ros_demo_loop_driver", **kwargs)
        self.names = list(names)
        self.drive = drive
        self.efforts = 0
        self.sent_to_subscriber = 0
        self.start_ns: int | None = None
        self._excitation = self.create_publisher(JointState, tm.TOPIC_EXCITATION, _QOS)
        self._efforts = self.create_subscription(JointState, tm.TOPIC_JOINT_EFFORTS,
                                                 self._on_efforts, _QOS)
        self.create_timer(1.0 / rate_hz, self._tick)
        self._tick()  # muscle_node has a drive before it starts

    def _on_efforts(self, msg: JointState) -> None:
        self.efforts += 1
        if self.start_ns is None:
            self.start_ns = self.get_clock().now().nanoseconds

    def stop_listening(self) -> None:
        """Close the joint_efforts subscription (``efforts`` stops counting)."""
        if self._efforts is not None:
            self.destroy_subscription(self._efforts)
            self._efforts = None

    def _tick(self) -> None:
        now = self.get_clock().now()
        t = 0.0 if self.start_ns is None else (now.nanoseconds - self.start_ns) * 1e-9
        msg = JointState(name=self.names,
                         position=np.asarray(self.drive(t), dtype=float).tolist())
        msg.header.stamp = now.to_msg()
        self._excitation.publish(msg)
        if self._excitation.get_subscription_count() > 0:
            self.sent_to_subscriber += 1


class DemoMonitor(Node):
    """Records what muscle_node publishes, in arrival order: muscle_force stamps and efforts,
    energy_rate arrays, energy_total values and the last /diagnostics values (key -> text).
    vm_ros.cli.demo.demo_summary turns them into the demo's table."""

    def __init__(self, **kwargs):
        super().__init__("vm_ros_demo_monitor", **kwargs)
        self.stamps_ns: list[int] = []
        self.efforts: list[np.ndarray] = []
        self.energy_rates: list[np.ndarray] = []
        self.energy_totals: list[float] = []
        self.names: tuple = ()
        self.diagnostics: dict = {}
        self.create_subscription(JointState, tm.TOPIC_FORCE, self._on_force, _QOS)
        self.create_subscription(Float64MultiArray, tm.TOPIC_ENERGY_RATE, self._on_energy, _QOS)
        self.create_subscription(Float64, tm.TOPIC_ENERGY_TOTAL,
                                 lambda m: self.energy_totals.append(m.data), _QOS)
        self.create_subscription(DiagnosticArray, tm.TOPIC_DIAGNOSTICS, self._on_diagnostics,
                                 _QOS)

    def model_time_s(self) -> float:
        """Model time covered so far (s): the stamp of the last muscle_force whose energy_rate and
        energy_total have arrived too, minus the first."""
        k = min(len(self.stamps_ns), len(self.energy_rates), len(self.energy_totals))
        return (self.stamps_ns[k - 1] - self.stamps_ns[0]) * 1e-9 if k else 0.0

    def _on_diagnostics(self, msg: DiagnosticArray) -> None:
        for status in msg.status:
            if status.hardware_id == "vm_ros":
                self.diagnostics = {kv.key: kv.value for kv in status.values}

    def _on_force(self, msg: JointState) -> None:
        self.names = tuple(msg.name)
        self.stamps_ns.append(msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec)
        self.efforts.append(np.array(msg.effort))

    def _on_energy(self, msg: Float64MultiArray) -> None:
        shape = tuple(d.size for d in msg.layout.dim)
        labels = tuple(d.label for d in msg.layout.dim)
        if labels != ("muscle", "fibre", "component"):
            raise ValueError(f"energy_rate layout {labels} is not (muscle, fibre, component)")
        self.energy_rates.append(np.array(msg.data[msg.layout.data_offset:]).reshape(shape))


__all__ = ["DemoDriver", "DemoMonitor", "LoopDriver"]
