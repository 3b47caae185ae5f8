"""McapRecorder: a ROS 2 MCAP log written by a background thread, never blocking the caller (or,
with ``background=False``, by the caller's own thread).

    with McapRecorder("run.mcap", metadata={"vm_ros.run": {...}}) as rec:
        rec.add_channel("/muscle_force", "sensor_msgs/msg/JointState")
        rec.write("/muscle_force", cdr_bytes, log_time_ns)
        rec.write_block(topics, cdr_bytes_list, log_times_ns)   # many at once (offline runs)
        rec.write_block(..., more=True)   # a block handed over in parts (its chunks the same)
    rec.status      # RecorderStatus(ok, error, written, dropped, bytes_written, path)

The file follows rosbag2's MCAP conventions (profile ``ros2``; schema ``pkg/msg/Type``,
encoding ``ros2msg``, text as rosbag2 concatenates it; message encoding ``cdr``; channel
metadata ``offered_qos_profiles`` and ``topic_type_hash``), so ``ros2 bag info/play``, Foxglove
and the ``mcap`` library read it.

Threading: ``write`` puts (topic, bytes, times) on a bounded queue and returns; a writer thread
owns the ``mcap.writer.Writer``, drains the queue every DRAIN_PERIOD_S (at once when it holds
WAKE_SIZE entries, or a quarter of ``queue_size`` if less, or at close) and yields the GIL
every few messages. Woken by every message, as a ``queue.Queue`` would, the writer thread cost
a thread switch per message: 600 a second in a node at 1 kHz publishing at 100 Hz, in the
middle of its model ticks. When the queue is full, or after the writer failed, ``write``
returns False and counts the message as dropped. A write error (disk full...) is caught by the
writer thread: ``status.ok`` turns False with the error text and later messages are dropped;
the caller never sees an exception. ``status.written`` then counts the messages that reached
the file (a reader gets them back): those of the chunk being written are lost with it, unless
the chunk itself was written whole and the error came after it (in its message index, say).

Written by the caller (``background=False``): no writer thread; each ``write`` and
``write_block`` encodes, compresses and writes what it takes before it returns, and ``close``
finishes the file. Nothing is queued, so nothing is dropped for a full queue, and the errors are
caught and counted as above. It is for a caller that runs on a core of its own with nothing else
to do meanwhile, such as a study worker (one worker process per core: vm_ros.study.task): a
background thread there only competes with the other workers for the cores, and the thread's
hand-offs cost CPU (measured in docs/studies.md, section 7). A chunk is then closed by its size,
or by the first write after it has been open ``flush_interval_s``.

Crash safety: messages are written in zstd chunks of ``chunk_size`` bytes (uncompressed); each
closed chunk goes straight to the OS (the sink is unbuffered), so a process killed with SIGKILL
leaves a file readable up to its last complete chunk (vm_ros.recording.reader). A chunk is also
closed when its first message has waited ``flush_interval_s`` of wall time (default
FLUSH_INTERVAL_S, 1 s), the first chunk included: a SIGKILL loses at most the messages of the
last ``flush_interval_s`` (plus the writer thread's latency, at most DRAIN_PERIOD_S). Metadata
and attachments are written at start-up, before any message.

Memory: building, compressing and writing a chunk allocates buffers of about ``chunk_size``
bytes (zstd's context among them) and frees them again; glibc's allocator may keep such freed
memory in the process instead of returning it. Every RELEASE_PERIOD_S of wall time, and after
finishing a file of a split bag, the writer thread hands the allocator's free pages back to the
OS (glibc's ``malloc_trim``; nothing where the C library has none). mcap's Writer keeps a file's
chunk indexes (a ChunkIndex record of a few hundred bytes per chunk) until the file is finished,
as the MCAP summary needs them: a single file's grow with the recording; splitting
(max_file_size, max_file_duration_s) bounds them.

Bag directories: a path without the ``.mcap`` suffix is a rosbag2 bag directory ``NAME/`` holding
``NAME_0.mcap`` and, once the log is finished, rosbag2's ``metadata.yaml``
(vm_ros.recording.bag).
"""

from __future__ import annotations

import ctypes
import threading
import time
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import BinaryIO

import numpy as np
from mcap.opcode import Opcode
from mcap.writer import LIBRARY_IDENTIFIER, CompressionType, Writer

