"""Sequential reading of an MCAP log that survives truncation (a recorder killed mid-run).

    log = LogReader("run.mcap")
    for msg in log.messages(topics={"/muscle_force"}):
        msg.topic, msg.type_name, msg.data, msg.log_time_ns
    log.metadata, log.attachments, log.complete, log.stop_reason

``path`` is an MCAP file or a rosbag2 bag directory holding one (vm_ros.recording.bag). The file
is read front to back with mcap's StreamReader (no summary or index needed), with chunk
CRCs checked: a chunk cut short by a crash fails its check, so everything up to the last complete
chunk is returned and ``complete`` is False with the reason in ``stop_reason``. A message whose
channel was never declared cannot be attributed to a topic: it is skipped and counted in
``unknown_channels``.
"""

from __future__ import annotations

import io
import struct
from collections.abc import Callable, Container, Iterator
from pathlib import Path
from typing import NamedTuple

import numpy as np
from mcap.data_stream import ReadDataStream
from mcap.opcode import Opcode
from mcap.reader import make_reader
from mcap.records import (
    Attachment,
    Channel,
    Chunk,
    DataEnd,
    Footer,
    Header,
    Metadata,
    Schema,
)
from mcap.stream_reader import StreamReader, get_chunk_data_stream

from vm_ros.errors import VmRosError
from vm_ros.recording.bag import (
    SUFFIX,
    BagError,
    BagFiles,
    FileStats,
    bag_files,
    check_numbering,
    directory_files,
    summary_stats,
    write_bag_metadata,
)
from vm_ros.recording.schema import MESSAGE_ENCODING


class LogReadError(VmRosError):
    """The file is not an MCAP log (or cannot be opened). Attributes: ``path``, ``reason``."""

    def __init__(self, path, reason: str):
        self.path = str(path)
        self.reason = reason
        super().__init__(f"cannot read MCAP log {self.path}: {reason}")


class RecordedMessage(NamedTuple):
    topic: str
    type_name: str  # schema name, pkg/msg/Type
    data: bytes  # CDR, as recorded
    log_time_ns: int
    publish_time_ns: int
    encoding: str = MESSAGE_ENCODING  # the channel's message encoding


class ChannelInfo(NamedTuple):
    type_name: str  # schema name, pkg/msg/Type for ROS 2 messages ("" without a schema)
    metadata: dict
    encoding: str  # message encoding, "cdr" for ROS 2 messages


class _Records(StreamReader):
    """mcap's StreamReader, emitting chunks whole (LogReader splits them, _chunk_records) and
    skipping message indexes unread (a sequential reader has no use for them; parsing their
    (time, offset) pairs one by one cost about a third of the reading time)."""

    def __init__(self, stream):
        super().__init__(stream, validate_crcs=True, emit_chunks=True)

    def _read_record(self, opcode: int, length: int):
        if opcode == Opcode.MESSAGE_INDEX:
            self._stream.read(length)
            return None
        return super()._read_record(opcode, length)


_RECORD = struct.Struct("<BQ")  # opcode, length of what follows
_MESSAGE = struct.Struct("<HIQQ")  # channel id, sequence, log time, publish time


class ChunkMessages(NamedTuple):
    """The Message records of one chunk, in chunk order, as arrays: ``channel_id`` and
    ``log_time_ns`` (k,), ``publish_time_ns`` (k,), and where each message's data lies in
    ``data`` (``begin``, ``end``, (k,) offsets); ``others``: the Schema and Channel records, each
    with the number of messages before it."""

    data: bytes
    channel_id: np.ndarray
    log_time_ns: np.ndarray
    publish_time_ns: np.ndarray
    begin: np.ndarray
    end: np.ndarray
    others: list

    def payloads(self, rows) -> list[bytes]:
        """The data of the messages ``rows`` (indices into the arrays), as bytes."""
        data = self.data
        return [data[a:b] for a, b in zip(self.begin[rows].tolist(), self.end[rows].tolist(),
                                          strict=True)]


