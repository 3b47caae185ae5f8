r"""muscle_node under load: N muscles at a given model and publish rate, measured from outside.

    result = run_node_benchmark(100, workdir=Path("bench"))  # inside scripts/netns-run
    # from the repository root (the package is not installed):
    PYTHONPATH=bench python -m vm_ros_bench.node_bench --muscles 100 --duration 60  # JSON
    PYTHONPATH=bench python -m vm_ros_bench.node_bench --geometry geometry.yaml \
        --library muscles.yaml  # joint_states
    PYTHONPATH=bench python -m vm_ros_bench.node_bench --duration 600 --warmup 30 --bag \
        --max-bag-duration 60

What runs: a library YAML in ``workdir`` with ``n_muscles`` uniquely named copies of the shipped
muscles (every field and source kept), a params YAML, and ``python -P -m vm_ros.node`` (this
process's vm_ros, never a source tree in the working folder: vm_ros.child_process) as a child
process (MCAP to ``workdir/node_bench.mcap`` when ``mcap``; with ``bag`` to the rosbag2 bag
directory ``workdir/node_bench/``, split by ``max_bag_size`` / ``max_bag_duration_s`` as the
node's mcap.max_bag_size / mcap.max_bag_duration_s). A driver node in this process
publishes ``muscle_kinematics`` (path lengths oscillating by 10 % of each muscle's anatomical
range at 0.25 Hz, with their velocities) and ``excitation`` (JointState, every muscle the same
drive, stepping between 0.2 and 0.7 every 0.5 s) at ``drive_rate_hz``, and subscribes to every
output. After the model starts and ``warmup_s`` passes, the measurement window of ``duration_s``
begins.

Joint input (``run_joint_node_benchmark``): the node gets a geometry file and a muscle library
(for example those of ``vm-ros import-mjcf``); its muscles are the library's muscles that the
geometry covers, all joint-driven. The driver publishes ``joint_states`` for every coordinate of
the geometry (each oscillating by ``JOINT_SWING`` of its box about the box's middle at 0.25 Hz,
with its velocity) at ``joint_rate_hz`` from its own timer, and ``excitation`` at
``drive_rate_hz``; it also counts joint_efforts and joint_effort_commands. Keys as below, with
rate_joint_states_sent_hz in place of rate_kinematics_sent_hz.

The rclpy floor (``floor_level``, ``--floor LEVEL``): vm_ros_bench.rclpy_floor in place of
muscle_node, started from the same params file and driven and measured the same way: a bare
rclpy node with muscle_node's subscriptions, timers, publishers (bytes of the same sizes),
executor, main and MCAP writer, up to LEVEL (subscriptions, timer, publishers, mcap), and no
model; with --geometry the joint-space node's (joint_states in, joint_efforts and
joint_effort_commands out for its output joints). Its run waits for the driver's two
publishers to be matched instead of a muscle_force; its result has the CPU, thread, memory and
rate keys below (latency, drift and the log's read-back are muscle_node's only).

Definitions (keys of the returned dict; times are the benchmark's steady clock unless stated):

| key | meaning |
| cpu_percent_one_core | node process user+sys CPU (/proc/<pid>/stat) over the window / wall time |
| driver_cpu_percent_one_core | this process (the driver) likewise |
| node_threads_cpu_percent | the node's CPU by thread name (/proc/<pid>/task/*/stat), largest
  first; the Python thread that spins the executor is named after the process (python3...) |
| node_cpus, driver_cpus | the CPUs the node's threads and the driver's were pinned to
  (sched_setaffinity: the node on the last CPU this process may use, the driver on the others,
  so that the two do not take turns on one core; other processes of the machine still share
  them); None with one CPU |
| load_average_1min_start, _end | the machine's 1-minute load average around the window (other load
  competing with the node shows here) |
| rss_window_start_mib, rss_final_mib | node VmRSS at the window's start (after the warm-up)
  and end |
| rss_peak_mib | node VmHWM at the window's end (peak since the process started) |
| rss_growth_mib, rss_max_growth_mib | rss_final_mib, and the largest sample, minus
  rss_window_start_mib |
| rss_growth_mib_per_min | rss_growth_mib / the window in minutes |
| rss_slope_mib_per_hour | least-squares slope of the window's VmRSS samples (every
  rss_sample_period_s, from /proc/<pid>/status), x 3600 s/h; rss_trace: the samples as
  [seconds into the window, MiB] |
| rss_slope_second_half_mib_per_hour | the same over the samples of the window's second half |
| latency_p50_ms, _p99_ms, _max_ms | excitation-to-force latency, below (latency_samples) |
| latency_publish_wait_p50_ms, _p99_ms | of that latency, the wait for the publish step: the
  answering muscle_force's stamp - the excitation's stamp (ROS time), below |
| latency_after_publish_step_p50_ms, _p99_ms | the latency minus that wait, per excitation: the
  node's answer after the publish step that carries the excitation (its tick's lag, the run of
  the steps, the publication and delivery), whatever the timers' phase, below |
| excitation_not_in_node_log | window excitations the node never logged: dropped from its
  subscription queue (depth qos_depth) while it was busy (MCAP only) |
| latency_no_response | window excitations without a muscle_force response here |
| model_wall_drift_percent | 100 (integrated model time - wall time) / wall time, below |
| model_time_skipped_s | model time the node skipped (fell more than max_catch_up_steps behind) |
| model_lag_p50_ms, _p99_ms, _max_ms | ROS time a muscle_force arrived here - its stamp |
| step_time_p50_ms, _p99_ms | median over the window's /diagnostics reports of the node's values |
| rate_<topic>_hz | messages received here (outputs) or sent (inputs) per second of window |
| mcap_file_mib | size of the finished MCAP file (bag: of all its files) |
| log_files, log_file_mib_max | MCAP files of the log (a single file: 1) and the largest one |
| log_messages_summary | messages by the files' summaries (each file's statistics record) |
| log_messages_read | messages read back through every file (vm_ros.recording.LogReader, chunk
  CRCs checked) |
| log_read_complete | every file read to its end and log_messages_read == log_messages_summary;
  for a bag also metadata.yaml present and listing every file (log_metadata_files); False with
  log_read_error when the log cannot be read at all |

Excitation-to-force latency: for each excitation message published in the window, the time from
just before ``publish()`` to the arrival here of the first ``muscle_force`` message whose stamp is
at or after ``e + 1/model_rate_hz``, where ``e`` is the model time of the first model step that
used the excitation. With MCAP on, ``e`` is exact: the node logs every input at that model time
(vm_ros.node.recording); the message is found by its header stamp. Without MCAP
(``latency_from_node_log`` false), ``e`` is taken as the excitation's publish time (ROS time):
the force then comes from a step that started after the excitation was sent, so the value is an
upper bound (too high by up to one publish period plus the model's lag behind ROS time). The
latency includes waiting for the next publish (outputs go out every
round(model_rate_hz/publish_rate_hz) steps), DDS delivery both ways and both executors.
The wait for the publish step (latency_publish_wait_*) is set by the phase of the driver's
excitation timer against the node's publish steps: both run at their own fixed rate, so the
phase stays as it fell at the start, from a step (about one model step) to a publish period plus
a step for every excitation of a run. The rest of the latency (latency_after_publish_step_*)
is about model_lag (the node's tick after the publish step, its outputs' delivery). So the
latency's p99 under one publish period holds for some phases only: an excitation stamped within
the last model step before a publish step is first used by the step that starts at that publish
step (a step takes the inputs held at its start), and its answer is the next publish step's, a
publish period plus up to a step after its stamp (docs/performance.md, the joint-space node).

Model time vs wall time: the node's /diagnostics report, at one instant, its model time and the
skipped and paused model time so far (vm_ros.node.timing). Between the first and last report in
the window, integrated model time = change of model time - change of skipped - change of paused
time (= steps run x dt); wall time = change of the reports' stamps. Skipping keeps the stamps
near wall time, so the stamps alone would hide a node that cannot keep up.

ROS time is the system clock here (no use_sim_time), so stamps compare with ``time.time_ns()``.
"""