from vm_ros.errors import VmRosError
from vm_ros.recording import mcap_bulk
from vm_ros.recording.bag import BagError, is_bag_path, prepare_bag_directory, write_bag_metadata
from vm_ros.recording.message_types import UnknownMessageTypeError, schema_text, type_hash
from vm_ros.recording.qos import offered_qos_profiles_yaml
from vm_ros.recording.schema import MESSAGE_ENCODING, SCHEMA_ENCODING, full_type_name
from vm_ros.recording.versions import VM_ROS_VERSION

PROFILE = "ros2"
COMPRESSIONS = {"zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4,
                "none": CompressionType.NONE}
_MEDIA_TYPES = {".yaml": "application/yaml", ".yml": "application/yaml",
                ".json": "application/json", ".csv": "text/csv", ".txt": "text/plain"}
_CLOSE = object()
# Longest wall time (s) a message waits in an open chunk before the chunk goes to the file: what
# a SIGKILL can lose; its cost in bytes and CPU: docs/log_format.md section 1.
FLUSH_INTERVAL_S = 1.0
# The writer thread gives up the GIL after this many messages, so that a caller waiting for it
# (a 1 kHz loop) waits about one batch, not CPython's 5 ms switch interval; it stops
# doing so while the queue is more than a quarter full, to catch up.
_YIELD_EVERY = 32
# The writer thread drains the queue this often (s), or at once when WAKE_SIZE queue entries
# (messages, or write_block blocks) wait, or a quarter of the queue if that is less.
DRAIN_PERIOD_S = 0.05
WAKE_SIZE = 256
# The writer thread returns the C allocator's free memory to the OS this often (s of wall time;
# module docstring, Memory).
RELEASE_PERIOD_S = 60.0


def _c_malloc_trim():
    """glibc's ``malloc_trim(pad)`` (free heap pages back to the OS), or None without glibc."""
    try:
        trim = ctypes.CDLL(None).malloc_trim
    except (OSError, AttributeError):
        return None
    trim.argtypes, trim.restype = [ctypes.c_size_t], ctypes.c_int
    return trim


_MALLOC_TRIM = _c_malloc_trim()


def release_free_memory() -> None:
    """Hand the C allocator's free pages back to the OS (glibc; elsewhere nothing)."""
    if _MALLOC_TRIM is not None:
        _MALLOC_TRIM(0)


class RecorderError(VmRosError):
    """The MCAP log cannot be written as asked. Attributes: ``path``, ``reason``."""

    def __init__(self, path, reason: str):
        self.path = str(path)
        self.reason = reason
        super().__init__(f"MCAP log {self.path}: {reason}")


@dataclass(frozen=True)
class RecorderStatus:
    """A snapshot of the recorder.

    | field | meaning |
    | ok | False once a write failed (the file is then incomplete) |
    | error | the failure, as text, or None |
    | written | messages handed to the MCAP writer (if a chunk cannot be written, its messages
      move to dropped: after a failure, the messages in the file) |
    | dropped | messages not recorded (queue full, lost with a failed chunk, after a failure or
      after close) |
    | bytes_written | bytes that reached the file |
    | path | the file |
    """

    ok: bool
    error: str | None
    written: int
    dropped: int
    bytes_written: int
    path: str


@dataclass(frozen=True)
class _Block:
    """Messages queued together by ``write_block``; ``more``: the block goes on in the next
    one (write_block's ``more``)."""

    topics: list
    data: list
    log_times_ns: np.ndarray
    more: bool = False

    def joined(self, after: _Block) -> _Block:
        """These messages, then ``after``'s (with its ``more``)."""
        return _Block(self.topics + after.topics, self.data + after.data,
                      np.concatenate([self.log_times_ns, after.log_times_ns]), after.more)

    def tail(self, start: int) -> _Block:
        """The messages from ``start`` on."""
        return _Block(self.topics[start:], self.data[start:], self.log_times_ns[start:],
                      self.more)


def _message_count(item) -> int:
    """Messages in a queue entry: a block's, or one."""
    return len(item.data) if isinstance(item, _Block) else 1


class _BlockError(Exception):
    """A block failed after ``handed`` of its messages went to the writer."""

    def __init__(self, handed: int):
        super().__init__(handed)
        self.handed = handed


@dataclass(frozen=True)
class _ChannelSpec:
    topic: str
    type_name: str
    metadata: dict


