"""mujoco_sim_node: a MuJoCo model as the body of muscle_node's joint-space loop (extras
``mujoco`` and ``ros``).

It steps a MuJoCo model with its own actuation disabled (``mjDSBL_ACTUATION``), applies the latest
generalized forces it received, and publishes the joint coordinates. Topics (relative names):

- in ``joint_effort_commands`` (std_msgs/Float64MultiArray): one generalized force per joint of
  the ``joints`` parameter, in that order (N m for hinges, N for slides), applied as
  ``qfrc_applied`` on each joint's degree of freedom from the next step on and held until the
  next command (muscle_node publishes tau = r^T F there). A command of the wrong length or with
  NaN/inf is dropped and counted.
- out ``joint_states`` (sensor_msgs/JointState): name[] the ``joints`` parameter, position[]
  (rad or m), velocity[], effort[] the generalized forces applied, stamped with the node's clock
  (or with simulated time when ``publish_clock`` is true). With ``wait_for_command`` the initial
  pose is published every tick, without stepping, until the first command arrives: a controller
  that needs joint_states to start (muscle_node with a geometry) then starts the simulation.
- out ``/clock`` (rosgraph_msgs/Clock) when ``publish_clock``: the simulated time after each
  batch of steps, so that muscle_node with ``use_sim_time`` runs on the simulation's time.

QoS: reliable, keep last 10, volatile, for both streams (as muscle_node's; a best-effort peer
needs qos_overrides). /clock: reliable, keep last 1.

Both streams go as bytes, as muscle_node's do: joint_states from a fixed CDR layout
(vm_ros.recording.bulk, the bytes rclpy would serialise), the commands read by the decoder
muscle_node uses for its array input (vm_ros.recording.cdr.input_decoder), without a Python
message object per tick (a command that is not a Float64MultiArray's bytes is dropped and
counted, as one of the wrong length).

Joints are the model's coordinates as vm_ros.geometry.mujoco_backend.MujocoGeometry defines them
(independent hinge and slide joints that a muscle tendon crosses; dependent joints of joint
equalities follow through MuJoCo's constraints). Time: a steady-clock timer every ``tick_s``
steps the model up to ``real_time_factor`` x the wall time elapsed (0: as fast as it can, in
batches of ``max_steps_per_tick``); at most ``max_steps_per_tick`` per tick, steps that could not
be done are counted as overruns, never made up later.
"""

from __future__ import annotations

import argparse
import sys

import numpy as np
from rcl_interfaces.msg import ParameterDescriptor
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock as ClockMsg
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray

from vm_ros.errors import VmRosError
from vm_ros.geometry.mujoco_backend import MujocoGeometry, require_mujoco
from vm_ros.node.shell import make_executor, run_node
from vm_ros.recording import bulk
from vm_ros.recording.cdr import input_decoder
from vm_ros.telemetry import TOPIC_JOINT_EFFORT_COMMANDS, TOPIC_JOINT_STATES

NODE_NAME = "mujoco_sim_node"


def _descriptor(text: str, read_only: bool = True) -> ParameterDescriptor:
    return ParameterDescriptor(description=text, read_only=read_only)


PARAMETERS = (
    ("model", "myoelbow", "myo-sim model name or MJCF file path"),
    ("joints", [""], "joints of joint_effort_commands and joint_states, in order ([''] : every "
     "coordinate of the model)"),
    ("initial_positions", [float("nan")], "initial position per joint of `joints` (rad or m; "
     "[nan]: the middle of each joint's range)"),
    ("dt", 0.001, "simulation step (s), > 0"),
    ("real_time_factor", 1.0, "simulated seconds per wall second; 0: as fast as possible"),
    ("tick_s", 0.002, "period of the stepping timer (s, steady clock), > 0"),
    ("max_steps_per_tick", 100, "most steps one tick may do (catch-up bound), >= 1"),
    ("publish_clock", False, "publish /clock with the simulated time and stamp joint_states "
     "with it"),
    ("wait_for_command", False, "hold the initial pose (publishing joint_states, not stepping) "
     "until the first joint_effort_commands arrives"),
)


