"""What a vm_ros run log holds, how to open one for writing and how to read one back.

Channels (topic names as the node resolves them, ``/`` + name in the root namespace):

| topic | type | recorded |
| excitation, excitation_array, muscle_kinematics | as in vm_ros.telemetry | inputs as received |
| muscle_force, energy_rate, energy_rate_total, energy_total | as in vm_ros.telemetry | outputs
  as published (same bytes) |
| muscle_telemetry | vm_ros/msg/MuscleTelemetry | per-step record, offline only |
| /diagnostics | diagnostic_msgs/msg/DiagnosticArray | node health (muscle_node only) |
| joint_states | as in vm_ros.telemetry | input as received (runs with a geometry) |
| joint_efforts, joint_effort_commands | as in vm_ros.telemetry | outputs as published (runs
  with a geometry) |
| energy_rate_models | as in vm_ros.telemetry | output at the publish rate (runs with
  energetics models) |

Metadata record ``vm_ros.run`` (RunInfo.to_metadata): muscles, recruitment, recovery mode,
overrides, dt, model/publish/telemetry rates, start time, time base, input hold rule, source
(simulate, muscle_node, recompute), scenario, versions; with a geometry also ``geometry_file``,
``joint_map`` and ``joints`` (RunConfig); with published energetics models ``energetics_models``
(a JSON list of their names, the model axis of energy_rate_models). Attachments: ``model.yaml``
and ``muscles.yaml`` (exact bytes of the files used), ``overrides.yaml`` and, with a geometry,
``geometry.yaml`` (exact bytes): with the recorded inputs, enough to recompute the run
(vm_ros.offline.runner). A log without a geometry has none of the joint channels, keys or
attachment; a log without energetics models has no energy_rate_models channel or key.

Times: log_time is in integer ns on one timeline per log: the start time (``start_time_ns`` of the
metadata: the wall clock when an offline run started, the ROS time of the node's model start)
plus the model time, so model time = log_time - start_time_ns (RunTiming.model_time_ns; logs of
older offline runs start at 0). Header stamps of the outputs equal their log time. Inputs follow
a zero-order hold: the model step [t, t + dt) uses the latest input with log_time <= t.

Reading back (read_run) never fails on a message: one that does not decode (muscle_node records
inputs as received, and any DDS peer can send malformed bytes) is left out of its series and
counted in ``RunLog.skipped``. A ``vm_ros.run`` record that cannot be parsed is an error
(ConfigError naming the file and the key): without it the log cannot be interpreted.
"""

from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import NamedTuple

import numpy as np
import yaml

from vm_ros import telemetry as tm
from vm_ros.errors import ConfigError, VmRosError
from vm_ros.geometry.file import plain_data
from vm_ros.model import MuscleBank
from vm_ros.model.params import DRIVE_LAWS, RECOVERY_MODES
from vm_ros.model.run_config import RunConfig
from vm_ros.recording.messages import TOPIC_TELEMETRY, TYPE_MUSCLE_TELEMETRY
from vm_ros.recording.reader import LogReader
from vm_ros.recording.series import SeriesBuilder, SkippedMessages, TopicSeries, skipped_line
from vm_ros.recording.versions import library_versions
from vm_ros.recording.writer import McapRecorder

METADATA_NAME = "vm_ros.run"
FORMAT = "vm_ros.run/1"
ATTACHMENT_MODEL = "model.yaml"
ATTACHMENT_LIBRARY = "muscles.yaml"
ATTACHMENT_OVERRIDES = "overrides.yaml"
ATTACHMENT_GEOMETRY = "geometry.yaml"
# run metadata key: muscle_node's parameters as JSON, in a log whose inputs the node conditioned
NODE_PARAMETERS_KEY = "node_parameters"
NODE_SOURCE = "muscle_node"  # RunInfo.source of a log muscle_node wrote (a real-time run)
INPUT_TIME_KEY = "input_time"  # vm_ros.run key of a muscle_node log: how inputs were timed
INPUT_TIME_STAMPED = ("header stamp when on the node's clock, else receipt; placed there, not "
                      "before the model time reached (vm_ros.node.inputs.input_time_ns)")