from __future__ import annotations

import argparse
import contextlib
import copy
import fcntl
import json
import math
import os
import shutil
import signal
import socket
import struct
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

from vm_ros import telemetry as tm
from vm_ros.child_process import module_command, module_environment
from vm_ros.model import MuscleBank
from vm_ros.model.params import load_muscle_library
from vm_ros.node.inputs import physical_path_length_range

MIB = 1024.0 * 1024.0
START_TIMEOUT_S = 60.0  # node process start until the first muscle_force (imports, bank build)
STOP_TIMEOUT_S = 30.0  # SIGINT until exit (the MCAP file is finished), then SIGKILL
TAIL_S = 0.5  # driving and receiving after the window, so late responses still arrive
DRIVE_LOW, DRIVE_HIGH = 0.2, 0.7
DRIVE_STEP_PERIOD_S = 0.5
LENGTH_SWING = 0.1  # amplitude, as a fraction of the anatomical path-length range
LENGTH_FREQUENCY_HZ = 0.25
JOINT_SWING = 0.25  # amplitude, as a fraction of each coordinate's box (joint input)
STAMP_MATCH_NS = 1000  # an excitation's stamp read back from the log (float64) vs as sent
RSS_SAMPLE_PERIOD_S = 5.0  # node VmRSS sampled this often during the window
SECONDS_PER_HOUR = 3600.0
LOG_NAME = "node_bench"  # workdir/node_bench.mcap, or the bag directory workdir/node_bench/
# the rclpy floor's levels (vm_ros_bench.rclpy_floor), each with the ones before
FLOOR_LEVELS = ("subscriptions", "timer", "publishers", "mcap")
FLOOR_NODE_PARAMETERS = ("executor", "qos_depth")  # the node parameters the floor takes

_SIOCGIFFLAGS = 0x8913  # linux/sockios.h
_IFF_UP = 0x1


# --- set-up ------------------------------------------------------------------------------------


def check_loopback_only() -> None:
    """Raise RuntimeError unless loopback is the only interface that is up.

    Asks the kernel about this process's network namespace (if_nameindex, SIOCGIFFLAGS):
    /sys/class/net would list the host's interfaces inside ``unshare -n`` unless sysfs is
    remounted.
    """
    up, loopback_up = [], False
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        for _, name in socket.if_nameindex():
            request = struct.pack("16s24x", name.encode()[:15])
            flags = struct.unpack_from("H", fcntl.ioctl(sock.fileno(), _SIOCGIFFLAGS, request),
                                       16)[0]
            if name == "lo":
                loopback_up = bool(flags & _IFF_UP)
            elif flags & _IFF_UP:
                up.append(name)
    if up:
        raise RuntimeError(
            f"network interface(s) {', '.join(up)} are up: the node benchmark starts DDS, whose "
            "discovery multicasts on every interface. Run it in a loopback-only network "
            "namespace: scripts/netns-run vm-ros bench ... (docs/node.md section 6)")
    if not loopback_up:
        raise RuntimeError("the loopback interface is down: DDS needs it (`ip link set lo up`, "
                           "as scripts/netns-run does)")


def write_library(path: Path, n_muscles: int) -> list[str]:
    """A muscle library with ``n_muscles`` copies of the shipped muscles, cycled in file order
    and named ``<muscle>_<k>`` (k = 0..n-1, zero-padded); every field and source kept."""
    if n_muscles < 1:
        raise ValueError(f"n_muscles must be >= 1, got {n_muscles}")
    shipped = list(load_muscle_library().items())
    width = len(str(n_muscles - 1))
    entries = {}
    for k in range(n_muscles):
        name, fields = shipped[k % len(shipped)]
        entries[f"{name}_{k:0{width}d}"] = copy.deepcopy(fields)
    header = (f"# vm_ros node benchmark: {n_muscles} copies of the shipped muscles "
              "(config/muscles.yaml), renamed <muscle>_<k>\n")
    path.write_text(header + yaml.safe_dump({"muscles": entries}, sort_keys=False,
                                            allow_unicode=True, width=100), encoding="utf-8")
    return list(entries)


def write_params(path: Path, names: list[str], library: Path, model_rate_hz: float,
                 publish_rate_hz: float, mcap_path: Path | None,
                 diagnostics_period_s: float, geometry: Path | None = None,
                 node_parameters: dict | None = None, mcap_options: dict | None = None) -> None:
    """muscle_node's params YAML (the model starts at the first muscle_kinematics, or with a
    ``geometry`` file at the first joint_states naming every coordinate); ``node_parameters``
    adds or replaces parameters (e.g. ``{"executor": "single_threaded"}``); ``mcap_options``
    adds mcap.* parameters (e.g. ``{"max_bag_duration_s": 60.0}``)."""
    params = {
        "muscles": list(names), "library": str(library), "model_rate_hz": float(model_rate_hz),
        "publish_rate_hz": float(publish_rate_hz),
        "diagnostics_period_s": float(diagnostics_period_s),
        "mcap": {"enabled": mcap_path is not None,
                 "path": str(mcap_path) if mcap_path is not None else "",
                 **(mcap_options or {})},
    }
    if geometry is not None:
        params["geometry"] = str(geometry)
    params.update(node_parameters or {})
    path.write_text(yaml.safe_dump({"/**": {"ros__parameters": params}}, sort_keys=False),
                    encoding="utf-8")


def _node_command(params_path: Path, floor_level: str | None = None) -> tuple[list[str], dict]:
    """(command, environment) of muscle_node of the vm_ros this process runs (not a source tree
    in the working folder), or with ``floor_level`` of the rclpy floor
    (vm_ros_bench.rclpy_floor) reading the same params file."""
    if floor_level is None:
        return (module_command("vm_ros.node", "--ros-args", "--params-file", str(params_path)),
                module_environment())
    from vm_ros_bench import child_environment

    return (module_command("vm_ros_bench.rclpy_floor", "--params", str(params_path),
                           "--level", floor_level), child_environment())


# --- /proc -------------------------------------------------------------------------------------


