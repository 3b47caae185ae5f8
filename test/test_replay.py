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


def _replay_to(ros, subscriptions, log, *options) -> tuple[int, str]:
    """`vm-ros replay LOG --wait 10 OPTIONS` as a subprocess, spinning ``ros`` until it ends:
    (exit status, stderr). --wait: the replay publishes once its publishers have matched the
    subscriptions, and a settling time later, so that they have matched back (reliable:
    nothing is then lost)."""
    proc = subprocess.Popen([sys.executable, "-m", "vm_ros.cli", "replay", str(log),
                             "--wait", "10", *options], env=os.environ.copy(),
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert ros.spin_until(lambda: all(s.get_publisher_count() for s in subscriptions)
                              or proc.poll() is not None, 30)
        assert ros.spin_until(lambda: proc.poll() is not None, 30)
        ros.spin_for(0.2)
        _, err = proc.communicate(timeout=10)
    finally:
        if proc.poll() is None:
            proc.send_signal(signal.SIGINT)
            proc.wait(timeout=5)
    return proc.returncode, err


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
    code, err = _replay_to(ros, subscriptions, log, "--topics", "energy_rate,/energy_total")
    assert code == 0, err
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


def test_restamped_changes_the_header_stamp_and_nothing_else():
    import struct

    from vm_ros.recording import cdr

    data = cdr.serialize("sensor_msgs/msg/JointState", {
        "header": {"stamp": {"sec": 12, "nanosec": 345}, "frame_id": "f"},
        "name": ["a", "b"], "position": [0.25, 0.5], "velocity": [], "effort": []})
    assert cdr.header_stamp_ns(data) == 12_000_000_345
    new = cdr.restamped(data, 1_796_000_000_123_456_789)
    message = cdr.deserialize("sensor_msgs/msg/JointState", new)
    assert (message.header.stamp.sec, message.header.stamp.nanosec) == (1_796_000_000, 123_456_789)
    assert new[:4] == data[:4] and new[12:] == data[12:] and len(new) == len(data)
    big_endian = b"\x00\x00\x00\x00" + struct.pack(">iI", 5, 7) + b"\x00" * 8
    assert cdr.header_stamp_ns(big_endian) == 5_000_000_007
    assert cdr.header_stamp_ns(cdr.restamped(big_endian, 9_000_000_001)) == 9_000_000_001
    for bad in (b"\x00\x01\x00", b"\x00\x07\x00\x00" + bytes(8)):
        with pytest.raises(ValueError):
            cdr.header_stamp_ns(bad)
    with pytest.raises(ValueError, match="range"):
        cdr.restamped(data, 1 << 62)


def test_restamper_keeps_the_recorded_spacing_over_the_rate():
    from vm_ros.recording import cdr
    from vm_ros.recording.replay import Restamper

    def stamped(ns):
        return cdr.serialize("sensor_msgs/msg/JointState", {"header": {"stamp": {
            "sec": ns // 1_000_000_000, "nanosec": ns % 1_000_000_000}}})

    restamp = Restamper(rate=2.0)
    recorded = [5_000_000_000, 5_010_000_000, 5_030_000_000, 5_040_000_000, 0]
    now = [1_000_000_000_000, 1_000_006_000_000, 1_000_016_000_000, 1_000_019_000_000,
           1_000_020_000_000]
    new = [cdr.header_stamp_ns(restamp(stamped(s), t)) for s, t in zip(recorded, now,
                                                                       strict=True)]
    # published early (the fourth, due at +20 ms): stamped at its publication, not ahead of it
    assert new == [1_000_000_000_000, 1_000_005_000_000, 1_000_015_000_000,
                   1_000_019_000_000, 0]
    with pytest.raises(ValueError):
        Restamper(rate=0.0)


def test_a_first_message_published_late_does_not_stamp_the_rest_at_their_publication():
    """The first message published 4 ms after its due time (late_ns): it is stamped at its due
    time, and the later ones, each published 1 ms after theirs, keep the recorded 10 ms spacing
    (counted from their publication instead, all would have been stamped when published)."""
    from vm_ros.recording import cdr
    from vm_ros.recording.replay import Restamper

    def stamped(ns):
        return cdr.serialize("sensor_msgs/msg/JointState", {"header": {"stamp": {
            "sec": ns // 1_000_000_000, "nanosec": ns % 1_000_000_000}}})

    ms, due0 = 1_000_000, 7_000_000_000_000
    restamp = Restamper()
    recorded = [5_000 * ms, 5_010 * ms, 5_020 * ms]
    published = [due0 + 4 * ms, due0 + 11 * ms, due0 + 21 * ms]
    late = [4 * ms, 1 * ms, 1 * ms]
    new = [cdr.header_stamp_ns(restamp(stamped(s), t, d))
           for s, t, d in zip(recorded, published, late, strict=True)]
    assert new == [due0, due0 + 10 * ms, due0 + 20 * ms]


def test_replay_restamps_messages_with_a_header_on_its_clock(log, ros):
    """`vm-ros replay --restamp`: the excitation's JointState stamps start at the replay's own
    time (within the replay, after the log's own stamps) and keep the recorded spacing to the ns;
    energy_total (no header) is sent as recorded; the values are unchanged."""
    import time

    from rclpy.qos import QoSProfile
    from sensor_msgs.msg import JointState
    from std_msgs.msg import Float64

    received, totals = [], []
    node = ros.rclpy.create_node("restamp_probe", context=ros.context)
    ros._add(node)
    subscriptions = [
        node.create_subscription(JointState, "excitation", lambda msg, info: received.append(
            (msg, info["source_timestamp"])), QoSProfile(depth=1000)),
        node.create_subscription(Float64, "energy_total", totals.append, QoSProfile(depth=1000))]
    start_ns = time.time_ns()
    code, err = _replay_to(ros, subscriptions, log, "--topics", "excitation,energy_total",
                           "--restamp")
    end_ns = time.time_ns()
    assert code == 0, err
    recorded = read_run(log, topics=["excitation", "energy_total"])
    excitation = recorded.get("excitation")
    assert len(received) == len(excitation) == 50, err
    assert excitation.time_ns[-1] < start_ns  # the log's own stamps: before this replay
    stamps = np.array([m.header.stamp.sec * 1_000_000_000 + m.header.stamp.nanosec
                       for m, _ in received], dtype=np.int64)
    sent = np.array([t for _, t in received], dtype=np.int64)  # DDS source timestamps
    assert start_ns < stamps[0] < end_ns
    assert np.all(stamps <= sent)  # never ahead of its publication: the node can use it
    # the recorded spacing, but for messages the replay sent early (then stamped when sent)
    spacing = np.diff(stamps) == np.diff(excitation.time_ns)
    assert np.count_nonzero(spacing) >= 0.5 * len(spacing)
    early = stamps - stamps[0] < excitation.time_ns - excitation.time_ns[0]
    assert np.all(stamps[early] >= sent[early] - 2_000_000)  # stamped at its publication
    np.testing.assert_array_equal(np.array([m.position for m, _ in received]),
                                  excitation.fields["position"])
    assert [m.data for m in totals] == list(recorded.get("energy_total").fields["data"])