def _chunk_messages(chunk: Chunk) -> ChunkMessages:
    """A chunk decompressed and CRC-checked by mcap's own function, its records walked once
    (only each record's opcode and length are read one by one); Message fields gathered as
    arrays, Schema and Channel records parsed as mcap parses them, others skipped (as mcap's
    breakup_chunk does, without an object per message). Raises when the chunk is corrupt."""
    stream, size = get_chunk_data_stream(chunk, validate_crc=True)
    data = stream.read(size)
    bodies, ends, others, offset = [], [], [], 0
    message, unpack, header = Opcode.MESSAGE, _RECORD.unpack_from, _RECORD.size
    while offset < size:
        opcode, length = unpack(data, offset)
        body, offset = offset + header, offset + header + length
        if opcode == message:
            bodies.append(body)
            ends.append(offset)
        elif opcode in (Opcode.SCHEMA, Opcode.CHANNEL):
            record_stream = ReadDataStream(io.BytesIO(data[body:offset]))
            others.append((len(bodies), (Schema if opcode == Opcode.SCHEMA else Channel).read(
                record_stream)))
    if offset > size:
        raise ValueError(f"a record of the chunk runs past its end ({offset} > {size})")
    body = np.array(bodies, dtype=np.int64)
    end = np.array(ends, dtype=np.int64)
    if np.any(end - body < _MESSAGE.size):
        raise ValueError("a message record of the chunk is shorter than its fields")
    raw = np.frombuffer(data, dtype=np.uint8)

    def field(at: int, dtype: str) -> np.ndarray:
        width = np.dtype(dtype).itemsize
        cells = raw[(body + at)[:, None] + np.arange(width)]
        return np.ascontiguousarray(cells).view(dtype).ravel().astype(np.int64)

    return ChunkMessages(data, field(0, "<u2"), field(6, "<u8"), field(14, "<u8"),
                         body + _MESSAGE.size, end, others)


def _chunk_records(chunk: Chunk) -> list:
    """The records of a chunk (_chunk_messages) in chunk order: Message records as (channel id,
    log time, publish time, data) tuples, Schema and Channel records as mcap parses them."""
    return _chunk_records_of(_chunk_messages(chunk))


def _chunk_records_of(parts: ChunkMessages) -> list:
    """_chunk_records of a chunk already split."""
    messages = list(zip(parts.channel_id.tolist(), parts.log_time_ns.tolist(),
                        parts.publish_time_ns.tolist(),
                        parts.payloads(np.arange(len(parts.begin))), strict=True))
    records, done = [], 0
    for position, record in parts.others:
        records.extend(messages[done:position])
        records.append(record)
        done = position
    records.extend(messages[done:])
    return records


class MessageBatch(NamedTuple):
    """Messages of one channel from one chunk, in file order (LogReader.batches): ``rows`` of
    ``chunk``; their bytes are sliced out when ``data`` is asked for."""

    topic: str
    type_name: str
    encoding: str
    chunk: ChunkMessages
    rows: np.ndarray

    @property
    def data(self) -> list[bytes]:
        """CDR bytes of each message, as recorded."""
        return self.chunk.payloads(self.rows)

    @property
    def log_time_ns(self) -> np.ndarray:
        return self.chunk.log_time_ns[self.rows]


