"""McapRecorder: rosbag2-compatible files read back by the mcap library itself, a caller that is
never blocked, and failures that are reported instead of raised."""

from __future__ import annotations

import errno
import io
import threading
import time
from pathlib import Path

import pytest
import yaml
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory

from vm_ros.recording import cdr
from vm_ros.recording.message_types import schema_text, type_hash
from vm_ros.recording.qos import INFINITE_DURATION_NS, offered_qos_profiles_yaml
from vm_ros.recording.reader import LogReader
from vm_ros.recording.writer import McapRecorder, RecorderError

FLOAT64 = "std_msgs/msg/Float64"
JOINT_STATE = "sensor_msgs/msg/JointState"


def _float64(value: float) -> bytes:
    return cdr.serialize(FLOAT64, {"data": value})


def _read_all(path):
    with open(path, "rb") as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        header = reader.get_header()
        summary = reader.get_summary()
        decoded = [(channel.topic, message.log_time, msg) for _, channel, message, msg in
                   reader.iter_decoded_messages()]
        metadata = {m.name: dict(m.metadata) for m in reader.iter_metadata()}
        attachments = {a.name: (a.media_type, a.data) for a in reader.iter_attachments()}
    return header, summary, decoded, metadata, attachments


def test_round_trip_read_by_mcap_and_mcap_ros2(tmp_path):
    path = tmp_path / "run.mcap"
    with McapRecorder(path, metadata={"vm_ros.run": {"dt_s": 0.001}},
                      attachments={"model.yaml": b"a: 1\n"}) as rec:
        rec.add_channel("/energy_total", FLOAT64)
        rec.add_channel("/muscle_force", JOINT_STATE)
        for k in range(50):
            assert rec.write("/energy_total", _float64(0.5 * k), 1000 + k)
            rec.write("/muscle_force", cdr.serialize(JOINT_STATE, {
                "header": {"stamp": {"sec": 1, "nanosec": k}}, "name": ["a", "b"],
                "effort": [float(k), -float(k)]}), 1000 + k, publish_time_ns=2000 + k)
    assert rec.status.ok and rec.status.written == 100 and rec.status.dropped == 0
    assert rec.status.bytes_written == path.stat().st_size
    header, summary, decoded, metadata, attachments = _read_all(path)
    assert header.profile == "ros2"
    assert summary.statistics.message_count == 100
    totals = [m.data for topic, _, m in decoded if topic == "/energy_total"]
    assert totals == [0.5 * k for k in range(50)]
    forces = [m for topic, _, m in decoded if topic == "/muscle_force"]
    assert [m.effort for m in forces] == [[float(k), -float(k)] for k in range(50)]
    assert forces[7].name == ["a", "b"] and forces[7].header.stamp.nanosec == 7
    assert metadata == {"vm_ros.run": {"dt_s": "0.001"}}
    assert attachments == {"model.yaml": ("application/yaml", b"a: 1\n")}


def test_schemas_and_channels_follow_rosbag2(tmp_path):
    path = tmp_path / "run.mcap"
    qos = offered_qos_profiles_yaml(depth=7, reliability="best_effort")
    with McapRecorder(path) as rec:
        rec.add_channel("/muscle_force", JOINT_STATE, qos)
        rec.add_channel("/energy_total", FLOAT64)
        rec.write("/muscle_force", cdr.serialize(JOINT_STATE, {}), 1)
    _, summary, _, _, _ = _read_all(path)
    schemas = {s.name: s for s in summary.schemas.values()}
    assert set(schemas) == {JOINT_STATE, FLOAT64}
    for name, schema in schemas.items():
        assert schema.encoding == "ros2msg"
        assert schema.data.decode() == schema_text(name)
    channels = {c.topic: c for c in summary.channels.values()}
    assert all(c.message_encoding == "cdr" for c in channels.values())
    force = channels["/muscle_force"].metadata
    assert force["topic_type_hash"] == type_hash(JOINT_STATE)
    assert force["topic_type_hash"].startswith("RIHS01_")
    assert force["offered_qos_profiles"] == qos
    (profile,) = yaml.safe_load(channels["/energy_total"].metadata["offered_qos_profiles"])
    assert list(profile) == ["history", "depth", "reliability", "durability", "deadline",
                             "lifespan", "liveliness", "liveliness_lease_duration",
                             "avoid_ros_namespace_conventions"]
    assert (profile["history"], profile["reliability"], profile["durability"],
            profile["liveliness"]) == ("keep_last", "reliable", "volatile", "automatic")
    infinite = divmod(INFINITE_DURATION_NS, 1_000_000_000)
    assert (profile["deadline"]["sec"], profile["deadline"]["nsec"]) == infinite