def cpu_seconds(pid: int | str) -> float:
    """User + system CPU time (s) of a process (all its threads) from /proc/<pid>/stat."""
    text = Path(f"/proc/{pid}/stat").read_text()
    fields = text[text.rindex(")") + 2:].split()  # fields 3.. (comm may hold spaces)
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def memory_mib(pid: int | str) -> tuple[float, float]:
    """(VmRSS, VmHWM) of a process in MiB from /proc/<pid>/status."""
    values = {}
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        key, _, rest = line.partition(":")
        if key in ("VmRSS", "VmHWM"):
            values[key] = int(rest.split()[0]) / 1024.0  # kB
    return values["VmRSS"], values["VmHWM"]


def thread_cpu_seconds(pid: int | str) -> dict[str, float]:
    """User + system CPU time (s) of each thread of a process by thread name (threads of one
    name added), from /proc/<pid>/task/*/stat."""
    out: dict[str, float] = {}
    for task in Path(f"/proc/{pid}/task").iterdir():
        try:
            text = (task / "stat").read_text()
        except OSError:  # the thread ended
            continue
        name = text[text.index("(") + 1:text.rindex(")")]
        fields = text[text.rindex(")") + 2:].split()
        out[name] = out.get(name, 0.0) + (int(fields[11]) + int(fields[12])) / os.sysconf(
            "SC_CLK_TCK")
    return out


def pin_cpus() -> tuple[set[int], set[int]] | None:
    """(node CPUs, driver CPUs): the last CPU this process may run on for the node, the others
    for the driver; None with fewer than two (or no sched_setaffinity)."""
    if not hasattr(os, "sched_setaffinity"):
        return None
    cpus = sorted(os.sched_getaffinity(0))
    return ({cpus[-1]}, set(cpus[:-1])) if len(cpus) >= 2 else None


def set_process_affinity(pid: int | str, cpus: set[int]) -> None:
    """Every thread of a process on ``cpus`` (threads started later inherit their creator's)."""
    for task in Path(f"/proc/{pid}/task").iterdir():
        with contextlib.suppress(OSError):  # the thread ended
            os.sched_setaffinity(int(task.name), cpus)


# --- the driver --------------------------------------------------------------------------------


def _stamp_ns(stamp) -> int:
    return stamp.sec * 1_000_000_000 + stamp.nanosec


@dataclass(frozen=True)
class Sweep:
    """The kinematics the driver publishes: on ``topic``, for ``names``, positions
    mid + swing sin(2 pi f t) (m or rad) and their velocities."""

    topic: str
    names: tuple
    mid: np.ndarray
    swing: np.ndarray
    frequency_hz: float = LENGTH_FREQUENCY_HZ

    @classmethod
    def around(cls, topic: str, names, lower, upper, fraction: float) -> Sweep:
        """Oscillating by ``fraction`` of [lower, upper] about its middle."""
        lower, upper = np.asarray(lower, dtype=float), np.asarray(upper, dtype=float)
        return cls(topic, tuple(names), 0.5 * (lower + upper), fraction * (upper - lower))

    def at(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        phase = 2.0 * math.pi * self.frequency_hz * t
        return (self.mid + self.swing * math.sin(phase),
                self.swing * 2.0 * math.pi * self.frequency_hz * math.cos(phase))


class BenchDriver:
    """The benchmark's ROS node: publishes the drive and kinematics, records what arrives.

    ``sweep`` gives the kinematics (muscle_kinematics or joint_states); ``sweep_rate_hz`` None
    publishes them with each excitation, else from a timer of their own. Outputs are subscribed
    raw; a muscle_force stamp is read from the CDR bytes (encapsulation header, then
    header.stamp sec int32 and nanosec uint32), so that receiving costs little.
    """

    def __init__(self, context, names, sweep: Sweep, drive_rate_hz: float,
                 sweep_rate_hz: float | None = None):
        from diagnostic_msgs.msg import DiagnosticArray
        from rclpy.node import Node
        from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
        from sensor_msgs.msg import JointState
        from std_msgs.msg import Float64, Float64MultiArray

        self._joint_state = JointState
        self.names = list(names)
        self.node = Node("vm_ros_bench_driver", context=context)
        qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1000,
                         reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.VOLATILE)
        self._excitation = self.node.create_publisher(JointState, tm.TOPIC_EXCITATION, qos)
        self.sweep = sweep
        self._kinematics = self.node.create_publisher(JointState, sweep.topic, qos)
        self._sweep_names = list(sweep.names)
        joints = sweep.topic == tm.TOPIC_JOINT_STATES
        # received outputs: steady-clock arrival (ns); muscle_force also ROS arrival and stamp
        self.force_mono_ns: list[int] = []
        self.force_ros_ns: list[int] = []
        self.force_stamp_ns: list[int] = []
        self.last_force: bytes | None = None
        self.last_joint_efforts: bytes | None = None
        outputs = [(tm.TOPIC_ENERGY_RATE, Float64MultiArray), (tm.TOPIC_ENERGY_RATE_TOTAL, Float64),
                   (tm.TOPIC_ENERGY_TOTAL, Float64)]
        if joints:
            outputs += [(tm.TOPIC_JOINT_EFFORTS, JointState),
                        (tm.TOPIC_JOINT_EFFORT_COMMANDS, Float64MultiArray)]
        self.received = {topic: [] for topic, _ in outputs}
        self.diagnostics: list[tuple[int, dict]] = []  # (stamp ns, key -> value)
        # sent inputs: steady clock just before publish(); excitation also its stamp (ROS time)
        self.excitation_mono_ns: list[int] = []
        self.excitation_stamp_ns: list[int] = []
        self.kinematics_mono_ns: list[int] = []
        self.drive_steps = 0
        self._last_drive: float | None = None
        self._start_mono_ns: int | None = None

        self.node.create_subscription(JointState, tm.TOPIC_FORCE, self._on_force, qos, raw=True)
        for topic, msg_type in outputs:
            arrivals = self.received[topic]
            callback = (self._on_joint_efforts if topic == tm.TOPIC_JOINT_EFFORTS else
                        lambda _data, a=arrivals: a.append(time.monotonic_ns()))
            self.node.create_subscription(msg_type, topic, callback, qos, raw=True)
        self.node.create_subscription(DiagnosticArray, tm.TOPIC_DIAGNOSTICS,
                                      self._on_diagnostics, qos)
        self._timers = [self.node.create_timer(1.0 / drive_rate_hz, self._tick)]
        self._sweep_with_drive = sweep_rate_hz is None
        if not self._sweep_with_drive:
            self._timers.append(self.node.create_timer(1.0 / sweep_rate_hz, self._sweep_tick))

    def matched(self) -> bool:
        """Both inputs' publishers have a subscriber (a node that takes them is there)."""
        return (self._excitation.get_subscription_count() > 0
                and self._kinematics.get_subscription_count() > 0)

    def stop_driving(self) -> None:
        for timer in self._timers:
            self.node.destroy_timer(timer)
        self._timers = []

    def _elapsed_s(self, mono_ns: int) -> float:
        if self._start_mono_ns is None:
            self._start_mono_ns = mono_ns
        return (mono_ns - self._start_mono_ns) * 1e-9

    def _kinematics_message(self, t: float):
        position, velocity = self.sweep.at(t)
        return self._joint_state(name=self._sweep_names, position=position.tolist(),
                                 velocity=velocity.tolist())

    def _tick(self) -> None:
        t = self._elapsed_s(time.monotonic_ns())
        drive = DRIVE_HIGH if int(t / DRIVE_STEP_PERIOD_S) % 2 else DRIVE_LOW
        if self._last_drive is not None and drive != self._last_drive:
            self.drive_steps += 1
        self._last_drive = drive

        messages = [self._kinematics_message(t)] if self._sweep_with_drive else []
        excitation = self._joint_state(name=self.names, position=[drive] * len(self.names))
        stamp_ns = time.time_ns()
        for msg in (*messages, excitation):
            msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(stamp_ns, 1_000_000_000)
        if messages:
            self.kinematics_mono_ns.append(time.monotonic_ns())
            self._kinematics.publish(messages[0])
        self.excitation_stamp_ns.append(stamp_ns)
        self.excitation_mono_ns.append(time.monotonic_ns())
        self._excitation.publish(excitation)

    def _sweep_tick(self) -> None:
        kinematics = self._kinematics_message(self._elapsed_s(time.monotonic_ns()))
        kinematics.header.stamp.sec, kinematics.header.stamp.nanosec = divmod(
            time.time_ns(), 1_000_000_000)
        self.kinematics_mono_ns.append(time.monotonic_ns())
        self._kinematics.publish(kinematics)

    def _on_joint_efforts(self, data: bytes) -> None:
        self.received[tm.TOPIC_JOINT_EFFORTS].append(time.monotonic_ns())
        self.last_joint_efforts = data

    def _on_force(self, data: bytes) -> None:
        self.force_mono_ns.append(time.monotonic_ns())
        self.force_ros_ns.append(time.time_ns())
        sec, nanosec = struct.unpack_from("<iI" if data[1] == 1 else ">iI", data, 4)
        self.force_stamp_ns.append(sec * 1_000_000_000 + nanosec)
        self.last_force = data

    def _on_diagnostics(self, msg) -> None:
        for status in msg.status:
            if status.hardware_id == "vm_ros":
                self.diagnostics.append((_stamp_ns(msg.header.stamp),
                                         {kv.key: kv.value for kv in status.values}))

    def last_force_message(self):
        """The newest muscle_force, deserialised (None before the first)."""
        return self._deserialize(self.last_force)

    def last_joint_efforts_message(self):
        """The newest joint_efforts, deserialised (None before the first)."""
        return self._deserialize(self.last_joint_efforts)

    def _deserialize(self, data: bytes | None):
        from rclpy.serialization import deserialize_message

        return None if data is None else deserialize_message(data, self._joint_state)


