"""CDR bytes of many messages of one fixed layout at once, from arrays (no dict per message).

    layout = joint_state_layout(names, position=n, velocity=n)
    messages = layout.encode(stamp_ns=times, position=lengths, velocity=speeds)   # list[bytes]

A message whose strings and array lengths are the same in every message (the names of the
bank's muscles, n values per array) has the same bytes everywhere except the stamp and the
float64 values, at fixed offsets. The layout is built once by writing a template message with
the CDR rules (little endian, encapsulation header ``00 01 00 00``, each primitive aligned to its
size counted from the end of the header, a sequence prefixed by its uint32 length, a string by
its length including the terminating NUL, padding bytes zero); ``encode`` fills a structured
array whose fields sit at those offsets and cuts its bytes into messages. The bytes equal those
of vm_ros.recording.cdr.serialize for the same values (test/test_recording_bulk.py).
"""

from __future__ import annotations

import struct

import numpy as np

from vm_ros import telemetry as tm

_ENCAPSULATION = b"\x00\x01\x00\x00"  # CDR, little endian


class _Template:
    """Writes one message with the CDR rules and notes where the variable values go."""

    def __init__(self):
        self.data = bytearray(_ENCAPSULATION)
        # name -> (dtype, shape: () for a primitive or (count,) for a sequence, offset)
        self.fields: dict[str, tuple[str, tuple, int]] = {}

    def _align(self, size: int) -> None:
        self.data += bytes(-(len(self.data) - len(_ENCAPSULATION)) % size)

    def uint32(self, value: int) -> None:
        self._align(4)
        self.data += struct.pack("<I", value)

    def slot(self, name: str, dtype: str, size: int) -> None:
        """A primitive filled per message (stamp seconds, nanoseconds, a float64 scalar)."""
        self._align(size)
        self.fields[name] = (dtype, (), len(self.data))
        self.data += bytes(size)

    def string(self, text: str) -> None:
        encoded = text.encode()
        self.uint32(len(encoded) + 1)
        self.data += encoded + b"\x00"

    def strings(self, texts) -> None:
        self.uint32(len(texts))
        for text in texts:
            self.string(text)

    def float64s(self, name: str, count: int) -> None:
        """A float64[] of ``count`` values filled per message (none: an empty sequence)."""
        self.uint32(count)
        if count:
            self._align(8)
            self.fields[name] = ("<f8", (count,), len(self.data))
            self.data += bytes(8 * count)

    def header(self, frame_id: str = "") -> None:
        self.slot("sec", "<i4", 4)
        self.slot("nanosec", "<u4", 4)
        self.string(frame_id)


class FixedLayout:
    """The CDR layout of messages of one type with fixed strings and array lengths.

    ``encode(stamp_ns=..., **values)`` takes, per float64 field, an array whose first axis is the
    message and whose other axes flatten (C order) to the field's length, and the header stamps
    (k,) in integer ns when the type has a header; it returns the k messages' bytes.
    """

    def __init__(self, template: _Template):
        self.template = np.frombuffer(bytes(template.data), dtype=np.uint8)
        self.size = len(template.data)
        self.fields = dict(template.fields)
        self.dtype = np.dtype({
            "names": list(self.fields),
            "formats": [(dt, shape) if shape else dt for dt, shape, _ in self.fields.values()],
            "offsets": [offset for _, _, offset in self.fields.values()],
            "itemsize": self.size,
        })

    @property
    def value_fields(self) -> tuple:
        return tuple(name for name in self.fields if name not in ("sec", "nanosec"))

    def encode_one(self, stamp_ns=None, **values) -> bytes:
        """One message's bytes (values without the leading message axis), through a record
        kept for the purpose: the template's bytes stay in place, only the stamp and values
        are written (a node publishing every period)."""
        record = self.__dict__.get("_one")
        if record is None:
            record = self._one = np.frombuffer(bytearray(self.template.tobytes()),
                                               dtype=self.dtype)
        if "sec" in self.fields:
            record["sec"] = stamp_ns // 1_000_000_000
            record["nanosec"] = stamp_ns % 1_000_000_000
        for name in self.value_fields:
            record[name] = np.asarray(values[name], dtype=float).reshape(self.fields[name][1])
        return record.tobytes()

    def encode(self, stamp_ns=None, **values) -> list[bytes]:
        k = _count(stamp_ns, values)
        records = np.empty(k, dtype=self.dtype)
        records.view(np.uint8).reshape(k, self.size)[:] = self.template
        if "sec" in self.fields:
            stamp = np.asarray(stamp_ns, dtype=np.int64)
            records["sec"] = stamp // 1_000_000_000
            records["nanosec"] = stamp % 1_000_000_000
        for name in self.value_fields:
            shape = self.fields[name][1]
            records[name] = np.asarray(values[name], dtype=float).reshape((k, *shape))
        return records.view(np.dtype((np.void, self.size))).tolist()  # bytes, one per message


def _count(stamp_ns, values) -> int:
    if stamp_ns is not None:
        return len(stamp_ns)
    return len(next(iter(values.values())))


def joint_state_layout(names, position: int = 0, velocity: int = 0,
                       effort: int = 0) -> FixedLayout:
    """sensor_msgs/JointState with ``names`` and that many position, velocity, effort values."""
    t = _Template()
    t.header()
    t.strings(list(names))
    t.float64s("position", position)
    t.float64s("velocity", velocity)
    t.float64s("effort", effort)
    return FixedLayout(t)


