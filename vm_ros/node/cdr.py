"""A bounds check of a serialised ROS message (CDR) before rclpy deserialises it (no rclpy here).

rclpy's Fast DDS type support writes ``sequence size exceeds remaining buffer`` to stderr, once
per message and without any throttle, when a sequence or string claims more elements than the
payload holds (229 lines in 60 s of hostile input), and then raises. muscle_node checks the
claimed lengths first: such a message is counted as undecodable, with its reason in the node's
throttled log, and never reaches the deserialiser.

The walk follows the message's rosidl type description (``SLOT_TYPES``): plain CDR (XCDR1),
little- or big-endian by the encapsulation header, alignment relative to the payload after it.
Types it does not know (wide strings) end the check: the deserialiser judges the rest.
"""

from __future__ import annotations

import importlib
import struct

_HEADER_BYTES = 4
_BASIC_SIZES = {"boolean": 1, "octet": 1, "char": 1, "uint8": 1, "int8": 1, "int16": 2,
                "uint16": 2, "int32": 4, "uint32": 4, "float": 4, "int64": 8, "uint64": 8,
                "double": 8, "long double": 16, "wchar": 2}


class _UncheckedTypeError(Exception):
    """A type this check does not walk."""


class _ShortPayloadError(Exception):
    """The payload ends before a claimed length: the reason as its argument."""


def payload_problem(data: bytes, msg_type) -> str | None:
    """Why ``data`` cannot be a ``msg_type`` message (a claimed length past the end), or None."""
    if len(data) < _HEADER_BYTES:
        return f"{len(data)} bytes, shorter than the CDR header"
    endian = "<" if data[1] & 1 else ">"
    try:
        _walk_message(data, _HEADER_BYTES, msg_type, endian)
    except _ShortPayloadError as exc:
        return str(exc)
    except _UncheckedTypeError:
        return None
    return None


def _align(offset: int, size: int) -> int:
    rel = offset - _HEADER_BYTES
    return offset + (-rel) % min(size, 8)


def _count(data: bytes, offset: int, endian: str, what: str) -> tuple[int, int]:
    offset = _align(offset, 4)
    if offset + 4 > len(data):
        raise _ShortPayloadError(f"payload ends before the length of {what}")
    return struct.unpack_from(endian + "I", data, offset)[0], offset + 4


def _walk_message(data: bytes, offset: int, msg_type, endian: str) -> int:
    for name, slot in zip(msg_type.get_fields_and_field_types(), msg_type.SLOT_TYPES,
                          strict=True):
        offset = _walk(data, offset, slot, endian, name)
    return offset


def _walk(data: bytes, offset: int, slot, endian: str, name: str) -> int:
    kind = type(slot).__name__
    if kind == "BasicType":
        size = _BASIC_SIZES[slot.typename]
        offset = _align(offset, size) + size
        if offset > len(data):
            raise _ShortPayloadError(f"payload ends inside {name}")
        return offset
    if kind in ("UnboundedString", "BoundedString"):
        n, offset = _count(data, offset, endian, name)
        if offset + n > len(data):
            raise _ShortPayloadError(f"{name}: string of {n} bytes claimed, "
                                     f"{len(data) - offset} left")
        return offset + n
    if kind in ("UnboundedSequence", "BoundedSequence", "Array"):
        if kind == "Array":
            n = slot.size
        else:
            n, offset = _count(data, offset, endian, name)
        element = slot.value_type
        if type(element).__name__ == "BasicType":
            size = _BASIC_SIZES[element.typename]
            start = _align(offset, size) if n else offset
            if start + n * size > len(data):
                raise _ShortPayloadError(f"{name}: {n} elements of {size} bytes claimed, "
                             f"{len(data) - start} bytes left")
            return start + n * size
        if n > len(data) - offset:  # every element takes at least one byte
            raise _ShortPayloadError(f"{name}: {n} elements claimed, "
                                     f"{len(data) - offset} bytes left")
        for _ in range(n):
            offset = _walk(data, offset, element, endian, name)
        return offset
    if kind == "NamespacedType":
        module = importlib.import_module(".".join(slot.namespaces))
        return _walk_message(data, offset, getattr(module, slot.name), endian)
    raise _UncheckedTypeError(kind)


__all__ = ["payload_problem"]
