"""muscle_node's counted troubles that never reach a message callback: publishers of another
type on an input topic, input messages lost in a burst, payloads that claim more than they hold;
and a node started from initial_path_length_m without a kinematics topic is healthy.

Every test waits for matched endpoints and counts with QoS that cannot drop what it counts
(reliable, deep enough), so none depends on the pace of DDS delivery."""

from __future__ import annotations

import struct

import numpy as np
import pytest

from vm_ros.model import MuscleBank
from vm_ros.node.health import ISSUE_KINDS, lost_key
from vm_ros.node.inputs import physical_path_length_range
from vm_ros.recording import read_run

pytestmark = pytest.mark.ros

MUSCLES = ["vasti", "rectus_femoris"]


@pytest.fixture(scope="module")
def lengths():
    lo, hi = physical_path_length_range(MuscleBank.from_config(MUSCLES), 0.0)
    return 0.5 * (lo + hi)


@pytest.fixture
def other_participant(ros):
    """A node in a second context: its own DDS participant, as another process would be."""
    context = ros.rclpy.Context()
    ros.rclpy.init(context=context)
    from rclpy.node import Node

    node = Node("other", context=context)
    yield node
    node.destroy_node()
    ros.rclpy.try_shutdown(context=context)


def test_a_publisher_of_another_type_is_counted_and_named(ros, lengths, other_participant,
                                                          caplog):
    from std_msgs.msg import Float64

    node = ros.muscle_node(muscles=MUSCLES, initial_path_length_m=list(lengths),
                           diagnostics_period_s=0.1)
    probe = ros.probe()
    other_participant.create_publisher(Float64, "excitation", 10)
    label = ISSUE_KINDS["wrong_type_publisher"][0]
    assert ros.spin_until(lambda: node.issues.counts["wrong_type_publisher"] == 1, timeout_s=10)
    assert ros.spin_until(lambda: probe.last_diagnostics().get(label) == "1", timeout_s=5)
    ros.spin_for(1.5)  # a later graph check counts the same publisher once only
    assert node.issues.counts["wrong_type_publisher"] == 1


@pytest.fixture(params=["events", "single_threaded"])
def executor(request, ros):
    """The node's executor kind, and the harness spinning with that executor (the node's own
    main uses make_executor too)."""
    from vm_ros.node.shell import make_executor

    ros.executor.shutdown(timeout_sec=1.0)
    ros.executor = make_executor(request.param, ros.context)
    return request.param


def _counting_node(ros, lengths, executor, **params):
    """A muscle_node whose accepted excitation_array messages are also counted in ``taken``."""
    node = ros.muscle_node(muscles=MUSCLES, initial_path_length_m=list(lengths),
                           executor=executor, **params)
    taken = []
    original = node.inputs.on_drive
    node.inputs.on_drive = lambda *args: taken.append(1) or original(*args)
    return node, taken


def _reliable_publisher(ros, participant, depth: int):
    from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
    from std_msgs.msg import Float64MultiArray

    qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=depth,
                     reliability=ReliabilityPolicy.RELIABLE)
    publisher = participant.create_publisher(Float64MultiArray, "excitation_array", qos)
    assert ros.spin_until(lambda: publisher.get_subscription_count() == 1, timeout_s=10)
    return publisher


