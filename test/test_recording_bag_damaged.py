"""Damaged and partial bag directories (vm_ros.recording.bag): every reader (read_run, report,
recompute, replay) stops on one line (exit 2) where metadata.yaml cannot be used or a file of
the log is missing, notes the .mcap files metadata.yaml leaves out; `vm-ros bag reindex` writes
the metadata of a bag whose recorder was killed, which rosbags (an independent rosbag2 reader)
then opens."""

from __future__ import annotations

import shutil
import subprocess
import sys

import numpy as np
import pytest
import yaml
from test_recording_bag import write_split

from vm_ros import telemetry as tm
from vm_ros.cli import main
from vm_ros.recording import read_run
from vm_ros.recording.bag import MAX_METADATA_DEPTH, METADATA_FILE
from vm_ros.recording.reader import LogReadError

rosbags_rosbag2 = pytest.importorskip("rosbags.rosbag2")
rosbags_typesys = pytest.importorskip("rosbags.typesys")

COUNT = 1000  # messages of the split bag: /energy_total data k at log time k ms
NESTED_LINES = 3000


@pytest.fixture(scope="module")
def split_bag(tmp_path_factory):
    """A bag of 1000 messages in several files, written by McapRecorder."""
    out = tmp_path_factory.mktemp("split") / "split"
    write_split(out, COUNT, max_file_duration_s=0.1)
    return out


@pytest.fixture
def bag(split_bag, tmp_path):
    """A fresh copy of the split bag, to damage."""
    copy = tmp_path / "split"
    shutil.copytree(split_bag, copy)
    return copy


def _listed(directory):
    return yaml.safe_load((directory / METADATA_FILE).read_text())[
        "rosbag2_bagfile_information"]["relative_file_paths"]


def _replace_listed(directory, old, new):
    path = directory / METADATA_FILE
    path.write_text(path.read_text().replace(f"- {old}\n", f"- {new}\n"))


def not_utf8(bag):
    with open(bag / METADATA_FILE, "ab") as handle:
        handle.write(b"# caf\xe9\n")  # Latin-1
    return "metadata.yaml: not UTF-8 text (byte 0xe9 at offset"


def nested(bag):
    (bag / METADATA_FILE).write_text("rosbag2_bagfile_information:\n"
                                     + " [\n" * NESTED_LINES + " ]\n" * NESTED_LINES)
    return f"metadata.yaml: nested {NESTED_LINES + 1} levels deep"


def nested_block(bag):
    """Nested by indentation: 9 MB."""
    (bag / METADATA_FILE).write_text(
        "rosbag2_bagfile_information:\n"
        + "".join(f"{'  ' * k}- \n" for k in range(NESTED_LINES)))
    return f"metadata.yaml: nested {NESTED_LINES + 1} levels deep"


def syntax_error(bag):
    (bag / METADATA_FILE).write_text("rosbag2_bagfile_information:\n  relative_file_paths: [a\n")
    return "metadata.yaml: not valid YAML (line 3, column 1: "


def not_rosbag2(bag):
    (bag / METADATA_FILE).write_text("- just\n- a list\n")
    return "metadata.yaml: no rosbag2_bagfile_information.relative_file_paths list"


def outside(bag):
    (bag.parent / "elsewhere.mcap").write_bytes((bag / "split_0.mcap").read_bytes())
    _replace_listed(bag, "split_0.mcap", "../elsewhere.mcap")
    return "metadata.yaml: file path '../elsewhere.mcap' is outside the bag directory"


def absolute(bag):
    _replace_listed(bag, "split_0.mcap", str((bag / "split_0.mcap").resolve()))
    return "is outside the bag directory"


def listed_file_missing(bag):
    (bag / "split_1.mcap").unlink()
    return ("metadata.yaml lists split_1.mcap, missing from the directory: the log has a gap "
            "(each remaining .mcap file is a run log of its own and reads alone)")


def numbered_file_missing(bag):
    """No metadata.yaml (a killed split recording) and a file in the middle gone."""
    (bag / METADATA_FILE).unlink()
    (bag / "split_2.mcap").unlink()
    return "split_2.mcap missing: the log has a gap"


