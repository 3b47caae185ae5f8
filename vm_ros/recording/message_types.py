"""The message types a run log can hold: schema text and RIHS01 hash of each, without ROS.

Backed by the generated vm_ros.recording.definitions (verbatim .msg texts of the ROS 2 Jazzy
packages and of msg_defs/), so `pip install .` without ROS can still write rosbag2-compatible
logs.
"""

from __future__ import annotations

from functools import cache

from vm_ros.errors import VmRosError
from vm_ros.recording.definitions import MSG_TEXTS, TYPE_HASHES
from vm_ros.recording.schema import concatenated_definition, full_type_name


class UnknownMessageTypeError(VmRosError):
    """A message type whose definition is not bundled; carries ``type_name``."""

    def __init__(self, type_name: str):
        self.type_name = type_name
        super().__init__(
            f"message type {type_name!r} is not bundled with vm_ros (have: "
            f"{', '.join(sorted(MSG_TEXTS))})"
        )


@cache
def schema_text(type_name: str) -> str:
    """rosbag2's concatenated ``ros2msg`` definition of ``type_name`` (``pkg/msg/Type``)."""
    try:
        return concatenated_definition(full_type_name(type_name), MSG_TEXTS)
    except (KeyError, ValueError) as exc:
        raise UnknownMessageTypeError(type_name) from exc


def type_hash(type_name: str) -> str:
    """RIHS01 type hash string (as in ``share/<pkg>/msg/<Type>.json``)."""
    try:
        return TYPE_HASHES[full_type_name(type_name)]
    except (KeyError, ValueError) as exc:
        raise UnknownMessageTypeError(type_name) from exc
