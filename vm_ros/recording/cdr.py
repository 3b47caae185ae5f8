"""CDR (de)serialisation of ROS 2 messages from plain dicts, without rclpy.

    data = serialize("std_msgs/msg/Float64", {"data": 1.5})
    msg = deserialize("std_msgs/msg/Float64", data)      # msg.data == 1.5

Uses mcap_ros2's dynamic encoders and decoders, built once per type from the bundled definitions
(vm_ros.recording.message_types). Fields missing from the dict take their zero value. Decoded
messages are attribute objects (``msg.header.stamp.sec``); arrays decode to lists.
CDR padding bytes are not specified: compare decoded values, never bytes.
"""

from __future__ import annotations

import struct
from collections.abc import Callable
from functools import cache
from typing import Any

import numpy as np
from mcap_ros2._dynamic import generate_dynamic, serialize_dynamic

from vm_ros.recording.message_types import schema_text
from vm_ros.recording.schema import full_type_name


@cache
def _encoder(type_name: str):
    return serialize_dynamic(type_name, schema_text(type_name))[type_name]


@cache
def _decoder(type_name: str):
    return generate_dynamic(type_name, schema_text(type_name))[type_name]


def serialize(type_name: str, fields: dict) -> bytes:
    """CDR bytes (with the 4-byte encapsulation header) of a message given as nested dicts."""
    return _encoder(full_type_name(type_name))(fields)


def decoder(type_name: str) -> Callable[[bytes], Any]:
    """The decoding function of ``type_name`` (built once). Raises UnknownMessageTypeError for
    a type that is not bundled, ValueError for a name that is not ``pkg/msg/Type``."""
    return _decoder(full_type_name(type_name))


def deserialize(type_name: str, data: bytes) -> Any:
    """Decode CDR bytes of ``type_name`` into an attribute object. Bytes that are not a valid
    message raise whatever the decoder meets (struct.error, UnicodeDecodeError...)."""
    return decoder(type_name)(data)


# --- the node's input messages, decoded with NumPy ------------------------------------------------

_KINDS = {0: ">", 1: "<"}  # CDR_BE, CDR_LE; parameter-list encapsulations are not ROS 2 CDR


class _Reader:
    """A bounds-checked cursor over one CDR message (alignment counted from after the 4-byte
    encapsulation header, as mcap_ros2's CdrReader does)."""

    __slots__ = ("data", "offset", "order", "_u32")

    def __init__(self, data: bytes):
        if len(data) < 4:
            raise ValueError(f"{len(data)} bytes: shorter than the CDR header")
        order = _KINDS.get(data[1])
        if data[0] != 0 or order is None:
            raise ValueError(f"encapsulation {data[:2].hex()} is not plain CDR")
        self.data, self.offset, self.order = data, 4, order
        self._u32 = struct.Struct(order + "I").unpack_from

    def align(self, size: int) -> None:
        self.offset += -(self.offset - 4) % size

    def take(self, size: int) -> int:
        """The offset of the next ``size`` bytes, which must be there."""
        start = self.offset
        if start + size > len(self.data):
            raise ValueError(f"message ends at byte {len(self.data)}, {size} bytes needed at "
                             f"{start}")
        self.offset = start + size
        return start

    def uint32(self) -> int:
        self.align(4)
        return self._u32(self.data, self.take(4))[0]

    def string(self) -> str:
        length = self.uint32()
        start = self.take(length)
        return bytes(self.data[start:start + max(length - 1, 0)]).decode("utf-8")

    def strings(self, count: int) -> tuple[tuple, list]:
        """``count`` strings (a sequence's elements) and the offset where each ends: one loop
        over their length words (a length past the message's end raises ValueError), then one
        UTF-8 decode of them all (joined by NUL and split again; when a string holds a NUL
        itself, each is decoded alone)."""
        data, offset, u32 = self.data, self.offset, self._u32
        parts, ends = [], []
        try:
            for _ in range(count):
                offset = (offset + 3) & -4  # aligned (the CDR origin, byte 4, is aligned)
                start = offset + 4
                offset = start + u32(data, offset)[0]
                parts.append(data[start:offset - 1])  # without the NUL (b"" for length 0)
                ends.append(offset)
        except struct.error:  # a length word past the end
            raise ValueError(f"message ends at byte {len(data)}, a string length needed at "
                             f"{offset}") from None
        if offset > len(data):  # the last string (the others: their successor's length word)
            raise ValueError(f"message ends at byte {len(data)}, {offset} bytes needed")
        self.offset = offset
        names = str(b"\0".join(parts), "utf-8").split("\0")
        if len(names) != len(parts):
            names = [str(part, "utf-8") for part in parts]
        return tuple(names), ends

    def float64s_at(self) -> tuple[int, int, np.ndarray]:
        """A float64 sequence: (offset of its count, offset of its values, the values)."""
        count_at = self.offset + -(self.offset - 4) % 4
        count = self.uint32()
        if count == 0:
            return count_at, self.offset, np.zeros(0)
        self.align(8)
        start = self.take(8 * count)
        return count_at, start, np.frombuffer(self.data, dtype=self.order + "f8", count=count,
                                              offset=start)

    def float64s(self) -> np.ndarray:
        return self.float64s_at()[2]