class _FileSink:
    """Unbuffered output for mcap's Writer: each record it emits is handed to the OS at once.

    ``chunks`` counts the Chunk records that reached the file whole: mcap's Writer hands each
    chunk over in one write of its own, before the chunk's message indexes, so after a failure
    the recorder can tell whether the chunk it was closing made it."""

    def __init__(self, raw: BinaryIO):
        self._raw = raw
        self.position = 0
        self.chunks = 0

    def write(self, data) -> int:
        view = memoryview(data).cast("B")
        is_chunk = view.nbytes > 0 and view[0] == Opcode.CHUNK
        while view.nbytes:
            count = self._raw.write(view)
            if not count:
                raise OSError("short write: the file accepted no bytes")
            self.position += count
            view = view[count:]
        if is_chunk:
            self.chunks += 1
        return len(data)

    def tell(self) -> int:
        return self.position

    def flush(self) -> None:
        self._raw.flush()

    def close(self) -> None:
        self._raw.close()


def open_unbuffered(path: Path) -> BinaryIO:
    """The default opener: create or truncate ``path`` for unbuffered binary writing."""
    return open(path, "wb", buffering=0)


def _media_type(name: str) -> str:
    return _MEDIA_TYPES.get(Path(name).suffix.lower(), "application/octet-stream")