def stream_qos(depth: int = 10) -> QoSProfile:
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=depth,
                      reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.VOLATILE)


class MujocoSim:
    """The simulation without ROS: model, data, joint addresses, applied efforts."""

    def __init__(self, model, joints=None, dt: float = 0.001, initial_positions=None):
        mujoco = self._mujoco = require_mujoco()
        geometry = MujocoGeometry(model)
        names = list(joints) if joints else list(geometry.coordinate_names)
        unknown = [n for n in names if n not in geometry.coordinate_names]
        if unknown:
            raise VmRosError(f"joints {unknown} are not coordinates of the model (have: "
                             f"{', '.join(geometry.coordinate_names)})")
        if not dt > 0:
            raise VmRosError(f"dt must be > 0 s (got {dt})")
        self.geometry = geometry
        self.joint_names = tuple(names)
        index = [geometry.coordinate_index(n) for n in names]
        self.qpos_adr = geometry.qpos_addresses[index]
        self.dof_adr = geometry.dof_addresses[index]
        m = self.model = geometry.model
        m.opt.timestep = float(dt)
        m.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_ACTUATION)
        self.data = mujoco.MjData(m)
        q0 = (geometry.lower + geometry.upper) / 2
        if initial_positions is not None:
            values = np.asarray(initial_positions, dtype=float)
            if values.shape != (len(names),):
                raise VmRosError(f"initial_positions: need {len(names)} values, one per joint")
            q0[index] = values
        geometry.set_pose(q0)
        self.data.qpos[:] = geometry.data.qpos
        mujoco.mj_forward(m, self.data)
        self.effort = np.zeros(len(names))
        self.steps = 0

    @property
    def time_s(self) -> float:
        return float(self.data.time)

    def set_effort(self, effort) -> None:
        self.effort = np.asarray(effort, dtype=float).copy()

    def step(self, n: int = 1) -> None:
        d = self.data
        for _ in range(int(n)):
            d.qfrc_applied[:] = 0.0
            d.qfrc_applied[self.dof_adr] = self.effort
            self._mujoco.mj_step(self.model, d)
        self.steps += int(n)

    def positions(self) -> np.ndarray:
        return self.data.qpos[self.qpos_adr].copy()

    def velocities(self) -> np.ndarray:
        return self.data.qvel[self.dof_adr].copy()


