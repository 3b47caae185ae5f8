"""Replay: the generator paces recorded messages (no ROS), and `vm-ros replay` republishes them
over ROS 2 with the recorded values and spacing (needs rclpy; runs inside scripts/netns-run)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from vm_ros.cli import main
from vm_ros.recording.replay import paced, recorded_messages, replay
from vm_ros.recording.run_log import read_run


@pytest.fixture(scope="module")
def log(tmp_path_factory):
    out = tmp_path_factory.mktemp("replay") / "sine.mcap"
    assert main(["simulate", "--scenario", "sinusoidal_drive", "--duration", "0.5", "--out",
                 str(out), "--input-rate", "100"]) == 0
    return out


class FakeClock:
    def __init__(self):
        self.now = 100.0

    def __call__(self):
        return self.now

    def sleep(self, seconds):
        self.now += seconds


def test_paced_follows_log_time_over_rate(log):
    clock = FakeClock()
    messages = list(recorded_messages(log, topics={"/energy_rate"}))
    yielded = []
    for _ in paced(messages, rate=2.0, clock=clock, sleep=clock.sleep):
        yielded.append(clock.now)
    assert len(yielded) == 50
    np.testing.assert_allclose(np.diff(yielded), 0.005)  # 10 ms of log time at x2


def test_offline_types_are_skipped_unless_asked(log):
    topics = {m.topic for m in recorded_messages(log)}
    assert "/muscle_telemetry" not in topics and "/energy_rate" in topics
    assert "/muscle_telemetry" in {m.topic for m in recorded_messages(log, include_offline=True)}


def test_loop_starts_over(log):
    clock = FakeClock()
    stream = replay(log, topics={"/energy_total"}, loop=True, clock=clock, sleep=clock.sleep)
    times = [next(stream).log_time_ns for _ in range(120)]
    assert times[:50] == times[50:100] and times[100] == times[0]


def test_replay_publishes_recorded_bytes_at_recorded_pace(log, ros):
    """A subscriber in this process receives energy_rate from `vm-ros replay` (a subprocess):
    every recorded message, and at the recorded pace as the replay sent them (the DDS source
    timestamps, so that a busy test process that takes them late does not count)."""
    from rclpy.qos import QoSProfile
    from std_msgs.msg import Float64, Float64MultiArray

    received, totals = [], []
    node = ros.rclpy.create_node("replay_probe", context=ros.context)
    ros._add(node)
    subscriptions = [
        node.create_subscription(Float64MultiArray, "energy_rate",
                                 lambda msg, info: received.append(
                                     (info["source_timestamp"] * 1e-9, list(msg.data))),
                                 QoSProfile(depth=1000)),
        node.create_subscription(Float64, "energy_total", totals.append, QoSProfile(depth=1000))]
    # --wait: the replay publishes once its publishers have matched these subscriptions, and a
    # settling time later, so that they have matched back (reliable: nothing is then lost)
    proc = subprocess.Popen([sys.executable, "-m", "vm_ros.cli", "replay", str(log),
                             "--topics", "energy_rate,/energy_total", "--wait", "10"],
                            env=os.environ.copy(), stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    try:
        assert ros.spin_until(lambda: all(s.get_publisher_count() for s in subscriptions)
                              or proc.poll() is not None, 30)
        assert ros.spin_until(lambda: proc.poll() is not None, 30)
        ros.spin_for(0.2)
        out, err = proc.communicate(timeout=10)
    finally:
        if proc.poll() is None:
            proc.send_signal(signal.SIGINT)
            proc.wait(timeout=5)
    assert proc.returncode == 0, err
    recorded = read_run(log, topics=["energy_rate"]).get("energy_rate")
    assert len(received) == len(recorded) == len(totals) == 50, err
    np.testing.assert_array_equal(np.array([d for _, d in received]), recorded.fields["data"])
    gaps = np.diff([t for t, _ in received])
    assert np.median(gaps) == pytest.approx(0.010, abs=0.003)
    assert received[-1][0] - received[0][0] == pytest.approx(0.49, abs=0.15)


def test_replay_without_rclpy_is_a_clear_error(log, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "rclpy", None)
    assert main(["replay", str(log)]) == 2
    assert "needs rclpy" in capsys.readouterr().err


def test_replay_unknown_topic(log, capsys):
    assert main(["replay", str(log), "--topics", "nope"]) == 2
    assert "no topic /nope" in capsys.readouterr().err


@pytest.mark.ros
def test_undecodable_messages_are_one_line_per_cause(tmp_path):
    """rosidl's C typesupport prints 'sequence size exceeds remaining buffer' on stderr twice for
    each of these Float64MultiArray messages (220 lines before): captured, and summed up in one
    line per cause with its counts and the first occurrence."""
    from conftest import require_ros

    from vm_ros.model.run_config import RunConfig
    from vm_ros.recording import RunInfo, RunTiming, open_run_log

    require_ros()  # the replay subprocess starts rclpy
    malformed = b"\x00\x01\x00\x00" + b"\xfa" * 24    # CDR header, then no valid message
    big_endian = b"\x00\x00\x00\x00" + b"\x01" * 40
    path = tmp_path / "malformed.mcap"
    with open_run_log(path, RunInfo(RunConfig(("vasti", "rectus_femoris")), RunTiming(),
                                    "test")) as rec:
        for k in range(100):
            rec.write("/excitation_array", malformed, 1000 + k)
            rec.write("/excitation", malformed, 1000 + k)
        for k in range(10):
            rec.write("/excitation_array", big_endian, 5000 + k)
    proc = subprocess.run([str(Path(sys.executable).with_name("vm-ros")), "replay", str(path),
                           "--topics", "excitation_array,excitation"], capture_output=True,
                          text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert "replayed 0 messages" in proc.stdout
    lines = [line for line in proc.stderr.splitlines() if "[INFO]" not in line]
    assert len(lines) == 2, proc.stderr
    assert lines[0] == ("vm-ros replay: skipped 110 undecodable messages on /excitation_array: "
                        "sequence size exceeds remaining buffer (first: /excitation_array at log "
                        "time 0.000001000 s)")
    # rclpy's own text for the JointState: "failed to deserialize ROS message: Fast CDR ..."
    assert lines[1].startswith("vm-ros replay: skipped 100 undecodable messages on /excitation: "
                               "failed to deserialize ROS message")
    assert lines[1].endswith("(first: /excitation at log time 0.000001000 s)")