# --- measuring ---------------------------------------------------------------------------------


def _make_executor(context):
    try:
        from rclpy.experimental import EventsExecutor
    except ImportError:  # pragma: no cover - older rclpy
        from rclpy.executors import SingleThreadedExecutor

        return SingleThreadedExecutor(context=context)
    return EventsExecutor(context=context)


def _percentiles_ms(values_ns) -> tuple[float, float, float]:
    """(p50, p99, max) in ms; NaN when empty."""
    if len(values_ns) == 0:
        return math.nan, math.nan, math.nan
    a = np.asarray(values_ns, dtype=float) * 1e-6
    return float(np.percentile(a, 50)), float(np.percentile(a, 99)), float(a.max())


def _count_between(times_ns, start_ns: int, end_ns: int) -> int:
    a = np.asarray(times_ns, dtype=np.int64)
    return int(np.count_nonzero((a >= start_ns) & (a < end_ns)))


def _number(text) -> float:
    try:
        return float(text)
    except (TypeError, ValueError):
        return math.nan


def _stop_process(process: subprocess.Popen) -> tuple[int, float]:
    """SIGINT, wait up to STOP_TIMEOUT_S, then SIGKILL; (exit code, seconds to stop)."""
    start = time.monotonic()
    if process.poll() is None:
        process.send_signal(signal.SIGINT)
        try:
            process.wait(timeout=STOP_TIMEOUT_S)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()
    return process.returncode, time.monotonic() - start


def _tail(path: Path, lines: int = 20) -> str:
    try:
        return "\n".join(path.read_text(errors="replace").splitlines()[-lines:])
    except OSError:
        return ""


def _drift(diagnostics, start_ros_ns: int, end_ros_ns: int) -> dict:
    """Model time vs wall time from the node's /diagnostics reports inside the window."""
    reports = [(stamp, v) for stamp, v in diagnostics
               if start_ros_ns <= stamp <= end_ros_ns and _number(v.get("model time (s)")) >= 0]
    out = {"model_wall_drift_percent": math.nan, "model_time_skipped_s": math.nan,
           "model_step_rate_hz": math.nan, "diagnostics_span_s": 0.0, "overruns": math.nan,
           "catch_up_ticks": math.nan, "step_time_p50_ms": math.nan,
           "step_time_p99_ms": math.nan, "step_time_max_ms": math.nan,
           "tick_time_p99_ms": math.nan}
    if len(reports) < 2:
        return out
    (t0, first), (t1, last) = reports[0], reports[-1]
    wall_s = (t1 - t0) * 1e-9

    def change(key):
        return _number(last.get(key)) - _number(first.get(key))

    skipped_s = change("skipped model time (s)")
    integrated_s = change("model time (s)") - skipped_s - change("paused model time (s)")
    out.update(model_wall_drift_percent=100.0 * (integrated_s - wall_s) / wall_s,
               model_time_skipped_s=skipped_s, diagnostics_span_s=wall_s,
               overruns=change("overruns (ticks longer than their period)"),
               catch_up_ticks=change("catch-up ticks"))
    values = [v for _, v in reports]
    for key, name in (("step time p50 (ms)", "step_time_p50_ms"),
                      ("step time p99 (ms)", "step_time_p99_ms"),
                      ("tick time p99 (ms)", "tick_time_p99_ms"),
                      ("step rate (Hz)", "model_step_rate_hz")):
        out[name] = float(np.nanmedian([_number(v.get(key)) for v in values]))
    out["step_time_max_ms"] = float(np.nanmax([_number(v.get("step time max (ms)"))
                                               for v in values]))
    return out


def _effective_times(mcap_path: Path) -> tuple[np.ndarray, np.ndarray]:
    """(header stamps, model times of the first step that used them), ns, sorted by stamp, of
    the excitation messages in the node's MCAP log (inputs are logged at that model time).
    read_run gives stamps as float64 (256 ns resolution at today's epoch times)."""
    from vm_ros.recording import read_run

    series = read_run(mcap_path, topics=[tm.TOPIC_EXCITATION]).get(tm.TOPIC_EXCITATION)
    if series is None:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    stamps = np.rint(np.asarray(series.fields["stamp_ns"], dtype=float)).astype(np.int64)
    order = np.argsort(stamps, kind="stable")
    return stamps[order], np.asarray(series.time_ns, dtype=np.int64)[order]


