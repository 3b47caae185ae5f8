"""muscle_node's run log (vm_ros.node.recording): opened at the model start, earlier messages
buffered, readable by read_run, a full disk reported in the status, never raised (no ROS needed:
messages are CDR-encoded from bundled definitions)."""

from __future__ import annotations

import dataclasses
import json
import time

import pytest
from test_recording_writer import FullDisk

from vm_ros import telemetry as tm
from vm_ros.model.run_config import RunConfig
from vm_ros.node.recording import NodeRunLog, node_run_extra
from vm_ros.recording import RecorderError, RunInfo, RunTiming, read_run
from vm_ros.recording.cdr import serialize
from vm_ros.recording.messages import excitation_fields, float64_fields, kinematics_fields

MUSCLES = ("vasti", "rectus_femoris")
T0 = 1_700_000_000_000_000_000


def run_info(start_time_ns):
    extra = node_run_extra("/muscle_node", {"muscles": list(MUSCLES)})
    if start_time_ns is None:
        extra["started"] = "false"
    return RunInfo(RunConfig(MUSCLES, recovery_mode="static"),
                   RunTiming(dt_s=1e-3, publish_rate_hz=100.0, telemetry_rate_hz=0.0,
                             start_time_ns=start_time_ns or 0),
                   source="muscle_node", namespace="/", extra=extra)


def test_messages_before_the_start_are_buffered_then_logged(tmp_path):
    path = tmp_path / "sub" / "run.mcap"
    log = NodeRunLog(path, run_info, buffer_size=100)
    assert path.exists() and not log.started  # the path is checked at once
    log.write(tm.TOPIC_KINEMATICS,
              serialize(tm.TYPE_JOINT_STATE, kinematics_fields(MUSCLES, [0.3, 0.5], None, T0)),
              T0, T0)
    log.write(tm.TOPIC_EXCITATION,
              serialize(tm.TYPE_JOINT_STATE, excitation_fields(MUSCLES, [0.2, 0.1], T0)), T0)
    log.start(T0 + 5_000_000)
    assert log.started
    log.write(tm.TOPIC_ENERGY_TOTAL, serialize(tm.TYPE_FLOAT64, float64_fields(1.5)),
              T0 + 15_000_000)
    log.close()
    log.close()  # idempotent
    assert log.status.ok and log.status.written == 3 and log.status.dropped == 0

    run = read_run(path)
    assert run.complete
    assert run.info.source == "muscle_node"
    assert run.info.timing.start_time_ns == T0 + 5_000_000
    assert json.loads(run.info.extra["node_parameters"]) == {"muscles": list(MUSCLES)}
    assert run.info.extra["started"] == "true"
    assert run.get(tm.TOPIC_KINEMATICS).fields["position"][0].tolist() == [0.3, 0.5]
    assert run.get(tm.TOPIC_ENERGY_TOTAL).fields["data"].tolist() == [1.5]
    assert {"model.yaml", "muscles.yaml"} <= set(run.attachments)
    assert "/diagnostics" in run.topic_types


def test_buffer_is_bounded(tmp_path):
    log = NodeRunLog(tmp_path / "run.mcap", run_info, buffer_size=3)
    data = serialize(tm.TYPE_FLOAT64, float64_fields(0.0))
    for k in range(5):
        log.write(tm.TOPIC_ENERGY_TOTAL, data, T0 + k)
    assert log.status.dropped == 2
    log.start(T0)
    log.close()
    assert log.status.written == 3 and log.status.dropped == 2


def test_closing_before_the_start_leaves_a_complete_file(tmp_path):
    path = tmp_path / "run.mcap"
    log = NodeRunLog(path, run_info)
    log.write(tm.TOPIC_EXCITATION,
              serialize(tm.TYPE_JOINT_STATE, excitation_fields(MUSCLES, [0.2, 0.1], T0)), T0)
    log.close()
    assert not log.write(tm.TOPIC_EXCITATION, b"", T0)
    run = read_run(path)
    assert run.complete and run.info.extra["started"] == "false"
    assert len(run.get(tm.TOPIC_EXCITATION)) == 1


def test_attachments_are_the_files_as_they_were_when_the_node_was_built(tmp_path):
    """The model file is read when the log object is made (the node's construction, when the
    model was built from it), not at the model start: a later edit of the file is not logged."""
    model_file = tmp_path / "model.yaml"
    model_file.write_bytes(b"# the model the node was built from\n")

    def info_with_model_file(start_time_ns):
        info = run_info(start_time_ns)
        return dataclasses.replace(info, config=info.config.replace(params=str(model_file)))

    log = NodeRunLog(tmp_path / "run.mcap", info_with_model_file)
    model_file.write_bytes(b"# edited after the node started\n")
    log.start(T0)
    log.close()
    run = read_run(tmp_path / "run.mcap")
    assert run.attachments["model.yaml"] == b"# the model the node was built from\n"


def test_unwritable_path_fails_at_once(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("")
    with pytest.raises(RecorderError) as info:
        NodeRunLog(blocker / "run.mcap", run_info)
    assert str(blocker) in str(info.value)


# --- a full disk: the status says so, nothing is raised ------------------------------------------


def test_disk_full_when_the_log_opens_is_a_failed_state(tmp_path):
    """The header and attachments do not fit: start() and close() do not raise; the status is
    failed with the error, every message counted as dropped, on_error called once."""
    errors = []
    log = NodeRunLog(tmp_path / "run.mcap", run_info, on_error=errors.append,
                     opener=lambda path: FullDisk(path, room=4096))
    data = serialize(tm.TYPE_FLOAT64, float64_fields(0.0))
    assert log.write(tm.TOPIC_ENERGY_TOTAL, data, T0)  # buffered before the start
    log.start(T0)
    for k in range(5):
        assert not log.write(tm.TOPIC_ENERGY_TOTAL, data, T0 + k)
    log.close()
    log.close()
    status = log.status
    assert not status.ok and "No space left on device" in status.error
    assert (status.written, status.dropped, status.bytes_written) == (0, 6, 4096)
    assert len(errors) == 1 and "No space left on device" in errors[0]


def test_disk_full_later_counts_the_messages_in_the_file(tmp_path):
    path = tmp_path / "run.mcap"
    errors = []
    room = 60_000  # the attachments (~40 kB), then a few chunks
    log = NodeRunLog(path, run_info, on_error=errors.append, chunk_size=2048,
                     opener=lambda p: FullDisk(p, room=room))
    log.start(T0)
    count = 0
    while log.status.ok or count < 3000:
        log.write(tm.TOPIC_ENERGY_TOTAL, serialize(tm.TYPE_FLOAT64, float64_fields(count)),
                  T0 + count)
        count += 1
        if count % 100 == 0:
            time.sleep(0.001)  # let the writer thread keep up
        assert count < 100_000, "the disk never filled"
    log.close()
    status = log.status
    assert not status.ok and "No space left on device" in status.error
    in_file = read_run(path).get(tm.TOPIC_ENERGY_TOTAL)
    assert status.written == len(in_file) > 0
    assert in_file.fields["data"].tolist() == list(range(len(in_file)))
    assert status.written + status.dropped == count and status.bytes_written == room
    assert len(errors) == 1 and str(path) in errors[0]
