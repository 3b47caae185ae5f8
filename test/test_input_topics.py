"""One table of input topics (vm_ros.topics.INPUT_TOPICS): muscle_node's subscriptions, the
node-log replay (NodeConditioning) and the offline runner (RecordedInputs, one message at a time
and in blocks) all dispatch from it. A topic added to the table in a fixture reaches all of them
with the same meaning; a topic not in the table is an error, never a fall-through."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from vm_ros import topics as tp
from vm_ros.model import MuscleBank
from vm_ros.node.params import NodeConfig
from vm_ros.node.replay import NodeConditioning
from vm_ros.offline.runner import RecordedInputs
from vm_ros.recording.run_log import EventTable, RecordedEvent

MUSCLES = ["vasti", "rectus_femoris"]
MS = 1_000_000
# inside both muscles' valid path ranges (vasti 0.286-0.338 m, rectus femoris 0.497-0.544 m)
LENGTH, VELOCITY = [0.31, 0.52], [0.01, -0.02]
DRIVE = [0.25, 0.75]


@pytest.fixture
def new_topics(monkeypatch):
    """Two topics added to the table: a path input by name and a drive input by position."""
    rows = (tp.InputTopic("muscle_kinematics_b", tp.TYPE_JOINT_STATE, tp.PATH, True,
                          ("position", "velocity"), "a second source of path lengths"),
            tp.InputTopic("drive_b", tp.TYPE_FLOAT64_MULTI_ARRAY, tp.DRIVE, False, ("data",),
                          "a second drive, one per muscle"))
    monkeypatch.setattr(tp, "INPUT_TOPICS", tp.INPUT_TOPICS + rows)
    return rows


class _Run:
    """A run log of one drive_b message at 1 ms and one muscle_kinematics_b message at 2 ms
    (series decoded into bank order, as read_run gives them)."""

    path = "fixture.mcap"

    def __init__(self):
        kinematics = _Series(position=[LENGTH], velocity=[VELOCITY])
        drive = _Series(data=[DRIVE])
        self.series = {"muscle_kinematics_b": kinematics, "drive_b": drive,
                       # RecordedInputs needs a muscle_kinematics message to start from
                       tp.TOPIC_KINEMATICS: _Series(position=[[0.3, 0.5]], velocity=[[0, 0]])}
        self._events = [RecordedEvent(0, tp.TOPIC_KINEMATICS, self.series[tp.TOPIC_KINEMATICS],
                                      0, None),
                        RecordedEvent(1 * MS, "drive_b", drive, 0, None),
                        RecordedEvent(2 * MS, "muscle_kinematics_b", kinematics, 0, None)]

    def get(self, topic):
        return self.series.get(topic)

    def events(self, topics):
        assert {"drive_b", "muscle_kinematics_b"} <= set(topics)  # asked from the table
        return [e for e in self._events if e.topic in topics]

    def event_table(self, topics):
        names = tuple(topics)
        events = self.events(names)
        return EventTable(names, tuple(self.get(name) for name in names),
                          np.array([e.time_ns for e in events], dtype=np.int64),
                          np.array([names.index(e.topic) for e in events]),
                          np.array([e.index for e in events]), [e.data for e in events])


class _Series:
    def __init__(self, **fields):
        self.fields = {k: np.asarray(v, dtype=float) for k, v in fields.items()}

    def __len__(self):
        return len(next(iter(self.fields.values())))


class _Pending:
    def add_one(self, *args):
        pass

    def add_each(self, *args):
        pass


def _offline_one_by_one():
    inputs = RecordedInputs(_Run(), len(MUSCLES), sink=None)
    return inputs.advance_to(3 * MS)


def _offline_block():
    inputs = RecordedInputs(_Run(), len(MUSCLES), sink=None)
    u, lp, vp = inputs.block(np.array([0, 3 * MS]), 0, _Pending())
    return u[-1], lp[-1], vp[-1]


def _conditioning():
    bank = MuscleBank.from_config(MUSCLES, backend="numpy")
    return NodeConditioning(bank, NodeConfig.from_values({"muscles": MUSCLES}))


def _messages():
    return [("drive_b", SimpleNamespace(data=DRIVE), 1 * MS),
            ("muscle_kinematics_b", SimpleNamespace(name=MUSCLES, position=LENGTH,
                                                    velocity=VELOCITY), 2 * MS)]


def _replay():
    conditioning = _conditioning()
    for topic, msg, time_ns in _messages():
        conditioning.on_message(topic, msg, time_ns)
    assert not conditioning.issues, conditioning.issue_text()
    return conditioning.sample(2 * MS)


def _expected():
    return np.array(DRIVE), np.array(LENGTH), np.array(VELOCITY)


def test_a_topic_added_to_the_table_is_read_alike_offline_and_by_the_node_replay(new_topics):
    for taken in (_offline_one_by_one(), _offline_block(), _replay()):
        for got, want in zip(taken, _expected(), strict=True):
            np.testing.assert_allclose(got, want, rtol=0, atol=1e-12)


def test_the_node_subscribes_and_applies_a_topic_added_to_the_table(new_topics, ros):
    from rclpy.serialization import serialize_message
    from sensor_msgs.msg import JointState
    from std_msgs.msg import Float64MultiArray

    node = ros.muscle_node(muscles=MUSCLES)
    assert {"drive_b", "muscle_kinematics_b"} <= set(node._subscriptions_by_topic)
    classes = {"drive_b": Float64MultiArray, "muscle_kinematics_b": JointState}
    for topic, fields, _ in _messages():
        msg = classes[topic]()
        for key, value in vars(fields).items():
            setattr(msg, key, list(value))
        receive = node._receiver(topic, classes[topic])
        receive(serialize_message(msg), {"publication_sequence_number": 1})
    assert not any(node.issues.counts.values()), node.issues.counts  # accepted as they are
    # at the time the node took the path lengths: nothing extrapolated yet
    taken = node.inputs.sample(int(node.inputs.length_time_ns.max()))
    for got, want in zip(taken, _expected(), strict=True):
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-12)


def test_a_topic_not_in_the_table_is_an_error_on_every_path(new_topics):
    with pytest.raises(tp.UnknownInputTopicError, match="'nope' is not an input topic"):
        tp.input_topic("nope")
    with pytest.raises(tp.UnknownInputTopicError):
        _conditioning().on_message("nope", SimpleNamespace(data=DRIVE), 0)
    inputs = RecordedInputs(_Run(), len(MUSCLES), sink=None)
    with pytest.raises(tp.UnknownInputTopicError):
        inputs._apply("nope", _Series(data=[DRIVE]), 0)


def test_a_row_whose_fields_do_not_fit_its_role_is_refused():
    with pytest.raises(ValueError, match="role 'path'"):
        tp.InputTopic("x", tp.TYPE_JOINT_STATE, tp.PATH, True, ("position",), "")
    with pytest.raises(ValueError, match="role 'torque'"):
        tp.InputTopic("x", tp.TYPE_JOINT_STATE, "torque", True, ("position",), "")


def test_every_role_has_a_receiver_on_the_node_and_joint_roles_are_refused_offline(new_topics):
    """The node handles every role; the offline runner every role but JOINTS, which a log
    without node parameters cannot condition (a RunLogError at the log, tested in
    test_recording_run_log)."""
    from vm_ros.node.inputs import node_receivers

    assert set(node_receivers(_conditioning().inputs, None)) == set(tp.ROLE_FIELDS)
    inputs = RecordedInputs(_Run(), len(MUSCLES), sink=None)
    assert set(inputs._hold) == set(tp.ROLE_FIELDS) - {tp.JOINTS}