def _lookup(keys: np.ndarray, values: np.ndarray, key: int, tolerance: int) -> int | None:
    """values[i] for the sorted ``keys[i]`` nearest to ``key`` if within ``tolerance``."""
    k = int(np.searchsorted(keys, key))
    best = min((i for i in (k - 1, k) if 0 <= i < len(keys)), key=lambda i: abs(keys[i] - key),
               default=None)
    if best is None or abs(int(keys[best]) - key) > tolerance:
        return None
    return int(values[best])


def _latencies(driver: BenchDriver, start_mono_ns: int, end_mono_ns: int, step_ns: int,
               effective: tuple[np.ndarray, np.ndarray] | None
               ) -> tuple[list[int], int, int, list[int]]:
    """(latencies in ns, number not in the node's log, number without a response, the waits
    for the publish step in ns) of the window's excitation messages (module docstring).
    ``effective`` None: the publish time stands for the model time."""
    stamps = np.asarray(driver.force_stamp_ns, dtype=np.int64)
    arrivals = np.asarray(driver.force_mono_ns, dtype=np.int64)
    order = np.argsort(stamps, kind="stable")  # arrival order already, unless time went back
    stamps, arrivals = stamps[order], arrivals[order]
    latencies, lost, missing, waits = [], 0, 0, []
    for sent_ns, stamp_ns in zip(driver.excitation_mono_ns, driver.excitation_stamp_ns,
                                 strict=True):
        if not start_mono_ns <= sent_ns < end_mono_ns:
            continue
        applied_ns = (stamp_ns if effective is None
                      else _lookup(*effective, stamp_ns, tolerance=STAMP_MATCH_NS))
        if applied_ns is None:  # never reached the node (its subscription queue overflowed)
            lost += 1
            continue
        k = int(np.searchsorted(stamps, applied_ns + step_ns, side="left"))
        if k == len(stamps):
            missing += 1
            continue
        latencies.append(int(arrivals[k]) - sent_ns)
        waits.append(int(stamps[k]) - stamp_ns)
    return latencies, lost, missing, waits


def run_node_benchmark(n_muscles: int, model_rate_hz: float = 1000.0,
                       publish_rate_hz: float = 100.0, duration_s: float = 60.0,
                       mcap: bool = True, workdir: Path | str | None = None,
                       progress: Callable[[float, float], None] | None = None, *,
                       warmup_s: float = 5.0, drive_rate_hz: float = 100.0,
                       node_parameters: dict | None = None, bag: bool = False,
                       max_bag_size: int = 0, max_bag_duration_s: float = 0.0,
                       rss_sample_period_s: float = RSS_SAMPLE_PERIOD_S,
                       floor_level: str | None = None) -> dict:
    """Run muscle_node with ``n_muscles`` as a process and measure it (module docstring);
    ``node_parameters`` are added to its params file. ``bag``: log to a rosbag2 bag directory,
    split at ``max_bag_size`` bytes / ``max_bag_duration_s`` seconds (0: no split; splitting
    needs ``bag``). ValueError for inconsistent options. ``floor_level`` (one of
    vm_ros_bench.rclpy_floor.LEVELS): the rclpy floor of the same traffic in place of
    muscle_node (its MCAP log with ``mcap`` at level mcap); the result says ``floor_level``
    (None for muscle_node).

    Call inside a loopback-only network namespace (scripts/netns-run); raises RuntimeError when
    another interface is up, and when the node does not start or dies. ``workdir`` receives the
    library, params, node log (muscle_node.log) and MCAP file; None: a temporary directory,
    removed afterwards. ``progress(done_s, total_s)`` is called about twice a second during the
    warm-up and the window. Returns a flat dict of numbers (units in the key names).
    """

    def setup(workdir: Path):
        library = workdir / "node_bench_muscles.yaml"
        names = write_library(library, n_muscles)
        lo, hi = physical_path_length_range(MuscleBank.from_config(names, library=library), 0.0)
        return names, library, None, Sweep.around(tm.TOPIC_KINEMATICS, names, lo, hi,
                                                  LENGTH_SWING)

    mcap, log = _floor_log(floor_level, mcap, bag, max_bag_size, max_bag_duration_s,
                           node_parameters)
    result = _run(setup, model_rate_hz, publish_rate_hz, duration_s, mcap, workdir, progress,
                  warmup_s, drive_rate_hz, None, node_parameters, log=log,
                  rss_sample_period_s=rss_sample_period_s, floor_level=floor_level)
    return {"n_muscles": n_muscles, "model_rate_hz": float(model_rate_hz),
            "publish_rate_hz": float(publish_rate_hz), "mcap": bool(mcap),
            "floor_level": floor_level,
            "node_parameters": dict(node_parameters or {}), **log, **result}


def _floor_log(floor_level: str | None, mcap: bool, bag: bool, max_bag_size: int,
               max_bag_duration_s: float, node_parameters: dict | None) -> tuple[bool, dict]:
    """(mcap, the log's result keys) of a run of muscle_node (``floor_level`` None) or of the
    rclpy floor at ``floor_level``, which logs at its last level only; ValueError for a level
    not in FLOOR_LEVELS, a bag, or node_parameters the floor does not take."""
    if floor_level is not None and (floor_level not in FLOOR_LEVELS or bag or set(
            node_parameters or {}) - set(FLOOR_NODE_PARAMETERS)):
        raise ValueError(f"floor_level must be one of {', '.join(FLOOR_LEVELS)} (got "
                         f"{floor_level!r}), without bag, with node_parameters among "
                         f"{', '.join(FLOOR_NODE_PARAMETERS)}")
    if floor_level is not None:
        mcap = mcap and floor_level == FLOOR_LEVELS[-1]
    return mcap, _log_options(mcap, bag, max_bag_size, max_bag_duration_s)


def run_joint_node_benchmark(geometry: Path | str, library: Path | str,
                             model_rate_hz: float = 1000.0, publish_rate_hz: float = 100.0,
                             duration_s: float = 60.0, mcap: bool = True,
                             workdir: Path | str | None = None,
                             progress: Callable[[float, float], None] | None = None, *,
                             warmup_s: float = 5.0, drive_rate_hz: float = 100.0,
                             joint_rate_hz: float = 1000.0,
                             node_parameters: dict | None = None, bag: bool = False,
                             max_bag_size: int = 0, max_bag_duration_s: float = 0.0,
                             rss_sample_period_s: float = RSS_SAMPLE_PERIOD_S,
                             floor_level: str | None = None) -> dict:
    """Run muscle_node from joint space (module docstring) and measure it as
    :func:`run_node_benchmark` does: the ``geometry`` file, the ``library`` muscles it covers
    (all joint-driven), joint_states for every coordinate at ``joint_rate_hz``;
    ``floor_level``: the rclpy floor of this traffic (joint_states in, the joint topics out)
    in place of muscle_node, as for :func:`run_node_benchmark`."""
    from vm_ros.geometry import load_geometry

    geometry, library = Path(geometry).resolve(), Path(library).resolve()
    paths = load_geometry(geometry, backend="numpy")  # names and boxes only
    known = load_muscle_library(library)
    names = [m for m in paths.muscle_names if m in known]
    if not names:
        raise RuntimeError(f"no muscle of {geometry} is in the library {library}")
    sweep = Sweep.around(tm.TOPIC_JOINT_STATES, paths.coordinate_names, paths.lower,
                         paths.upper, JOINT_SWING)
    mcap, log = _floor_log(floor_level, mcap, bag, max_bag_size, max_bag_duration_s,
                           node_parameters)
    result = _run(lambda _workdir: (names, library, geometry, sweep), model_rate_hz,
                  publish_rate_hz, duration_s, mcap, workdir, progress, warmup_s,
                  drive_rate_hz, joint_rate_hz, node_parameters, log=log,
                  rss_sample_period_s=rss_sample_period_s, floor_level=floor_level)
    return {"n_muscles": len(names), "n_geometry_muscles": len(paths.muscle_names),
            "n_coordinates": len(paths.coordinates), "input": tm.TOPIC_JOINT_STATES,
            "joint_rate_hz": float(joint_rate_hz), "model_rate_hz": float(model_rate_hz),
            "publish_rate_hz": float(publish_rate_hz), "mcap": bool(mcap),
            "floor_level": floor_level,
            "node_parameters": dict(node_parameters or {}), **log, **result}


