"""What a SIGKILL loses: a run log's chunks go to the file at least every flush interval (1 s by
default), the first one included, so a process killed at any time leaves a file that read_run
reads and whose data ends at most about one interval before the kill.

The bound is checked on times, not on message counts: muscle_node logs its outputs at their model
time, which is the ROS clock (the system clock without use_sim_time), so the newest logged time
can be compared with the wall time of the kill. Nothing waits on DDS: the node starts its model
from ``initial_path_length_m``, and the log's start is seen from the file (its header and
metadata are written when the model starts).
"""

from __future__ import annotations

import dataclasses
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
from conftest import require_ros

from vm_ros.errors import ConfigError
from vm_ros.model import MuscleBank
from vm_ros.node.inputs import physical_path_length_range
from vm_ros.node.params import NodeConfig
from vm_ros.node.recording import NodeRunLog
from vm_ros.recording import RecorderError, read_run
from vm_ros.recording.writer import FLUSH_INTERVAL_S, McapRecorder

NS = 1_000_000_000
MUSCLES = ["vasti", "rectus_femoris"]
# The newest message in the file may be older than the kill by one flush interval, plus the
# writer thread's wake-up (GIL, a model tick) and the node's model time lagging the clock after a
# stall (at most max_catch_up_steps = 50 ms before it skips): 0.5 s leaves room for a loaded
# machine running tests in parallel, and is still far below the 5 s of the former interval.
LATENESS_S = 0.5

WRITER_SCRIPT = """
import os, signal, sys, time
from vm_ros.recording.writer import McapRecorder
from vm_ros.recording.cdr import serialize
from vm_ros.recording.messages import float64_fields
rec = McapRecorder(sys.argv[1], **({"flush_interval_s": float(sys.argv[3])}
                                   if len(sys.argv) > 3 else {}))
rec.add_channel("/energy_total", "std_msgs/msg/Float64")
end = time.monotonic() + float(sys.argv[2])
k = 0
while time.monotonic() < end:
    rec.write("/energy_total", serialize("std_msgs/msg/Float64", float64_fields(k)),
              time.time_ns())
    k += 1
    time.sleep(0.001)
print(time.time_ns(), flush=True)
os.kill(os.getpid(), signal.SIGKILL)
"""


def _newest_time_ns(run) -> int:
    return max(int(s.time_ns.max()) for s in run.series.values() if len(s))


