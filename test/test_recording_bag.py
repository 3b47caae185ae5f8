"""rosbag2 bag directories (vm_ros.recording.bag): a log path without ``.mcap`` is a directory
NAME/ with NAME_0.mcap and rosbag2's metadata.yaml; rosbags' reader (an independent rosbag2
implementation) opens it, and every vm_ros reader takes the directory as it takes the file."""

from __future__ import annotations

import subprocess
import sys
import time

import numpy as np
import pytest
import yaml

from vm_ros import telemetry as tm
from vm_ros.recording import read_run
from vm_ros.recording.bag import METADATA_FILE, bag_file_path, is_bag_path
from vm_ros.recording.reader import LogReadError, log_channels

rosbags_rosbag2 = pytest.importorskip("rosbags.rosbag2")
rosbags_typesys = pytest.importorskip("rosbags.typesys")


def simulate(out, *extra):
    proc = subprocess.run([sys.executable, "-m", "vm_ros.cli", "simulate", "--scenario",
                           "isometric_ramp", "--duration", "0.5", "--out", str(out), *extra],
                          capture_output=True, text=True, timeout=120)
    return proc


@pytest.fixture(scope="module")
def bag(tmp_path_factory):
    """A simulate run written to a bag directory, and the same run to a single file (the same
    start time, so that their log times are equal)."""
    root = tmp_path_factory.mktemp("bags")
    out, single = root / "ramp", root / "ramp.mcap"
    start = str(time.time_ns())
    for path in (out, single):
        proc = simulate(path, "--start-time", start)
        assert proc.returncode == 0, proc.stderr
    return out, single


def test_paths():
    assert is_bag_path("runs/ramp") and is_bag_path("runs/ramp.bag")
    assert not is_bag_path("ramp.mcap") and not is_bag_path("RAMP.MCAP")
    assert bag_file_path("runs/ramp").as_posix() == "runs/ramp/ramp_0.mcap"


def test_directory_layout_and_metadata(bag):
    out, _ = bag
    assert sorted(p.name for p in out.iterdir()) == [METADATA_FILE, "ramp_0.mcap"]
    info = yaml.safe_load((out / METADATA_FILE).read_text())["rosbag2_bagfile_information"]
    assert info["version"] == 9 and info["storage_identifier"] == "mcap"
    assert info["relative_file_paths"] == ["ramp_0.mcap"]
    run = read_run(out)
    counts = {topic: len(series) for topic, series in run.series.items()}
    assert info["message_count"] == sum(counts.values()) > 0
    topics = {t["topic_metadata"]["name"]: t for t in info["topics_with_message_count"]}
    for topic, count in counts.items():
        assert topics[topic]["message_count"] == count
        meta = topics[topic]["topic_metadata"]
        assert meta["type"] == run.topic_types[topic]
        assert meta["serialization_format"] == "cdr"
        assert meta["type_description_hash"].startswith("RIHS01_")
        assert meta["offered_qos_profiles"][0]["reliability"] == "reliable"
    times = np.concatenate([s.time_ns for s in run.series.values()])
    assert info["starting_time"]["nanoseconds_since_epoch"] == times.min()
    assert info["duration"]["nanoseconds"] == times.max() - times.min()
    assert info["files"] == [{"path": "ramp_0.mcap",
                              "starting_time": info["starting_time"],
                              "duration": info["duration"],
                              "message_count": info["message_count"]}]


def test_rosbags_reads_the_bag(bag):
    out, _ = bag
    run = read_run(out)
    typestore = rosbags_typesys.get_typestore(rosbags_typesys.Stores.ROS2_JAZZY)
    counts, efforts = {}, []
    with rosbags_rosbag2.Reader(out) as reader:
        assert reader.message_count == sum(len(s) for s in run.series.values())
        for connection, _timestamp, data in reader.messages():
            counts[connection.topic] = counts.get(connection.topic, 0) + 1
            if connection.topic == "/" + tm.TOPIC_FORCE:
                efforts.append(typestore.deserialize_cdr(data, connection.msgtype).effort)
    assert counts == {topic: len(series) for topic, series in run.series.items()}
    np.testing.assert_array_equal(np.array(efforts), run.get(tm.TOPIC_FORCE).fields["effort"])