def test_qos_from_an_rclpy_like_profile():
    class Policy:
        def __init__(self, name):
            self.name = name

    class Duration:
        nanoseconds = 1_500_000_000

    class Profile:
        history, depth = Policy("KEEP_LAST"), 5
        reliability, durability = Policy("BEST_EFFORT"), Policy("TRANSIENT_LOCAL")
        liveliness = Policy("AUTOMATIC")
        deadline = lifespan = liveliness_lease_duration = Duration()
        avoid_ros_namespace_conventions = False

    (profile,) = yaml.safe_load(offered_qos_profiles_yaml(Profile()))
    assert profile["reliability"] == "best_effort" and profile["durability"] == "transient_local"
    assert profile["depth"] == 5 and profile["lifespan"] == {"sec": 1, "nsec": 500_000_000}


class GatedFile(io.RawIOBase):
    """A file whose writes wait for ``gate`` once ``armed`` is set (a stalled disk)."""

    def __init__(self):
        self.buffer = bytearray()
        self.armed = False
        self.gate = threading.Event()

    def writable(self):
        return True

    def write(self, data):
        if self.armed:
            self.gate.wait()
        self.buffer += bytes(data)
        return len(data)


def test_write_never_blocks_and_counts_what_it_drops(tmp_path):
    gated = GatedFile()
    rec = McapRecorder(tmp_path / "x.mcap", queue_size=20, chunk_size=64,
                       opener=lambda path: gated)
    rec.add_channel("/t", FLOAT64)
    gated.armed = True  # the writer thread stalls on its first chunk
    durations, accepted = [], 0
    for k in range(500):
        start = time.perf_counter()
        accepted += rec.write("/t", _float64(k), k)
        durations.append(time.perf_counter() - start)
    assert max(durations) < 0.05, "write() waited for the stalled file"
    assert accepted < 500 and rec.status.dropped == 500 - accepted
    gated.gate.set()
    rec.close()
    assert rec.status.ok
    assert rec.status.written == accepted and rec.status.dropped == 500 - accepted


class FailingFile(io.RawIOBase):
    """A file that fails with ENOSPC once ``limit`` bytes have been written."""

    def __init__(self, limit):
        self.limit, self.size = limit, 0

    def writable(self):
        return True

    def write(self, data):
        if self.size + len(data) > self.limit:
            raise OSError(errno.ENOSPC, "No space left on device")
        self.size += len(data)
        return len(data)


def _voluntary_switches(thread: threading.Thread) -> int:
    status = Path(f"/proc/self/task/{thread.native_id}/status").read_text()
    return int(status.split("voluntary_ctxt_switches:")[1].split()[0])


