"""The demos' ROS nodes: a driver that plays a scenario's inputs in real time, a monitor that
collects what muscle_node publishes (the demo's summary comes from these messages, never from the
model's internals), and the closed-loop demo's driver, which only sends drive (the simulator
sends joint_states).

    driver = DemoDriver("knee_extension", context=ctx)   # excitation + muscle_kinematics
    monitor = DemoMonitor(context=ctx)                   # muscle_force, energy_rate, energy_total
    ...spin...
    summary = monitor.summary()

    loop = LoopDriver(names, pulses, context=ctx)        # excitation; counts joint_efforts
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64, Float64MultiArray

from vm_ros import telemetry as tm
from vm_ros.scenarios import load_scenario

_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1000,
                  reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE)


class DemoDriver(Node):
    """Publishes a scenario's drive and path kinematics at ``rate_hz``, scenario time running
    from the first tick (ROS clock), wrapped at the scenario's duration."""

    def __init__(self, scenario: str = "knee_extension", rate_hz: float = 200.0, **kwargs):
        super().__init__("vm_ros_demo_driver", **kwargs)
        self.scenario = load_scenario(scenario)
        bank = self.scenario.make_bank()  # the scenario's path lengths follow the muscles' geometry
        self.names = list(bank.names)
        self.inputs = self.scenario.inputs(bank)
        self._excitation = self.create_publisher(JointState, tm.TOPIC_EXCITATION, _QOS)
        self._kinematics = self.create_publisher(JointState, tm.TOPIC_KINEMATICS, _QOS)
        self._start_ns: int | None = None
        self.create_timer(1.0 / rate_hz, self._tick)

    def _tick(self) -> None:
        now = self.get_clock().now()
        if self._start_ns is None:
            self._start_ns = now.nanoseconds
        t = ((now.nanoseconds - self._start_ns) * 1e-9) % self.scenario.duration_s
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
    published while some subscriber (muscle_node) was matched."""

    def __init__(self, names: Sequence[str], drive: Callable[[float], np.ndarray],
                 rate_hz: float = 100.0, **kwargs):
        super().__init__("vm_ros_demo_loop_driver", **kwargs)
        self.names = list(names)
        self.drive = drive
        self.efforts = 0
        self.sent_to_subscriber = 0
        self.start_ns: int | None = None
        self._excitation = self.create_publisher(JointState, tm.TOPIC_EXCITATION, _QOS)
        self.create_subscription(JointState, tm.TOPIC_JOINT_EFFORTS, self._on_efforts, _QOS)
        self.create_timer(1.0 / rate_hz, self._tick)
        self._tick()  # muscle_node has a drive before it starts

    def _on_efforts(self, msg: JointState) -> None:
        self.efforts += 1
        if self.start_ns is None:
            self.start_ns = self.get_clock().now().nanoseconds

    def _tick(self) -> None:
        now = self.get_clock().now()
        t = 0.0 if self.start_ns is None else (now.nanoseconds - self.start_ns) * 1e-9
        msg = JointState(name=self.names,
                         position=np.asarray(self.drive(t), dtype=float).tolist())
        msg.header.stamp = now.to_msg()
        self._excitation.publish(msg)
        if self._excitation.get_subscription_count() > 0:
            self.sent_to_subscriber += 1


@dataclass(frozen=True)
class DemoSummary:
    """What the monitor saw. Energies in J by integrating energy_rate over the force stamps.

    | field | shape | unit |
    | names | (n,) | muscle names |
    | duration_s | () | s, first to last force stamp |
    | messages | () | force messages received |
    | peak_force, mean_force | (n,) | N |
    | energy | (n, 3 fibre labels, 4 components) | J, telemetry layout |
    | energy_total | () | J, change of energy_total over the run |
    | diagnostics | dict | the node's last /diagnostics values (key -> text) |
    """

    names: tuple
    duration_s: float
    messages: int
    peak_force: np.ndarray
    mean_force: np.ndarray
    energy: np.ndarray
    energy_total: float
    diagnostics: dict


class DemoMonitor(Node):
    """Records muscle_force stamps and efforts, energy_rate arrays and energy_total values."""

    def __init__(self, **kwargs):
        super().__init__("vm_ros_demo_monitor", **kwargs)
        self.forces: list[tuple[int, np.ndarray]] = []
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

    def _on_diagnostics(self, msg: DiagnosticArray) -> None:
        for status in msg.status:
            if status.hardware_id == "vm_ros":
                self.diagnostics = {kv.key: kv.value for kv in status.values}

    def _on_force(self, msg: JointState) -> None:
        self.names = tuple(msg.name)
        stamp_ns = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
        self.forces.append((stamp_ns, np.array(msg.effort)))

    def _on_energy(self, msg: Float64MultiArray) -> None:
        shape = tuple(d.size for d in msg.layout.dim)
        labels = tuple(d.label for d in msg.layout.dim)
        if labels != ("muscle", "fibre", "component"):
            raise ValueError(f"energy_rate layout {labels} is not (muscle, fibre, component)")
        self.energy_rates.append(np.array(msg.data[msg.layout.data_offset:]).reshape(shape))

    def summary(self) -> DemoSummary:
        """Force statistics and energies; energy_rate k is paired with force stamp k (both are
        published together) and held over the interval ending at that stamp."""
        k = min(len(self.forces), len(self.energy_rates))
        if k < 2:
            raise RuntimeError(f"too few messages from muscle_node ({k})")
        stamps = np.array([s for s, _ in self.forces[:k]], dtype=np.int64)
        efforts = np.array([f for _, f in self.forces[:k]])
        rates = np.array(self.energy_rates[:k])
        dt_s = np.diff(stamps) * 1e-9
        totals = self.energy_totals
        return DemoSummary(
            names=self.names, duration_s=float((stamps[-1] - stamps[0]) * 1e-9), messages=k,
            peak_force=efforts.max(axis=0), mean_force=efforts.mean(axis=0),
            energy=np.tensordot(dt_s, rates[1:], axes=1),
            energy_total=float(totals[-1] - totals[0]) if len(totals) > 1 else float("nan"),
            diagnostics=dict(self.diagnostics))


__all__ = ["DemoDriver", "DemoMonitor", "DemoSummary", "LoopDriver"]
