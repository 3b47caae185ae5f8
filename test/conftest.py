"""Shared fixtures for the ROS tests. rclpy is imported lazily, so the model and MCAP tests run
without ROS.

ROS tests run only inside a loopback-only network namespace (scripts/netns-run, which `make test`
uses and which sets VM_ROS_NETNS=1): DDS discovery must never reach a real interface. Outside it
they are skipped, except under `make test` or CI, where a missing rclpy or a missing namespace
fails instead: a skip there would hide a broken install.

    def test_x(ros):                      # a fresh rclpy.Context per test
        node = ros.muscle_node(use_sim_time=True)
        probe = ros.probe()
        assert ros.spin_until(lambda: probe.forces, timeout_s=5)
"""

from __future__ import annotations

import contextlib
import os
import sys
import tempfile
import time
from pathlib import Path

import pytest

# The developer benchmarks (bench/vm_ros_bench, not installed with vm_ros) for the tests that
# cover them; only that package is in bench/, so the source tree's vm_ros stays out of sys.path.
sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "bench"))

# `make test` runs the suite on pytest-xdist workers in one loopback-only namespace: each worker's
# ROS graph gets a DDS domain of its own (scripts/netns-run's 42, plus 1 + the worker's number), so
# that nodes and topics of the same names in two workers do not hear each other. Set at import,
# before any rclpy context or child process starts; children inherit it.
_XDIST_WORKER = os.environ.get("PYTEST_XDIST_WORKER", "")
if _XDIST_WORKER.startswith("gw"):
    os.environ["ROS_DOMAIN_ID"] = str(int(os.environ.get("ROS_DOMAIN_ID", "42")) + 1
                                      + int(_XDIST_WORKER[2:]))

STRICT = os.environ.get("VM_ROS_NETNS") == "1" or os.environ.get("CI", "").lower() not in (
    "", "0", "false")

# Variables that a library imported in this process may rewrite (opensim's import sets
# LD_LIBRARY_PATH and PATH): child processes started by later tests (muscle_node, the ROS wheels'
# bootstrapper) need them as they were.
_ENVIRONMENT_GUARDED = ("LD_LIBRARY_PATH", "PATH", "SIMBODY_HOME")
_ENVIRONMENT_AT_START = {name: os.environ.get(name) for name in _ENVIRONMENT_GUARDED}


@pytest.fixture(scope="module")
def osim():
    """The opensim module, imported through test/osim_models (which skips the test without the
    opensim extra and keeps this process's environment intact)."""
    import osim_models

    return osim_models.osim


@pytest.fixture(autouse=True)
def _environment_as_at_start():
    """Fail the test that changed a guarded variable, and put it back for the next one."""
    yield
    changed = {name for name, value in _ENVIRONMENT_AT_START.items()
               if os.environ.get(name) != value}
    for name in changed:
        if _ENVIRONMENT_AT_START[name] is None:
            os.environ.pop(name, None)
        else:
            os.environ[name] = _ENVIRONMENT_AT_START[name]
    assert not changed, (f"the test changed {sorted(changed)} of this process (a child process "
                         "would inherit it): import opensim through "
                         "vm_ros.importers.osim.load_opensim")


def require_module(name: str, extra: str):
    """The module ``name`` of the optional extra ``extra``; without it skip the test (or the
    module, where called at its top), or fail under make test / CI, which install every extra."""
    import importlib

    try:
        return importlib.import_module(name)
    except ImportError as exc:
        reason = f"{name} is not importable ({exc}): install the [{extra}] extra"
        if STRICT:
            pytest.fail(f"{reason} (not skipped: CI or VM_ROS_NETNS=1 is set)")
        pytest.skip(reason, allow_module_level=True)