class MujocoSimNode(Node):
    """The ROS shell around MujocoSim (module docstring). Usable in-process with a given
    ``context`` and ``parameter_overrides``, like vm_ros.node.shell.MuscleNode."""

    def __init__(self, **kwargs):
        super().__init__(NODE_NAME, **kwargs)
        for name, default, text in PARAMETERS:
            self.declare_parameter(name, default, _descriptor(text))
        p = {name: self.get_parameter(name).value for name, _, _ in PARAMETERS}
        joints = [j for j in (p["joints"] or []) if j]
        initial = [v for v in (p["initial_positions"] or []) if np.isfinite(v)]
        if not p["tick_s"] > 0 or p["max_steps_per_tick"] < 1 or p["real_time_factor"] < 0:
            raise VmRosError("tick_s must be > 0, max_steps_per_tick >= 1, "
                             "real_time_factor >= 0")
        self.sim = MujocoSim(p["model"], joints or None, float(p["dt"]),
                             initial or None)
        self.real_time_factor = float(p["real_time_factor"])
        self.max_steps = int(p["max_steps_per_tick"])
        self.publish_clock = bool(p["publish_clock"])
        self.wait_for_command = bool(p["wait_for_command"])
        self.dropped_commands = 0
        self.commands = 0
        self.overrun_steps = 0
        n = len(self.sim.joint_names)
        self._state_layout = bulk.joint_state_layout(self.sim.joint_names, n, n, n)
        self._decode_command = input_decoder("std_msgs/msg/Float64MultiArray")
        self.states = self.create_publisher(JointState, TOPIC_JOINT_STATES, stream_qos())
        self.create_subscription(Float64MultiArray, TOPIC_JOINT_EFFORT_COMMANDS,
                                 self._on_command, stream_qos(), raw=True)
        self.clock_pub = (self.create_publisher(ClockMsg, "/clock", stream_qos(1))
                          if self.publish_clock else None)
        self._steady = Clock(clock_type=ClockType.STEADY_TIME)
        self._start_ns = None
        self._last_tick_ns = None
        self.timer = self.create_timer(float(p["tick_s"]), self._tick, clock=self._steady)
        self.get_logger().info(
            f"{p['model']}: joints {', '.join(self.sim.joint_names)}, dt {p['dt']} s, "
            f"real time factor {self.real_time_factor:g}")

    def _on_command(self, raw: bytes) -> None:
        try:
            data = self._decode_command(raw).data
        except (ValueError, UnicodeDecodeError):
            data = np.zeros(0)  # not a Float64MultiArray: dropped as a wrong length
        if data.shape != (len(self.sim.joint_names),) or not np.all(np.isfinite(data)):
            self.dropped_commands += 1
            self.get_logger().warning(
                f"joint_effort_commands dropped: need {len(self.sim.joint_names)} finite values "
                f"({', '.join(self.sim.joint_names)}), got {len(data)}",
                throttle_duration_sec=5.0)
            return
        self.commands += 1
        self.sim.set_effort(data)

    def _tick(self) -> None:
        now = self._last_tick_ns = self._steady.now().nanoseconds
        if self.wait_for_command and not self.commands:
            self.publish_state()  # the controller sees the pose; time starts with its command
            return
        if self._start_ns is None:
            self._start_ns = now
        if self.real_time_factor > 0:
            due = int((now - self._start_ns) * 1e-9 * self.real_time_factor
                      / self.sim.model.opt.timestep) - self.sim.steps - self.overrun_steps
            n = min(max(due, 0), self.max_steps)
            self.overrun_steps += max(due - n, 0)
        else:
            n = self.max_steps
        if n:
            self.sim.step(n)
            self.publish_state()

    def destroy_node(self):
        self.get_logger().info(self.run_summary())
        return super().destroy_node()

    def run_summary(self) -> str:
        """One line: simulated and wall time, steps not simulated (fell behind), commands."""
        wall_s = ((self._last_tick_ns - self._start_ns) * 1e-9
                  if self._start_ns is not None else 0.0)
        dt = self.sim.model.opt.timestep
        return (f"simulated {self.sim.time_s:.3f} s in {wall_s:.3f} s of wall time "
                f"({self.sim.steps} steps); {self.overrun_steps * dt:.3f} s not simulated "
                f"(fell behind); {self.commands} commands applied, {self.dropped_commands} "
                "dropped")

    def publish_state(self) -> None:
        if self.publish_clock:
            stamp_ns = int(round(self.sim.time_s * 1e9))
            clock = ClockMsg()
            clock.clock.sec, clock.clock.nanosec = divmod(stamp_ns, 1_000_000_000)
            self.clock_pub.publish(clock)
        else:
            stamp_ns = self.get_clock().now().nanoseconds
        self.states.publish(self._state_layout.encode_one(
            stamp_ns, position=self.sim.positions(), velocity=self.sim.velocities(),
            effort=self.sim.effort))


def _argument_parser() -> argparse.ArgumentParser:
    lines = [f"  {name} (default {default!r}): {text}" for name, default, text in PARAMETERS]
    return argparse.ArgumentParser(
        prog=NODE_NAME, formatter_class=argparse.RawDescriptionHelpFormatter,
        description="A MuJoCo model stepped in real time, driven by joint_effort_commands, "
                    "publishing joint_states. Set parameters with --ros-args -p NAME:=VALUE.",
        epilog="parameters:\n" + "\n".join(lines))


def main(args=None) -> int:
    """mujoco_sim_node [--help] [--ros-args ...]: init, node, spin, destroy, shutdown."""
    return run_node(NODE_NAME, _argument_parser(), MujocoSimNode,
                    lambda node: make_executor("events"), args)


if __name__ == "__main__":
    sys.exit(main())