class McapRecorder:
    """Writes a ROS 2 MCAP log from a background thread (see the module docstring).

    path: the file, or without the ``.mcap`` suffix a bag directory (parent folders are
    created); metadata: MCAP metadata records
    ``{name: {key: value}}``; attachments: ``{name: bytes}`` (media type from the extension);
    compression: "zstd", "lz4" or "none"; chunk_size: uncompressed bytes per chunk; queue_size:
    messages that may wait for the writer thread; flush_interval_s: longest wall time (s) a
    chunk stays open, counted from its first message; max_file_size (bytes),
    max_file_duration_s (s of log time): with a bag directory, start a new file NAME_<k>.mcap
    when the current one reaches either (0: one file; vm_ros.recording.bag); opener:
    ``opener(path) -> binary file`` (tests inject failing files); attachment_time_ns: log and
    create time of the attachments (None: the wall clock when each file starts; offline runs
    give their start time, so that a run with a fixed start time writes the same bytes);
    background: False to write in the caller's thread (module docstring), the same bytes.
    Raises RecorderError naming the path when the file cannot be created or started.
    """

    def __init__(
        self,
        path,
        *,
        metadata: dict[str, dict[str, str]] | None = None,
        attachments: dict[str, bytes] | None = None,
        compression: str = "zstd",
        chunk_size: int = 1 << 20,
        queue_size: int = 20000,
        flush_interval_s: float = FLUSH_INTERVAL_S,
        max_file_size: int = 0,
        max_file_duration_s: float = 0.0,
        opener: Callable[[Path], BinaryIO] = open_unbuffered,
        attachment_time_ns: int | None = None,
        background: bool = True,
    ):
        self._path = Path(path)
        self._attachment_time_ns = attachment_time_ns
        if compression not in COMPRESSIONS:
            raise RecorderError(path, f"compression {compression!r} is not one of "
                                      f"{', '.join(COMPRESSIONS)}")
        if chunk_size <= 0 or queue_size <= 0:
            raise RecorderError(path, "chunk_size and queue_size must be > 0")
        if not flush_interval_s > 0 or flush_interval_s == float("inf"):
            raise RecorderError(path, f"flush_interval_s must be a finite number of seconds > 0, "
                                      f"not {flush_interval_s!r}")
        self._flush_interval_s = float(flush_interval_s)
        if not (max_file_size >= 0 and 0 <= max_file_duration_s < float("inf")):
            raise RecorderError(path, "max_file_size and max_file_duration_s must be >= 0 "
                                      "(0: one file)")
        self._max_file_size = int(max_file_size)
        self._max_file_duration_ns = int(round(max_file_duration_s * 1e9))
        self._bag_directory: Path | None = None
        if is_bag_path(self._path):  # a rosbag2 bag directory NAME/ with NAME_0.mcap
            try:
                self._bag_directory, self._path = self._path, prepare_bag_directory(self._path)
            except BagError as exc:
                raise RecorderError(path, exc.reason) from exc
        elif self._max_file_size or self._max_file_duration_ns:
            raise RecorderError(path, "splitting into several files needs a bag directory "
                                      "(a path without .mcap)")
        self._files: list[Path] = [self._path]  # in a bag directory, the files written so far
        self._bytes_in_closed_files = 0
        self._file_start_log_time: int | None = None
        self._opener = opener
        self._chunk_size, self._compression = chunk_size, COMPRESSIONS[compression]
        self._metadata = {name: {str(k): str(v) for k, v in record.items()}
                          for name, record in (metadata or {}).items()}
        self._attachments = {name: bytes(data) for name, data in (attachments or {}).items()}
        self._queue: deque = deque()  # appended by callers, taken by the writer thread
        self._queue_size = queue_size
        self._wake = threading.Event()  # set: the writer thread drains without waiting
        self._catch_up_size = max(1, queue_size // 4)
        self._wake_size = min(WAKE_SIZE, self._catch_up_size)
        self._channel_lock = threading.Lock()
        self._channels: dict[str, _ChannelSpec] = {}
        self._pending: list[_ChannelSpec] = []
        self._counter_lock = threading.Lock()
        self._dropped = 0
        self._written = 0
        self._error: str | None = None
        self._closing = False
        self._closed = False
        self._close_lock = threading.Lock()
        self._sink = self._open(opener)
        try:
            self._writer = self._start_file()
        except Exception as exc:
            self._sink.close()
            raise RecorderError(path, f"cannot start the log: {exc}") from exc
        self._schema_ids: dict[str, int] = {}
        self._channel_ids: dict[str, int] = {}
        self._sequence: dict[str, int] = {}
        # writer thread only: messages in the chunk being built, wall time of its first one,
        # chunks known to be in the file
        self._open_chunk_count = 0
        self._chunk_opened_at: float | None = None
        self._carry: _Block | None = None  # a block's messages waiting for its next part
        self._chunks_seen = self._sink.chunks
        self._release_at = time.monotonic() + RELEASE_PERIOD_S
        self._thread: threading.Thread | None = None
        self._caller_lock = threading.Lock()  # background=False: one write at a time
        if background:
            self._thread = threading.Thread(target=self._run, daemon=True,
                                            name=f"mcap-recorder {self._path.name}")
            self._thread.start()

    def _start_file(self) -> Writer:
        """An mcap Writer on the current sink, started, with the metadata and attachments (every
        file of a split bag has them, so that each one is a complete run log header)."""
        writer = Writer(self._sink, chunk_size=self._chunk_size, compression=self._compression)
        writer.start(profile=PROFILE, library=f"vm_ros/{VM_ROS_VERSION} {LIBRARY_IDENTIFIER}")
        now = time.time_ns() if self._attachment_time_ns is None else self._attachment_time_ns
        for name, record in self._metadata.items():
            writer.add_metadata(name, record)
        for name, data in self._attachments.items():
            writer.add_attachment(now, now, name, _media_type(name), data)
        return writer

    def _open(self, opener) -> _FileSink:
        try:
            self._path.parent.mkdir(parents=True, exist_ok=True)
            return _FileSink(opener(self._path))
        except OSError as exc:
            raise RecorderError(self._path, f"cannot create the file: {exc.strerror or exc}") \
                from exc

    # --- caller side ----------------------------------------------------------------------

    @property
    def path(self) -> Path:
        """The MCAP file (in a bag directory: ``NAME/NAME_0.mcap``)."""
        return self._path

    @property
    def bag_directory(self) -> Path | None:
        """The bag directory, when the recorder was given a path without ``.mcap``."""
        return self._bag_directory

    def add_channel(self, topic: str, type_name: str, qos_profiles_yaml: str | None = None) -> None:
        """Declare a channel (idempotent). type_name: ``pkg/msg/Type``, a bundled type;
        qos_profiles_yaml: the publisher's offered QoS (vm_ros.recording.qos), default reliable,
        volatile, keep last 10."""
        try:
            full_name = full_type_name(type_name)
            metadata = {
                "offered_qos_profiles": qos_profiles_yaml or offered_qos_profiles_yaml(),
                "topic_type_hash": type_hash(full_name),
            }
            schema_text(full_name)
        except (UnknownMessageTypeError, ValueError) as exc:
            raise RecorderError(self._path, f"channel {topic!r}: {exc}") from exc
        with self._channel_lock:
            existing = self._channels.get(topic)
            if existing is not None:
                if existing.type_name != full_name:
                    raise RecorderError(self._path, f"channel {topic!r} already has type "
                                                    f"{existing.type_name}, not {full_name}")
                return
            spec = _ChannelSpec(topic, full_name, metadata)
            self._channels[topic] = spec
            self._pending.append(spec)

    def write(self, topic: str, data: bytes, log_time_ns: int,
              publish_time_ns: int | None = None) -> bool:
        """Queue one serialised message; never blocks. False (and counted as dropped) when the
        queue is full, the writer failed or the recorder is closed. ``data`` must not change
        afterwards. Raises RecorderError for a topic never declared with add_channel (a bug)."""
        if topic not in self._channels:
            raise RecorderError(self._path, f"write to undeclared channel {topic!r}")
        if self._error is not None or self._closing:
            self._count_dropped(1)
            return False
        publish = log_time_ns if publish_time_ns is None else publish_time_ns
        return self._put((topic, data, int(log_time_ns), int(publish)), 1)

    def _put(self, item, messages: int) -> bool:
        """Queue ``item`` (``messages`` messages) unless the queue is full (counted dropped); or,
        written by the caller, write it now."""
        if self._thread is None:
            with self._caller_lock:
                self._handle(item)
            return self._error is None
        waiting = len(self._queue)
        if waiting >= self._queue_size:
            self._count_dropped(messages)
            return False
        self._queue.append(item)
        if waiting + 1 >= self._wake_size:
            self._wake.set()
        return True

    def write_block(self, topics: Sequence[str], data: Sequence[bytes], log_times_ns,
                    more: bool = False) -> bool:
        """Queue many serialised messages at once (``topics``, ``data`` and ``log_times_ns``
        per message, in file order; publish time = log time): one queue entry, written as whole
        chunks of about ``chunk_size`` bytes without a Python call per message
        (vm_ros.recording.mcap_bulk), the last one at once, however full. ``more``: the block
        goes on in the next write_block, so its messages after the last chunk they fill wait
        for the next block's and are written with them (until then they are neither in the
        file nor counted as written; a ``write``, ``close`` or a failure ends the wait): the
        chunks are those of one block of all the parts, and the writer compresses the first
        parts while the caller builds the next. Otherwise as ``write``: never blocks; False,
        with every message counted as dropped, when the queue is full, the writer failed or the
        recorder is closed."""
        unknown = set(topics) - self._channels.keys()
        if unknown:
            raise RecorderError(self._path, f"write to undeclared channel {sorted(unknown)[0]!r}")
        if not len(data):
            return True
        if len(topics) != len(data) or len(log_times_ns) != len(data):
            raise RecorderError(self._path, "write_block needs one topic and one time per "
                                            "message")
        if self._error is not None or self._closing:
            self._count_dropped(len(data))
            return False
        block = _Block(list(topics), list(data), np.asarray(log_times_ns, dtype=np.int64),
                       bool(more))
        return self._put(block, len(data))

    @property
    def status(self) -> RecorderStatus:
        return RecorderStatus(ok=self._error is None, error=self._error, written=self._written,
                              dropped=self._dropped,
                              bytes_written=self._bytes_in_closed_files + self._sink.position,
                              path=str(self._path))

    def close(self) -> None:
        """Write what is queued, finish the file (summary and indexes) and close it. Idempotent;
        blocks until the writer thread is done."""
        with self._close_lock:
            if self._closed:
                return
            self._closing = True
            if self._thread is None:
                with self._caller_lock:
                    self._finish()
            else:
                self._queue.append(_CLOSE)
                self._wake.set()
                self._thread.join()
            late = 0
            while self._queue:  # written after close() began: never recorded
                late += _message_count(self._queue.popleft())
            self._count_dropped(late)
            self._closed = True

    def __enter__(self) -> McapRecorder:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def _count_dropped(self, count: int) -> None:
        if count:
            with self._counter_lock:
                self._dropped += count

    # --- writer thread --------------------------------------------------------------------

    def _run(self) -> None:
        handled = 0
        while True:
            item = self._next_item()
            if item is _CLOSE:
                break
            handled += 1
            if handled % _YIELD_EVERY == 0 and len(self._queue) < self._catch_up_size:
                time.sleep(0)
            self._handle(item)
        self._finish()

    def _handle(self, item) -> None:
        """Write one queued item (None: only close the open chunk if it is due), in the writer
        thread or, with background=False, in the caller's."""
        if self._error is not None:
            if item is not None:
                self._count_dropped(_message_count(item))
            return
        try:
            if isinstance(item, _Block):
                self._add_block(item)
            elif item is not None:
                self._write_carry()
                self._add_message(*item)
            self._flush_if_old()
        except Exception as exc:  # disk full, I/O error: record it, keep draining
            self._fail(exc)
        if time.monotonic() >= self._release_at:
            self._release_memory()

    def _next_item(self):
        """The next queued item, or None when the open chunk is due to be flushed first."""
        while True:
            try:
                return self._queue.popleft()
            except IndexError:
                pass
            wait = DRAIN_PERIOD_S
            if self._chunk_opened_at is not None:
                wait = self._chunk_opened_at + self._flush_interval_s - time.monotonic()
                if wait <= 0.0:
                    return None
            self._wake.wait(min(wait, DRAIN_PERIOD_S))
            self._wake.clear()

    def _add_message(self, topic: str, data: bytes, log_time: int, publish_time: int) -> None:
        if self._split_due(log_time):
            self._next_file()
        if self._file_start_log_time is None:
            self._file_start_log_time = log_time
        if topic not in self._channel_ids:
            try:
                self._register_pending()  # may close the open chunk
            except Exception:
                self._count_dropped(1)  # never reached the writer
                raise
            self._note_written_chunks()
        sequence = self._sequence[topic] = self._sequence[topic] + 1
        # in the open chunk from here on, even if adding it closes the chunk and that fails
        self._written += 1
        self._open_chunk_count += 1
        if self._chunk_opened_at is None:
            self._chunk_opened_at = time.monotonic()
        self._writer.add_message(self._channel_ids[topic], log_time, data, publish_time,
                                 sequence)
        self._note_written_chunks()

    def _add_block(self, block: _Block) -> None:
        """The block's messages (after those a previous part left waiting) as whole chunks, cut
        where ``write`` would cut them (after the message that takes a chunk past chunk_size
        bytes), the last one written at once unless the block has ``more`` to come (then its
        messages wait: write_block); a file split falls between chunks, before the first
        message due to start a new file. On a failure the messages not yet handed to the
        writer count as dropped (those of the chunk being written: _fail)."""
        if self._carry is not None:
            block, self._carry = self._carry.joined(block), None
        try:
            handed = self._write_block_chunks(block)
        except _BlockError as failure:
            self._count_dropped(len(block.data) - failure.handed)
            raise failure.__cause__ from None
        if handed < len(block.data):
            self._carry = block.tail(handed)

    def _write_carry(self) -> None:
        """Write the messages waiting for a block's next part, as the block's last chunk."""
        if self._carry is not None:
            carry, self._carry = self._carry, None
            self._add_block(replace(carry, more=False))

    def _write_block_chunks(self, block: _Block) -> int:
        """Write the block's chunks; the number of its messages written (all but the
        waiting ones of a block with ``more``)."""
        topics, handed = set(block.topics), 0
        try:
            ids = self._block_channel_ids(block, topics)
            sequences = np.empty(len(ids), dtype=np.int64)
            for topic in topics:
                mine = np.flatnonzero(ids == self._channel_ids[topic])
                sequences[mine] = self._sequence[topic] + 1 + np.arange(len(mine))
                self._sequence[topic] += len(mine)
            sizes = np.fromiter(map(len, block.data), dtype=np.int64, count=len(ids))
            ends = np.cumsum(sizes + mcap_bulk.MESSAGE_RECORD_HEADER)  # record bytes to each
            times = block.log_times_ns
            while handed < len(ids):
                begin = handed
                if self._split_due(int(times[begin])):
                    self._next_file()
                    ids = self._block_channel_ids(block, topics)
                if self._file_start_log_time is None:
                    self._file_start_log_time = int(times[begin])
                base = ends[begin - 1] if begin else 0
                end = begin + mcap_bulk.chunk_length(self._writer, ends[begin:] - base,
                                                     self._chunk_size)
                cut = end < len(ids) or mcap_bulk.chunk_closes(
                    self._writer, ends[begin:end] - base, self._chunk_size)
                if self._max_file_duration_ns:  # stop before the message that starts a file
                    late = np.flatnonzero(times[begin + 1:end] - self._file_start_log_time
                                          >= self._max_file_duration_ns)
                    end, cut = (begin + 1 + int(late[0]), True) if len(late) else (end, cut)
                if block.more and not cut:  # the block's last chunk, not full: it waits
                    break
                self._written += end - begin
                self._open_chunk_count += end - begin
                handed = end
                mcap_bulk.add_chunk(self._writer, ids[begin:end], sequences[begin:end],
                                    times[begin:end], times[begin:end], block.data[begin:end],
                                    sizes[begin:end])
                self._note_written_chunks()
        except Exception as exc:
            raise _BlockError(handed) from exc
        for topic in topics:  # the waiting messages are numbered again when they are written
            self._sequence[topic] -= block.topics[handed:].count(topic)
        return handed

    def _block_channel_ids(self, block: _Block, topics: set) -> np.ndarray:
        """The channel id of each message of ``block`` in the current file (channels registered
        first where needed)."""
        if any(topic not in self._channel_ids for topic in topics):
            self._register_pending()
            self._note_written_chunks()
        return np.fromiter(map(self._channel_ids.__getitem__, block.topics), dtype=np.int64,
                           count=len(block.topics))

    def _split_due(self, log_time: int) -> bool:
        """A new file before this message: the current one has reached max_file_size bytes, or
        spans max_file_duration_s of log time (rosbag2's --max-bag-size, --max-bag-duration)."""
        if self._file_start_log_time is None:
            return False
        return bool(self._max_file_size and self._sink.position >= self._max_file_size
                    or self._max_file_duration_ns
                    and log_time - self._file_start_log_time >= self._max_file_duration_ns)

    def _next_file(self) -> None:
        """Finish the current file and start NAME_<k+1>.mcap (channels registered again)."""
        self._writer.finish()
        self._note_written_chunks()
        self._sink.close()
        self._bytes_in_closed_files += self._sink.position
        directory = self._bag_directory
        self._path = directory / f"{directory.name}_{len(self._files)}.mcap"
        self._files.append(self._path)
        self._sink = self._open(self._opener)
        self._chunks_seen = self._sink.chunks
        self._chunk_opened_at, self._open_chunk_count = None, 0
        self._file_start_log_time = None
        self._writer = self._start_file()
        with self._channel_lock:
            self._pending = list(self._channels.values())
        self._schema_ids, self._channel_ids = {}, {}
        self._release_memory()  # the finished file's indexes and buffers

    def _release_memory(self) -> None:
        release_free_memory()
        self._release_at = time.monotonic() + RELEASE_PERIOD_S

    def _note_written_chunks(self) -> None:
        """A new chunk in the file holds every message of the open chunk: start a new one."""
        if self._sink.chunks != self._chunks_seen:
            self._chunks_seen = self._sink.chunks
            self._chunk_opened_at, self._open_chunk_count = None, 0

    def _flush_if_old(self) -> None:
        if self._chunk_opened_at is not None and (
                time.monotonic() - self._chunk_opened_at >= self._flush_interval_s):
            self._writer.flush()
            self._note_written_chunks()

    def _register_pending(self) -> None:
        with self._channel_lock:
            pending, self._pending = self._pending, []
        for spec in pending:
            schema_id = self._schema_ids.get(spec.type_name)
            if schema_id is None:
                schema_id = self._writer.register_schema(
                    spec.type_name, SCHEMA_ENCODING, schema_text(spec.type_name).encode())
                self._schema_ids[spec.type_name] = schema_id
            self._channel_ids[spec.topic] = self._writer.register_channel(
                spec.topic, MESSAGE_ENCODING, schema_id, spec.metadata)
            self._sequence.setdefault(spec.topic, 0)  # numbering goes on in a new file

    def _finish(self) -> None:
        if self._error is None:
            try:
                self._write_carry()
                self._register_pending()
                self._writer.finish()
            except Exception as exc:
                self._fail(exc)
        if self._carry is not None:  # after a failure: never written
            self._count_dropped(len(self._carry.data))
            self._carry = None
        try:
            self._sink.close()
        except OSError as exc:
            if self._error is None:
                self._fail(exc)
        if self._bag_directory is not None and self._error is None:
            try:
                write_bag_metadata(self._bag_directory, self._files)
            except BagError as exc:
                self._error = f"writing {self._bag_directory} failed: {exc}"

    def _fail(self, exc: Exception) -> None:
        """Record the first failure; the open chunk's messages are lost with it unless the
        chunk reached the file before the error."""
        self._note_written_chunks()
        lost, self._open_chunk_count = self._open_chunk_count, 0
        self._written -= lost
        self._count_dropped(lost)
        if self._error is None:
            self._error = f"writing {self._path} failed: {type(exc).__name__}: {exc}"