def stamp_on_clock(stamp_ns, placed_ns, timeout_ns):
    """Whether muscle_node takes an input's header stamp as its time (INPUT_TIME_STAMPED): the
    stamp is not zero, not after the sample's placement (its arrival, or a later model time) and
    at most ``timeout_ns`` (input_timeout_s) before it; else the sample is placed at its arrival.
    Python ints (the node, per message: no NumPy) or int64 arrays (elementwise)."""
    return (stamp_ns > 0) & (stamp_ns <= placed_ns) & (placed_ns - stamp_ns <= timeout_ns)
INPUT_HOLD = "zero-order hold: the step [t, t + dt) uses the latest input with log_time <= t"

INPUT_TOPICS = tm.input_topic_names()  # the table vm_ros.topics.INPUT_TOPICS
OUTPUT_TOPICS = (tm.TOPIC_FORCE, tm.TOPIC_ENERGY_RATE, tm.TOPIC_ENERGY_RATE_TOTAL,
                 tm.TOPIC_ENERGY_TOTAL, tm.TOPIC_JOINT_EFFORTS, tm.TOPIC_JOINT_EFFORT_COMMANDS)
# channels of a run with a geometry only (vm_ros.joint_space); joint_work: offline runs only
JOINT_TOPICS = (*(row.name for row in tm.INPUT_TOPICS if row.role == tm.JOINTS),
                tm.TOPIC_JOINT_EFFORTS, tm.TOPIC_JOINT_EFFORT_COMMANDS, tm.TOPIC_JOINT_WORK)
# channels of a run with published energetics models only (RunConfig.energetics_models)
MODEL_TOPICS = (tm.TOPIC_ENERGY_RATE_MODELS,)
# channels of a muscle_node log with live coordination: the target topics as received and the
# drives the coordinator applied (coordination_drive, at the start of each publish period), which
# a recompute copies and applies, and the node's coordination outputs
COORDINATION_INPUT_TOPICS = (tm.TOPIC_JOINT_EFFORT_TRAJECTORY, tm.TOPIC_JOINT_EFFORT_TARGETS,
                             tm.TOPIC_JOINT_EFFORT_TARGETS_ARRAY, tm.TOPIC_COORDINATION_DRIVE)
COORDINATION_TOPICS = (*COORDINATION_INPUT_TOPICS, tm.TOPIC_MUSCLE_DRIVE, tm.TOPIC_JOINT_RESERVES)
# JointState channels whose columns are joints, not muscles (read_run)
JOINT_COLUMN_TOPICS = (*JOINT_TOPICS, tm.TOPIC_JOINT_RESERVES, tm.TOPIC_JOINT_EFFORT_TARGETS)
LOG_TOPIC_TYPES = {
    **{topic: tm.TOPIC_TYPES[topic]
       for topic in INPUT_TOPICS + OUTPUT_TOPICS + JOINT_TOPICS + MODEL_TOPICS
       + COORDINATION_TOPICS},
    TOPIC_TELEMETRY: TYPE_MUSCLE_TELEMETRY,
    tm.TOPIC_DIAGNOSTICS: tm.TYPE_DIAGNOSTIC_ARRAY,
}


class RunLogError(VmRosError, ValueError):
    """A run log lacks what is asked of it (a metadata record, an attachment, inputs to run
    from). Attributes: ``path``, ``reason``."""

    def __init__(self, path, reason: str):
        self.path = str(path)
        self.reason = reason
        super().__init__(f"{self.path}: {reason}")


def resolve_topic(name: str, namespace: str = "/") -> str:
    """A relative topic name resolved as ROS does for a node in ``namespace``."""
    if name.startswith("/"):
        return name
    return f"{namespace.rstrip('/')}/{name}"


# --- the metadata record -------------------------------------------------------------------


