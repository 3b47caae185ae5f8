"""muscle_node's MCAP run log (no rclpy here).

The file is a vm_ros run log (vm_ros.recording.run_log): its ``vm_ros.run`` metadata needs the
model's start time, known only when the first kinematics arrive. So the path is checked (and the
file created) when the node starts, the log itself is opened when the model starts, and what is
written before that is held in a bounded buffer and written first. What the log needs but the
start time (the attachments read from their files, the topics, the recorder options) is prepared
when the node starts, so that the tick that starts the model does not read files. A node stopped
before the model started still leaves a complete file (metadata key ``started`` = false).

Recording never stops the model: when the disk is full (or any other write error) at the
start of the log or later, the status turns failed (``ok`` False, the error, the messages that
reached the file counted as written), later messages are dropped and counted, ``on_error`` is
called once with the error, and closing is quiet.

Times, chosen so that `vm-ros recompute` applies every input at the step where the node did:
inputs are logged at the model time from which the steps use them (their header stamp when it is
on the node's clock, else their arrival; never before the model time reached when they arrived:
vm_ros.node.input_timeline; the ROS receipt time before the start) with the ROS receipt time as
publish time; outputs at their stamp (model time); /diagnostics at the ROS time. The ``vm_ros.run``
key ``input_time`` (INPUT_TIME_STAMPED) says so; logs without it were written by muscle_node
versions that placed every input at the model time reached when it arrived and gave it that
time, and `vm-ros recompute` reads them so.
"""

from __future__ import annotations

import contextlib
import json
from collections import deque
from collections.abc import Callable
from pathlib import Path

from vm_ros import telemetry as tm
from vm_ros.errors import VmRosError
from vm_ros.recording.bag import BagError, is_bag_path, prepare_bag_directory
from vm_ros.recording.message_types import schema_text
from vm_ros.recording.run_log import (
    INPUT_TIME_KEY,
    INPUT_TIME_STAMPED,
    INPUT_TOPICS,
    JOINT_TOPICS,
    LOG_TOPIC_TYPES,
    MODEL_TOPICS,
    OUTPUT_TOPICS,
    RunInfo,
    open_run_log,
    resolve_topic,
    run_attachments,
)
from vm_ros.recording.versions import library_versions
from vm_ros.recording.writer import McapRecorder, RecorderError, RecorderStatus

# node parameter -> McapRecorder option
RECORDER_PARAMETERS = {"mcap.flush_interval_s": "flush_interval_s",
                       "mcap.max_bag_size": "max_file_size",
                       "mcap.max_bag_duration_s": "max_file_duration_s"}
LOG_TOPICS = (*INPUT_TOPICS, *OUTPUT_TOPICS, tm.TOPIC_DIAGNOSTICS)  # JOINT_TOPICS: geometry only
INPUT_RULE = ("muscle_node: inputs conditioned by vm_ros.node.inputs.NodeInputs with the "
              "node_parameters (bad messages dropped, drive clipped, kinematics extrapolated for "
              "at most extrapolation_max_s, stale_input_policy), joint_states by "
              "vm_ros.node.joint_inputs.JointInputs with the geometry; each input is logged at the "
              "model time of the first step that uses it")  # muscle_node: how, in input_time


def node_run_extra(node_name: str, parameters: dict) -> dict:
    """Extra ``vm_ros.run`` metadata keys of a muscle_node log."""
    return {"node": node_name, "node_parameters": json.dumps(parameters, sort_keys=True),
            "input_hold": INPUT_RULE, INPUT_TIME_KEY: INPUT_TIME_STAMPED, "started": "true"}


def recorded_recorder_options(info: RunInfo) -> dict:
    """McapRecorder options from the ``mcap.*`` node parameters of the run info's
    ``node_parameters`` (RECORDER_PARAMETERS; those not there are left out)."""
    try:
        parameters = json.loads(info.extra.get("node_parameters", "{}"))
    except (ValueError, TypeError):
        return {}
    if not isinstance(parameters, dict):
        return {}
    return {option: parameters[name] for name, option in RECORDER_PARAMETERS.items()
            if isinstance(parameters.get(name), (int, float))
            and not isinstance(parameters.get(name), bool)}