def _log_options(mcap: bool, bag: bool, max_bag_size: int, max_bag_duration_s: float) -> dict:
    """The log's result keys (bag, max_bag_size, max_bag_duration_s), checked."""
    if max_bag_size < 0 or max_bag_duration_s < 0:
        raise ValueError(f"max_bag_size and max_bag_duration_s must be >= 0, got "
                         f"{max_bag_size} and {max_bag_duration_s}")
    if (max_bag_size or max_bag_duration_s) and not bag:
        raise ValueError("splitting (max_bag_size, max_bag_duration_s) needs bag=True")
    if bag and not mcap:
        raise ValueError("bag=True needs mcap=True")
    return {"bag": bool(bag), "max_bag_size": int(max_bag_size),
            "max_bag_duration_s": float(max_bag_duration_s)}


def log_summary(path: Path) -> dict:
    """Files, size and messages of a finished log (an MCAP file or a bag directory), read back
    through every file (module docstring: log_* keys)."""
    from mcap.reader import make_reader

    from vm_ros.recording import LogReader
    from vm_ros.recording.bag import METADATA_FILE, bag_log_files, is_bag_path

    bag = is_bag_path(path)
    files = bag_log_files(path) if bag else [path]
    sizes = [f.stat().st_size for f in files]
    summary_count = 0
    for file in files:
        with open(file, "rb") as stream:
            summary = make_reader(stream).get_summary()
        if summary is not None and summary.statistics is not None:
            summary_count += summary.statistics.message_count
    reader = LogReader(path)
    read = sum(1 for _ in reader.messages())
    out = {"log_files": len(files), "mcap_file_mib": sum(sizes) / MIB,
           "log_file_mib_max": max(sizes) / MIB, "log_messages_summary": summary_count,
           "log_messages_read": read}
    complete = reader.complete and read == summary_count
    if bag:
        listed = []
        metadata = path / METADATA_FILE
        if metadata.is_file():
            info = yaml.safe_load(metadata.read_text(encoding="utf-8"))
            listed = info["rosbag2_bagfile_information"]["relative_file_paths"]
        out["log_metadata_files"] = len(listed)
        complete = complete and sorted(listed) == sorted(f.name for f in files)
    out["log_read_complete"] = bool(complete)
    if reader.stop_reason:
        out["log_read_stop_reason"] = reader.stop_reason
    return out


def _run(setup, model_rate_hz, publish_rate_hz, duration_s, mcap, workdir, progress, warmup_s,
         drive_rate_hz, sweep_rate_hz, node_parameters=None, *, log: dict | None = None,
         rss_sample_period_s: float = RSS_SAMPLE_PERIOD_S, pin: bool = True,
         floor_level: str | None = None) -> dict:
    """The benchmark of either input: ``setup(workdir)`` gives (muscle names, library path,
    geometry path or None, Sweep); ``sweep_rate_hz`` None publishes the sweep with the drive;
    ``log`` from _log_options; ``pin``: the node on one CPU, the driver on the others
    (pin_cpus); ``floor_level``: the rclpy floor (vm_ros_bench.rclpy_floor) at that level in
    place of muscle_node, measured the same way (its outputs answer nothing: no latency, no
    drift, its log not read back)."""
    import rclpy

    check_loopback_only()
    if duration_s <= 0 or warmup_s < 0 or rss_sample_period_s <= 0:
        raise ValueError("duration_s and rss_sample_period_s must be > 0 and warmup_s >= 0")
    log = log or _log_options(mcap, False, 0, 0.0)
    with contextlib.ExitStack() as stack:
        if workdir is None:
            workdir = stack.enter_context(tempfile.TemporaryDirectory(prefix="vm_ros-bench-"))
        workdir = Path(workdir).resolve()  # the node runs with workdir as its cwd
        workdir.mkdir(parents=True, exist_ok=True)
        names, library, geometry, sweep = setup(workdir)
        mcap_path = None
        if mcap:
            mcap_path = workdir / (LOG_NAME if log["bag"] else f"{LOG_NAME}.mcap")
            if mcap_path.is_dir():
                shutil.rmtree(mcap_path)
            elif mcap_path.exists():
                mcap_path.unlink()
        split = {key: log[key] for key in ("max_bag_size", "max_bag_duration_s") if log[key]}
        params_path = workdir / "node_bench_params.yaml"
        write_params(params_path, names, library, model_rate_hz, publish_rate_hz, mcap_path,
                     diagnostics_period_s=1.0 if duration_s >= 10.0 else 0.25,
                     geometry=geometry, node_parameters=node_parameters, mcap_options=split)
        step_ns = int(round(1e9 / model_rate_hz))
        log_path = workdir / "muscle_node.log"

        pinned = pin_cpus() if pin else None
        if pinned is not None:  # the driver's threads on the other CPUs, the node on its own
            before = os.sched_getaffinity(0)
            set_process_affinity("self", pinned[1])
            stack.callback(set_process_affinity, "self", before)
        context = rclpy.Context()
        rclpy.init(context=context)
        stack.callback(rclpy.try_shutdown, context=context)
        driver = BenchDriver(context, names, sweep, drive_rate_hz, sweep_rate_hz)
        stack.callback(driver.node.destroy_node)
        executor = _make_executor(context)
        stack.callback(executor.shutdown)  # unwound first: executor, node, context
        executor.add_node(driver.node)

        command, environment = _node_command(params_path, floor_level)
        with open(log_path, "wb") as log:
            process = subprocess.Popen(command, env=environment, cwd=workdir, stdout=log,
                                       stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL)
        try:
            if pinned is not None:
                set_process_affinity(process.pid, pinned[0])
            result = _measure(process, driver, executor, duration_s, warmup_s, progress,
                              log_path, rss_sample_period_s,
                              None if pinned is None else pinned[0],
                              started=None if floor_level is None else driver.matched)
            result.update(node_cpus=sorted(pinned[0]) if pinned else None,
                          driver_cpus=sorted(pinned[1]) if pinned else None)
            driver.stop_driving()
            window = result.pop("_window")
        finally:
            exit_code, stop_s = _stop_process(process)
        if floor_level is not None:  # its outputs' stamps are 0: no lag either
            result.update({f"model_lag_{p}_ms": math.nan for p in ("p50", "p99", "max")})
            result.update(node_exit_code=exit_code, node_stop_s=stop_s, mcap_file_mib=(
                mcap_path.stat().st_size / MIB if mcap_path is not None and mcap_path.is_file()
                else math.nan))
            return result
        effective = _effective_times(mcap_path) if mcap_path is not None else None
        latencies, lost, missing, waits = _latencies(driver, *window, step_ns, effective)
        p50, p99, pmax = _percentiles_ms(latencies)
        wait_p50, wait_p99, _ = _percentiles_ms(waits)
        after_p50, after_p99, _ = _percentiles_ms(np.subtract(latencies, waits))
        last = driver.last_force_message()
        result.update(
            latency_p50_ms=p50, latency_p99_ms=p99, latency_max_ms=pmax,
            latency_publish_wait_p50_ms=wait_p50, latency_publish_wait_p99_ms=wait_p99,
            latency_after_publish_step_p50_ms=after_p50,
            latency_after_publish_step_p99_ms=after_p99,
            latency_samples=len(latencies), latency_no_response=missing,
            excitation_not_in_node_log=lost if effective is not None else math.nan,
            latency_from_node_log=effective is not None,
            node_exit_code=exit_code, node_stop_s=stop_s,
            forces_finite=_finite(last, len(names)), mcap_file_mib=math.nan)
        if mcap_path is not None and mcap_path.exists():
            try:
                result.update(log_summary(mcap_path))
            except Exception as exc:  # an unfinished or corrupt log: reported, not raised
                result.update(log_read_complete=False,
                              log_read_error=f"{type(exc).__name__}: {exc}")
        if geometry is not None:
            result["efforts_finite"] = _finite(driver.last_joint_efforts_message(),
                                               len(sweep.names))
        return result