def test_the_writer_thread_drains_in_batches_not_at_every_message(tmp_path):
    """A caller writing a message every millisecond for 0.4 s (a node's log at 1 kHz) wakes the
    writer thread about every DRAIN_PERIOD_S, not 400 times; every message reaches the file."""
    from vm_ros.recording.writer import DRAIN_PERIOD_S

    path = tmp_path / "drain.mcap"
    rec = McapRecorder(path)
    rec.add_channel("/x", FLOAT64)
    rec.write("/x", _float64(0.0), 0)
    time.sleep(2 * DRAIN_PERIOD_S)  # the channel registered, the thread waiting
    before = _voluntary_switches(rec._thread)
    count = 400
    for i in range(1, count + 1):
        rec.write("/x", _float64(float(i)), i)
        time.sleep(0.001)
    switches = _voluntary_switches(rec._thread) - before
    rec.close()
    assert switches < count / 4, switches  # about 0.4 s / DRAIN_PERIOD_S, plus GIL waits
    assert rec.status.written == count + 1 and rec.status.dropped == 0
    assert [m.data for _, _, m in _read_all(path)[2]] == [float(i) for i in range(count + 1)]


def test_write_error_mid_run_is_reported_not_raised(tmp_path):
    rec = McapRecorder(tmp_path / "full.mcap", chunk_size=256,
                       opener=lambda path: FailingFile(limit=4096))
    rec.add_channel("/t", FLOAT64)
    results = []
    deadline = time.monotonic() + 5
    k = 0
    while rec.status.ok and time.monotonic() < deadline:
        results.append(rec.write("/t", _float64(k), k))
        k += 1
        if k % 50 == 0:
            time.sleep(0.001)
    status = rec.status
    assert not status.ok and "No space left on device" in status.error
    assert "full.mcap" in status.error
    assert not rec.write("/t", _float64(-1.0), k)  # refused at once after the failure
    rec.close()  # finishing is impossible: still no exception
    final = rec.status
    assert final.written + final.dropped == len(results) + 1
    assert final.dropped >= 1 and 0 < final.bytes_written <= 4096


class FullDisk(io.RawIOBase):
    """A real file on a disk with room for ``room`` bytes: a write that does not fit writes what
    fits (as the OS does), the next one fails with ENOSPC. ``writes`` logs (offset, size) of
    every write the disk took whole."""

    def __init__(self, path, room):
        self._file = open(path, "wb", buffering=0)  # noqa: SIM115 (closed by close())
        self.room, self.size, self.writes = room, 0, []

    def writable(self):
        return True

    def write(self, data):
        if self.size >= self.room:
            raise OSError(errno.ENOSPC, "No space left on device")
        data = bytes(data)[: self.room - self.size]
        count = self._file.write(data)
        if count == len(data):
            self.writes.append((self.size, count))
        self.size += count
        return count

    def close(self):
        self._file.close()
        super().close()


def _write_floats(path, room, count, **options):
    """``count`` Float64 messages through a recorder on a FullDisk of ``room`` bytes."""
    disks = []

    def opener(p):
        disks.append(FullDisk(p, room))
        return disks[0]

    rec = McapRecorder(path, chunk_size=512, opener=opener, **options)
    rec.add_channel("/t", FLOAT64)
    for k in range(count):
        rec.write("/t", _float64(k), k)
    rec.close()
    return rec.status, disks[0]


def test_status_counts_the_messages_in_the_file_wherever_the_disk_fills(tmp_path):
    """written = what a reader gets back and written + dropped = every message, whether the
    disk fills inside a chunk, just after one (in its message index) or in the summary."""
    path = tmp_path / "full.mcap"
    count = 400
    status, disk = _write_floats(path, 1 << 30, count)  # room enough: where the chunks fall
    assert status.ok and status.written == count
    ends = [offset + size for offset, size in disk.writes]
    rooms = {end + extra for end in ends[3:-1:7] for extra in (-5, 0, 3)} | {ends[-2] + 3}
    for room in sorted(rooms):
        status, _ = _write_floats(path, room, count)
        assert not status.ok and "No space left on device" in status.error, room
        in_file = sum(1 for _ in LogReader(path).messages())
        assert (status.written, status.written + status.dropped) == (in_file, count), room
    assert in_file > 0  # failed in the summary: every message is in the file


