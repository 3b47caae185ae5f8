"""One channel of a log decoded into arrays (TopicSeries), as read_run returns them.

JointState arrays are mapped by muscle name onto the run's muscle columns (NaN where a message
has no value for a muscle), or, for joint topics (joint_states, joint_efforts), by joint name onto
the joints in the order they first appear (``grow_columns``: a message may name some joints
only), Float64MultiArray and Float64 become (k, m) and (k,) arrays,
vm_ros/msg/MuscleTelemetry one array per field; other types keep their decoded messages.

A message that does not decode (malformed bytes, which any DDS peer can send and muscle_node
records as received; a type vm_ros has no definition of; an encoding other than CDR) is left out
of the series and counted in SkippedMessages; ``skipped_line`` says so in one line.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from vm_ros import telemetry as tm
from vm_ros.recording import bulk
from vm_ros.recording.cdr import decoder
from vm_ros.recording.message_types import UnknownMessageTypeError
from vm_ros.recording.messages import TYPE_MUSCLE_TELEMETRY
from vm_ros.recording.schema import MESSAGE_ENCODING


@dataclass
class TopicSeries:
    """One channel decoded into arrays (first axis: message).

    | attribute | meaning |
    | topic, type_name | channel |
    | time_ns | (k,) log times, ns |
    | fields | name -> array (k,) or (k, m); JointState arrays are mapped by name onto the run's
      muscles, or the joints for joint topics (NaN where a message had no value); ``stamp_ns``
      from the header when there is one |
    | names | column labels of per-muscle (per-joint) fields, or None |
    | layout | Float64MultiArray dims of the first message ([{label, size, stride}]) |
    | raw | recorded CDR bytes per message (only when asked for) |
    | messages | decoded messages (only for types without an array form, e.g. diagnostics) |
    """

    topic: str
    type_name: str
    time_ns: np.ndarray
    fields: dict
    names: tuple | None = None
    layout: list | None = None
    raw: list | None = None
    messages: list | None = None

    def __len__(self) -> int:
        return len(self.time_ns)

    @property
    def time_s(self) -> np.ndarray:
        return self.time_ns * 1e-9


@dataclass
class SkippedMessages:
    """The messages of one topic that did not decode, left out of its series.

    | field | meaning |
    | count | how many |
    | reason | why the first one did not decode |
    | raw | ``(position, log_time_ns, bytes)`` of each when the topic's bytes were kept, else
      None; position: how many messages of the topic before it did decode (their index in the
      series), so that it can be put back in file order |
    """

    count: int = 0
    reason: str = ""
    raw: list | None = None


def skipped_line(skipped: Mapping[str, SkippedMessages | int]) -> str | None:
    """One line saying what was skipped, per topic (None when nothing was), e.g.
    ``skipped 1 undecodable message on /excitation (UnicodeDecodeError)``. ``skipped``: topic ->
    SkippedMessages, or a count."""
    parts = []
    for topic, entry in sorted(skipped.items()):
        count, reason = (entry, "") if isinstance(entry, int) else (entry.count, entry.reason)
        if count:
            parts.append((count, f"on {topic}" + (f" ({reason})" if reason else "")))
    if not parts:
        return None
    total = sum(count for count, _ in parts)
    noun = "message" if total == 1 else "messages"
    if len(parts) == 1:
        return f"skipped {total} undecodable {noun} {parts[0][1]}"
    return f"skipped {total} undecodable {noun}: " + ", ".join(f"{c} {where}"
                                                               for c, where in parts)


def _type_problem(type_name: str, encoding: str):
    """(decoding function, None), or (None, why no message of this channel can be decoded)."""
    if encoding != MESSAGE_ENCODING:
        return None, f"message encoding {encoding!r}, not {MESSAGE_ENCODING}"
    if not type_name:
        return None, "the channel has no schema"
    try:
        return decoder(type_name), None
    except UnknownMessageTypeError:
        return None, f"no bundled definition of {type_name}"
    except ValueError:
        return None, f"schema name {type_name!r} is not pkg/msg/Type"


class SeriesBuilder:
    """Accumulates one channel's messages (CDR) and builds its TopicSeries; the messages that
    do not decode go to ``skipped`` instead. JointState values go onto ``columns`` by name; with
    ``grow_columns`` (and no columns) each new name adds a column (earlier rows NaN there).

    JointState messages laid out as the first one (same names and array lengths, told apart by
    their length and constant bytes, compared as arrays over a batch: add_many) are not decoded
    one by one: build() reads their values at once from their bytes. Every other message is
    decoded by itself (a "decoded row")."""

    def __init__(self, topic: str, type_name: str, columns: tuple | None, keep_raw: bool,
                 encoding: str = MESSAGE_ENCODING, grow_columns: bool = False):
        self.topic, self.type_name = topic, type_name
        self.grow = grow_columns and not columns
        self.columns = [] if self.grow else columns
        self.index = {name: i for i, name in enumerate(columns or ())}
        self._count = 0
        self._times: list[np.ndarray] = []  # log times, in parts
        self._decoded: list[int] = []  # which messages are decoded rows
        self.rows: dict[str, list] = {}  # field -> values of the decoded rows (None: none)
        self.raw = [] if keep_raw else None
        self.messages: list | None = None
        self.layout = None
        self.names = None
        self.skipped = SkippedMessages(raw=[] if keep_raw else None)
        self._decode, self._problem = _type_problem(type_name, encoding)
        # (layout, constant byte ranges, column of each name) of the first JointState, and
        # the messages laid out so: (message indices, their records)
        self._fixed = None
        self._fixed_parts: list[tuple[np.ndarray, np.ndarray]] = []

    def __len__(self) -> int:
        """Messages decoded so far."""
        return self._count

    def add(self, data: bytes, log_time_ns: int) -> bool:
        """Decode one message into the series; False (and counted in ``skipped``) when its
        bytes do not decode."""
        if self._fixed is not None and self._matches_fixed(data):
            self._add_fixed([data], np.array([log_time_ns], dtype=np.int64))
            return True
        problem = self._problem
        if problem is None:
            try:
                msg = self._decode(data)
            except Exception as exc:  # malformed bytes: struct.error, UnicodeDecodeError...
                problem = type(exc).__name__
        if problem is not None:
            skipped = self.skipped
            skipped.count += 1
            skipped.reason = skipped.reason or problem
            if skipped.raw is not None:
                skipped.raw.append((self._count, log_time_ns, data))
            return False
        row = self._row(msg)
        if row is None:
            if self.messages is None:
                self.messages = []
            self.messages.append(msg)
        else:
            for key, value in row.items():
                if key not in self.rows:  # a field first seen now: earlier rows lack it
                    self.rows[key] = [None] * len(self._decoded)
                self.rows[key].append(value)
            self._decoded.append(self._count)
            for values in self.rows.values():
                if len(values) < len(self._decoded):  # a field this row lacks
                    values.append(None)
        self._times.append(np.array([log_time_ns], dtype=np.int64))
        self._count += 1
        if self.raw is not None:
            self.raw.append(data)
        return True

    def add_many(self, data: list, log_time_ns) -> None:
        """add() for each message, in order; the messages laid out as the first JointState are
        recognised as arrays (their lengths and constant bytes), not one by one."""
        times = np.asarray(log_time_ns, dtype=np.int64)
        i = 0
        while i < len(data) and self._fixed is None:
            self.add(data[i], int(times[i]))
            i += 1
        if i == len(data):
            return
        data, times = data[i:], times[i:]
        layout, constant, _ = self._fixed
        lengths = np.fromiter(map(len, data), dtype=np.int64, count=len(data))
        candidates = np.flatnonzero(lengths == layout.size)
        matches = np.zeros(len(data), dtype=bool)
        if len(candidates):
            cells = np.frombuffer(b"".join([data[j] for j in candidates.tolist()]),
                                  dtype=np.uint8).reshape(len(candidates), layout.size)
            same = np.ones(len(candidates), dtype=bool)
            for begin, end, part in constant:
                same &= (cells[:, begin:end] == np.frombuffer(part, dtype=np.uint8)).all(axis=1)
            matches[candidates[same]] = True
        done = 0
        for j in [*np.flatnonzero(~matches).tolist(), len(data)]:
            if j > done:
                self._add_fixed(data[done:j], times[done:j])
            if j < len(data):
                self.add(data[j], int(times[j]))
            done = j + 1

    def _add_fixed(self, data: list, times: np.ndarray) -> None:
        """Messages known to be laid out as the first JointState: kept as records."""
        layout = self._fixed[0]
        records = np.frombuffer(b"".join(data), dtype=layout.dtype)
        self._fixed_parts.append((self._count + np.arange(len(data)), records))
        self._times.append(times)
        self._count += len(data)
        if self.raw is not None:
            self.raw.extend(data)

    def _by_name(self, names, values) -> np.ndarray:
        """Values of a JointState array on the columns (NaN where missing); name-less values
        as they are unless there is one per column."""
        values = np.asarray(values, dtype=float)
        if self.grow and names:
            for name in names:
                if name not in self.index:
                    self.index[name] = len(self.columns)
                    self.columns.append(name)
        if not self.columns:
            return values
        row = np.full(len(self.columns), np.nan)
        if names:
            for name, value in zip(names, values, strict=False):
                if name in self.index:
                    row[self.index[name]] = value
        elif len(values) == len(self.columns):
            row[:] = values
        return row

    def _row(self, msg) -> dict | None:
        if self.type_name == tm.TYPE_JOINT_STATE:
            row = {"stamp_ns": _stamp_ns(msg.header),
                   **{key: self._by_name(msg.name, getattr(msg, key))
                      for key in ("position", "velocity", "effort")}}
            self.names = tuple(self.columns or msg.name)
            if self._fixed is None:
                self._learn_fixed(msg)
            return row
        if self.type_name == tm.TYPE_FLOAT64_MULTI_ARRAY:
            if self.layout is None:
                self.layout = [{"label": d.label, "size": d.size, "stride": d.stride}
                               for d in msg.layout.dim]
            return {"data": np.asarray(msg.data, dtype=float)}
        if self.type_name == tm.TYPE_FLOAT64:
            return {"data": float(msg.data)}
        if self.type_name == TYPE_MUSCLE_TELEMETRY:
            self.names = tuple(msg.name)
            row = {"stamp_ns": _stamp_ns(msg.header)}
            for key in msg.__slots__:
                value = getattr(msg, key)
                if isinstance(value, float):
                    row[key] = value
                elif isinstance(value, list) and key != "name":
                    row[key] = np.asarray(value, dtype=float)
            return row
        return None

    def _learn_fixed(self, msg) -> None:
        """The layout of JointState messages like ``msg`` (unique names, each array empty or
        one value per name, empty frame_id), when their names all have columns (or there are
        none)."""
        names = list(msg.name)
        counts = [len(getattr(msg, key)) for key in _JOINT_ARRAYS]
        if (not names or len(set(names)) != len(names) or msg.header.frame_id
                or any(c not in (0, len(names)) for c in counts)):
            return
        if self.columns and not all(name in self.index for name in names):
            return
        layout = bulk.joint_state_layout(names, *counts)
        constant, begin = [], 0
        for _, _, offset, size in sorted((*_offsets(layout), ("", 0, layout.size, 0)),
                                         key=lambda f: f[2]):
            if offset > begin:
                constant.append((begin, offset, layout.template[begin:offset].tobytes()))
            begin = offset + size
        columns = [self.index[name] for name in names] if self.columns else None
        self._fixed = (layout, constant, columns)

    def _matches_fixed(self, data: bytes) -> bool:
        layout, constant, _ = self._fixed
        return len(data) == layout.size and all(data[a:b] == part for a, b, part in constant)

    def _fixed_values(self) -> tuple[np.ndarray, dict]:
        """(message indices, field -> values) of the messages kept as records, as _row would
        give them."""
        layout, _, columns = self._fixed
        index = np.concatenate([rows for rows, _ in self._fixed_parts])
        records = np.concatenate([part for _, part in self._fixed_parts])
        values = {"stamp_ns": records["sec"].astype(np.int64) * 1_000_000_000
                  + records["nanosec"].astype(np.int64)}
        width = len(self.columns) if self.columns else None
        for key in _JOINT_ARRAYS:
            array = records[key] if key in layout.fields else None
            if width is None:
                values[key] = array if array is not None else np.zeros((len(records), 0))
                continue
            full = np.full((len(records), width), np.nan)
            if array is not None:
                full[:, columns] = array
            values[key] = full
        return index, values

    def _field(self, key: str, fixed_index, fixed: np.ndarray | None) -> np.ndarray:
        """One field over every message: the decoded rows' values and the records' as one
        array (_stack's result, built without a list per message when the rows agree)."""
        decoded = self.rows.get(key, [None] * len(self._decoded))
        if fixed is not None:
            if all(type(v) is int for v in decoded) and fixed.ndim == 1:
                out = np.empty(self._count, dtype=np.int64)
            elif all(isinstance(v, np.ndarray) and v.shape == fixed.shape[1:]
                     for v in decoded) and fixed.ndim == 2:
                out = np.empty((self._count, fixed.shape[1]))
            else:
                out = None
            if out is not None:
                out[fixed_index] = fixed
                if decoded:
                    out[self._decoded] = decoded
                return out
        values = [None] * self._count
        for i, value in zip(self._decoded, decoded, strict=True):
            values[i] = value
        if fixed is not None:
            for i, value in zip(fixed_index.tolist(), list(fixed), strict=True):
                values[i] = int(value) if fixed.ndim == 1 else value
        return _stack(values)

    def build(self) -> TopicSeries:
        fixed_index, fixed = (self._fixed_values() if self._fixed_parts
                              else (np.zeros(0, dtype=np.int64), {}))
        fields = {key: self._field(key, fixed_index, fixed.get(key))
                  for key in dict.fromkeys([*self.rows, *fixed])}
        times = (np.concatenate(self._times) if self._times else np.zeros(0, dtype=np.int64))
        return TopicSeries(self.topic, self.type_name, times, fields, self.names, self.layout,
                           self.raw, self.messages)


_JOINT_ARRAYS = ("position", "velocity", "effort")


def _offsets(layout) -> list:
    """(name, dtype, offset, size in bytes) of each variable field of a bulk layout."""
    found = []
    for name, (dtype, shape, offset) in layout.fields.items():
        size = np.dtype(dtype).itemsize * (shape[0] if shape else 1)
        found.append((name, dtype, offset, size))
    return found


def _stamp_ns(header) -> int:
    return int(header.stamp.sec) * 1_000_000_000 + int(header.stamp.nanosec)


def _stack(values: list) -> np.ndarray:
    """Rows (scalars or 1-D arrays, possibly of different lengths or missing) as one array.
    Integers present in every row (header stamps in ns) stay int64: as float64 they would be
    rounded to about 256 ns at today's epoch."""
    kinds = set(map(type, values))
    if kinds == {int}:
        return np.array(values, dtype=np.int64)
    if kinds == {np.ndarray} and len({v.shape for v in values}) == 1 and values[0].ndim == 1:
        return np.array(values, dtype=float)  # rows of one width (the common case)
    if all(np.ndim(v) == 0 for v in values if v is not None):
        return np.array([np.nan if v is None else v for v in values], dtype=float)
    width = max(np.size(v) for v in values if v is not None)
    out = np.full((len(values), width), np.nan)
    for i, v in enumerate(values):
        if v is not None:
            out[i, : np.size(v)] = v
    return out