@pytest.mark.parametrize("run_s", [1.5, 3.2])
def test_recorder_killed_keeps_all_but_the_last_interval(tmp_path, run_s):
    """McapRecorder at 1 kHz in a process that SIGKILLs itself: the first chunk is in the file
    after one interval, every later one too."""
    path = tmp_path / "killed.mcap"
    proc = subprocess.run([sys.executable, "-c", WRITER_SCRIPT, str(path), str(run_s)],
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == -signal.SIGKILL, proc.stderr
    started_ns = path.stat().st_mtime_ns  # not used for the bound: the first message is
    kill_ns = int(proc.stdout.split()[0])
    run = read_run(path)
    assert not run.complete and started_ns > 0
    data = run.get("/energy_total")
    assert len(data) > 0
    np.testing.assert_array_equal(data.fields["data"], np.arange(len(data)))  # no gap
    first_ns, last_ns = int(data.time_ns[0]), int(data.time_ns[-1])
    assert (kill_ns - first_ns) / NS == pytest.approx(run_s, abs=0.2)
    assert 0 <= (kill_ns - last_ns) / NS <= FLUSH_INTERVAL_S + LATENESS_S


def test_a_five_second_interval_loses_the_first_seconds(tmp_path):
    """The former default: a kill at 1.5 s left no message at all."""
    path = tmp_path / "killed.mcap"
    proc = subprocess.run([sys.executable, "-c", WRITER_SCRIPT, str(path), "1.5", "5.0"],
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == -signal.SIGKILL, proc.stderr
    assert "/energy_total" not in read_run(path).series or not len(
        read_run(path).get("/energy_total"))


def test_flush_interval_is_checked():
    for bad in (0.0, -1.0, float("nan"), float("inf")):
        with pytest.raises(RecorderError, match="flush_interval_s must be"):
            McapRecorder("unused.mcap", flush_interval_s=bad)
    with pytest.raises(ConfigError, match="mcap.flush_interval_s") as info:
        NodeConfig.from_values({"mcap.flush_interval_s": 0.0})
    assert "\n" not in str(info.value)
    assert NodeConfig.defaults().mcap_flush_interval_s == FLUSH_INTERVAL_S


def test_cli_flush_interval_is_checked(tmp_path):
    for bad in ("0", "-2", "nan", "soon"):
        proc = subprocess.run([sys.executable, "-m", "vm_ros.cli", "simulate", "--flush-interval",
                               bad, "--out", str(tmp_path / "x.mcap")],
                              capture_output=True, text=True, timeout=60)
        assert proc.returncode == 2
        assert "--flush-interval" in proc.stderr and "Traceback" not in proc.stderr
        assert not (tmp_path / "x.mcap").exists()


def test_node_log_uses_the_recorded_flush_interval(tmp_path):
    """NodeRunLog takes mcap.flush_interval_s from the node parameters it records."""
    from test_node_recording import run_info

    def info_with_interval(start_ns):
        info = run_info(start_ns)
        return dataclasses.replace(info, extra=dict(
            info.extra, node_parameters='{"mcap.flush_interval_s": 0.25}'))

    log = NodeRunLog(tmp_path / "run.mcap", info_with_interval)
    log.start(0)
    try:
        assert log.recorder._flush_interval_s == 0.25
    finally:
        log.close()
    default = NodeRunLog(tmp_path / "default.mcap", run_info)
    default.start(0)
    try:
        assert default.recorder._flush_interval_s == FLUSH_INTERVAL_S
    finally:
        default.close()


# --- muscle_node killed ----------------------------------------------------------------------


@pytest.mark.ros
@pytest.mark.parametrize("after_start_s", [1.5, 7.0])
def test_killed_node_log_ends_within_an_interval_of_the_kill(tmp_path, after_start_s):
    require_ros()  # the node starts rclpy: only inside scripts/netns-run
    lo, hi = physical_path_length_range(MuscleBank.from_config(MUSCLES), 0.0)
    lengths = 0.5 * (lo + hi)
    path = tmp_path / "node.mcap"
    command = [sys.executable, "-m", "vm_ros.node", "--ros-args",
               "-p", "muscles:=[" + ", ".join(MUSCLES) + "]",
               "-p", "initial_path_length_m:=[" + ", ".join(f"{x:.6f}" for x in lengths) + "]",
               "-p", "mcap.enabled:=true", "-p", f"mcap.path:={path}"]
    process = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                               text=True)
    try:
        deadline = time.monotonic() + 60
        while not (path.exists() and path.stat().st_size > 0):  # the model started
            assert process.poll() is None, process.communicate()[1]
            assert time.monotonic() < deadline, "the node did not start its model in 60 s"
            time.sleep(0.01)
        opened_ns = time.time_ns()
        time.sleep(after_start_s)
        kill_ns = time.time_ns()
        process.kill()
        process.communicate(timeout=30)
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
    assert process.returncode == -signal.SIGKILL
    run = read_run(path)
    assert not run.complete and run.stop_reason
    assert run.info.source == "muscle_node"
    start_ns = run.info.timing.start_time_ns
    assert abs(opened_ns - start_ns) / NS < LATENESS_S  # model time is the system clock
    forces = run.get("/muscle_force")
    assert len(forces) > 0 and np.all(np.isfinite(forces.fields["effort"]))
    last_ns = _newest_time_ns(run)
    lost_s = (kill_ns - last_ns) / NS
    assert -LATENESS_S <= lost_s <= FLUSH_INTERVAL_S + LATENESS_S, (lost_s, after_start_s)
    # published every 10 ms from the start to the last chunk: nothing missing before it
    stamps = forces.fields["stamp_ns"]
    assert np.all(np.diff(stamps) > 0)
    assert len(forces) >= 0.8 * (forces.time_ns[-1] - start_ns) / (NS / 100)