class LogReader:
    """One pass over a log (see module docstring). ``progress(bytes_read, file_size)`` is called
    now and then while reading."""

    def __init__(self, path, progress: Callable[[int, int], None] | None = None):
        bag = _log_bag(path)
        self.files = bag.files
        self.unlisted_note = bag.note()  # other .mcap files of a bag directory, not read
        self.path = self.files[0] if len(self.files) == 1 else Path(path)
        self.size = sum(f.stat().st_size for f in self.files)
        self._progress = progress
        self.profile: str | None = None
        self.schemas: dict[int, Schema] = {}
        self.channels: dict[int, Channel] = {}
        self.metadata: dict[str, dict[str, str]] = {}
        self.attachments: dict[str, bytes] = {}
        self.unknown_channels: dict[int, int] = {}  # channel id -> messages skipped
        self.complete = False
        self.stop_reason: str | None = None
        self._topic_types: dict[str, str] = {}  # over every file of a split bag

    def topic_types(self) -> dict[str, str]:
        """``{topic: pkg/msg/Type}`` of the channels seen so far."""
        return {**self._topic_types,
                **{c.topic: self._type_name(c) for c in self.channels.values()}}

    def _type_name(self, channel: Channel) -> str:
        schema = self.schemas.get(channel.schema_id)
        return schema.name if schema is not None else ""

    def messages(self, topics: Container[str] | None = None) -> Iterator[RecordedMessage]:
        """Messages in file order (topics: full topic names to keep; None keeps all). Metadata,
        attachments, schemas and channels are collected on the way. The files of a split bag are
        read one after the other (each has its own schemas and channels); the log is complete
        when every file is."""
        for item in self._items():
            if not isinstance(item, ChunkMessages):
                self._collect(item)
                continue
            for record in _chunk_records_of(item):
                if not isinstance(record, tuple):
                    self._collect(record)
                    continue
                channel_id, log_time, publish_time, data = record
                channel = self._channel(channel_id, 1)
                if channel is not None and (topics is None or channel.topic in topics):
                    yield RecordedMessage(channel.topic, self._type_name(channel), data,
                                          log_time, publish_time, channel.message_encoding)

    def batches(self, topics: Container[str] | None = None) -> Iterator[MessageBatch]:
        """The messages of ``messages``, as batches: per chunk, those of each channel together
        (in file order within a channel; channels in the order of their first message)."""
        for item in self._items():
            if not isinstance(item, ChunkMessages):
                self._collect(item)
                continue
            done = 0
            for position, record in [*item.others, (len(item.begin), None)]:
                yield from self._batches(item, done, position, topics)
                if record is not None:
                    self._collect(record)
                done = position

    def _batches(self, chunk: ChunkMessages, begin: int, end: int,
                 topics) -> Iterator[MessageBatch]:
        ids = chunk.channel_id[begin:end]
        if not len(ids):
            return
        found, first = np.unique(ids, return_index=True)
        for channel_id in found[np.argsort(first)].tolist():
            rows = begin + np.flatnonzero(ids == channel_id)
            channel = self._channel(channel_id, len(rows))
            if channel is not None and (topics is None or channel.topic in topics):
                yield MessageBatch(channel.topic, self._type_name(channel),
                                   channel.message_encoding, chunk, rows)

    def _channel(self, channel_id: int, count: int) -> Channel | None:
        """The channel record of ``channel_id``; None (``count`` messages counted in
        ``unknown_channels``) when it was never declared."""
        channel = self.channels.get(channel_id)
        if channel is None:
            self.unknown_channels[channel_id] = self.unknown_channels.get(channel_id, 0) + count
        return channel

    def _items(self) -> Iterator:
        """Each file's records in order, a chunk as its ChunkMessages (module docstring for how
        a file cut short or a split bag is read)."""
        done = 0
        for index, path in enumerate(self.files):
            if index:
                self._topic_types.update(self.topic_types())
                self.schemas, self.channels = {}, {}
                if not self.complete:  # an earlier file was cut short: stop there
                    return
                self.complete = False
                if path.stat().st_size == 0:  # killed as it was created
                    self.stop_reason = f"{path.name} is empty"
                    return
            yield from self._file_items(path, done)
            done += path.stat().st_size

    def _file_items(self, path: Path, done: int) -> Iterator:
        with open(path, "rb") as stream:
            records = _Records(stream).records
            count = 0
            while True:
                try:
                    record = next(records)
                    item = _chunk_messages(record) if isinstance(record, Chunk) else record
                except StopIteration:
                    break
                except Exception as exc:  # truncated or corrupt: keep what was read
                    if count == 0 and stream.tell() == 0 and path.stat().st_size == 0:
                        raise LogReadError(path, "the file is empty (nothing was written to "
                                           "it yet, or it was stopped as it was created)"
                                           ) from exc
                    if count == 0:
                        raise LogReadError(path, f"not an MCAP file ({exc})") from exc
                    self.stop_reason = f"{type(exc).__name__}: {exc}".rstrip(": ")
                    return
                count += 1
                yield item
                if self._progress is not None:
                    self._progress(done + stream.tell(), self.size)

    def _collect(self, record) -> None:
        if isinstance(record, Header):
            self.profile = record.profile
        elif isinstance(record, Schema):
            self.schemas[record.id] = record
        elif isinstance(record, Channel):
            self.channels[record.id] = record
        elif isinstance(record, Metadata):
            self.metadata[record.name] = dict(record.metadata)
        elif isinstance(record, Attachment):
            self.attachments[record.name] = bytes(record.data)
        elif isinstance(record, Footer):
            self.complete = True