def multi_array_layout(dims: list[dict], count: int, data_offset: int = 0) -> FixedLayout:
    """std_msgs/Float64MultiArray with layout ``dims`` ({label, size, stride}) and ``count``
    data values (field ``data``)."""
    t = _Template()
    t.uint32(len(dims))
    for dim in dims:
        t.string(dim["label"])
        t.uint32(int(dim["size"]))
        t.uint32(int(dim["stride"]))
    t.uint32(data_offset)
    t.float64s("data", count)
    return FixedLayout(t)


def float64_layout() -> FixedLayout:
    """std_msgs/Float64 (field ``data``)."""
    t = _Template()
    t.slot("data", "<f8", 8)
    return FixedLayout(t)


class OutputLayouts:
    """The CDR layouts of the published muscle topics (muscle_force, energy_rate,
    energy_rate_total, energy_total, and energy_rate_models with ``models``) for the bank's
    muscles, built once: muscle_node encodes one step at a time (``encode``), offline runs
    many (vm_ros.offline.runner)."""

    def __init__(self, names, models=()):
        n = len(names)
        self.names = tuple(names)
        self.force = joint_state_layout(names, n, n, n)
        self.energy_rate = multi_array_layout(
            tm.energy_rate_layout(n), n * len(tm.FIBRE_LABELS) * len(tm.COMPONENT_LABELS))
        self.float64 = float64_layout()
        self.models = (multi_array_layout(
            tm.energy_rate_models_layout(names, models),
            n * len(models) * len(tm.MODEL_COMPONENT_LABELS)) if models else None)

    def _topics(self, position, velocity, effort, energy_rate, rate_total, energy_total,
                models) -> list:
        """(topic, layout, values) of each published muscle topic, in publishing order: the one
        place that says which output goes into which message."""
        topics = [
            (tm.TOPIC_FORCE, self.force,
             {"position": position, "velocity": velocity, "effort": effort}),
            (tm.TOPIC_ENERGY_RATE, self.energy_rate, {"data": energy_rate}),
            (tm.TOPIC_ENERGY_RATE_TOTAL, self.float64, {"data": rate_total}),
            (tm.TOPIC_ENERGY_TOTAL, self.float64, {"data": energy_total}),
        ]
        if self.models is not None:
            topics.append((tm.TOPIC_ENERGY_RATE_MODELS, self.models, {"data": models}))
        return topics

    def encode(self, out, stamp_ns: int, energy_offset_j: float = 0.0) -> list:
        """[(topic, bytes)] of ``out``, the force message stamped ``stamp_ns``; energy_total
        adds ``energy_offset_j`` (energy before a model reset)."""
        topics = self._topics(out.fascicle_length, out.fascicle_velocity, out.force,
                              tm.energy_rate_array(out), out.total_energy_rate,
                              energy_offset_j + out.total_energy,
                              out.energy_rate_models if self.models is not None else None)
        return [(topic, layout.encode_one(stamp_ns, **values))
                for topic, layout, values in topics]

    def encode_many(self, stamps_ns, position, velocity, effort, energy_rate, rate_total,
                    energy_total, models=None) -> list:
        """[(topic, [bytes] per step)] of k published steps, the arrays with a leading step
        axis (energy_rate as telemetry.energy_rate_rows gives it)."""
        topics = self._topics(position, velocity, effort, energy_rate, rate_total, energy_total,
                              models)
        return [(topic, layout.encode(stamps_ns, **values)) for topic, layout, values in topics]


class JointLayouts:
    """The CDR layouts of the joint topics for the joints ``names`` (joint_efforts: JointState
    with position, velocity and effort per joint; joint_effort_commands and joint_work:
    Float64MultiArray of telemetry.joint_array_layout), built once: muscle_node encodes one step
    at a time (``encode``), offline runs many (vm_ros.offline.runner). The bytes are those of
    telemetry.joint_efforts_fields, joint_effort_commands_fields and joint_work_fields."""

    def __init__(self, names):
        n = len(names)
        self.names = tuple(names)
        self.state = joint_state_layout(names, n, n, n)
        self.array = multi_array_layout(tm.joint_array_layout(n), n)

    def encode(self, efforts, stamp_ns: int) -> list:
        """[(topic, bytes)] of joint_efforts (stamped ``stamp_ns``) and joint_effort_commands of
        one vm_ros.joint_space.JointEfforts, whose names are ``names``."""
        return [(tm.TOPIC_JOINT_EFFORTS,
                 self.state.encode_one(stamp_ns, position=efforts.position,
                                       velocity=efforts.velocity, effort=efforts.effort)),
                (tm.TOPIC_JOINT_EFFORT_COMMANDS, self.array.encode_one(data=efforts.effort))]


# vm_ros/msg/MuscleTelemetry arrays in message order, with their length per muscle
TELEMETRY_ARRAYS = (
    ("excitation", 1), ("path_length", 1), ("path_velocity", 1), ("effective_drive", 1),
    ("force", 1), ("contractile_force", 1), ("fascicle_length", 1), ("fascicle_velocity", 1),
    ("mechanical_power", 1), ("mechanical_work", 1), ("firing_rate", 2),
    ("recruited_fraction", 2), ("effective_activation", 2),
    ("energy_rate", len(tm.FIBRE_LABELS) * len(tm.COMPONENT_LABELS)),
    ("energy", len(tm.FIBRE_LABELS) * len(tm.COMPONENT_LABELS)),
)


def telemetry_layout(names) -> FixedLayout:
    """vm_ros/msg/MuscleTelemetry for the muscles ``names`` (msg_defs/MuscleTelemetry.msg)."""
    t = _Template()
    t.header()
    t.strings(list(names))
    for name, per_muscle in TELEMETRY_ARRAYS:
        t.float64s(name, per_muscle * len(names))
    t.slot("total_energy_rate", "<f8", 8)
    t.slot("total_energy", "<f8", 8)
    return FixedLayout(t)
