"""The ``offered_qos_profiles`` channel metadata, in the YAML form rosbag2 (Jazzy) writes.

rosbag2_storage (qos.cpp, metadata version 9) dumps a YAML sequence with one mapping per
publisher; policies are rmw's string names (``keep_last``, ``reliable``, ``volatile``,
``automatic``...) and durations ``{sec, nsec}`` (an rmw "infinite" duration is
sec 9223372036, nsec 854775807). ``ros2 bag play`` reads it back to offer the same QoS.
"""

from __future__ import annotations

# RMW_DURATION_INFINITE as rmw reports it for a publisher that sets no deadline, lifespan or lease.
INFINITE_DURATION_NS = 9_223_372_036_854_775_807
_POLICIES = {
    "history": ("system_default", "keep_last", "keep_all", "unknown"),
    "reliability": ("system_default", "reliable", "best_effort", "best_available", "unknown"),
    "durability": ("system_default", "transient_local", "volatile", "best_available", "unknown"),
    "liveliness": ("system_default", "automatic", "manual_by_topic", "best_available", "unknown"),
}


def _policy(kind: str, value) -> str:
    """A policy given as rmw string name or as an enum with ``.name`` (rclpy's QoS enums)."""
    name = str(getattr(value, "name", value)).lower()
    if name not in _POLICIES[kind]:
        raise ValueError(f"QoS {kind} {value!r}: expected one of {_POLICIES[kind]}")
    return name


def _duration_ns(value) -> int:
    """Nanoseconds from an int or an rclpy Duration; 0 (unspecified) reads as infinite, as rmw
    reports the offered QoS of such a publisher."""
    ns = int(getattr(value, "nanoseconds", value))
    return INFINITE_DURATION_NS if ns <= 0 else ns


def _duration_yaml(key: str, ns: int) -> str:
    return f"  {key}:\n    sec: {ns // 1_000_000_000}\n    nsec: {ns % 1_000_000_000}"


def offered_qos_profiles_yaml(
    profile=None,
    *,
    history="keep_last",
    depth: int = 10,
    reliability="reliable",
    durability="volatile",
    liveliness="automatic",
    deadline_ns: int = 0,
    lifespan_ns: int = 0,
    liveliness_lease_duration_ns: int = 0,
    avoid_ros_namespace_conventions: bool = False,
) -> str:
    """One offered profile as rosbag2's YAML. ``profile`` may be an rclpy ``QoSProfile`` (read by
    attribute, rclpy not imported here); otherwise the keywords give the policies."""
    if profile is not None:
        history, depth = profile.history, profile.depth
        reliability, durability = profile.reliability, profile.durability
        liveliness = profile.liveliness
        deadline_ns, lifespan_ns = profile.deadline, profile.lifespan
        liveliness_lease_duration_ns = profile.liveliness_lease_duration
        avoid_ros_namespace_conventions = profile.avoid_ros_namespace_conventions
    lines = [
        f"- history: {_policy('history', history)}",
        f"  depth: {int(depth)}",
        f"  reliability: {_policy('reliability', reliability)}",
        f"  durability: {_policy('durability', durability)}",
        _duration_yaml("deadline", _duration_ns(deadline_ns)),
        _duration_yaml("lifespan", _duration_ns(lifespan_ns)),
        f"  liveliness: {_policy('liveliness', liveliness)}",
        _duration_yaml("liveliness_lease_duration", _duration_ns(liveliness_lease_duration_ns)),
        f"  avoid_ros_namespace_conventions: {str(bool(avoid_ros_namespace_conventions)).lower()}",
    ]
    return "\n".join(lines)