def _log_bag(path) -> BagFiles:
    path = Path(path)
    if path.is_dir():
        try:
            return bag_files(path)
        except BagError as exc:
            raise LogReadError(path, exc.reason) from exc
    if not path.is_file():
        raise LogReadError(path, "no such file")
    return BagFiles([path])


def log_files(path) -> list[Path]:
    """The MCAP files of a log path, in order: the file itself, or a bag directory's files
    (vm_ros.recording.bag). Raises LogReadError (one line) when there is none or the bag
    directory cannot be used."""
    return _log_bag(path).files


def unlisted_note(path) -> str | None:
    """For a bag directory, the line naming its ``.mcap`` files that metadata.yaml does not list
    (not read); else None. Raises LogReadError as log_files."""
    return _log_bag(path).note()


def log_channels(path) -> dict[str, ChannelInfo]:
    """``{topic: ChannelInfo}``: from the summary section when the file has one, else (a file
    cut short) from a pass over the whole file. Raises LogReadError when it is not MCAP."""
    channels: dict[str, ChannelInfo] = {}
    for file in log_files(path):
        channels.update({topic: info for topic, info in _file_channels(file).items()
                         if topic not in channels})
    return channels


def _file_channels(path: Path) -> dict[str, ChannelInfo]:
    try:
        with open(path, "rb") as stream:
            summary = make_reader(stream).get_summary()
    except Exception:  # no footer or summary: read everything instead
        summary = None
    if summary is not None and summary.channels:
        return {c.topic: ChannelInfo(summary.schemas[c.schema_id].name
                                     if c.schema_id in summary.schemas else "",
                                     dict(c.metadata), c.message_encoding)
                for c in summary.channels.values()}
    reader = LogReader(path)
    for _ in reader.messages(topics=()):
        pass
    return {c.topic: ChannelInfo(reader._type_name(c), dict(c.metadata), c.message_encoding)
            for c in reader.channels.values()}


# --- reindexing a bag directory (``vm-ros bag reindex``) -------------------------------------

_MAGIC = b"\x89MCAP0\r\n"
_DATA_END = struct.pack("<BQI", Opcode.DATA_END, 4, 0)  # data section CRC 0: not computed
# no summary section (summary start 0, summary offset start 0, CRC 0), then the closing magic
_FOOTER = struct.pack("<BQQQI", Opcode.FOOTER, 20, 0, 0, 0) + _MAGIC


class _Scan(NamedTuple):
    """One pass over an MCAP file: what a cut-short file keeps and metadata.yaml needs."""

    stats: FileStats
    end: int  # bytes up to the end of the last complete record (data section only)
    footer: bool  # a footer was read: the file is finished
    data_end: bool  # the data section's DataEnd record is among the complete records


