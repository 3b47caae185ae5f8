"""CDR (de)serialisation of ROS 2 messages from plain dicts, without rclpy.

    data = serialize("std_msgs/msg/Float64", {"data": 1.5})
    msg = deserialize("std_msgs/msg/Float64", data)      # msg.data == 1.5

Uses mcap_ros2's dynamic encoders and decoders, built once per type from the bundled definitions
(vm_ros.recording.message_types). Fields missing from the dict take their zero value. Decoded
messages are attribute objects (``msg.header.stamp.sec``); arrays decode to lists.
CDR padding bytes are not specified: compare decoded values, never bytes.
"""

from __future__ import annotations

from collections.abc import Callable
from functools import cache
from typing import Any

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