def require_ros():
    """rclpy, inside the loopback-only namespace; else skip (or fail under make test / CI)."""
    if os.environ.get("VM_ROS_NETNS") != "1":
        reason = ("ROS tests run only inside scripts/netns-run (loopback-only network "
                  "namespace): use `make test`")
        if STRICT:
            pytest.fail(f"{reason} (not skipped: CI is set)")
        pytest.skip(reason)
    try:
        import rclpy
    except Exception as exc:  # ImportError, or the wheels' RMW failing to load
        reason = f"rclpy is not importable ({type(exc).__name__}: {exc}): install the [ros] extra"
        if STRICT:
            pytest.fail(f"{reason} (not skipped: CI or VM_ROS_NETNS=1 is set)")
        pytest.skip(reason)
    if not os.environ.get("HOME") and not os.environ.get("ROS_LOG_DIR"):
        os.environ["ROS_LOG_DIR"] = tempfile.mkdtemp(prefix="vm_ros-roslog-")
    return rclpy


def _handles_sigterm(pid: int) -> bool:
    """Whether process ``pid`` has a handler for SIGTERM (its SigCgt mask in /proc)."""
    import signal

    try:
        with open(f"/proc/{pid}/status", encoding="ascii") as status:
            for line in status:
                if line.startswith("SigCgt:"):
                    return bool(int(line.split()[1], 16) >> (signal.SIGTERM - 1) & 1)
    except OSError:
        pass
    return False


def early_signal_stop(command, sig, delay_s: float, cwd) -> tuple[int, str]:
    """Start ``command``, send ``sig`` ``delay_s`` after its stop handlers are in (the program's
    first line, vm_ros.node.signals; before that the interpreter itself is starting, 30-80 ms
    idle and several times that on a loaded machine, and a SIGINT there is Python's own
    KeyboardInterrupt), and return its exit status and stderr (the process is killed if it has
    not exited 30 s after the signal). Python installs no SIGTERM handler of its own, so the
    handlers are in when SIGTERM appears in the process's caught-signal mask."""
    import subprocess

    process = subprocess.Popen(command, cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                               text=True)
    try:
        deadline = time.monotonic() + 60.0
        while not _handles_sigterm(process.pid) and process.poll() is None:
            assert time.monotonic() < deadline, "the program installed no SIGTERM handler in 60 s"
            time.sleep(0.001)
        time.sleep(delay_s)
        process.send_signal(sig)
        _, stderr = process.communicate(timeout=30)
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
    return process.returncode, stderr


def stamp_ns(msg) -> int:
    """A message's header stamp in ns."""
    return msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec


def set_clock(ros, probe, node, time_ns: int, tick: bool = True) -> None:
    """Publish /clock from ``probe`` (a Probe) until the node's clock shows ``time_ns`` and
    (``tick``) a model tick ran after that. A backward jump re-arms the timer one period later:
    use tick=False."""
    ticks = node.ticks

    def done():
        if node.get_clock().now().nanoseconds != time_ns:
            probe.send_clock(time_ns)
            return False
        return not tick or node.ticks > ticks
    assert ros.spin_until(done, timeout_s=10), f"clock {time_ns} not reached"