def _finite(message, size: int) -> bool:
    """A JointState whose effort[] has ``size`` finite values."""
    return bool(message is not None and len(message.effort) == size
                and np.all(np.isfinite(message.effort)))


def _measure(process, driver: BenchDriver, executor, duration_s: float, warmup_s: float,
             progress, log_path: Path, rss_sample_period_s: float = RSS_SAMPLE_PERIOD_S,
             node_cpus: set[int] | None = None,
             started: Callable[[], bool] | None = None) -> dict:
    """Wait for the model start (the first muscle_force; or until ``started()``), warm up,
    measure the window; the numbers known then."""

    def spin_until(end_mono: float, tick: Callable[[float], None] | None = None) -> None:
        next_report = time.monotonic()
        while (now := time.monotonic()) < end_mono:
            if process.poll() is not None:
                raise RuntimeError(f"muscle_node exited ({process.returncode}) during the "
                                   f"benchmark; its log ({log_path}):\n{_tail(log_path)}")
            if tick is not None and now >= next_report:
                tick(now)
                next_report = now + 0.5
            executor.spin_once(timeout_sec=min(0.01, max(end_mono - now, 0.0)))

    deadline = time.monotonic() + START_TIMEOUT_S
    what = "published no muscle_force" if started is None else "subscribed to no input"
    started = started or (lambda: bool(driver.force_mono_ns))
    while not started():
        if time.monotonic() > deadline:
            raise RuntimeError(f"the node {what} within "
                               f"{START_TIMEOUT_S:g} s; its log ({log_path}):\n{_tail(log_path)}")
        spin_until(time.monotonic() + 0.05)

    total_s = warmup_s + duration_s
    started = time.monotonic()

    def report(now: float) -> None:
        if progress is not None:
            progress(min(now - started, total_s), total_s)

    spin_until(started + warmup_s, report)
    pid = process.pid
    if node_cpus is not None:  # threads started since
        set_process_affinity(pid, node_cpus)
    threads0 = thread_cpu_seconds(pid)
    cpu0, self_cpu0, load0 = cpu_seconds(pid), cpu_seconds("self"), os.getloadavg()[0]
    rss0, _ = memory_mib(pid)
    mono0, ros0 = time.monotonic_ns(), time.time_ns()
    rss_trace = [(0.0, rss0)]

    def report_and_sample(now: float) -> None:
        report(now)
        elapsed = now - mono0 * 1e-9
        if elapsed >= rss_trace[-1][0] + rss_sample_period_s:
            rss_trace.append((elapsed, memory_mib(pid)[0]))

    spin_until(mono0 * 1e-9 + duration_s, report_and_sample)
    mono1, ros1 = time.monotonic_ns(), time.time_ns()
    cpu1, self_cpu1, load1 = cpu_seconds(pid), cpu_seconds("self"), os.getloadavg()[0]
    threads1 = thread_cpu_seconds(pid)
    rss1, hwm = memory_mib(pid)
    rss_trace.append(((mono1 - mono0) * 1e-9, rss1))
    report(time.monotonic())
    spin_until(time.monotonic() + TAIL_S)  # responses to the window's last excitations

    wall_s = (mono1 - mono0) * 1e-9
    in_window = [k for k, t in enumerate(driver.force_mono_ns) if mono0 <= t < mono1]
    lags = [driver.force_ros_ns[k] - driver.force_stamp_ns[k] for k in in_window]
    lag_p50, lag_p99, lag_max = _percentiles_ms(lags)
    last_diagnostics = driver.diagnostics[-1][1] if driver.diagnostics else {}

    def rate(times) -> float:
        return _count_between(times, mono0, mono1) / wall_s

    sent_key = ("rate_kinematics_sent_hz" if driver.sweep.topic == tm.TOPIC_KINEMATICS
                else f"rate_{driver.sweep.topic}_sent_hz")

    result = {
        "duration_s": wall_s, "warmup_s": float(warmup_s),
        "cpu_percent_one_core": 100.0 * (cpu1 - cpu0) / wall_s,
        "driver_cpu_percent_one_core": 100.0 * (self_cpu1 - self_cpu0) / wall_s,
        "node_threads_cpu_percent": {
            name: round(100.0 * (threads1[name] - threads0.get(name, 0.0)) / wall_s, 2)
            for name in sorted(threads1, key=lambda n: threads0.get(n, 0.0) - threads1[n])
            if threads1[name] > threads0.get(name, 0.0)},
        "load_average_1min_start": load0, "load_average_1min_end": load1,
        "cpu_cores": os.cpu_count(),
        "rss_window_start_mib": rss0, "rss_final_mib": rss1, "rss_peak_mib": hwm,
        **rss_growth(rss_trace),
        **_drift(driver.diagnostics, ros0, ros1),
        "model_lag_p50_ms": lag_p50, "model_lag_p99_ms": lag_p99, "model_lag_max_ms": lag_max,
        "rate_muscle_force_hz": len(in_window) / wall_s,
        **{f"rate_{topic}_hz": rate(times) for topic, times in driver.received.items()},
        "rate_excitation_sent_hz": rate(driver.excitation_mono_ns),
        sent_key: rate(driver.kinematics_mono_ns),
        "drive_steps": driver.drive_steps,
        "mcap_messages_written": _number(last_diagnostics.get("mcap messages written")),
        "mcap_messages_dropped": _number(last_diagnostics.get("mcap messages dropped")),
        "_window": (mono0, mono1),
    }
    return result


