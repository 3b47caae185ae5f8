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

    def float64s(self) -> np.ndarray:
        count = self.uint32()
        if count == 0:
            return np.zeros(0)
        self.align(8)
        start = self.take(8 * count)
        return np.frombuffer(self.data, dtype=self.order + "f8", count=count, offset=start)


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


def _header(reader: _Reader) -> _Header:
    sec = reader.uint32()
    sec = sec - (1 << 32) if sec >= 1 << 31 else sec  # int32
    return _Header(_Stamp(sec, reader.uint32()), reader.string())


class JointStateDecoder:
    """JointState bytes to a :class:`JointStateInput`, the names decoded once for a publisher
    that repeats them: a message whose name block is byte-for-byte the previous one's (at the
    same offset) reuses its tuple, so that a 1000-muscle message costs a comparison of its name
    bytes instead of 1000 string decodes."""

    def __init__(self):
        self._names_start = -1
        self._names_bytes = b""
        self._names: tuple = ()

    def __call__(self, data: bytes) -> JointStateInput:
        reader = _Reader(data)
        header = _header(reader)
        reader.align(4)
        start, cached = reader.offset, self._names_bytes
        if start == self._names_start and data[start:start + len(cached)] == cached:
            reader.offset = start + len(cached)
            names = self._names
        else:
            names = tuple(reader.string() for _ in range(reader.uint32()))
            self._names_start, self._names = start, names
            self._names_bytes = bytes(data[start:reader.offset])
        return JointStateInput(header, names, reader.float64s(), reader.float64s(),
                               reader.float64s())


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