class Probe:
    """A test node: publishes inputs (and /clock), records every output message."""

    def __init__(self, context, name: str = "probe"):
        from diagnostic_msgs.msg import DiagnosticArray
        from rclpy.node import Node
        from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
        from rosgraph_msgs.msg import Clock
        from sensor_msgs.msg import JointState
        from std_msgs.msg import Float64, Float64MultiArray

        self.node = Node(name, context=context)
        keep = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1000,
                          reliability=ReliabilityPolicy.RELIABLE)
        self.forces, self.energy_rates, self.energy_rate_totals = [], [], []
        self.energy_totals, self.diagnostics, self.energy_rate_models = [], [], []
        for msg_type, topic, store in ((JointState, "muscle_force", self.forces),
                                       (Float64MultiArray, "energy_rate_models",
                                        self.energy_rate_models),
                                       (Float64MultiArray, "energy_rate", self.energy_rates),
                                       (Float64, "energy_rate_total", self.energy_rate_totals),
                                       (Float64, "energy_total", self.energy_totals),
                                       (DiagnosticArray, "/diagnostics", self.diagnostics)):
            self.node.create_subscription(msg_type, topic, store.append, keep)
        self.excitation = self.node.create_publisher(JointState, "excitation", keep)
        self.excitation_array = self.node.create_publisher(Float64MultiArray, "excitation_array",
                                                           keep)
        self.kinematics = self.node.create_publisher(JointState, "muscle_kinematics", keep)
        self.clock = self.node.create_publisher(Clock, "/clock", keep)
        self._types = {"JointState": JointState, "Float64MultiArray": Float64MultiArray,
                       "Clock": Clock}

    def joint_state(self, names=(), position=(), velocity=(), stamp_ns: int = 0):
        msg = self._types["JointState"]()
        msg.name, msg.position, msg.velocity = list(names), list(position), list(velocity)
        msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(int(stamp_ns), 1_000_000_000)
        return msg

    def send_excitation(self, names, drive, stamp_ns: int = 0):
        self.excitation.publish(self.joint_state(names, drive, stamp_ns=stamp_ns))

    def send_excitation_array(self, drive):
        self.excitation_array.publish(self._types["Float64MultiArray"](data=list(drive)))

    def send_kinematics(self, names, length, velocity=(), stamp_ns: int = 0):
        self.kinematics.publish(self.joint_state(names, length, velocity, stamp_ns))

    def send_clock(self, time_ns: int):
        msg = self._types["Clock"]()
        msg.clock.sec, msg.clock.nanosec = divmod(int(time_ns), 1_000_000_000)
        self.clock.publish(msg)

    def last_diagnostics(self) -> dict:
        """Key -> value of the newest diagnostics status ({} if none yet)."""
        if not self.diagnostics:
            return {}
        status = self.diagnostics[-1].status[0]
        return {kv.key: kv.value for kv in status.values} | {"_level": int.from_bytes(
            status.level, "little") if isinstance(status.level, bytes) else int(status.level),
            "_message": status.message}


class RosHarness:
    """Nodes in one context, spun by one executor in short slices."""

    def __init__(self, rclpy, context):
        from rclpy.executors import SingleThreadedExecutor

        self.rclpy, self.context = rclpy, context
        self.executor = SingleThreadedExecutor(context=context)
        self.nodes = []

    def muscle_node(self, **params):
        """A MuscleNode with parameters NAME=VALUE (use mcap__enabled for mcap.enabled)."""
        from rclpy.parameter import Parameter

        from vm_ros.node.shell import MuscleNode

        overrides = [Parameter(k.replace("__", "."), value=v) for k, v in params.items()]
        node = MuscleNode(context=self.context, parameter_overrides=overrides)
        self._add(node)
        return node

    def probe(self, name: str = "probe") -> Probe:
        probe = Probe(self.context, name)
        self._add(probe.node)
        return probe

    def _add(self, node):
        self.nodes.append(node)
        self.executor.add_node(node)

    def spin_for(self, seconds: float) -> None:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.executor.spin_once(timeout_sec=0.002)

    def spin_until(self, predicate, timeout_s: float = 5.0) -> bool:
        """Spin until ``predicate()`` is true or ``timeout_s`` of steady time passed."""
        end = time.monotonic() + timeout_s
        while time.monotonic() < end:
            if predicate():
                return True
            self.executor.spin_once(timeout_sec=0.002)
        return bool(predicate())

    def close(self) -> None:
        self.executor.shutdown(timeout_sec=1.0)
        for node in self.nodes:
            node.destroy_node()


@contextlib.contextmanager
def ros_context():
    """A RosHarness in an rclpy context of its own, shut down on leaving."""
    rclpy = require_ros()
    context = rclpy.Context()
    rclpy.init(context=context)
    harness = RosHarness(rclpy, context)
    try:
        yield harness
    finally:
        harness.close()
        rclpy.try_shutdown(context=context)


@pytest.fixture
def ros():
    with ros_context() as harness:
        yield harness