def _slope_per_hour(t: np.ndarray, rss: np.ndarray) -> float:
    """Least-squares slope of rss (MiB) against t (s), x 3600 s/h; NaN for fewer than two
    distinct times."""
    if len(t) < 2 or np.ptp(t) <= 0:
        return math.nan
    return float(np.polyfit(t, rss, 1)[0]) * SECONDS_PER_HOUR


def rss_growth(trace) -> dict:
    """rss_growth_mib, rss_growth_mib_per_min, rss_max_growth_mib, rss_slope_mib_per_hour,
    rss_slope_second_half_mib_per_hour, rss_samples and rss_trace of ``trace``, [(seconds into
    the window, VmRSS MiB)...] starting at the window's start."""
    t = np.array([s for s, _ in trace], dtype=float)
    rss = np.array([m for _, m in trace], dtype=float)
    growth = float(rss[-1] - rss[0])
    second_half = t >= 0.5 * t[-1]
    return {"rss_growth_mib": growth,
            "rss_growth_mib_per_min": growth / (t[-1] / 60.0) if t[-1] > 0 else math.nan,
            "rss_max_growth_mib": float(rss.max() - rss[0]),
            "rss_slope_mib_per_hour": _slope_per_hour(t, rss),
            "rss_slope_second_half_mib_per_hour": _slope_per_hour(t[second_half],
                                                                  rss[second_half]),
            "rss_samples": len(trace),
            "rss_trace": [[round(float(a), 3), round(float(b), 3)] for a, b in trace]}


# --- command line ------------------------------------------------------------------------------


def main(argv=None) -> int:
    """python -m vm_ros_bench.node_bench [--muscles N] [--duration S] ...: the dict as JSON."""
    parser = argparse.ArgumentParser(
        prog="python -m vm_ros_bench.node_bench",
        description="Benchmark muscle_node as a process (run inside scripts/netns-run).")
    parser.add_argument("--muscles", type=int, default=100, help="number of muscles")
    parser.add_argument("--model-rate", type=float, default=1000.0, help="model rate (Hz)")
    parser.add_argument("--publish-rate", type=float, default=100.0, help="publish rate (Hz)")
    parser.add_argument("--duration", type=float, default=60.0, help="window (s)")
    parser.add_argument("--warmup", type=float, default=5.0, help="warm-up (s)")
    parser.add_argument("--drive-rate", type=float, default=100.0,
                        help="excitation (and muscle_kinematics) rate (Hz)")
    parser.add_argument("--geometry", type=Path, default=None,
                        help="joint input: this geometry file, with --library; --muscles is "
                             "ignored (the library's muscles that the geometry covers)")
    parser.add_argument("--library", type=Path, default=None,
                        help="muscle library for --geometry (e.g. vm-ros import-mjcf's)")
    parser.add_argument("--joint-rate", type=float, default=1000.0,
                        help="joint_states rate with --geometry (Hz)")
    parser.add_argument("--no-mcap", action="store_true", help="run the node without MCAP")
    parser.add_argument("--bag", action="store_true",
                        help=f"log to the rosbag2 bag directory WORKDIR/{LOG_NAME}/ instead of "
                             f"WORKDIR/{LOG_NAME}.mcap")
    parser.add_argument("--max-bag-duration", type=float, default=0.0, metavar="S",
                        help="with --bag: a new file every S seconds of log time "
                             "(mcap.max_bag_duration_s; default 0, no split)")
    parser.add_argument("--max-bag-size", type=int, default=0, metavar="BYTES",
                        help="with --bag: a new file once one holds BYTES "
                             "(mcap.max_bag_size; default 0, no split)")
    parser.add_argument("--rss-period", type=float, default=RSS_SAMPLE_PERIOD_S, metavar="S",
                        help=f"sample the node's VmRSS every S seconds of the window "
                             f"(default {RSS_SAMPLE_PERIOD_S:g})")
    parser.add_argument("--node-param", action="append", default=[], metavar="NAME=VALUE",
                        help="a muscle_node parameter for the run (VALUE read as YAML), e.g. "
                             "executor=single_threaded; repeatable")
    parser.add_argument("--floor", choices=FLOOR_LEVELS,
                        default=None, metavar="LEVEL",
                        help="run the rclpy floor of the same traffic (vm_ros_bench.rclpy_floor: "
                             "subscriptions, timer, publishers or mcap, each with the ones "
                             "before) in place of muscle_node; its MCAP log at level mcap")
    parser.add_argument("--workdir", type=Path, default=None,
                        help="keep library, params, node log and MCAP here (default: temporary)")
    args = parser.parse_args(argv)
    if (args.geometry is None) != (args.library is None):
        parser.error("--geometry and --library go together")
    if (args.max_bag_duration or args.max_bag_size) and not args.bag:
        parser.error("--max-bag-duration and --max-bag-size need --bag")
    if args.bag and args.no_mcap:
        parser.error("--bag and --no-mcap exclude each other")
    if args.floor and args.bag:
        parser.error("--floor goes without --bag")
    if args.max_bag_duration < 0 or args.max_bag_size < 0 or args.rss_period <= 0:
        parser.error("--max-bag-duration and --max-bag-size must be >= 0, --rss-period > 0")

    def progress(done: float, total: float) -> None:
        if sys.stderr.isatty():
            sys.stderr.write(f"\rnode bench {100.0 * done / total:5.1f}% ")
            sys.stderr.flush()

    node_parameters = {}
    for item in args.node_param:
        name, sep, value = item.partition("=")
        if not sep or not name:
            parser.error(f"--node-param {item!r}: expected NAME=VALUE")
        try:
            node_parameters[name] = yaml.safe_load(value)
        except yaml.YAMLError as exc:
            parser.error(f"--node-param {item!r}: VALUE is not YAML ({exc.problem})")
    common = dict(mcap=not args.no_mcap, workdir=args.workdir, progress=progress,
                  warmup_s=args.warmup, drive_rate_hz=args.drive_rate,
                  node_parameters=node_parameters, bag=args.bag,
                  max_bag_size=args.max_bag_size, max_bag_duration_s=args.max_bag_duration,
                  rss_sample_period_s=args.rss_period)
    try:
        if args.geometry is not None:
            result = run_joint_node_benchmark(
                args.geometry, args.library, args.model_rate, args.publish_rate, args.duration,
                joint_rate_hz=args.joint_rate, floor_level=args.floor, **common)
        else:
            result = run_node_benchmark(args.muscles, args.model_rate, args.publish_rate,
                                        args.duration, floor_level=args.floor, **common)
    except RuntimeError as exc:
        print(f"node_bench: error: {exc}", file=sys.stderr)
        return 1
    if sys.stderr.isatty():
        sys.stderr.write("\n")
    plain = {k: None if isinstance(v, float) and not math.isfinite(v) else v
             for k, v in result.items()}  # JSON has no NaN
    print(json.dumps(plain, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