class _Stamp:
    __slots__ = ("sec", "nanosec")

    def __init__(self, sec: int, nanosec: int):
        self.sec, self.nanosec = sec, nanosec


class _Header:
    __slots__ = ("stamp", "frame_id")

    def __init__(self, stamp: _Stamp, frame_id: str):
        self.stamp, self.frame_id = stamp, frame_id


class JointStateInput:
    """A decoded sensor_msgs/JointState: ``name`` a tuple of str, ``position``, ``velocity`` and
    ``effort`` float64 arrays (read-only views of the message bytes)."""

    __slots__ = ("header", "name", "position", "velocity", "effort")

    def __init__(self, header, name, position, velocity, effort):
        self.header, self.name = header, name
        self.position, self.velocity, self.effort = position, velocity, effort


class _Dimension:
    __slots__ = ("label", "size", "stride")

    def __init__(self, label: str, size: int, stride: int):
        self.label, self.size, self.stride = label, size, stride


class _Layout:
    __slots__ = ("dim", "data_offset")

    def __init__(self, dim: list, data_offset: int):
        self.dim, self.data_offset = dim, data_offset


class MultiArrayInput:
    """A decoded std_msgs/Float64MultiArray: ``layout.dim`` (label, size, stride), ``data`` a
    float64 array (a read-only view of the message bytes)."""

    __slots__ = ("layout", "data")

    def __init__(self, layout: _Layout, data: np.ndarray):
        self.layout, self.data = layout, data


def header_stamp_ns(data: bytes) -> int:
    """The header stamp (ns) of the CDR bytes of a message whose first field is a
    ``std_msgs/Header`` (sec, int32, and nanosec, uint32, right after the encapsulation header).
    ValueError for bytes too short or not ROS 2 CDR."""
    if len(data) < 12 or data[1] not in _KINDS or data[0] != 0:
        raise ValueError("not the CDR bytes of a message with a header")
    sec, nanosec = struct.unpack_from(_KINDS[data[1]] + "iI", data, 4)
    return sec * 1_000_000_000 + nanosec


def restamped(data: bytes, stamp_ns: int) -> bytes:
    """``data`` (as for :func:`header_stamp_ns`) with its header stamp set to ``stamp_ns``; every
    other byte unchanged. ValueError as header_stamp_ns, or for a stamp sec cannot hold."""
    header_stamp_ns(data)
    sec, nanosec = divmod(int(stamp_ns), 1_000_000_000)
    if not -(1 << 31) <= sec < 1 << 31:
        raise ValueError(f"stamp {stamp_ns} ns is out of the header's range")
    out = bytearray(data)
    struct.pack_into(_KINDS[data[1]] + "iI", out, 4, sec, nanosec)
    return bytes(out)


def _header(reader: _Reader) -> _Header:
    sec = reader.uint32()
    sec = sec - (1 << 32) if sec >= 1 << 31 else sec  # int32
    return _Header(_Stamp(sec, reader.uint32()), reader.string())


class JointStateDecoder:
    """JointState bytes to a :class:`JointStateInput`, safe and fast for a publisher that keeps
    its layout: every message is checked against its own length (a count or string length that
    claims more bytes than the message holds raises ValueError), and a message laid out as the
    previous one (the same encapsulation, frame_id length, name block byte for byte and array
    counts) is read at the previous one's offsets: one header unpack, a comparison of the name
    bytes and three NumPy views, instead of a walk over 4 + 3 fields and every name."""

    def __init__(self):
        self._layout: _JointStateLayout | None = None

    def __call__(self, data: bytes) -> JointStateInput:
        layout = self._layout
        if layout is not None:
            decoded = layout.read(data)
            if decoded is not None:
                return decoded
        reader = _Reader(data)
        header = _header(reader)
        reader.align(4)
        names_start = reader.offset
        if layout is not None and layout.same_names(data, names_start):
            names, ends = layout.names, layout.string_ends
            reader.offset = names_start + len(layout.names_bytes)
        else:
            names, ends = reader.strings(reader.uint32())
        names_end = reader.offset
        arrays = [reader.float64s_at() for _ in range(3)]
        self._layout = _JointStateLayout(data, header, (names, ends), names_start, names_end,
                                         arrays, reader.offset)
        if names is getattr(layout, "names", None):
            self._layout.names_kept = layout.names_kept
        return JointStateInput(header, names, *(values for _, _, values in arrays))