def test_readers_take_the_directory_as_the_file(bag):
    out, single = bag
    from_bag, from_file = read_run(out), read_run(single)
    assert from_bag.complete and from_bag.info.config.muscles == from_file.info.config.muscles
    assert set(from_bag.series) == set(from_file.series)
    for topic, series in from_file.series.items():
        np.testing.assert_array_equal(from_bag.series[topic].time_ns, series.time_ns)
    assert set(log_channels(out)) == set(log_channels(single))


def test_recompute_reads_a_bag_and_writes_one(bag, tmp_path):
    out, _ = bag
    again = tmp_path / "again"
    proc = subprocess.run([sys.executable, "-m", "vm_ros.cli", "recompute", str(out),
                           "--out", str(again)], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert (again / METADATA_FILE).is_file()
    np.testing.assert_array_equal(read_run(again).get(tm.TOPIC_FORCE).fields["effort"],
                                  read_run(out).get(tm.TOPIC_FORCE).fields["effort"])


def test_node_log_in_a_bag_directory(tmp_path):
    from test_node_recording import MUSCLES, T0, run_info

    from vm_ros.node.recording import NodeRunLog
    from vm_ros.recording.cdr import serialize
    from vm_ros.recording.messages import excitation_fields

    out = tmp_path / "node_run"
    log = NodeRunLog(out, run_info)
    assert log.file_path == out / "node_run_0.mcap" and log.file_path.exists()
    data = serialize(tm.TYPE_JOINT_STATE, excitation_fields(MUSCLES, [0.2, 0.1], T0))
    log.write(tm.TOPIC_EXCITATION, data, T0)
    log.start(T0)
    log.write(tm.TOPIC_EXCITATION, data, T0 + 1_000_000)
    log.close()
    assert log.status.ok and log.status.written == 2
    with rosbags_rosbag2.Reader(out) as reader:
        assert reader.message_count == 2
        assert [t for _, t, _ in reader.messages()] == [T0, T0 + 1_000_000]
    assert len(read_run(out).get(tm.TOPIC_EXCITATION)) == 2


def test_killed_writer_leaves_a_bag_the_readers_read(tmp_path):
    """No metadata.yaml (the log was not finished): vm_ros reads the directory's .mcap file."""
    from test_recording_crash import WRITER_SCRIPT

    out = tmp_path / "killed"
    proc = subprocess.run([sys.executable, "-c", WRITER_SCRIPT, str(out), "1.5"],
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode < 0
    assert not (out / METADATA_FILE).exists()
    run = read_run(out)
    assert not run.complete and len(run.get("/energy_total")) > 0


def test_bad_bag_paths(tmp_path):
    blocker = tmp_path / "taken"
    blocker.write_text("")
    proc = simulate(blocker)
    assert proc.returncode != 0 and "Traceback" not in proc.stderr
    assert "not a directory" in proc.stderr and len(proc.stderr.strip().splitlines()) == 1
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(LogReadError, match="no .mcap file"):
        read_run(empty)


# --- split bags ------------------------------------------------------------------------------


def write_split(out, count, **options):
    from vm_ros.recording.cdr import serialize
    from vm_ros.recording.messages import float64_fields
    from vm_ros.recording.writer import McapRecorder

    with McapRecorder(out, metadata={"note": {"k": "v"}}, attachments={"a.txt": b"x"},
                      chunk_size=4096, **options) as rec:
        rec.add_channel("/energy_total", "std_msgs/msg/Float64")
        for k in range(count):
            rec.write("/energy_total", serialize(tm.TYPE_FLOAT64, float64_fields(float(k))),
                      k * 1_000_000)
    return rec


@pytest.mark.parametrize("options", [{"max_file_duration_s": 0.1},
                                     {"max_file_size": 1500}], ids=["duration", "size"])
def test_split_bag(tmp_path, options):
    out = tmp_path / "split"
    rec = write_split(out, 1000, **options)
    assert rec.status.ok and rec.status.written == 1000
    info = yaml.safe_load((out / METADATA_FILE).read_text())["rosbag2_bagfile_information"]
    names = info["relative_file_paths"]
    assert len(names) >= 3 and names == [f"split_{k}.mcap" for k in range(len(names))]
    assert sorted(p.name for p in out.glob("*.mcap")) == sorted(names)
    assert sum(f["message_count"] for f in info["files"]) == info["message_count"] == 1000
    assert info["topics_with_message_count"][0]["message_count"] == 1000
    assert info["duration"]["nanoseconds"] == 999_000_000
    if "max_file_duration_s" in options:  # 0.1 s of log time per file: 100 messages each
        assert [f["message_count"] for f in info["files"]] == [100] * 10
    else:
        sizes = [(out / name).stat().st_size for name in names]
        # past the limit by at most one chunk (4 kB before compression) and the summary
        assert all(size < 1500 + 4096 + 2048 for size in sizes)
    run = read_run(out)  # chained: every message once, in order
    assert run.complete and run.metadata["note"] == {"k": "v"}
    np.testing.assert_array_equal(run.get("/energy_total").fields["data"], np.arange(1000.0))
    assert len(read_run(out / names[1]).get("/energy_total")) > 0  # each file is a log
    assert bytes(read_run(out / names[1]).attachments["a.txt"]) == b"x"
    with rosbags_rosbag2.Reader(out) as reader:
        times = [t for _, t, _ in reader.messages()]
    assert times == [k * 1_000_000 for k in range(1000)]
    assert rec.status.bytes_written == sum((out / n).stat().st_size for n in names)


def test_split_needs_a_bag_directory_and_sane_limits(tmp_path):
    from vm_ros.errors import ConfigError
    from vm_ros.node.params import NodeConfig
    from vm_ros.recording import RecorderError
    from vm_ros.recording.writer import McapRecorder

    with pytest.raises(RecorderError, match="needs a bag directory"):
        McapRecorder(tmp_path / "one.mcap", max_file_size=1000)
    with pytest.raises(RecorderError, match=">= 0"):
        McapRecorder(tmp_path / "bag", max_file_duration_s=-1.0)
    with pytest.raises(ConfigError, match="bag directory"):
        NodeConfig.from_values({"mcap.max_bag_size": 1000, "mcap.path": "run.mcap"})
    config = NodeConfig.from_values({"mcap.max_bag_duration_s": 60, "mcap.path": "runs/x"})
    assert config.mcap_max_bag_duration_s == 60.0


def test_reused_directory_drops_the_former_files(tmp_path):
    out = tmp_path / "again"
    write_split(out, 1000, max_file_duration_s=0.1)
    write_split(out, 100)
    assert sorted(p.name for p in out.iterdir()) == ["again_0.mcap", METADATA_FILE]
    assert len(read_run(out).get("/energy_total")) == 100


def test_node_log_splits_by_its_recorded_parameters(tmp_path):
    import dataclasses

    from test_node_recording import T0, run_info

    from vm_ros.node.recording import NodeRunLog
    from vm_ros.recording.cdr import serialize
    from vm_ros.recording.messages import float64_fields

    def info(start_ns):
        base = run_info(start_ns)
        return dataclasses.replace(base, extra=dict(
            base.extra, node_parameters='{"mcap.max_bag_duration_s": 0.25}'))

    out = tmp_path / "node_split"
    log = NodeRunLog(out, info)
    log.start(T0)
    for k in range(100):
        log.write(tm.TOPIC_ENERGY_TOTAL, serialize(tm.TYPE_FLOAT64, float64_fields(float(k))),
                  T0 + k * 10_000_000)
    log.close()
    assert log.status.ok
    assert sorted(p.name for p in out.glob("*.mcap")) == [f"node_split_{k}.mcap"
                                                          for k in range(4)]
    np.testing.assert_array_equal(read_run(out).get(tm.TOPIC_ENERGY_TOTAL).fields["data"],
                                  np.arange(100.0))


def test_simulate_names_the_bag_directory_it_wrote(tmp_path):
    """The verb's last line names the bag directory and its file count, not the last file."""
    out = tmp_path / "split"
    proc = simulate(out, "--max-bag-duration", "0.2")
    assert proc.returncode == 0, proc.stderr
    files = sorted(out.glob("split_*.mcap"))
    assert len(files) >= 2
    assert f"log: {out}/ (rosbag2 bag, {len(files)} files)" in proc.stdout
    single = simulate(tmp_path / "one.mcap")
    assert f"log: {tmp_path / 'one.mcap'} (" in single.stdout