def test_unwritable_path_is_named_at_start(tmp_path):
    blocker = tmp_path / "not_a_dir"
    blocker.write_text("")
    target = blocker / "run.mcap"
    with pytest.raises(RecorderError) as info:
        McapRecorder(target)
    assert info.value.path == str(target) and str(target) in str(info.value)


def test_channel_errors_and_idempotence(tmp_path):
    with McapRecorder(tmp_path / "c.mcap") as rec:
        rec.add_channel("/t", FLOAT64)
        rec.add_channel("/t", "std_msgs/Float64")  # same type, short form: no-op
        with pytest.raises(RecorderError, match="already has type"):
            rec.add_channel("/t", JOINT_STATE)
        with pytest.raises(RecorderError, match="geometry_msgs/msg/Twist"):
            rec.add_channel("/u", "geometry_msgs/msg/Twist")
        with pytest.raises(RecorderError, match="undeclared"):
            rec.write("/u", b"", 0)
        assert rec.write("/t", _float64(1.0), 5)
    rec.close()  # idempotent
    assert not rec.write("/t", _float64(2.0), 6)
    assert rec.status.written == 1 and rec.status.dropped == 1
    assert [m.topic for m in LogReader(tmp_path / "c.mcap").messages()] == ["/t"]


def test_open_chunk_reaches_the_file_after_flush_interval(tmp_path):
    """A crash loses at most flush_interval_s of messages, even at a low data rate."""
    path = tmp_path / "slow.mcap"
    rec = McapRecorder(path, flush_interval_s=0.1)
    rec.add_channel("/t", FLOAT64)
    for k in range(3):
        rec.write("/t", _float64(k), k)
    deadline = time.monotonic() + 5
    seen = []
    while time.monotonic() < deadline and len(seen) < 3:
        time.sleep(0.05)
        seen = list(LogReader(path).messages())  # the file is still open: no footer yet
    assert [cdr.deserialize(FLOAT64, m.data).data for m in seen] == [0.0, 1.0, 2.0]
    rec.close()


def _two_topic_messages(count):
    """Interleaved Float64 and JointState messages with varied sizes, in log-time order."""
    topics, data, times = [], [], []
    for k in range(count):
        if k % 3:
            topics.append("/f")
            data.append(_float64(0.5 * k))
        else:
            topics.append("/j")
            data.append(cdr.serialize(JOINT_STATE, {
                "header": {"stamp": {"sec": k, "nanosec": 7}, "frame_id": ""},
                "name": ["m"] * (k % 5), "position": [float(k)] * (k % 7),
                "velocity": [], "effort": []}))
        times.append(1_000_000_000 + 1_000_000 * k)
    return topics, data, times


def _record(path, topics, data, times, block, after_writes=None, **options):
    with McapRecorder(path, **options) as rec:
        rec.add_channel("/f", FLOAT64)
        rec.add_channel("/j", JOINT_STATE)
        if block:
            assert rec.write_block(topics, data, times)
        else:
            for topic, payload, time_ns in zip(topics, data, times, strict=True):
                assert rec.write(topic, payload, time_ns)
        if after_writes is not None:
            after_writes(rec)
    return rec.status


@pytest.mark.parametrize("compression", ["none", "zstd"])
@pytest.mark.parametrize("bulk", [True, False], ids=["bulk", "fallback"])
def test_write_block_writes_the_bytes_mcaps_writer_writes(tmp_path, monkeypatch, compression,
                                                          bulk):
    """One block through write_block gives the same file, byte for byte, as the same messages
    through write, i.e. mcap's own Writer.add_message: records, chunk boundaries, message
    indexes, statistics and summary (and so does the per-message fallback)."""
    from vm_ros.recording import mcap_bulk

    if not bulk:
        monkeypatch.setattr(mcap_bulk, "bulk_available", lambda writer: False)
    topics, data, times = _two_topic_messages(3000)
    options = dict(chunk_size=4096, compression=compression)
    one = _record(tmp_path / "one.mcap", topics, data, times, False, **options)
    many = _record(tmp_path / "many.mcap", topics, data, times, True, **options)
    assert one.ok and many.ok and one.written == many.written == 3000
    assert many.dropped == 0
    reference = (tmp_path / "one.mcap").read_bytes()
    assert (tmp_path / "many.mcap").read_bytes() == reference
    _, summary, decoded, _, _ = _read_all(tmp_path / "many.mcap")
    assert summary.statistics.chunk_count > 10  # the block really was cut into chunks
    assert [m[1] for m in decoded] == times