class _JointStateLayout:
    """Where the fields of one JointState message are, to read the next message of the same
    layout at the same offsets (:meth:`read`, None when the layout differs)."""

    __slots__ = ("kind", "order", "frame_id", "frame_bytes", "names", "string_ends",
                 "names_start", "names_bytes", "names_kept", "counts", "arrays", "end", "_head")

    def __init__(self, data, header, names_and_ends, names_start, names_end, arrays, end):
        self.kind, self.order = data[1], _KINDS[data[1]]
        self.frame_id = header.frame_id
        # frame_id's length word and bytes (its terminating NUL is not read, as by _Reader)
        self.frame_bytes = bytes(data[12:16 + len(header.frame_id.encode())])
        self.names, self.string_ends = names_and_ends
        self.names_start = names_start
        self.names_bytes = bytes(data[names_start:names_end])
        self.names_kept: np.ndarray | None = None  # see same_names
        # each array's count word (offset, bytes) and values (offset, count)
        self.counts = tuple((at, bytes(data[at:at + 4])) for at, _, _ in arrays)
        self.arrays = tuple((start, len(values)) for _, start, values in arrays)
        self.end = end  # a message this long holds every field read below
        self._head = struct.Struct(self.order + "iI").unpack_from

    def same_names(self, data, names_start: int) -> bool:
        """Whether ``data`` has this layout's name block at ``names_start``: the same bytes,
        or the same bytes but for the alignment padding between the strings (which not every
        serialiser initialises)."""
        if names_start != self.names_start:
            return False
        block = data[names_start:names_start + len(self.names_bytes)]
        if block == self.names_bytes:
            return True
        first = (self.string_ends[0] if self.string_ends else names_start + 4) - names_start
        if len(block) != len(self.names_bytes) or block[:first] != self.names_bytes[:first]:
            return False  # (the count, the first length and string: no padding among them)
        if self.names_kept is None:  # the block's bytes that are not padding, found once
            self.names_kept = np.flatnonzero(self._names_without_padding())
        kept = self.names_kept
        return np.array_equal(np.frombuffer(block, np.uint8)[kept],
                              np.frombuffer(self.names_bytes, np.uint8)[kept])

    def _names_without_padding(self) -> np.ndarray:
        """False at the 0-3 padding bytes after each string but the last (the next length word
        is aligned to 4 from the CDR origin, byte 4, itself aligned), True elsewhere."""
        keep = np.ones(len(self.names_bytes), dtype=bool)
        ends = np.asarray(self.string_ends[:-1], dtype=np.int64)
        padding = -ends % 4
        for k in range(3):
            keep[ends[padding > k] + k - self.names_start] = False
        return keep

    def read(self, data) -> JointStateInput | None:
        if len(data) < self.end or data[1] != self.kind or data[0] != 0:
            return None
        names_start = self.names_start
        if data[12:12 + len(self.frame_bytes)] != self.frame_bytes or (
                data[names_start:names_start + len(self.names_bytes)] != self.names_bytes
                and not self.same_names(data, names_start)):
            return None
        for at, word in self.counts:
            if data[at:at + 4] != word:
                return None
        dtype = self.order + "f8"
        sec, nanosec = self._head(data, 4)
        return JointStateInput(
            _Header(_Stamp(sec, nanosec), self.frame_id), self.names,
            *(np.frombuffer(data, dtype=dtype, count=count, offset=start) if count
              else np.zeros(0) for start, count in self.arrays))


def _multi_array(data: bytes) -> MultiArrayInput:
    reader = _Reader(data)
    dims = [_Dimension(reader.string(), reader.uint32(), reader.uint32())
            for _ in range(reader.uint32())]
    layout = _Layout(dims, reader.uint32())
    return MultiArrayInput(layout, reader.float64s())


def input_decoder(type_name: str) -> Callable[[bytes], Any]:
    """A decoding function for the node's input topics, the same for the node and its recompute
    (vm_ros.node.replay): JointState and Float64MultiArray with their arrays as NumPy views
    (:class:`JointStateDecoder`, a new one per call: it remembers its stream's names); other
    types as :func:`decoder`. Bytes that are not a message raise ValueError (or
    UnicodeDecodeError for a name)."""
    name = full_type_name(type_name)
    if name == "sensor_msgs/msg/JointState":
        return JointStateDecoder()
    if name == "std_msgs/msg/Float64MultiArray":
        return _multi_array
    return decoder(name)
