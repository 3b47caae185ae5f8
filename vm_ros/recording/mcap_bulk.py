"""Many messages into an ``mcap.writer.Writer`` at once, as one chunk, without a Python call per
message.

    add_chunk(writer, channel_ids, sequences, log_times_ns, publish_times_ns, payloads)

mcap's ``Writer.add_message`` does Python work per message (a Message object, its record written
field by field, a (time, offset) tuple for the index, the statistics): seconds for the messages of
a 180 s knee-extension log (docs/performance.md). Here the Message records of a block are built as
one NumPy array of their fixed 31-byte headers (opcode, record length, channel id, sequence, log
time, publish time; MCAP specification, "Message") joined with the payloads, and the message index
of each channel is one array, then handed to the writer's own chunk builder, which compresses the
chunk and writes it with its Chunk, MessageIndex and ChunkIndex records and statistics as for
``add_message`` (the file is the same: test/test_recording_writer.py reads both back). The chunk
builder and statistics are the Writer's private attributes (mcap 1.6, pinned in constraints.txt);
with a Writer that lacks them, ``add_chunk`` falls back to ``add_message`` per message (``BULK``
False).
"""

from __future__ import annotations

import numpy as np
from mcap.opcode import Opcode
from mcap.records import MessageIndex
from mcap.writer import Writer

# MCAP Message record: opcode, record length (of what follows it), then the message's fields
_HEADER = np.dtype([("opcode", "u1"), ("length", "<u8"), ("channel_id", "<u2"),
                    ("sequence", "<u4"), ("log_time", "<u8"), ("publish_time", "<u8")])
_AFTER_LENGTH = _HEADER.itemsize - 9  # channel id .. publish time: 22 bytes
MESSAGE_RECORD_HEADER = _HEADER.itemsize  # bytes of a Message record before its payload: 31


class _ArrayMessageIndex(MessageIndex):
    """A MessageIndex whose records are an (m, 2) uint64 array of (log time, offset), written at
    once (MCAP specification, "Message Index")."""

    def write(self, stream) -> None:
        pairs = np.ascontiguousarray(self.records, dtype="<u8")
        stream.start_record(Opcode.MESSAGE_INDEX)
        stream.write2(self.channel_id)
        stream.write4(pairs.nbytes)
        stream.write(pairs.tobytes())
        stream.finish_record()


def _private(writer: Writer, name: str):
    return getattr(writer, f"_Writer__{name}", None)


def bulk_available(writer: Writer) -> bool:
    """Whether ``writer`` exposes the chunk builder and statistics ``add_chunk`` feeds."""
    builder = _private(writer, "chunk_builder")
    return (builder is not None and _private(writer, "statistics") is not None
            and all(hasattr(builder, a) for a in ("record_writer", "message_indices",
                                                  "num_messages", "message_start_time",
                                                  "message_end_time")))


def chunk_length(writer: Writer, record_ends, chunk_size: int) -> int:
    """How many of the next messages ``writer.add_message`` would put in its open chunk:
    ``record_ends`` are the cumulative sizes of their Message records (bytes from the first
    one's start); the Writer closes a chunk after the message that takes it past
    ``chunk_size`` bytes, counting the schema and channel records already in it."""
    builder = _private(writer, "chunk_builder")
    held = builder.count if builder is not None else 0
    return min(int(np.searchsorted(record_ends, chunk_size - held, side="right")) + 1,
               len(record_ends))


def chunk_closes(writer: Writer, record_ends, chunk_size: int) -> bool:
    """Whether ``writer.add_message`` of the messages (``record_ends`` as for chunk_length)
    would close its open chunk after the last one: they take it past ``chunk_size`` bytes."""
    builder = _private(writer, "chunk_builder")
    held = builder.count if builder is not None else 0
    return len(record_ends) > 0 and int(record_ends[-1]) > chunk_size - held


def message_records(channel_ids, sequences, log_times_ns, publish_times_ns,
                    payloads, sizes=None) -> tuple[bytes, np.ndarray]:
    """The Message records of the messages, concatenated, and the offset of each one in it
    (``sizes``: the payloads' lengths, if known)."""
    count = len(payloads)
    if sizes is None:
        sizes = np.fromiter(map(len, payloads), dtype=np.int64, count=count)
    headers = np.empty(count, dtype=_HEADER)
    headers["opcode"] = Opcode.MESSAGE
    headers["length"] = sizes + _AFTER_LENGTH
    headers["channel_id"] = channel_ids
    headers["sequence"] = sequences
    headers["log_time"] = log_times_ns
    headers["publish_time"] = publish_times_ns
    width = _HEADER.itemsize
    parts: list = [None] * (2 * count)
    parts[0::2] = headers.view(np.dtype((np.void, width))).tolist()  # bytes, one per record
    parts[1::2] = payloads
    offsets = np.zeros(count, dtype=np.int64)
    np.cumsum(sizes[:-1] + width, out=offsets[1:])
    return b"".join(parts), offsets


def add_chunk(writer: Writer, channel_ids, sequences, log_times_ns, publish_times_ns,
              payloads, sizes=None) -> None:
    """Write the messages (arrays of channel id, sequence, log and publish time in ns, and a list
    of payload bytes, in file order; ``sizes``: the payloads' lengths, if known) as one chunk of
    ``writer``: the chunk it has open is closed first, and this one is closed (written) before
    returning."""
    if not len(payloads):
        return
    writer.flush()  # the open chunk, with its own index, goes first
    channel_ids = np.asarray(channel_ids, dtype=np.int64)
    log_times = np.asarray(log_times_ns, dtype=np.int64)
    if not bulk_available(writer):
        for channel, sequence, log_time, publish, data in zip(
                channel_ids.tolist(), np.asarray(sequences).tolist(), log_times.tolist(),
                np.asarray(publish_times_ns).tolist(), payloads, strict=True):
            writer.add_message(channel, log_time, data, publish, sequence)
        writer.flush()
        return
    builder = _private(writer, "chunk_builder")
    statistics = _private(writer, "statistics")
    records, offsets = message_records(channel_ids, sequences, log_times, publish_times_ns,
                                       payloads, sizes)
    offsets += builder.count
    builder.record_writer.write(records)
    start, end = int(log_times.min()), int(log_times.max())
    channels, first = np.unique(channel_ids, return_index=True)
    for channel in channels[np.argsort(first)].tolist():  # in order of first message, as mcap
        mine = channel_ids == channel
        builder.message_indices[channel] = _ArrayMessageIndex(
            channel_id=channel, records=np.column_stack([log_times[mine], offsets[mine]]))
        statistics.channel_message_counts[channel] += int(np.count_nonzero(mine))
    builder.message_start_time, builder.message_end_time = start, end
    builder.num_messages = len(payloads)
    if statistics.message_count == 0:
        statistics.message_start_time = start
    else:
        statistics.message_start_time = min(start, statistics.message_start_time)
    statistics.message_end_time = max(end, statistics.message_end_time)
    statistics.message_count += len(payloads)
    writer.flush()


__all__ = ["MESSAGE_RECORD_HEADER", "add_chunk", "bulk_available", "chunk_closes",
           "message_records"]