def _messages_by_file(directory):
    out = {}
    for path in sorted(directory.glob("*.mcap")):
        with open(path, "rb") as stream:
            out[path.name.split("_")[-1]] = [
                (channel.topic, message.log_time, message.sequence, message.data)
                for _, channel, message in make_reader(stream).iter_messages()]
    return out


def test_write_block_splits_a_bag_where_write_does(tmp_path):
    """Split by duration and by size: one block gives the same files, byte for byte, as write;
    two blocks (the second starting inside a file; a block ends its last chunk) the same
    messages, sequence numbers and times in each file."""
    topics, data, times = _two_topic_messages(3000)
    for options in (dict(max_file_duration_s=0.7), dict(max_file_size=20_000)):
        options.update(chunk_size=2048, compression="none")
        _record(tmp_path / "one", topics, data, times, False, **options)
        _record(tmp_path / "block", topics, data, times, True, **options)
        with McapRecorder(tmp_path / "two", **options) as rec:
            rec.add_channel("/f", FLOAT64)
            rec.add_channel("/j", JOINT_STATE)
            assert rec.write_block(topics[:1234], data[:1234], times[:1234])
            assert rec.write_block(topics[1234:], data[1234:], times[1234:])
        files = sorted(p.name for p in (tmp_path / "one").glob("*.mcap"))
        assert len(files) >= 3, options
        for name in files:
            block = tmp_path / "block" / name.replace("one", "block")
            assert block.read_bytes() == (tmp_path / "one" / name).read_bytes(), (options, name)
        if "max_file_duration_s" in options:  # a size split depends on the chunk boundaries
            assert _messages_by_file(tmp_path / "two") == _messages_by_file(tmp_path / "one")
        else:
            assert sum(map(len, _messages_by_file(tmp_path / "two").values())) == 3000
        for path in (tmp_path / "one", tmp_path / "block", tmp_path / "two"):
            for child in path.iterdir():
                child.unlink()
            path.rmdir()


def _record_in_parts(path, topics, data, times, cuts, **options):
    """The messages as one block handed over in parts ending at ``cuts`` (write_block's more)."""
    with McapRecorder(path, **options) as rec:
        rec.add_channel("/f", FLOAT64)
        rec.add_channel("/j", JOINT_STATE)
        bounds = [0, *cuts, len(data)]
        for begin, end in zip(bounds[:-1], bounds[1:], strict=True):
            assert rec.write_block(topics[begin:end], data[begin:end], times[begin:end],
                                   more=end < len(data))
    return rec.status


@pytest.mark.parametrize("options", [
    dict(chunk_size=4096, compression="zstd"),
    dict(chunk_size=4096, compression="none", background=False),
    dict(chunk_size=2048, compression="none", max_file_duration_s=0.7),
    dict(chunk_size=2048, compression="none", max_file_size=20_000)],
    ids=["zstd", "caller", "split-duration", "split-size"])