@dataclass(frozen=True)
class RunTiming:
    """Model step and output rates. Outputs every ``steps_per(publish_rate_hz)`` steps;
    telemetry_rate_hz 0 records no telemetry. start_time_ns: log time (ns) of the reset, model
    time 0: the wall clock when an offline run started (0 in logs of older offline runs), the
    ROS time of muscle_node's model start (None when not known when the log was opened, as for
    a node that never started its model)."""

    dt_s: float = 0.001
    publish_rate_hz: float = 100.0
    telemetry_rate_hz: float = 100.0
    start_time_ns: int | None = 0

    @property
    def dt_ns(self) -> int:
        return round(self.dt_s * 1e9)

    @property
    def model_rate_hz(self) -> float:
        return 1.0 / self.dt_s

    def model_time_ns(self, log_time_ns):
        """Model time (ns from the reset) of log times (an int or an integer array): log time -
        start_time_ns, exact in integers; the log time itself when the start is not known."""
        return log_time_ns - int(self.start_time_ns or 0)

    def steps_per(self, rate_hz: float) -> int:
        """Model steps between two samples at ``rate_hz`` (at least 1; 0 for rate 0)."""
        if rate_hz <= 0:
            return 0
        return max(1, round(self.model_rate_hz / rate_hz))


@dataclass(frozen=True)
class RunInfo:
    """The ``vm_ros.run`` metadata record, parsed. ``topics`` maps base names to the recorded
    topic names where they are not ``namespace`` + name (remapping); ``extra`` keeps the other
    keys (scenario, inputs file, versions...) as strings."""

    config: RunConfig
    timing: RunTiming
    source: str
    namespace: str = "/"
    time_base: str = "model time"
    extra: Mapping = field(default_factory=dict)
    topics: Mapping = field(default_factory=dict)

    def log_topic(self, name: str) -> str:
        """The recorded topic name of a base name such as ``muscle_force``."""
        return self.topics.get(name) or resolve_topic(name, self.namespace)

    def to_metadata(self) -> dict[str, str]:
        c, t = self.config, self.timing
        record = {
            "format": FORMAT,
            "source": self.source,
            "muscles": json.dumps(list(c.muscles)),
            "recruitment": c.recruitment,
            "recovery_mode": c.recovery_mode or "",
            "drive_law": c.drive_law or "",
            "units_per_type": "" if c.units_per_type is None else str(c.units_per_type),
            "overrides": json.dumps(plain_data(c.overrides), sort_keys=True),
            "model_params_file": str(c.params_path),
            "muscle_library_file": str(c.library_path),
            "dt_s": repr(float(t.dt_s)),
            "model_rate_hz": repr(t.model_rate_hz),
            "publish_rate_hz": repr(float(t.publish_rate_hz)),
            "telemetry_rate_hz": repr(float(t.telemetry_rate_hz)),
            "start_time_ns": "" if t.start_time_ns is None else str(int(t.start_time_ns)),
            "initial_state": "rest",
            "input_hold": INPUT_HOLD,
            "namespace": self.namespace,
            "topics": json.dumps(dict(self.topics), sort_keys=True),
            "time_base": self.time_base,
            "versions": json.dumps(library_versions(), sort_keys=True),
        }
        if c.geometry is not None:
            record.update({"geometry_file": str(c.geometry), "joint_map": c.joint_map,
                           "joints": json.dumps(list(c.joints))})
        if c.energetics_models:
            record["energetics_models"] = json.dumps(list(c.energetics_models))
        record.update({str(k): str(v) for k, v in self.extra.items()})
        return record

    @classmethod
    def from_metadata(cls, record: Mapping[str, str],
                      source: str = f"'{METADATA_NAME}' metadata") -> RunInfo:
        """Parse a record; tolerant of older writers (muscles as "a,b", missing rates).

        Raises ConfigError naming ``source`` and the key when a value is missing (muscles, dt_s)
        or cannot be used (not a number, dt_s <= 0, a rate < 0, overrides not a JSON object...).
        """
        known = {"format", "source", "muscles", "recruitment", "recovery_mode", "drive_law",
                 "units_per_type",
                 "overrides", "model_params_file", "muscle_library_file", "dt_s",
                 "model_rate_hz", "publish_rate_hz", "telemetry_rate_hz", "start_time_ns",
                 "initial_state", "input_hold", "namespace", "time_base", "topics",
                 "geometry_file", "joint_map", "joints", "energetics_models"}

        def value(key, parse, default=_REQUIRED):
            return _metadata_value(record, source, key, parse, default)

        config = RunConfig(
            muscles=value("muscles", _muscle_names),
            recruitment=record.get("recruitment", "lumped"),
            recovery_mode=record.get("recovery_mode") if record.get("recovery_mode") in
            RECOVERY_MODES else None,
            drive_law=record.get("drive_law") if record.get("drive_law") in DRIVE_LAWS else None,
            overrides=value("overrides", _json_object_of(dict), {}),
            units_per_type=value("units_per_type", _positive_int, None),
            geometry=value("geometry_file", Path, None),
            joint_map=record.get("joint_map", ""),
            joints=value("joints", _names, ()),
            energetics_models=value("energetics_models", _names, ()),
        )
        timing = RunTiming(
            dt_s=value("dt_s", _positive_float),
            publish_rate_hz=value("publish_rate_hz", _rate, 100.0),
            telemetry_rate_hz=value("telemetry_rate_hz", _rate, 0.0),
            start_time_ns=value("start_time_ns", int, None),
        )
        return cls(config, timing, record.get("source", ""), record.get("namespace", "/"),
                   record.get("time_base", ""),
                   {k: v for k, v in record.items() if k not in known},
                   value("topics", _json_object_of(str), {}))