DAMAGE = [not_utf8, nested, nested_block, syntax_error, not_rosbag2, outside, absolute,
          listed_file_missing, numbered_file_missing]


@pytest.mark.parametrize("damage", DAMAGE, ids=[d.__name__ for d in DAMAGE])
def test_damaged_bag_is_one_line_for_every_reader(bag, damage, capsys):
    expected = damage(bag)
    with pytest.raises(LogReadError) as error:
        read_run(bag)
    assert expected in str(error.value) and "\n" not in str(error.value)
    for verb in (["report", "--no-plots"], ["recompute"], ["replay"]):
        assert main([verb[0], str(bag), *verb[1:]]) == 2
        captured = capsys.readouterr()
        assert captured.err == f"vm-ros {verb[0]}: error: cannot read MCAP log {bag}: " \
                               f"{error.value.reason}\n"
        assert expected in captured.err
    assert not list(bag.parent.glob("*-report")) and not list(bag.parent.glob("*recomputed*"))


def test_deeply_nested_metadata_through_the_command(bag):
    """The case that overflowed the stack, run as the user runs it: one line, no traceback."""
    expected = nested(bag)
    for verb in (["report", "--no-plots"], ["recompute"]):
        proc = subprocess.run([sys.executable, "-m", "vm_ros.cli", verb[0], str(bag), *verb[1:]],
                              capture_output=True, text=True, timeout=120)
        assert proc.returncode == 2 and "Traceback" not in proc.stderr
        assert len(proc.stderr.strip().splitlines()) == 1 and expected in proc.stderr


def test_metadata_the_writer_makes_is_well_within_the_nesting_limit(split_bag):
    from vm_ros.recording.bag import _nesting_depth

    # the document, rosbag2_bagfile_information, topics_with_message_count, a topic, its
    # topic_metadata, offered_qos_profiles, a profile, its deadline: 8
    assert _nesting_depth((split_bag / METADATA_FILE).read_text()) == 8 < MAX_METADATA_DEPTH


def test_unlisted_mcap_file_is_noted_not_read(bag, capsys):
    """A .mcap file metadata.yaml does not list is left out, as rosbag2 does, and named."""
    shutil.copy(bag / "split_0.mcap", bag / "stray.mcap")
    run = read_run(bag)
    np.testing.assert_array_equal(run.get("/energy_total").fields["data"], np.arange(COUNT))
    note = f"bag {bag}: 1 .mcap file not listed in metadata.yaml, not read: stray.mcap"
    assert run.unlisted_note == note
    assert main(["replay", str(bag), "--topics", "nothing"]) == 2  # after the note, before ROS
    assert capsys.readouterr().err.startswith(f"vm-ros replay: {note}\n")


# --- vm-ros bag reindex ----------------------------------------------------------------------


def rosbags_values(directory) -> tuple[np.ndarray, np.ndarray]:
    """(data, log times) of /energy_total as rosbags reads the bag."""
    typestore = rosbags_typesys.get_typestore(rosbags_typesys.Stores.ROS2_JAZZY)
    values, times = [], []
    with rosbags_rosbag2.Reader(directory) as reader:
        for connection, timestamp, data in reader.messages():
            assert connection.topic == "/" + tm.TOPIC_ENERGY_TOTAL
            values.append(typestore.deserialize_cdr(data, connection.msgtype).data)
            times.append(timestamp)
        assert reader.message_count == len(values)
    return np.array(values), np.array(times)


def test_reindex_rebuilds_the_metadata(bag, capsys):
    names = _listed(bag)
    (bag / METADATA_FILE).unlink()
    with pytest.raises(Exception, match="metadata"):  # rosbags refuses the bag without it
        rosbags_values(bag)
    assert main(["bag", "reindex", str(bag)]) == 0
    assert capsys.readouterr().out == (f"{bag / METADATA_FILE}: {len(names)} files, "
                                       f"{COUNT} messages\n")
    assert _listed(bag) == names
    values, times = rosbags_values(bag)
    np.testing.assert_array_equal(values, np.arange(COUNT))
    np.testing.assert_array_equal(times, np.arange(COUNT) * 1_000_000)


