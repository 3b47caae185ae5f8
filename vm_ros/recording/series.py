"""One channel of a log decoded into arrays (TopicSeries), as read_run returns them.

JointState arrays are mapped by muscle name onto the run's muscle columns (NaN where a message
has no value for a muscle), Float64MultiArray and Float64 become (k, m) and (k,) arrays,
vm_ros/msg/MuscleTelemetry one array per field; other types keep their decoded messages.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vm_ros import telemetry as tm
from vm_ros.recording.cdr import deserialize
from vm_ros.recording.messages import TYPE_MUSCLE_TELEMETRY


@dataclass
class TopicSeries:
    """One channel decoded into arrays (first axis: message).

    | attribute | meaning |
    | topic, type_name | channel |
    | time_ns | (k,) log times, ns |
    | fields | name -> array (k,) or (k, m); JointState arrays are mapped by name onto the run's
      muscles (NaN where a message had no value); ``stamp_ns`` from the header when there is one |
    | names | column labels of per-muscle fields (the run's muscles), or None |
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


class SeriesBuilder:
    """Accumulates one channel's messages (CDR) and builds its TopicSeries."""

    def __init__(self, topic: str, type_name: str, columns: tuple | None, keep_raw: bool):
        self.topic, self.type_name = topic, type_name
        self.columns = columns
        self.index = {name: i for i, name in enumerate(columns or ())}
        self.times: list[int] = []
        self.rows: dict[str, list] = {}
        self.raw = [] if keep_raw else None
        self.messages: list | None = None
        self.layout = None
        self.names = None

    def add(self, data: bytes, log_time_ns: int) -> None:
        msg = deserialize(self.type_name, data)
        row = self._row(msg)
        if row is None:
            if self.messages is None:
                self.messages = []
            self.messages.append(msg)
        else:
            for key, value in row.items():
                if key not in self.rows:  # a field first seen now: earlier rows lack it
                    self.rows[key] = [None] * len(self.times)
                self.rows[key].append(value)
        self.times.append(log_time_ns)
        if self.raw is not None:
            self.raw.append(data)

    def _by_name(self, names, values) -> np.ndarray:
        """Values of a JointState array on the run's muscle columns (NaN where missing)."""
        values = np.asarray(values, dtype=float)
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
            self.names = self.columns or tuple(msg.name)
            return {"stamp_ns": _stamp_ns(msg.header),
                    **{key: self._by_name(msg.name, getattr(msg, key))
                       for key in ("position", "velocity", "effort")}}
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

    def build(self) -> TopicSeries:
        count = len(self.times)
        fields = {key: _stack(values + [None] * (count - len(values)))
                  for key, values in self.rows.items()}
        return TopicSeries(self.topic, self.type_name, np.asarray(self.times, dtype=np.int64),
                           fields, self.names, self.layout, self.raw, self.messages)


def _stamp_ns(header) -> int:
    return int(header.stamp.sec) * 1_000_000_000 + int(header.stamp.nanosec)


def _stack(values: list) -> np.ndarray:
    """Rows (scalars or 1-D arrays, possibly of different lengths or missing) as one array."""
    if all(np.ndim(v) == 0 for v in values if v is not None):
        return np.array([np.nan if v is None else v for v in values], dtype=float)
    width = max(np.size(v) for v in values if v is not None)
    out = np.full((len(values), width), np.nan)
    for i, v in enumerate(values):
        if v is not None:
            out[i, : np.size(v)] = v
    return out