def test_messages_lost_in_a_burst_are_counted(ros, lengths, other_participant, executor,
                                              tmp_path):
    """2000 messages at once into a queue of 10: what the node took plus what it counted as
    lost is every message sent (a last message after the burst shows a loss at the end), and
    /diagnostics gives the count for the topic, the run log's last one too."""
    from std_msgs.msg import Float64MultiArray

    path = tmp_path / "run.mcap"
    node, taken = _counting_node(ros, lengths, executor, qos_depth=10,
                                 diagnostics_period_s=0.1, mcap__enabled=True,
                                 mcap__path=str(path))
    probe = ros.probe()
    publisher = _reliable_publisher(ros, other_participant, depth=10)
    publisher.publish(Float64MultiArray(data=[0.5, 0.0]))  # the publisher's stream starts
    assert ros.spin_until(lambda: len(taken) == 1, timeout_s=10)
    sent = 2001
    for i in range(1, sent):
        publisher.publish(Float64MultiArray(data=[0.5, i / sent]))
    ros.spin_for(1.0)
    publisher.publish(Float64MultiArray(data=[0.5, 0.5]))  # reveals a loss at the burst's end
    sent += 1
    assert ros.spin_until(lambda: len(taken) + node.issues.counts["input_lost"] == sent,
                          timeout_s=10), (len(taken), node.issues.counts["input_lost"])
    lost = node.issues.counts["input_lost"]
    assert lost > 0
    assert np.array_equal(node.inputs.drive, [0.5, 0.5])
    key = lost_key("excitation_array")
    assert ros.spin_until(lambda: probe.last_diagnostics().get(key) == str(lost), timeout_s=5), \
        probe.last_diagnostics()
    node.close_run_log()
    last = read_run(path).get("/diagnostics").messages[-1]
    assert {kv.key: kv.value for kv in last.status[0].values}[key] == str(lost)


def test_no_loss_is_counted_for_a_steady_stream_or_a_restarted_publisher(
        ros, lengths, other_participant, executor):
    """Messages one at a time (each taken before the next is sent), then the publisher
    destroyed and created again (its sequence numbers start again at 1): none lost."""
    from std_msgs.msg import Float64MultiArray

    node, taken = _counting_node(ros, lengths, executor, diagnostics_period_s=0.1)
    probe = ros.probe()
    for _ in range(2):
        publisher = _reliable_publisher(ros, other_participant, depth=10)
        for _ in range(30):
            sent = len(taken) + 1
            publisher.publish(Float64MultiArray(data=[0.5, 0.5]))
            assert ros.spin_until(lambda sent=sent: len(taken) == sent, timeout_s=10)
        other_participant.destroy_publisher(publisher)
    assert len(taken) == 60
    assert node.issues.counts["input_lost"] == 0
    n = len(probe.diagnostics)
    assert ros.spin_until(lambda: len(probe.diagnostics) > n, timeout_s=5)
    assert probe.last_diagnostics()[lost_key("excitation_array")] == "0"


def test_oversized_payloads_are_counted_without_stderr_lines(ros, lengths, capfd):
    node = ros.muscle_node(muscles=MUSCLES, initial_path_length_m=list(lengths))
    probe = ros.probe()
    assert ros.spin_until(lambda: probe.excitation.get_subscription_count() == 1, timeout_s=10)
    payload = b"\x00\x01\x00\x00" + struct.pack("<iII", 0, 0, 10**9) + b"\x00" * 8
    for k in range(1, 51):  # one at a time: the queue of 10 must not overflow
        probe.excitation.publish(payload)
        assert ros.spin_until(lambda k=k: node.issues.counts["undecodable"] == k, timeout_s=10)
    assert "sequence size exceeds" not in capfd.readouterr().err


def test_initial_lengths_without_kinematics_are_healthy(ros, lengths):
    """initial_path_length_m holds until kinematics arrive: OK, not WARN 'stale inputs'."""
    node = ros.muscle_node(muscles=MUSCLES, initial_path_length_m=list(lengths),
                           diagnostics_period_s=0.1, input_timeout_s=1000.0)
    probe = ros.probe()
    assert ros.spin_until(lambda: probe.excitation_array.get_subscription_count() == 1,
                          timeout_s=10)
    probe.send_excitation_array([0.2, 0.2])
    assert ros.spin_until(lambda: node.inputs.drive_seen.all(), timeout_s=5)
    n = len(probe.diagnostics)
    assert ros.spin_until(lambda: len(probe.diagnostics) >= n + 3, timeout_s=5)
    diag = probe.last_diagnostics()
    # no stale-input WARN; a WARN for falling behind (pace, with both cores busy and the NumPy
    # step) is not what this checks
    assert diag["state"] == "running" and "stale" not in diag["_message"], diag
    assert diag["stale kinematics"] == "-"
