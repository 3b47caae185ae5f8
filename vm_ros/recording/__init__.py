"""MCAP run logs, the format: writing (McapRecorder), reading back (read_run) and replay.

Running a model offline is vm_ros.offline; reports of a run are vm_ros.report.

Importable without ROS: messages are CDR-encoded from bundled definitions (vm_ros.recording.cdr).
"""

from vm_ros.recording.reader import LogReader, LogReadError, RecordedMessage
from vm_ros.recording.run_log import (
    METADATA_NAME,
    RunInfo,
    RunLog,
    RunLogError,
    RunTiming,
    open_run_log,
    read_run,
)
from vm_ros.recording.series import TopicSeries
from vm_ros.recording.writer import McapRecorder, RecorderError, RecorderStatus

__all__ = [
    "METADATA_NAME",
    "LogReadError",
    "LogReader",
    "McapRecorder",
    "RecordedMessage",
    "RecorderError",
    "RecorderStatus",
    "RunInfo",
    "RunLog",
    "RunLogError",
    "RunTiming",
    "TopicSeries",
    "open_run_log",
    "read_run",
]