def _scan(path: Path) -> _Scan:
    """Read ``path`` front to back as LogReader does (chunk CRCs checked; a message of an
    undeclared channel is counted by its channel id but has no topic). Raises BagError when not
    even the header is readable (an empty file too)."""
    channels: dict[int, Channel] = {}
    schemas: dict[int, str] = {}
    counts: dict[int, int] = {}
    first, last = None, 0
    end, footer, data_end = 0, False, False
    if path.stat().st_size == 0:
        raise BagError(path.parent, f"{path.name} cannot be indexed: empty (the recorder was "
                                    "killed as it created it; remove it and reindex again)")
    with open(path, "rb") as stream:
        records = _Records(stream).records
        while not footer:
            try:
                record = next(records)
                inside = _chunk_records(record) if isinstance(record, Chunk) else [record]
            except StopIteration:
                break
            except Exception as exc:  # truncated or corrupt: the file ends at ``end``
                if end == 0:
                    raise BagError(path.parent, f"{path.name} cannot be indexed: not an MCAP "
                                                f"file ({type(exc).__name__})") from exc
                break
            for item in inside:
                if isinstance(item, tuple):
                    channel_id, log_time = item[0], item[1]
                    counts[channel_id] = counts.get(channel_id, 0) + 1
                    first = log_time if first is None else min(first, log_time)
                    last = max(last, log_time)
                elif isinstance(item, Schema):
                    schemas[item.id] = item.name
                elif isinstance(item, Channel):
                    channels[item.id] = item
            footer = isinstance(record, Footer)
            if not data_end and not footer:  # a cut summary section is left out
                end = stream.tell()
                data_end = isinstance(record, DataEnd)
    return _Scan(FileStats([(c, schemas.get(c.schema_id, ""), counts.get(i, 0))
                            for i, c in sorted(channels.items())],
                           sum(counts.values()), first or 0, last), end, footer, data_end)


class Reindexed(NamedTuple):
    """What reindex_bag did: the files indexed, their messages, and the file finished (its name
    and the bytes after its last complete record, moved to ``<name>.cut``), if one was."""

    files: list
    message_count: int
    finished: tuple | None


def _finish(path: Path, scan: _Scan) -> tuple[str, int]:
    """End a cut-short file after its last complete record with a DataEnd record and a footer
    without summary (a valid MCAP file: readers scan it, as rosbags does), the bytes after that
    record moved to ``<name>.cut``. Returns (name, bytes moved). Raises BagError."""
    size = path.stat().st_size
    try:
        if size > scan.end:
            with open(path, "rb") as source:
                source.seek(scan.end)
                path.with_name(path.name + ".cut").write_bytes(source.read())
        with open(path, "r+b") as target:
            target.truncate(scan.end)
            target.seek(scan.end)
            target.write(_FOOTER if scan.data_end else _DATA_END + _FOOTER)
    except OSError as exc:
        raise BagError(path.parent, f"cannot finish {path.name}: {exc.strerror or exc}") from exc
    return path.name, size - scan.end


def reindex_bag(directory) -> Reindexed:
    """Write ``directory/metadata.yaml`` from the directory's ``.mcap`` files (in name order,
    NAME_2 before NAME_10), as ``ros2 bag reindex`` does, so that rosbag2 readers open a bag
    whose recorder was killed. A cut-short last file (no footer: the recorder was killed while
    writing it) is first finished after its last complete record (_finish), so that it holds
    what every vm_ros reader reads of it. Raises BagError (one line, naming the file) when there
    is no file, the numbered files have a gap, a file before the last is cut short, or a file is
    not MCAP."""
    directory = Path(directory)
    if not directory.is_dir():
        raise BagError(directory, "not a directory")
    files = directory_files(directory)
    if not files:
        raise BagError(directory, f"no {SUFFIX} file in the bag directory")
    check_numbering(directory, files)
    stats: dict[Path, FileStats] = {}
    finished = None
    for path in files:
        try:
            stats[path] = summary_stats(path)
            continue
        except BagError:  # no summary: read the records
            scan = _scan(path)
        if not scan.footer:
            if path != files[-1]:
                raise BagError(directory, f"{path.name} is cut short but is not the last file "
                                          "(only a recorder's last file can be cut by a kill)")
            finished = _finish(path, scan)
        stats[path] = scan.stats
    write_bag_metadata(directory, files, file_stats=stats.__getitem__)
    return Reindexed(files, sum(s.message_count for s in stats.values()), finished)