def test_a_block_in_parts_gives_the_bytes_of_the_whole_block(tmp_path, options):
    """A block handed over in parts (more=True but the last; parts of one message, parts that
    end inside a chunk and parts that end where a chunk does) writes the same files, byte for
    byte, as the whole block at once, which writes those of write: the chunks, sequence numbers
    and file splits do not depend on where the parts end."""
    topics, data, times = _two_topic_messages(3000)
    _record(tmp_path / "one", topics, data, times, True, **options)
    status = _record_in_parts(tmp_path / "parts", topics, data, times,
                              [1, 2, 700, 701, 1234, 2999], **options)
    assert status.ok and status.written == 3000 and status.dropped == 0
    ones = sorted((tmp_path / "one").glob("*.mcap"))
    assert [p.name.replace("one", "parts") for p in ones] == sorted(
        p.name for p in (tmp_path / "parts").glob("*.mcap"))
    for one in ones:
        parts = tmp_path / "parts" / one.name.replace("one", "parts")
        assert parts.read_bytes() == one.read_bytes(), one.name
    _, summary, decoded, _, _ = _read_all(ones[0])
    assert summary.statistics.chunk_count > 3


def test_the_waiting_part_of_a_block_goes_first_at_a_write_and_at_close(tmp_path):
    """Messages of a block with more to come that wait for its next part are written before a
    later write's message, and at close when no part comes: every message in the file, in
    order, counted as written."""
    topics, data, times = _two_topic_messages(100)
    with McapRecorder(tmp_path / "w.mcap", chunk_size=1 << 20, compression="none") as rec:
        rec.add_channel("/f", FLOAT64)
        rec.add_channel("/j", JOINT_STATE)
        assert rec.write_block(topics[:50], data[:50], times[:50], more=True)
        assert rec.write(topics[50], data[50], times[50])
        assert rec.write_block(topics[51:], data[51:], times[51:], more=True)
    assert (rec.status.written, rec.status.dropped) == (100, 0)
    with open(tmp_path / "w.mcap", "rb") as stream:
        read = [(channel.topic, message.log_time, message.sequence) for _, channel, message
                in make_reader(stream).iter_messages(log_time_order=False)]
    assert [(t, s) for t, s, _ in read] == list(zip(topics, times, strict=True))
    assert [s for t, _, s in read if t == "/f"] == list(range(1, topics.count("/f") + 1))


def test_write_block_on_a_full_disk_counts_every_message(tmp_path):
    """A block that meets a full disk: written + dropped = every message, written = what a
    reader gets back, and nothing is raised."""
    topics, data, times = _two_topic_messages(3000)
    path = tmp_path / "full.mcap"
    for room in (3000, 20_000, 45_000):
        status = _record(path, topics, data, times, True, chunk_size=2048,
                         compression="none", opener=lambda p, room=room: FullDisk(p, room))
        assert not status.ok and "No space left on device" in status.error, room
        in_file = sum(1 for _ in LogReader(path).messages())
        assert (status.written, status.written + status.dropped) == (in_file, 3000), room


def test_write_block_refuses_bad_blocks(tmp_path):
    with McapRecorder(tmp_path / "b.mcap") as rec:
        rec.add_channel("/f", FLOAT64)
        with pytest.raises(RecorderError, match="undeclared channel '/g'"):
            rec.write_block(["/f", "/g"], [b"", b""], [0, 1])
        with pytest.raises(RecorderError, match="one topic and one time per message"):
            rec.write_block(["/f"], [_float64(1.0)], [0, 1])
        assert rec.write_block([], [], [])
    assert not rec.write_block(["/f"], [_float64(1.0)], [0])  # closed: dropped, counted
    assert rec.status.dropped == 1


def test_the_writer_thread_returns_free_memory_after_each_file_and_periodically(tmp_path,
                                                                                monkeypatch):
    """A split bag: the allocator's free memory goes back to the OS once per finished file; a
    single file: once per RELEASE_PERIOD_S of wall time (shortened here)."""
    from vm_ros.recording import writer

    calls = []
    monkeypatch.setattr(writer, "release_free_memory", lambda: calls.append(time.monotonic()))
    with McapRecorder(tmp_path / "bag", max_file_duration_s=0.1) as rec:
        rec.add_channel("/f", FLOAT64)
        for k in range(1000):  # 1 ms apart: ten files of 0.1 s
            assert rec.write("/f", _float64(k), k * 1_000_000)
    files = list((tmp_path / "bag").glob("*.mcap"))
    assert len(files) == 10
    assert len(calls) == len(files) - 1  # each file finished before the last one

    calls.clear()
    monkeypatch.setattr(writer, "RELEASE_PERIOD_S", 0.05)
    with McapRecorder(tmp_path / "one.mcap") as rec:
        rec.add_channel("/f", FLOAT64)
        start = time.monotonic()
        k = 0
        while time.monotonic() - start < 1.0:  # messages keep coming for 1 s
            rec.write("/f", _float64(k), k)
            k += 1
            time.sleep(0.001)
    assert len(calls) >= 2
    assert all(b - a >= 0.05 for a, b in zip(calls[:-1], calls[1:], strict=True))


