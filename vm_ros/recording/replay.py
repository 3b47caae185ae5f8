"""Replay of a log's messages at the recorded pace, as a generator (no ROS here; the replay
verb publishes what it yields).

    for item in replay("run.mcap", topics={"/energy_rate"}, rate=2.0):
        publish(item.topic, item.type_name, item.data)

Messages come in file order (log-time order for vm_ros logs). The pace follows the log times:
item k is yielded (t_k - t_0) / rate after the first, on a monotonic clock; a message whose log
time is earlier than the previous one is yielded at once. ``Restamper`` gives replayed messages
new header stamps on the replay's clock (the replay verb's --restamp). Types this package
defines itself (vm_ros/msg/...) have no typesupport outside a colcon build and are skipped
unless asked for.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable, Iterator

from vm_ros.recording.cdr import header_stamp_ns, restamped
from vm_ros.recording.reader import LogReader, RecordedMessage

OFFLINE_PACKAGES = ("vm_ros",)


def is_offline_type(type_name: str) -> bool:
    return type_name.split("/")[0] in OFFLINE_PACKAGES


def recorded_messages(path, topics: Iterable[str] | None = None,
                      include_offline: bool = False) -> Iterator[RecordedMessage]:
    """The log's messages in file order; ``topics``: full topic names (None: all)."""
    wanted = None if topics is None else set(topics)
    for message in LogReader(path).messages(wanted):
        if include_offline or not is_offline_type(message.type_name):
            yield message


def paced(messages: Iterable[RecordedMessage], rate: float = 1.0,
          clock: Callable[[], float] = time.monotonic,
          sleep: Callable[[float], None] = time.sleep, with_due: bool = False) -> Iterator:
    """Yield each message when (its log time - the first's) / rate has elapsed on ``clock``;
    with ``with_due``, (message, due) pairs, due the time on ``clock`` it was due at (the
    replay verb restamps from it: a message yielded late is stamped at its due time)."""
    if not rate > 0:
        raise ValueError(f"rate must be > 0, got {rate}")
    origin_log = origin_clock = None
    for message in messages:
        if origin_log is None:
            origin_log, origin_clock = message.log_time_ns, clock()
        due = origin_clock + (message.log_time_ns - origin_log) * 1e-9 / rate
        delay = due - clock()
        if delay > 0:
            sleep(delay)
        yield (message, due) if with_due else message


def replay(path, topics: Iterable[str] | None = None, rate: float = 1.0, loop: bool = False,
           include_offline: bool = False, clock: Callable[[], float] = time.monotonic,
           sleep: Callable[[float], None] = time.sleep, with_due: bool = False) -> Iterator:
    """Paced messages of the log (``with_due``: with their due times, as :func:`paced`); with
    ``loop`` the log starts over after its end, forever."""
    while True:
        yield from paced(recorded_messages(path, topics, include_offline), rate, clock, sleep,
                         with_due)
        if not loop:
            return


class Restamper:
    """Header stamps moved onto the replay's clock: the first message restamped gets the time it
    was due at (``now_ns - late_ns``: ``late_ns`` how long after its due time it is published),
    each later one that time plus the distance of its recorded stamp from the first one's,
    divided by ``rate``, so that the stamps keep their recorded spacing; never later than
    ``now_ns``, so that no stamp lies ahead of its publication (stamps 0.35 ms ahead of their
    arrival made muscle_node place most of them at their arrival). Counting from the first
    message's due time rather than its publication keeps a first message published late (the
    process descheduled on a loaded machine) from stamping every later one at its publication.
    A message stamped 0 (not stamped) is left so. ``restamper(data, now_ns, late_ns=0)``: the
    CDR bytes of a message whose first field is a std_msgs/Header (ValueError otherwise)."""

    def __init__(self, rate: float = 1.0):
        if not rate > 0:
            raise ValueError(f"rate must be > 0, got {rate}")
        self.rate = rate
        self.origin: tuple[int, int] | None = None  # (recorded stamp, new stamp) of the first

    def __call__(self, data: bytes, now_ns: int, late_ns: int = 0) -> bytes:
        stamp = header_stamp_ns(data)
        if stamp == 0:
            return data
        if self.origin is None:
            self.origin = (stamp, int(now_ns) - max(int(late_ns), 0))
        recorded, new = self.origin
        return restamped(data, min(new + round((stamp - recorded) / self.rate), int(now_ns)))
