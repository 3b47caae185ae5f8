"""muscle_node's health bookkeeping: input issues, throttled reporting, step-time statistics
(no rclpy here; vm_ros.node turns these into log lines and /diagnostics).

Every bad input or timing event is an :class:`Issue` of one of the kinds in :data:`ISSUE_KINDS`,
each with its diagnostics label and its documented behaviour. :class:`IssueLog` counts them and
decides when a log line is due (at most one per kind per ``throttle_s``, carrying the number
suppressed meanwhile). rclpy's own ``throttle_duration_sec`` is not used: in rclpy 7.1.6 every
logging call, suppressed or not, inspects the caller's source (docs/performance.md), which a
burst of bad messages would turn into seconds of stalled model time.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vm_ros.topics import lost_key

# kind -> (diagnostics key, behaviour). The README's bad-input table is this table.
ISSUE_KINDS = {
    "wrong_size": ("rejected: wrong size (messages)",
                   "message dropped: name/position/velocity sizes differ, or an unnamed array is "
                   "not one value per muscle"),
    "non_finite": ("rejected: NaN or inf (messages)",
                   "message dropped: a value for a known muscle is NaN or inf"),
    "duplicate_name": ("rejected: duplicate name (messages)",
                       "message dropped: a muscle is named twice"),
    "non_physical_length": ("rejected: non-physical length (messages)",
                            "message dropped: a path length lies outside the muscle's physical "
                            "range (library range widened by path_length_margin_l0, for a "
                            "joint-driven muscle also by its geometry's range; never below 1 mm)"),
    "non_physical_velocity": ("rejected: non-physical velocity (messages)",
                              "message dropped: |path velocity| > path_speed_max_m_per_s"),
    "undecodable": ("rejected: undecodable (messages)",
                    "message dropped: the bytes do not deserialize to the topic's type"),
    "unknown_name": ("ignored: unknown names",
                     "entries whose name is not in the muscles parameter are ignored, the rest "
                     "of the message is used (counted per name)"),
    "drive_clipped": ("clipped: drive outside [0, 1] (messages)",
                      "drive values clipped to [0, 1], the message is used"),
    "joint_wrong_size": ("rejected: joint_states wrong size (messages)",
                         "message dropped: name/position/velocity sizes differ, or an unnamed "
                         "message is not one position per joint of the joints parameter"),
    "joint_non_finite": ("rejected: joint_states NaN or inf (messages)",
                         "message dropped: a position or velocity of a known joint is NaN or "
                         "inf, or a coordinate overflows to inf (joint_map offset, extrapolation)"),
    "joint_duplicate_name": ("rejected: joint_states duplicate joint (messages)",
                             "message dropped: a joint is named twice"),
    "joint_unknown_name": ("ignored: joint_states unknown joints (entries)",
                           "entries whose joint is not a geometry coordinate (by joint_map or "
                           "its own name) are ignored, the rest of the message is used; logged "
                           "once per set of names, no WARN (joint_states often carries more "
                           "joints than the geometry)"),
    "joint_clamped": ("clamped: joint outside the geometry box (coordinates)",
                      "the coordinate is clamped to the geometry's valid box with velocity 0 "
                      "(paths are not extrapolated), the message is used"),
    "joint_driven_kinematics": ("ignored: muscle_kinematics for joint-driven muscles (entries)",
                                "entries for muscles whose path comes from joint_states through "
                                "the geometry are ignored (lengths stay consistent with the "
                                "moment arms), the rest of the message is used"),
    "target_wrong_size": ("rejected: effort targets wrong size (messages)",
                          "message dropped: joint names and efforts differ in number, an unnamed "
                          "array is not one effort per joint of joints, a trajectory has no "
                          "points or joint names, or its positions are not one per joint name "
                          "in every point (or in none)"),
    "target_non_finite": ("rejected: effort targets NaN or inf (messages)",
                          "message dropped: an effort or planned position of a known joint "
                          "is NaN or inf"),
    "target_duplicate_name": ("rejected: effort targets duplicate joint (messages)",
                              "message dropped: a joint is named twice"),
    "target_bad_time": ("rejected: effort trajectory times (messages)",
                        "message dropped: a point's time_from_start is negative or not "
                        "increasing"),
    "target_unknown_joint": ("ignored: effort targets unknown joints (entries)",
                             "entries whose joint is not in the joints parameter are ignored, "
                             "the rest of the message is used"),
    "plan_far_from_joints": ("counted: planned positions far from joint_states (periods)",
                             "at a publish period's solve a planned coordinate lies further than "
                             "coordination.plan_offset_max of its geometry box's width from the "
                             "latest joint sample: the plan is still moved by that offset to "
                             "start from the sample, and the period solved"),
    "stale_excitation": ("stale: excitation (events)",
                         "excitation older than input_timeout_s: stale_input_policy applies "
                         "(hold: drive held; zero_drive: drive 0; pause: model paused)"),
    "stale_kinematics": ("stale: kinematics (events)",
                         "kinematics older than input_timeout_s: length held, velocity 0 (with "
                         "stale_input_policy pause: model paused); a muscle given "
                         "initial_path_length_m is not stale before its first kinematics"),
    "input_lost": ("lost: input messages (publisher sequence gaps)",
                   "messages a publisher sent that never reached the node (a burst overflowed "
                   "the qos_depth queue): counted from gaps in each publisher's sequence numbers; "
                   "raise qos_depth for bursts"),
    "wrong_type_publisher": ("ignored: publishers of another message type (publishers)",
                             "a publisher on an input topic with another message type is never "
                             "matched, nothing of it arrives: each one counted once, its node "
                             "and type logged (the graph is checked every second)"),
    "time_backwards": ("time jumps backwards",
                       "ROS time went backwards (e.g. a simulator reset): model state kept, model "
                       "time base and input ages re-anchored at the new time"),
    "skipped_time": ("stalls beyond catch-up",
                     "more than max_catch_up_steps steps due: that many run, the rest of the "
                     "elapsed time is skipped (see 'skipped model time (s)')"),
    "model_reset": ("model resets",
                    "a model output was not finite: model reset to equilibrium at the current "
                    "path lengths, cumulative energy carried over"),
}


# Kinds that are expected in normal operation: counted, logged once per distinct text (at info
# level), and they do not make /diagnostics WARN.
QUIET_KINDS = frozenset({"joint_unknown_name"})
_QUIET_TEXTS_KEPT = 256


@dataclass(frozen=True)
class Issue:
    """One bad input or timing event; ``count`` > 1 for per-name kinds."""

    kind: str
    text: str
    count: int = 1
    behaviour: str | None = None  # the log line's behaviour text (None: ISSUE_KINDS')

    def __post_init__(self):
        if self.kind not in ISSUE_KINDS:
            raise ValueError(f"unknown issue kind {self.kind!r}")


class IssueLog:
    """Counters per issue kind, and at most one log line per kind per ``throttle_s``."""

    def __init__(self, throttle_s: float = 2.0):
        self.throttle_s = float(throttle_s)
        self.counts = dict.fromkeys(ISSUE_KINDS, 0)
        self._last_logged_s: dict[str, float] = {}
        self._suppressed = dict.fromkeys(ISSUE_KINDS, 0)
        self._quiet_texts: set[str] = set()

    def record(self, issue: Issue, now_s: float) -> str | None:
        """Count ``issue``; return the line to log now (None while throttled; for QUIET_KINDS,
        None once the same text was logged).

        ``now_s``: a steady clock (s), so that sim-time pauses do not silence the log.
        """
        self.counts[issue.kind] += issue.count
        behaviour = issue.behaviour or ISSUE_KINDS[issue.kind][1]
        if issue.kind in QUIET_KINDS:
            if issue.text in self._quiet_texts or len(self._quiet_texts) >= _QUIET_TEXTS_KEPT:
                return None
            self._quiet_texts.add(issue.text)
            return f"{issue.text}; {behaviour}"
        last = self._last_logged_s.get(issue.kind)
        if last is not None and now_s - last < self.throttle_s:
            self._suppressed[issue.kind] += 1
            return None
        suppressed, self._suppressed[issue.kind] = self._suppressed[issue.kind], 0
        self._last_logged_s[issue.kind] = now_s
        more = f" (+{suppressed} more in the last {self.throttle_s:g} s)" if suppressed else ""
        return f"{issue.text}{more}; {behaviour}"

    def total(self) -> int:
        return sum(self.counts.values())


class DurationWindow:
    """Durations (ns) collected over one diagnostics window: percentiles in ms."""

    def __init__(self, capacity: int = 16384):
        self._values = np.zeros(capacity, dtype=np.int64)
        self._n = 0  # samples seen this window (the ring keeps the last `capacity`)

    def add(self, duration_ns: int) -> None:
        self._values[self._n % self._values.size] = duration_ns
        self._n += 1

    @property
    def count(self) -> int:
        return self._n

    def percentiles_ms(self, qs=(50.0, 99.0, 100.0)) -> tuple:
        if self._n == 0:
            return tuple(float("nan") for _ in qs)
        values = self._values[: min(self._n, self._values.size)]
        return tuple(float(v) * 1e-6 for v in np.percentile(values, qs))

    def clear(self) -> None:
        self._n = 0


class SequenceGaps:
    """Messages lost between the publishers of one topic and the node, from the publication
    sequence number each message carries (rmw message info: 1, 2, 3... per publisher).

    A DDS reader hands on each publisher's messages in the order sent (reliable: in order;
    best effort: a message older than one already received is discarded, so it is lost to the
    node), so within one publisher only gaps mean loss. rclpy's message info gives no publisher
    id, so messages are assigned to publisher streams: a message continues the stream whose last
    number is the largest below its own (a gap of ``seq - last - 1`` lost); one with no such
    stream starts a new stream, lossless: a restarted publisher (its numbers start again at 1),
    a new one, or messages of several publishers arriving interleaved. Counting starts at a
    stream's first message: what a publisher sent before that (before the node matched it, or
    lost before anything of it arrived) is not counted. Exact for one publisher per topic; with
    several, a loss is counted on the nearest stream (a new publisher whose first number lies
    above another's last shows that difference as lost). The rmw's MESSAGE_LOST event is not
    used: rmw_fastrtps accepts it but never raised it for queue overflow (docs/performance.md).
    Header stamps are not a loss measure (publishers leave them
    0 or repeat them)."""

    def __init__(self, max_streams: int = 16):
        self.max_streams = max_streams
        self._last: list[int] = []  # last number per stream, most recently used last
        self.supported: bool | None = None  # None until a message arrived
        self.lost = 0

    def add(self, seq) -> int:
        """Record a message's publication sequence number; returns the messages lost before it
        (0 when the rmw gives no numbers: None, or 0 = RMW's 'unsupported')."""
        if not seq:
            self.supported = False
            return 0
        self.supported = True
        if self._last and self._last[-1] == seq - 1:  # the latest stream's next message
            self._last[-1] = seq
            return 0
        below = [i for i, last in enumerate(self._last) if last < seq]
        if not below:
            self._last.append(seq)
            del self._last[: max(0, len(self._last) - self.max_streams)]
            return 0
        i = max(below, key=self._last.__getitem__)
        lost = seq - self._last.pop(i) - 1
        self._last.append(seq)
        self.lost += lost
        return lost


def format_seconds(ns: int) -> str:
    """A duration in integer ns as exact seconds ('1000000.05', not '1e+06')."""
    sign = "-" if ns < 0 else ""
    whole, frac = divmod(abs(int(ns)), 1_000_000_000)
    return f"{sign}{whole}.{frac:09d}".rstrip("0").rstrip(".") or "0"


def format_value(value) -> str:
    """A diagnostics value: integers exact, floats with 12 significant digits (4 hid changes:
    1000000.05 s showed as 1e+06), None as 'never'."""
    if value is None:
        return "never"
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, (float, np.floating)):
        return "nan" if value != value else f"{float(value):.12g}"
    return str(value)


__all__ = ["ISSUE_KINDS", "QUIET_KINDS", "DurationWindow", "Issue", "IssueLog", "SequenceGaps",
           "format_seconds", "format_value", "lost_key"]