def test_reindex_replaces_damaged_metadata(bag):
    nested(bag)
    assert main(["bag", "reindex", str(bag)]) == 0
    np.testing.assert_array_equal(rosbags_values(bag)[0], np.arange(COUNT))


def test_reindex_a_killed_recording(tmp_path, capsys):
    """SIGKILL: no metadata.yaml and a last file without footer. Reindex finishes the file after
    its last complete chunk (no byte lost: the rest goes to .cut); rosbags reads what the vm_ros
    readers read before."""
    from test_recording_crash import WRITER_SCRIPT

    out = tmp_path / "killed"
    proc = subprocess.run([sys.executable, "-c", WRITER_SCRIPT, str(out), "1.5"],
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode < 0 and not (out / METADATA_FILE).exists()
    file = out / "killed_0.mcap"
    original = file.read_bytes()
    before = read_run(out)
    kept = before.get(tm.TOPIC_ENERGY_TOTAL).fields["data"]
    assert not before.complete and len(kept) > 0
    assert main(["bag", "reindex", str(out)]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[-1] == f"{out / METADATA_FILE}: 1 file, {len(kept)} messages"
    cut = out / "killed_0.mcap.cut"
    tail = cut.read_bytes() if cut.exists() else b""
    assert lines[0].startswith("killed_0.mcap was cut short: finished after its last complete "
                               "record")
    assert original == file.read_bytes()[:len(original) - len(tail)] + tail
    values, _ = rosbags_values(out)
    np.testing.assert_array_equal(values, np.arange(len(kept)))  # the writer's k, no gap
    after = read_run(out)
    np.testing.assert_array_equal(after.get(tm.TOPIC_ENERGY_TOTAL).fields["data"], kept)
    assert main(["bag", "reindex", str(out)]) == 0  # again: the file is finished now
    assert capsys.readouterr().out.splitlines() == lines[-1:]


def test_reindex_a_split_bag_whose_last_file_is_cut(bag):
    """The last file cut in the middle of its data: the earlier files and the complete chunks
    of the last are indexed, every message in order from the first."""
    names = _listed(bag)
    counts = [f["message_count"] for f in yaml.safe_load((bag / METADATA_FILE).read_text())[
        "rosbag2_bagfile_information"]["files"]]
    (bag / METADATA_FILE).unlink()
    last = bag / names[-1]
    last.write_bytes(last.read_bytes()[:last.stat().st_size // 2])
    assert main(["bag", "reindex", str(bag)]) == 0
    values, _ = rosbags_values(bag)
    assert sum(counts[:-1]) <= len(values) < COUNT
    np.testing.assert_array_equal(values, np.arange(len(values)))


@pytest.mark.parametrize("damage, expected", [
    ("cut_middle", "split_1.mcap is cut short but is not the last file"),
    ("empty_last", "cannot be indexed: empty"),
    ("not_mcap", "split_0.mcap cannot be indexed: not an MCAP file"),
    ("gap", "split_2.mcap missing: the log has a gap"),
])
def test_reindex_names_the_file_it_cannot_index(bag, damage, expected, capsys):
    names = _listed(bag)
    (bag / METADATA_FILE).unlink()
    if damage == "cut_middle":
        path = bag / "split_1.mcap"
        path.write_bytes(path.read_bytes()[:-100])
    elif damage == "empty_last":
        (bag / f"split_{len(names)}.mcap").write_bytes(b"")
    elif damage == "not_mcap":
        (bag / "split_0.mcap").write_bytes(b"not an mcap file at all")
    else:
        (bag / "split_2.mcap").unlink()
    assert main(["bag", "reindex", str(bag)]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"vm-ros bag: error: bag {bag}: ") and expected in err
    assert len(err.splitlines()) == 1 and not (bag / METADATA_FILE).exists()
