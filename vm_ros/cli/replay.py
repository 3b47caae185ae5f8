"""Republish the topics of a run log over ROS 2 at the recorded pace (needs rclpy: the [ros]
extra; run it where DDS may talk, e.g. inside scripts/netns-run on the development machines).

The recorded CDR bytes are published as they are, each topic with its recorded type and offered
reliability/durability (default reliable, volatile). The pace follows the log times (model time
for `vm-ros simulate` logs); --rate 2 plays twice as fast. Channels typed with vm_ros's own
offline definitions (muscle_telemetry) cannot be published without a colcon build and are
skipped, and so are channels that are not ROS 2 messages (schema name not pkg/msg/Type, or an
encoding other than CDR). A recorded message that does not decode as its type (muscle_node
records inputs as received, malformed or not) is not published, since subscribers would fail on
it; at the end one line on stderr per cause counts those per topic and names the first (what the
C typesupport prints on stderr for each of them is captured into that line). Names may be given
with or without the leading slash.

With --restamp, every message whose type starts with a std_msgs/Header gets a new header stamp on
this process's ROS clock (recording.replay.Restamper): the first one the time it was due at (its
publication less how late the pace yielded it), the others their recorded spacing from it. A
node that places its inputs at their stamps (muscle_node, within its input_timeout_s) then places
them as they were recorded, relative to each other, instead of at their arrival; without it the
log's own stamps, hours or days old, are sent.
"""

from __future__ import annotations

import argparse
import importlib
import os
import re
import sys
import tempfile
import time
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

import yaml

from vm_ros.errors import VmRosError
from vm_ros.recording.reader import ChannelInfo, log_channels, unlisted_note
from vm_ros.recording.replay import Restamper, is_offline_type, replay
from vm_ros.recording.run_log import resolve_topic
from vm_ros.recording.schema import MESSAGE_ENCODING, full_type_name
from vm_ros.recording.series import skipped_line

NODE_NAME = "vm_ros_replay"
ACK_WAIT_S = 5.0  # longest wait for subscribers to acknowledge the last reliable messages
_LOCATION = re.compile(r", at \S+:\d+$")  # rclpy's source location after an error message


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("log", type=Path, metavar="FILE.mcap", help="run log")
    parser.add_argument("--rate", type=float, default=1.0, metavar="FACTOR",
                        help="playback speed factor (default 1: recorded pace)")
    parser.add_argument("--topics", metavar="A,B",
                        help="comma-separated topics to publish (default: every ROS-typed one)")
    parser.add_argument("--loop", action="store_true", help="start over at the end, until "
                        "interrupted")
    parser.add_argument("--wait", type=float, default=0.0, metavar="S",
                        help="before the first message, wait up to S seconds until every "
                             "replayed topic has a subscriber (default 0: start at once)")
    parser.add_argument("--restamp", action="store_true",
                        help="give messages with a header new stamps on this clock: the first "
                             "one's publish time, the others their recorded spacing from it "
                             "(divided by --rate); default: the recorded stamps")


def _rclpy():
    try:
        import rclpy
    except Exception as exc:  # ImportError, or the wheels failing to load their RMW
        raise VmRosError(f"vm-ros replay needs rclpy (pip install 'vm_ros[ros]' in a venv, or a "
                         f"sourced ROS 2 install): {type(exc).__name__}: {exc}") from exc
    return rclpy


def message_class(type_name: str):
    """The rclpy message class of ``pkg/msg/Type``."""
    package, _, name = type_name.split("/")
    try:
        return getattr(importlib.import_module(f"{package}.msg"), name)
    except (ImportError, AttributeError) as exc:
        raise VmRosError(f"message type {type_name} is not installed: {exc}") from exc


def _qos(channel_metadata: dict):
    """The offered reliability and durability of a channel, as an rclpy QoSProfile."""
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

    profile = QoSProfile(depth=100)
    try:
        offered = yaml.safe_load(channel_metadata.get("offered_qos_profiles") or "") or []
    except yaml.YAMLError:
        offered = []
    if offered and isinstance(offered[0], dict):
        if offered[0].get("reliability") == "best_effort":
            profile.reliability = ReliabilityPolicy.BEST_EFFORT
        if offered[0].get("durability") == "transient_local":
            profile.durability = DurabilityPolicy.TRANSIENT_LOCAL
    return profile


def wait_for_subscribers(publishers, timeout_s: float, settle_s: float = 1.0) -> bool:
    """True once every publisher has matched a subscription (then ``settle_s`` more, for the
    subscription to match back: a reliable message published before the subscriber has matched
    the publisher is lost; 0.2 s lost the first message now and then on a loaded 2-core
    machine), False after ``timeout_s``."""
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        if all(p.get_subscription_count() > 0 for p in publishers):
            time.sleep(settle_s)
            return True
        time.sleep(0.02)
    return False


def has_header(message_type) -> bool:
    """Whether an rclpy message class's first field is a std_msgs/Header."""
    fields = iter(message_type.get_fields_and_field_types().items())
    return next(fields, None) == ("header", "std_msgs/Header")


def not_replayable(channel: ChannelInfo) -> str | None:
    """Why a channel cannot be republished (None when it can)."""
    if channel.encoding != MESSAGE_ENCODING:
        return f"message encoding {channel.encoding!r}, not {MESSAGE_ENCODING}"
    try:
        type_name = full_type_name(channel.type_name)
    except ValueError:
        return f"schema name {channel.type_name!r} is not pkg/msg/Type"
    if is_offline_type(type_name):
        return f"offline-only type {type_name}"
    return None


