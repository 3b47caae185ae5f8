"""ROS 2 message definitions as rosbag2 stores them in MCAP schemas (encoding ``ros2msg``).

rosbag2's MCAP storage (rosbag2_storage_mcap, message_definition_cache.cpp) stores the root
type's .msg text as found in ``share/<pkg>/msg/``, then each dependency once, depth first, in
sorted order at each level, each preceded by ``"\\n"``, a line of 80 ``=`` and ``MSG: pkg/Type``.
Dependencies are found with its regular expression on the text: the first word of each line that
is not a primitive type; a bare ``Type`` means ``<same package>/Type``.

Pure functions over a mapping of ``pkg/msg/Type`` to .msg text (this module imports nothing from
the package, so scripts/gen-msg-definitions can load it on its own).
"""

from __future__ import annotations

import re
from collections.abc import Mapping

SCHEMA_ENCODING = "ros2msg"
MESSAGE_ENCODING = "cdr"
DELIMITER = "=" * 80 + "\n"

# rosbag2_storage_mcap MSG_FIELD_TYPE_REGEX and PRIMITIVE_TYPES
_FIELD_TYPE = re.compile(r"(?:^|\n)\s*([a-zA-Z0-9_/]+)(?:\[[^\]]*\])?\s+")
_PRIMITIVES = frozenset((
    "bool", "byte", "char", "float32", "float64", "int8", "uint8", "int16", "uint16", "int32",
    "uint32", "int64", "uint64", "string",
))


def full_type_name(name: str) -> str:
    """``pkg/Type`` or ``pkg/msg/Type`` -> ``pkg/msg/Type``."""
    parts = name.split("/")
    if len(parts) == 2:
        return f"{parts[0]}/msg/{parts[1]}"
    if len(parts) == 3 and parts[1] == "msg":
        return name
    raise ValueError(f"not a message type name: {name!r} (expected pkg/msg/Type)")


def short_type_name(name: str) -> str:
    """``pkg/msg/Type`` -> ``pkg/Type`` (the form of rosbag2's ``MSG:`` lines)."""
    package, _, type_ = full_type_name(name).split("/")
    return f"{package}/{type_}"


def msg_dependencies(text: str, package: str) -> list[str]:
    """Types a .msg text refers to, as sorted ``pkg/msg/Type`` names (rosbag2's parse)."""
    found = set()
    for match in _FIELD_TYPE.finditer(text):
        word = match.group(1)
        if word in _PRIMITIVES:
            continue
        found.add(short_type_name(word if "/" in word else f"{package}/{word}"))
    return [full_type_name(name) for name in sorted(found)]


def concatenated_definition(type_name: str, texts: Mapping[str, str]) -> str:
    """The schema text rosbag2 writes for ``type_name`` (``pkg/msg/Type``).

    Raises KeyError naming the first type whose text is missing from ``texts``.
    """
    seen: set[str] = set()

    def append(name: str) -> str:
        text = texts[name]
        result = text
        for dependency in msg_dependencies(text, name.split("/")[0]):
            if dependency not in seen:
                seen.add(dependency)
                result += "\n" + DELIMITER + f"MSG: {short_type_name(dependency)}\n"
                result += append(dependency)
        return result

    return append(full_type_name(type_name))
