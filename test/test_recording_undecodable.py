"""Logs holding what vm_ros cannot decode: a malformed message (muscle_node records inputs as
received, and any DDS peer can send one) is skipped and counted by every reader, and recompute
drops it as the node did; a corrupt `vm_ros.run` record or an MCAP that is not a vm_ros log is
one clear line and exit status 2. The verbs run as the installed `vm-ros` command."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import require_ros
from mcap.writer import Writer

from vm_ros import telemetry as tm
from vm_ros.errors import ConfigError
from vm_ros.model.run_config import RunConfig
from vm_ros.recording import METADATA_NAME, McapRecorder, RunInfo, RunTiming, cdr, open_run_log
from vm_ros.recording.reader import LogReader
from vm_ros.recording.run_log import read_run

VM_ROS = str(Path(sys.prefix) / "bin" / "vm-ros")
MUSCLES = ("vasti", "rectus_femoris")
MALFORMED = b"\x00\x01\x00\x00" + b"\xfa" * 24  # CDR header, then no valid JointState


def vm_ros(*args, expect: int = 0) -> subprocess.CompletedProcess:
    proc = subprocess.run([VM_ROS, *map(str, args)], capture_output=True, text=True, timeout=120)
    assert proc.returncode == expect, proc.stderr
    assert "Traceback" not in proc.stderr, proc.stderr
    return proc


def one_error_line(proc) -> str:
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    return lines[0]


@pytest.fixture
def malformed_log(tmp_path):
    """The repro: one /excitation record of 4 header bytes and 24 bytes 0xFA."""
    path = tmp_path / "malformed.mcap"
    with open_run_log(path, RunInfo(RunConfig(MUSCLES), RunTiming(), "test")) as rec:
        rec.write("/excitation", MALFORMED, 0)
    return path


def test_malformed_message_is_skipped_counted_and_reported(malformed_log, tmp_path):
    run = read_run(malformed_log, raw=["excitation"])
    assert run.get("excitation") is None
    assert run.skipped["/excitation"].count == 1
    assert run.skipped_note().startswith("skipped 1 undecodable message on /excitation")
    [event] = run.events(["excitation"])  # kept for a verbatim copy, marked as not decoded
    assert event.series is None and event.data == MALFORMED and event.time_ns == 0

    proc = vm_ros("report", malformed_log, "--no-plots", "--out", tmp_path / "report")
    assert "note: skipped 1 undecodable message on /excitation" in proc.stdout
    assert (tmp_path / "report" / "summary.csv").exists()


@pytest.fixture(scope="module")
def knee_with_malformed(tmp_path_factory):
    """A `vm-ros simulate` log, and a copy with a malformed excitation and kinematics
    message added among the recorded ones."""
    folder = tmp_path_factory.mktemp("undecodable")
    original, spoiled = folder / "knee.mcap", folder / "knee-malformed.mcap"
    # logged from time 0 (--start-time 0), so that the inserted messages' times are model times
    vm_ros("simulate", "--scenario", "knee_extension", "--duration", "0.2", "--start-time", "0",
           "--out", original)
    reader = LogReader(original)
    messages = [(m.topic, m.data, m.log_time_ns) for m in reader.messages()]
    messages += [("/excitation", MALFORMED, 50_000_000),
                 ("/muscle_kinematics", MALFORMED[:9], 120_000_000)]
    messages.sort(key=lambda m: m[2])  # stable: each after the valid ones of its time
    with McapRecorder(spoiled, metadata=reader.metadata, attachments=reader.attachments) as rec:
        for topic, type_name in reader.topic_types().items():
            rec.add_channel(topic, type_name)
        for message in messages:
            assert rec.write(*message)
    return original, spoiled


def test_recompute_drops_malformed_inputs_and_reproduces_the_run(knee_with_malformed, tmp_path):
    original, spoiled = knee_with_malformed
    out = tmp_path / "again.mcap"
    proc = vm_ros("recompute", spoiled, "--out", out)
    assert "skipped 2 undecodable messages: 1 on /excitation" in proc.stderr
    assert "1 on /muscle_kinematics" in proc.stderr
    assert "max |difference| 0 N over 20 samples" in proc.stdout
    recorded = read_run(original)
    again = read_run(out, raw=["excitation", "muscle_kinematics"])
    for topic in (tm.TOPIC_FORCE, tm.TOPIC_ENERGY_RATE, tm.TOPIC_ENERGY_TOTAL):
        np.testing.assert_array_equal(again.get(topic).time_ns, recorded.get(topic).time_ns)
        for key, value in recorded.get(topic).fields.items():
            np.testing.assert_array_equal(again.get(topic).fields[key], value)
    # the malformed inputs are copied verbatim, at their times, after the valid ones
    assert {t: s.count for t, s in again.skipped.items()} == {"/excitation": 1,
                                                              "/muscle_kinematics": 1}
    excitation = [e for e in again.events(["excitation"]) if e.time_ns == 50_000_000]
    assert [e.data == MALFORMED for e in excitation] == [False, True]
    assert again.skipped["/muscle_kinematics"].raw[0][1:] == (120_000_000, MALFORMED[:9])
    report = vm_ros("report", spoiled, "--no-plots", "--out", tmp_path / "report")
    # the report reads every input topic (a node log's validity needs them): both are named
    assert "note: skipped 2 undecodable messages: 1 on /excitation" in report.stdout
    assert "1 on /muscle_kinematics" in report.stdout


# --- corrupt metadata and logs that are not vm_ros logs -------------------------------------


@pytest.mark.parametrize(("key", "value", "reason"), [
    ("dt_s", "abc", "not a number"),
    ("dt_s", "0", "> 0"),
    ("publish_rate_hz", "-5", ">= 0"),
    ("muscles", "[1, 2]", "muscle names"),
    ("muscles", None, "missing"),
    ("overrides", "{not json", "Expecting"),
    ("start_time_ns", "soon", "invalid literal"),
])
def test_corrupt_metadata_is_a_config_error_naming_the_key(key, value, reason):
    record = RunInfo(RunConfig(MUSCLES), RunTiming(), "test").to_metadata()
    if value is None:
        del record[key]
    else:
        record[key] = value
    with pytest.raises(ConfigError, match=reason) as info:
        RunInfo.from_metadata(record)
    assert info.value.field == key and METADATA_NAME in str(info.value)


@pytest.mark.parametrize(("key", "value", "expected"), [
    ("dt_s", "abc", "field 'dt_s' = 'abc': not a number"),
    ("node_parameters", '{"model_rate_hz": "x"}', "field 'node_parameters.model_rate_hz' = 'x'"),
])
def test_corrupt_metadata_stops_every_reader_with_one_line(tmp_path, key, value, expected):
    info = RunInfo(RunConfig(MUSCLES), RunTiming(), "test")
    path = tmp_path / "corrupt.mcap"
    with McapRecorder(path, metadata={METADATA_NAME: {**info.to_metadata(), key: value}}) as rec:
        rec.add_channel("/muscle_kinematics", tm.TYPE_JOINT_STATE)
        rec.write("/muscle_kinematics", cdr.serialize(tm.TYPE_JOINT_STATE, {
            "name": list(MUSCLES), "position": [0.3, 0.5]}), 0)
    verbs = [("recompute", path, "--out", tmp_path / "out.mcap")]
    if key == "dt_s":  # the node parameters matter to recompute only
        verbs.append(("report", path, "--no-plots", "--out", tmp_path / "report"))
    for args in verbs:
        line = one_error_line(vm_ros(*args, expect=2))
        assert line.startswith(f"vm-ros {args[0]}: error: {path}: '{METADATA_NAME}' metadata: "
                               f"{expected}")


def write_foreign_mcap(path: Path, schema_name: str, encoding: str, data: bytes) -> None:
    """An MCAP that vm_ros did not write: one channel, no vm_ros.run record."""
    with open(path, "wb") as stream:
        writer = Writer(stream)
        writer.start(profile="", library="test")
        schema = writer.register_schema(schema_name, "jsonschema" if encoding == "json"
                                        else "ros2msg", b"{}")
        channel = writer.register_channel("/chatter", encoding, schema)
        writer.add_message(channel, 1, data, 1)
        writer.finish()


@pytest.mark.parametrize(("schema_name", "encoding", "data", "why"), [
    ("Greeting", "json", b'{"text": "hello"}', "message encoding 'json', not cdr"),
    ("Greeting", "cdr", b"\x00\x01\x00\x00", "schema name 'Greeting' is not pkg/msg/Type"),
    ("std_msgs/msg/String", "cdr", b"\x00\x01\x00\x00\x06\x00\x00\x00hello\x00", None),
], ids=["json", "not-pkg-msg-type", "ros-without-metadata"])
def test_foreign_mcap_is_one_line_and_exit_2(tmp_path, schema_name, encoding, data, why):
    path = tmp_path / "foreign.mcap"
    write_foreign_mcap(path, schema_name, encoding, data)
    line = one_error_line(vm_ros("report", path, "--no-plots", expect=2))
    assert f"not a vm_ros run log (no '{METADATA_NAME}' metadata record" in line
    line = one_error_line(vm_ros("recompute", path, "--out", tmp_path / "r.mcap", expect=2))
    assert f"no '{METADATA_NAME}' metadata record" in line
    if why is not None:  # replay needs no metadata, but ROS 2 messages
        line = one_error_line(vm_ros("replay", path, expect=2))
        assert line == f"vm-ros replay: error: {path}: nothing to replay: /chatter ({why})"
        line = one_error_line(vm_ros("replay", path, "--topics", "chatter", expect=2))
        assert line.endswith(f"cannot replay /chatter ({why})")


def test_foreign_mcap_read_run_counts_what_it_cannot_decode(tmp_path):
    path = tmp_path / "foreign.mcap"
    write_foreign_mcap(path, "Greeting", "json", b'{"text": "hello"}')
    run = read_run(path)
    assert run.info is None and run.series == {}
    assert run.skipped_note() == ("skipped 1 undecodable message on /chatter (message encoding "
                                  "'json', not cdr)")


# --- with ROS: replay, and muscle_node's own log ---------------------------------------------


@pytest.mark.ros
def test_replay_skips_malformed_messages(malformed_log):
    require_ros()  # the replay subprocess starts rclpy
    proc = vm_ros("replay", malformed_log)
    assert "replayed 0 messages" in proc.stdout
    assert "vm-ros replay: skipped 1 undecodable message on /excitation" in proc.stderr


@pytest.mark.ros
def test_node_log_with_a_malformed_input_recomputes_to_the_same_outputs(ros, tmp_path):
    """muscle_node (simulated time) records a malformed excitation and drops it; recompute
    drops it too and gives the logged outputs."""
    from test_node import MS, SIM_T0, set_clock

    from vm_ros.model import MuscleBank
    from vm_ros.node.inputs import physical_path_length_range

    lo, hi = physical_path_length_range(MuscleBank.from_config(list(MUSCLES)), 0.0)
    path = tmp_path / "node.mcap"
    node = ros.muscle_node(use_sim_time=True, muscles=list(MUSCLES),
                           initial_path_length_m=list(0.5 * (lo + hi)), input_timeout_s=1000.0,
                           stale_input_policy="hold", mcap__enabled=True, mcap__path=str(path))
    probe = ros.probe()
    assert ros.spin_until(lambda: probe.excitation.get_subscription_count() > 0
                          and probe.clock.get_subscription_count() > 0, timeout_s=10)
    set_clock(ros, probe, node, SIM_T0)
    assert node.scheduler.started
    for k, drive in enumerate(([0.6, 0.2], MALFORMED, [0.1, 0.9])):
        if isinstance(drive, bytes):
            probe.excitation.publish(drive)  # already serialised: sent as it is
            assert ros.spin_until(lambda: node.issues.counts["undecodable"] == 1)
        else:
            probe.send_excitation(MUSCLES, drive)
            assert ros.spin_until(lambda d=drive: np.array_equal(node.inputs.drive, d))
        for j in range(1, 11):
            set_clock(ros, probe, node, SIM_T0 + (100 * k + 10 * j) * MS)
    node.close_run_log()

    run = read_run(path)
    assert run.skipped["/excitation"].count == 1 and len(run.get("excitation")) == 2
    out = tmp_path / "again.mcap"
    proc = vm_ros("recompute", path, "--out", out)
    assert "skipped 1 undecodable message on /excitation" in proc.stderr
    assert "approximate" not in proc.stdout
    assert "max |difference| 0 N over 31 samples" in proc.stdout
    again = read_run(out)
    assert again.skipped["/excitation"].count == 1
    for topic, key in ((tm.TOPIC_FORCE, "effort"), (tm.TOPIC_ENERGY_RATE, "data")):
        logged, recomputed = run.get(topic), again.get(topic)
        assert len(logged) == 31
        np.testing.assert_array_equal(recomputed.time_ns, logged.time_ns)
        np.testing.assert_array_equal(recomputed.fields[key], logged.fields[key])