def test_release_free_memory_is_callable_here():
    """glibc's malloc_trim is found on Linux with glibc; the call is harmless either way."""
    import platform

    from vm_ros.recording import writer

    if platform.system() == "Linux" and platform.libc_ver()[0] == "glibc":
        assert writer._MALLOC_TRIM is not None
    writer.release_free_memory()


def _writer_threads() -> list[str]:
    return [t.name for t in threading.enumerate() if t.name.startswith("mcap-recorder")]


@pytest.mark.parametrize("options", [dict(chunk_size=4096, compression="zstd"),
                                     dict(chunk_size=2048, compression="none",
                                          max_file_duration_s=0.7)],
                         ids=["one file", "split bag"])
def test_written_by_the_caller_the_same_bytes_without_a_thread(tmp_path, options):
    """background=False: no writer thread, every message in the file when write returns, and
    the same files, byte for byte, as the writer thread writes, message by message and as
    blocks."""
    topics, data, times = _two_topic_messages(3000)
    name = "log" if "max_file_duration_s" in options else "log.mcap"
    for block in (False, True):
        threaded = _record(tmp_path / "thread" / name, topics, data, times, block, **options)
        before = _writer_threads()

        def after_writes(rec, before=before):
            assert _writer_threads() == before  # none started for this recorder
            assert rec.status.written == 3000  # in the chunks written so far or the open one

        caller = _record(tmp_path / "caller" / name, topics, data, times, block, after_writes,
                         background=False, **options)
        assert threaded.ok and caller.ok and caller.written == 3000 and caller.dropped == 0
        files = sorted(p.relative_to(tmp_path / "thread")
                       for p in (tmp_path / "thread").rglob("*") if p.is_file())
        assert len(files) >= (3 if "max_file_duration_s" in options else 1)
        for path in files:
            assert (tmp_path / "caller" / path).read_bytes() == \
                (tmp_path / "thread" / path).read_bytes(), (block, path)
        for folder in (tmp_path / "thread", tmp_path / "caller"):
            for path in sorted(folder.rglob("*"), reverse=True):
                path.unlink() if path.is_file() else path.rmdir()


def test_written_by_the_caller_a_full_disk_is_counted_not_raised(tmp_path):
    """background=False on a full disk: nothing raised by write, write_block or close; a write
    that failed returns False; written = what a reader gets back, written + dropped = every
    message."""
    topics, data, times = _two_topic_messages(3000)
    path = tmp_path / "full.mcap"
    for room in (3000, 20_000, 45_000):
        for block in (False, True):
            with McapRecorder(path, chunk_size=2048, compression="none", background=False,
                              opener=lambda p, room=room: FullDisk(p, room)) as rec:
                rec.add_channel("/f", FLOAT64)
                rec.add_channel("/j", JOINT_STATE)
                if block:
                    results = [rec.write_block(topics, data, times)]
                else:
                    results = [rec.write(topic, payload, time_ns) for topic, payload, time_ns
                               in zip(topics, data, times, strict=True)]
                assert not results[-1]
            status = rec.status
            assert not status.ok and "No space left on device" in status.error, (room, block)
            in_file = sum(1 for _ in LogReader(path).messages())
            assert (status.written, status.written + status.dropped) == (in_file, 3000), room