# --- parsing the metadata record: each parser raises ValueError with the reason --------------

_REQUIRED = object()


def _metadata_value(record: Mapping[str, str], source: str, key: str, parse, default):
    """``parse(record[key])``; ``default`` when the key is missing or empty. Raises ConfigError
    naming ``source`` and ``key``."""
    text = record.get(key)
    if text is None or text == "":
        if default is _REQUIRED:
            raise ConfigError(source, key, text, "missing")
        return default
    try:
        return parse(text)
    except (ValueError, TypeError) as exc:
        raise ConfigError(source, key, text, str(exc) or type(exc).__name__) from None


def _float(text: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise ValueError("not a number") from None


def _positive_float(text: str) -> float:
    number = _float(text)
    if not (math.isfinite(number) and number > 0):
        raise ValueError("must be a finite number > 0")
    return number


def _rate(text: str) -> float:
    number = _float(text)
    if not (math.isfinite(number) and number >= 0):
        raise ValueError("must be a finite number >= 0")
    return number


def _positive_int(text: str) -> int:
    number = int(text)
    if number <= 0:
        raise ValueError("must be > 0")
    return number


def _muscle_names(text: str) -> tuple:
    """A JSON list of names, or (older writers) names separated by commas."""
    names = (json.loads(text) if text.lstrip().startswith("[") else
             [m.strip() for m in text.split(",") if m.strip()])
    if not (isinstance(names, list) and names and all(isinstance(n, str) and n for n in names)):
        raise ValueError("expected a non-empty list of muscle names")
    return tuple(names)


def _names(text: str) -> tuple:
    """A JSON list of strings (possibly empty)."""
    names = json.loads(text)
    if not (isinstance(names, list) and all(isinstance(n, str) for n in names)):
        raise ValueError("expected a JSON list of names")
    return tuple(names)


def _json_object_of(kind: type):
    """A parser of a JSON object whose values are all of ``kind``."""

    def parse(text: str) -> dict:
        parsed = json.loads(text)
        if not (isinstance(parsed, dict) and all(isinstance(v, kind) for v in parsed.values())):
            raise ValueError(f"expected a JSON object of {kind.__name__} values")
        return parsed

    return parse


def run_attachments(config: RunConfig) -> dict[str, bytes]:
    """The model YAML and muscle library used (exact bytes), the overrides as YAML and, for a
    joint-space run, the geometry file (exact bytes)."""
    attachments = {
        ATTACHMENT_MODEL: config.params_path.read_bytes(),
        ATTACHMENT_LIBRARY: config.library_path.read_bytes(),
        ATTACHMENT_OVERRIDES: yaml.safe_dump(plain_data(config.overrides), sort_keys=True).encode(),
    }
    if config.geometry is not None:
        attachments[ATTACHMENT_GEOMETRY] = Path(config.geometry).read_bytes()
    return attachments


def default_log_topics(info: RunInfo) -> list[str]:
    """The base names open_run_log declares by default (its docstring)."""
    return [t for t in LOG_TOPIC_TYPES if t != tm.TOPIC_DIAGNOSTICS
            and (t != TOPIC_TELEMETRY or info.timing.telemetry_rate_hz > 0)
            and (t not in JOINT_TOPICS or info.config.geometry is not None)
            and (t not in MODEL_TOPICS or bool(info.config.energetics_models))
            and t not in COORDINATION_TOPICS]


def open_run_log(path, info: RunInfo, bank: MuscleBank | None = None,
                 topics: Iterable[str] | None = None, qos: Mapping[str, str] | None = None,
                 attachments: Mapping[str, bytes] | None = None,
                 **recorder_options) -> McapRecorder:
    """A McapRecorder with the run's metadata and attachments, its channels declared.

    path: an MCAP file, or without the ``.mcap`` suffix a rosbag2 bag directory.

    info: the run (RunInfo; ``info.config.recovery_mode`` and ``drive_law`` None are filled
    from ``bank``);
    topics: base names to declare (default: all of LOG_TOPIC_TYPES but /diagnostics, telemetry
    when telemetry_rate_hz is 0, the JOINT_TOPICS without a geometry, the MODEL_TOPICS
    without energetics models and the COORDINATION_TOPICS); qos: ``{base name:
    offered_qos_profiles YAML}``; attachments: run_attachments(info.config) read before (a node
    reads them when it is built, not at the model start), default read now.
    Raises RecorderError naming the path when the file cannot be created.
    """
    if bank is not None and info.config.recovery_mode is None:
        info = dataclasses.replace(info, config=info.config.replace(
            recovery_mode=bank.recovery_mode))
    if bank is not None and info.config.drive_law is None:
        info = dataclasses.replace(info, config=info.config.replace(
            drive_law=bank.params.lumped.drive_law))
    if topics is None:
        topics = default_log_topics(info)
    if attachments is None:
        attachments = run_attachments(info.config)
    recorder = McapRecorder(path, metadata={METADATA_NAME: info.to_metadata()},
                            attachments=attachments, **recorder_options)
    for topic in topics:
        recorder.add_channel(info.log_topic(topic), LOG_TOPIC_TYPES[topic],
                             (qos or {}).get(topic))
    return recorder


# --- reading back ----------------------------------------------------------------------------


def logged_node_parameters(run: RunLog) -> dict | None:
    """The muscle_node parameters logged with ``run`` as a dict (None when it holds none).
    Raises ConfigError naming the log when they are not a JSON object."""
    if run.info is None or NODE_PARAMETERS_KEY not in run.info.extra:
        return None
    text = run.info.extra[NODE_PARAMETERS_KEY]
    source = f"{run.path}: '{METADATA_NAME}' metadata"
    try:
        values = json.loads(text)
    except ValueError as exc:
        raise ConfigError(source, NODE_PARAMETERS_KEY, text, f"not JSON: {exc}") from None
    if not isinstance(values, dict):
        raise ConfigError(source, NODE_PARAMETERS_KEY, text, "expected a JSON object")
    return values


class RecordedEvent(NamedTuple):
    """One recorded message of RunLog.events: ``series.fields[...][index]`` when it decoded
    (``series`` None when it did not), ``data`` its recorded bytes (None when not kept)."""

    time_ns: int
    topic: str  # the name asked for (a base name such as "excitation")
    series: TopicSeries | None
    index: int
    data: bytes | None


@dataclass
class EventTable:
    """RunLog.events as arrays: message k is of topic ``names[topic[k]]`` (its series
    ``series[topic[k]]``), logged at ``time_ns[k]``, row ``index[k]`` of that series (-1: it did
    not decode), recorded bytes ``data[k]`` (None when not kept)."""

    names: tuple
    series: tuple
    time_ns: np.ndarray
    topic: np.ndarray
    index: np.ndarray
    data: list

    def __len__(self) -> int:
        return len(self.time_ns)

    def event(self, k: int) -> RecordedEvent:
        topic, index = int(self.topic[k]), int(self.index[k])
        return RecordedEvent(int(self.time_ns[k]), self.names[topic],
                             self.series[topic] if index >= 0 else None, index, self.data[k])


@dataclass
class RunLog:
    """A run log read back (read_run). ``series`` is keyed by recorded topic name; ``get(name)``
    finds a base name such as ``muscle_force`` as the run recorded it (RunInfo.log_topic).
    ``complete`` is False for a file cut short (the series then end at the last complete chunk;
    ``stop_reason`` says why). ``skipped``: per recorded topic, the messages that did not decode
    (left out of ``series``; ``skipped_note()`` says so in one line). ``unlisted_note``: for a
    bag directory whose metadata.yaml leaves out some of its ``.mcap`` files (not read), the
    line naming them (LogReader)."""

    path: Path
    info: RunInfo | None
    metadata: dict
    attachments: dict
    series: dict
    topic_types: dict
    complete: bool
    stop_reason: str | None
    skipped: dict = field(default_factory=dict)
    unlisted_note: str | None = None

    def log_topic(self, name: str) -> str:
        """The recorded name of a base or full topic name."""
        return resolve_topic(name) if self.info is None else self.info.log_topic(name)

    def get(self, name: str) -> TopicSeries | None:
        return self.series.get(self.log_topic(name))

    def model_time_ns(self, log_time_ns):
        """Model time (ns from the reset) of log times or header stamps of this log
        (RunTiming.model_time_ns); unchanged for a log without a ``vm_ros.run`` record."""
        return log_time_ns if self.info is None else self.info.timing.model_time_ns(log_time_ns)

    def skipped_note(self) -> str | None:
        """``skipped 1 undecodable message on /excitation (UnicodeDecodeError)``, or None."""
        return skipped_line(self.skipped)

    def events(self, names: Iterable[str]) -> list[RecordedEvent]:
        """The messages of the topics ``names`` in the order a replay of the run applies them:
        by log time, then the order of ``names``, then file order. For a topic read raw the
        messages that did not decode are included (``series`` None), so that they can be copied
        verbatim; a consumer skips them, as muscle_node dropped them."""
        table = self.event_table(names)
        return [table.event(i) for i in range(len(table))]

    def event_table(self, names: Iterable[str]) -> EventTable:
        """``events(names)`` as arrays (EventTable), sorted at once."""
        names = tuple(names)
        times, topics, rows, decoded, data = [], [], [], [], []
        found = []
        for order, name in enumerate(names):
            series = self.get(name)
            found.append(series)
            if series is not None:
                count = len(series)
                times.append(np.asarray(series.time_ns, dtype=np.int64))
                topics.append(np.full(count, order))
                rows.append(np.arange(count))
                decoded.append(np.ones(count, dtype=bool))
                data.extend(series.raw if series.raw is not None else [None] * count)
            skipped = self.skipped.get(self.log_topic(name))
            kept = (skipped.raw or ()) if skipped is not None else ()
            if kept:
                times.append(np.array([t for _, t, _ in kept], dtype=np.int64))
                topics.append(np.full(len(kept), order))
                rows.append(np.array([position for position, _, _ in kept]))
                decoded.append(np.zeros(len(kept), dtype=bool))
                data.extend(item for _, _, item in kept)
        if not times:
            return EventTable(names, tuple(found), np.zeros(0, dtype=np.int64),
                              np.zeros(0, dtype=int), np.zeros(0, dtype=int), [])
        time_ns, topic, row, ok = (np.concatenate(parts) for parts in (times, topics, rows,
                                                                      decoded))
        order = np.lexsort((ok, row, topic, time_ns))  # stable: then the order added
        return EventTable(names, tuple(found), time_ns[order], topic[order],
                          np.where(ok, row, -1)[order], [data[i] for i in order.tolist()])

    def config(self, directory) -> RunConfig:
        """The run's RunConfig with its attached model and library YAML (and geometry, when it
        has one) written to ``directory`` (which must outlive any use of the returned paths).
        Raises RunLogError when the log lacks them (a geometry named in the metadata without
        its attachment, too)."""
        if self.info is None:
            raise RunLogError(self.path, f"no '{METADATA_NAME}' metadata record")
        directory = Path(directory)
        names = [ATTACHMENT_MODEL, ATTACHMENT_LIBRARY]
        if self.info.config.geometry is not None or ATTACHMENT_GEOMETRY in self.attachments:
            names.append(ATTACHMENT_GEOMETRY)
        paths = {}
        for name in names:
            if name not in self.attachments:
                raise RunLogError(self.path, f"no '{name}' attachment")
            paths[name] = directory / name
            paths[name].write_bytes(self.attachments[name])
        return self.info.config.replace(params=paths[ATTACHMENT_MODEL],
                                        library=paths[ATTACHMENT_LIBRARY],
                                        geometry=paths.get(ATTACHMENT_GEOMETRY))


def read_run(path, topics: Iterable[str] | None = None, raw: Iterable[str] = (),
             progress: Callable[[int, int], None] | None = None) -> RunLog:
    """Read a run log (any ROS 2 MCAP works; vm_ros logs get muscle-aligned arrays): an MCAP
    file or a rosbag2 bag directory holding one (vm_ros.recording.bag).

    topics: base or full names to decode (default all); raw: base names whose CDR bytes to keep
    (recompute copies inputs verbatim); progress(bytes_read, size) for long files. Messages that
    do not decode are skipped and counted (RunLog.skipped).
    Raises LogReadError when the file is missing or not MCAP, ConfigError when its
    ``vm_ros.run`` record cannot be parsed.
    """
    reader = LogReader(path, progress=progress)
    builders: dict[str, SeriesBuilder] = {}
    info: RunInfo | None = None
    wanted = keep_raw = joint_topics = None
    for batch in reader.batches():
        if info is None:
            info = _run_info(reader, path)
        if wanted is None:
            log_topic = info.log_topic if info is not None else resolve_topic
            wanted = None if topics is None else {log_topic(t) for t in topics}
            keep_raw = {log_topic(t) for t in raw}
            joint_topics = {log_topic(t) for t in JOINT_COLUMN_TOPICS}
        if wanted is not None and batch.topic not in wanted:
            continue
        builder = builders.get(batch.topic)
        if builder is None:
            joint = batch.topic in joint_topics
            columns = info.config.muscles if info is not None and not joint else None
            builder = builders[batch.topic] = SeriesBuilder(
                batch.topic, batch.type_name, columns, batch.topic in keep_raw,
                batch.encoding, grow_columns=joint)
        builder.add_many(batch.data, batch.log_time_ns)
    if info is None:
        info = _run_info(reader, path)
    skipped = {topic: b.skipped for topic, b in builders.items() if b.skipped.count}
    for channel_id, count in reader.unknown_channels.items():
        skipped[f"<channel {channel_id}>"] = SkippedMessages(count, "no channel record")
    return RunLog(Path(path), info, reader.metadata, reader.attachments,
                  {topic: b.build() for topic, b in builders.items() if len(b)},
                  reader.topic_types(), reader.complete, reader.stop_reason, skipped,
                  reader.unlisted_note)


def _run_info(reader: LogReader, path) -> RunInfo | None:
    """The parsed ``vm_ros.run`` record once the reader has met it, else None."""
    record = reader.metadata.get(METADATA_NAME)
    if record is None:
        return None
    return RunInfo.from_metadata(record, source=f"{path}: '{METADATA_NAME}' metadata")