class NodeRunLog:
    """A run log opened at the model start; writes before it are buffered (at most
    ``buffer_size`` messages, the oldest dropped first).

    path: the MCAP file, or without the ``.mcap`` suffix a rosbag2 bag directory
    (vm_ros.recording.bag; its MCAP file is ``file_path``).

    run_info(start_time_ns or None) -> RunInfo; qos: ``{base topic: offered_qos_profiles YAML}``;
    on_error(text): called once when recording fails (also settable as an attribute);
    extra_topics: base names logged beside LOG_TOPICS (live coordination's COORDINATION_TOPICS);
    recorder_options: passed to McapRecorder (chunk_size, opener, flush_interval_s...). Those
    not given come from the node's ``mcap.*`` parameters as recorded in the run info's
    ``node_parameters`` (RECORDER_PARAMETERS), else McapRecorder's defaults.
    Raises RecorderError naming the path when the file cannot be created; never after that.
    """

    def __init__(self, path, run_info: Callable[[int | None], RunInfo], namespace: str = "/",
                 qos: dict | None = None, buffer_size: int = 10000,
                 on_error: Callable[[str], object] | None = None, extra_topics=(),
                 **recorder_options):
        self.path = Path(path)
        self._extra_topics = tuple(extra_topics)
        self._run_info = run_info
        self._namespace = namespace
        self._qos = dict(qos or {})
        self._recorder_options = recorder_options
        self._buffer: deque = deque(maxlen=buffer_size)
        self._dropped = 0  # by this object: buffer overflow, or after the log failed to open
        self.recorder: McapRecorder | None = None
        self.on_error = on_error
        self._open_error: str | None = None
        self._bytes_before_error = 0
        self._failure_reported = False
        self._closed = False
        self.file_path = self.path  # the MCAP file (NAME/NAME_0.mcap for a bag directory)
        library_versions()  # looked up now, not at the model start (versions.package_version)
        try:  # fail at start-up, not at the model start
            if is_bag_path(self.path):
                self.file_path = prepare_bag_directory(self.path)
            self.file_path.parent.mkdir(parents=True, exist_ok=True)
            self.file_path.open("wb").close()
        except BagError as exc:
            raise RecorderError(self.path, exc.reason) from exc
        except OSError as exc:
            raise RecorderError(self.path, f"cannot create the file: {exc.strerror or exc}") \
                from exc
        self._prepared = self._prepare()

    def _preparation(self, info: RunInfo) -> tuple[list, dict, dict]:
        """(topics, attachments, recorder options) of the log: what it needs of the run info
        but its start time."""
        topics = [t for t in LOG_TOPICS
                  if t not in JOINT_TOPICS or info.config.geometry is not None]
        if info.config.energetics_models:
            topics += MODEL_TOPICS
        topics += self._extra_topics
        options = {**recorded_recorder_options(info), **self._recorder_options}
        return topics, run_attachments(info.config), options

    def _prepare(self) -> tuple[list, dict, dict] | None:
        """_preparation before the model start; None when it fails now (an attachment's file
        unreadable): then ``start`` tries again, and reports the error, as the log opens."""
        try:
            prepared = self._preparation(self._run_info(None))
        except (VmRosError, OSError):
            return None
        for topic in prepared[0]:  # each type's definition, composed once and cached
            schema_text(LOG_TOPIC_TYPES[topic])
        return prepared

    @property
    def started(self) -> bool:
        return self.recorder is not None

    @property
    def closed(self) -> bool:
        return self._closed

    def write(self, topic: str, data: bytes, log_time_ns: int,
              publish_time_ns: int | None = None) -> bool:
        """Log one serialised message on a base topic name (never blocks). False when it is
        dropped (counted in the status)."""
        full = resolve_topic(topic, self._namespace)
        if self.recorder is not None:
            if self.recorder.write(full, data, log_time_ns, publish_time_ns):
                return True
            self._report_failure()  # dropped: queue full, or the recorder failed
            return False
        if self._open_error is not None or self._closed:
            self._dropped += 1
            return False
        if len(self._buffer) == self._buffer.maxlen:
            self._dropped += 1
        self._buffer.append((full, data, log_time_ns, publish_time_ns))
        return True

    def start(self, start_time_ns: int | None) -> None:
        """Open the run log with the model's start time and write the buffered messages. When
        the log cannot be opened (disk full...), the status turns failed instead."""
        if self.recorder is not None or self._open_error is not None:
            return
        try:
            info = self._run_info(start_time_ns)
            topics, attachments, options = self._prepared or self._preparation(info)
            self.recorder = open_run_log(self.path, info, topics=topics, qos=self._qos,
                                         attachments=attachments, **options)
        except (VmRosError, OSError) as exc:
            self._open_error = str(exc)
            self._dropped += len(self._buffer)
            self._buffer.clear()
            with contextlib.suppress(OSError):  # what reached the file before the error
                self._bytes_before_error = self.file_path.stat().st_size
            self._report_failure()
            return
        while self._buffer:
            self.recorder.write(*self._buffer.popleft())

    def close(self) -> None:
        """Finish the file (idempotent); opens it first if the model never started."""
        if self._closed:
            return
        if self.recorder is None:
            self.start(None)
        self._closed = True
        if self.recorder is not None:
            self.recorder.close()

    def _report_failure(self) -> None:
        """Call on_error, once, when recording has failed."""
        if self._failure_reported:
            return
        status = self.status
        if not status.ok:
            self._failure_reported = True
            if self.on_error is not None:
                self.on_error(f"MCAP recording failed, the model keeps running without it: "
                              f"{status.error}")

    @property
    def status(self) -> RecorderStatus:
        if self.recorder is None:
            return RecorderStatus(ok=self._open_error is None, error=self._open_error,
                                  written=0, dropped=self._dropped,
                                  bytes_written=self._bytes_before_error, path=str(self.path))
        st = self.recorder.status
        return RecorderStatus(st.ok, st.error, st.written, st.dropped + self._dropped,
                              st.bytes_written, st.path)


__all__ = ["LOG_TOPICS", "NodeRunLog", "node_run_extra"]