def select_topics(log: Path, requested: str | None) -> dict:
    """``{topic: ChannelInfo}`` of the channels to publish. Raises VmRosError (one line) when
    a requested topic is missing or cannot be published, or nothing can be."""
    channels = log_channels(log)
    note = unlisted_note(log)
    if note:
        print(f"vm-ros replay: {note}", file=sys.stderr)
    if requested:
        names = [resolve_topic(t.strip()) for t in requested.split(",") if t.strip()]
        unknown = [t for t in names if t not in channels]
        if unknown:
            raise VmRosError(f"{log}: no topic {unknown[0]} (have: {', '.join(sorted(channels))})")
        channels = {t: channels[t] for t in names}
    reasons = {t: not_replayable(c) for t, c in channels.items()}
    skipped = ", ".join(f"{t} ({why})" for t, why in reasons.items() if why)
    if requested and skipped:
        raise VmRosError(f"{log}: cannot replay {skipped}")
    selected = {t: c for t, c in channels.items() if not reasons[t]}
    if not selected:
        raise VmRosError(f"{log}: nothing to replay" + (f": {skipped}" if skipped else ""))
    if skipped:
        print(f"vm-ros replay: skipping {skipped}", file=sys.stderr)
    return selected


@dataclass
class _Cause:
    """Undecodable messages with one cause: count per topic, and the first (topic, log time)."""

    topics: Counter = field(default_factory=Counter)
    first: tuple[str, int] | None = None


class DecodeCheck:
    """Whether recorded bytes deserialise as their type, as a subscriber would (rclpy), and the
    failures counted by cause. The C typesupport prints some causes itself on the process's
    stderr (rosidl's "sequence size exceeds remaining buffer", once or twice per malformed
    message, and rclpy then raises "error not set"): file descriptor 2 is captured during each
    deserialisation, and that text, else the exception's, is the cause. ``lines()``: one line
    per cause with its counts per topic and the first occurrence; ``close()`` when done."""

    def __init__(self):
        self.causes: dict[str, _Cause] = {}
        self._capture = tempfile.TemporaryFile()  # noqa: SIM115 - closed by close()

    def close(self) -> None:
        self._capture.close()

    def __call__(self, topic: str, data: bytes, message_type, log_time_ns: int) -> bool:
        from rclpy.serialization import deserialize_message

        error = None
        sys.stderr.flush()
        saved = os.dup(2)
        os.dup2(self._capture.fileno(), 2)
        try:
            deserialize_message(data, message_type)
        except Exception as exc:  # malformed bytes: rclpy raises whatever its typesupport meets
            error = exc
        finally:
            os.dup2(saved, 2)
            os.close(saved)
        self._capture.seek(0)
        printed = self._capture.read().decode("utf-8", errors="replace")
        self._capture.seek(0)
        self._capture.truncate()
        if error is None:
            return True
        lines = dict.fromkeys(line.strip() for line in printed.splitlines() if line.strip())
        text = "; ".join(lines) or _LOCATION.sub("", str(error).strip().splitlines()[0]
                                                 if str(error).strip() else type(error).__name__)
        cause = self.causes.setdefault(text, _Cause())
        cause.topics[topic] += 1
        cause.first = cause.first or (topic, log_time_ns)
        return False

    def lines(self) -> list[str]:
        return [f"{skipped_line(dict(c.topics))}: {text} (first: {c.first[0]} at log time "
                f"{c.first[1] * 1e-9:.9f} s)" for text, c in self.causes.items()]


def run(args) -> int:
    if not args.rate > 0:
        raise VmRosError(f"--rate must be > 0 (got {args.rate})")
    channels = select_topics(args.log, args.topics)
    if not channels:
        raise VmRosError(f"{args.log}: nothing to replay")
    rclpy = _rclpy()
    from rclpy.duration import Duration

    rclpy.init(args=None)
    node = rclpy.create_node(NODE_NAME)
    count = 0
    check = DecodeCheck()
    publishers = {}
    try:
        types = {topic: message_class(full_type_name(c.type_name))
                 for topic, c in channels.items()}
        publishers = {topic: node.create_publisher(types[topic], topic, _qos(c.metadata))
                      for topic, c in channels.items()}
        restamp = Restamper(args.rate) if args.restamp else None
        stamped = {topic for topic, kind in types.items() if has_header(kind)}
        node.get_logger().info(f"replaying {args.log} ({', '.join(publishers)}) at "
                               f"x{args.rate:g}{', looping' if args.loop else ''}"
                               f"{', restamped' if restamp is not None else ''}")
        if args.wait > 0 and not wait_for_subscribers(publishers.values(), args.wait):
            node.get_logger().warning(f"not every topic has a subscriber after {args.wait:g} s")
        for message, due in replay(args.log, topics=set(publishers), rate=args.rate,
                                   loop=args.loop, with_due=True):
            data = bytes(message.data)
            if restamp is not None and message.topic in stamped and len(data) >= 12:
                late_ns = round((time.monotonic() - due) * 1e9)   # replay's clock: monotonic
                data = restamp(data, node.get_clock().now().nanoseconds, late_ns)
            if not check(message.topic, data, types[message.topic], message.log_time_ns):
                continue
            publishers[message.topic].publish(data)
            count += 1
    except KeyboardInterrupt:
        pass
    finally:
        # a reliable message not yet acknowledged when its publisher is destroyed is lost (the
        # last of a replay, now and then on a loaded machine): wait for them, at most ACK_WAIT_S
        if rclpy.ok():
            for publisher in publishers.values():
                publisher.wait_for_all_acked(Duration(seconds=ACK_WAIT_S))
        node.destroy_node()
        rclpy.try_shutdown()
        check.close()
    print(f"replayed {count} messages")
    for line in check.lines():
        print(f"vm-ros replay: {line}", file=sys.stderr)
    return 0
