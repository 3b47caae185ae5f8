"""rosbag2 bag directories: a log path without the ``.mcap`` suffix is a directory, as
``ros2 bag record -o NAME`` makes it.

    NAME/NAME_0.mcap      the MCAP log (vm_ros.recording.writer)
    NAME/metadata.yaml    rosbag2's bag metadata, written when the log is finished

metadata.yaml follows rosbag2_storage's BagMetadata, version 9 (ROS 2 Jazzy):
``rosbag2_bagfile_information`` with version, storage_identifier ``mcap``, relative_file_paths,
duration, starting_time, message_count, topics_with_message_count (topic_metadata: name, type,
serialization_format ``cdr``, offered_qos_profiles as a YAML list, type_description_hash),
compression_format and compression_mode (empty: MCAP compresses its chunks itself), files (per
file: path, starting_time, duration, message_count), custom_data and ros_distro.

Split logs (McapRecorder's max_file_size, max_file_duration_s, as rosbag2's --max-bag-size and
--max-bag-duration) continue in NAME_1.mcap, NAME_2.mcap...: each file has the run's metadata and
attachments and its own channels, so each one is a readable run log; readers chain them.

A process killed before the log is finished leaves the directory without metadata.yaml: the vm_ros
readers then read the directory's ``.mcap`` files; ``ros2 bag reindex NAME`` rebuilds the
metadata for rosbag2.
"""

from __future__ import annotations

from pathlib import Path

import yaml
from mcap.reader import make_reader

from vm_ros.errors import VmRosError

SUFFIX = ".mcap"
METADATA_FILE = "metadata.yaml"
METADATA_VERSION = 9  # rosbag2_storage BagMetadata in ROS 2 Jazzy
STORAGE_IDENTIFIER = "mcap"
ROS_DISTRO = "jazzy"


class BagError(VmRosError):
    """A bag directory cannot be used. Attributes: ``path``, ``reason``."""

    def __init__(self, path, reason: str):
        self.path = str(path)
        self.reason = reason
        super().__init__(f"bag {self.path}: {reason}")


def is_bag_path(path) -> bool:
    """True when ``path`` names a bag directory (no ``.mcap`` suffix, any case), False for a
    single MCAP file."""
    return Path(path).suffix.lower() != SUFFIX


def shown_log_path(out_path, recorder_path) -> str:
    """What a verb prints as the log it wrote: a bag directory (with its file count) when
    ``out_path`` names one, else the file."""
    if not is_bag_path(out_path):
        return str(recorder_path)
    files = sorted(Path(out_path).glob(f"{Path(out_path).name}_*{SUFFIX}"))
    return f"{out_path}/ (rosbag2 bag, {len(files)} file{'s' if len(files) != 1 else ''})"


def bag_file_path(directory) -> Path:
    """The MCAP file of a bag directory: ``NAME/NAME_0.mcap``."""
    directory = Path(directory)
    return directory / f"{directory.name}_0{SUFFIX}"


def prepare_bag_directory(directory) -> Path:
    """Create the bag directory (or reuse it; a former metadata.yaml is removed, as the log it
    described is overwritten) and return the path of its MCAP file. Raises BagError."""
    directory = Path(directory)
    if directory.exists() and not directory.is_dir():
        raise BagError(directory, "exists and is not a directory (name a bag directory, or a "
                                  "file ending in .mcap)")
    try:
        directory.mkdir(parents=True, exist_ok=True)
        (directory / METADATA_FILE).unlink(missing_ok=True)
        for old in directory.glob(f"{directory.name}_*{SUFFIX}"):  # a former split log's
            if old.stem.rsplit("_", 1)[-1].isdigit():
                old.unlink()
    except OSError as exc:
        raise BagError(directory, f"cannot create the directory: {exc.strerror or exc}") from exc
    return bag_file_path(directory)


def _file_order(path: Path):
    """NAME_2.mcap before NAME_10.mcap."""
    stem, _, index = path.stem.rpartition("_")
    return (stem, int(index), "") if index.isdigit() else (path.stem, -1, path.name)


def bag_log_files(directory) -> list[Path]:
    """The MCAP files of a bag directory, in order: metadata.yaml's relative_file_paths, or
    without it (a recorder killed before finishing) the directory's ``*.mcap`` files by name.
    Raises BagError when there is none or metadata.yaml cannot be read."""
    directory = Path(directory)
    metadata_path = directory / METADATA_FILE
    if metadata_path.is_file():
        try:
            info = yaml.safe_load(metadata_path.read_text(encoding="utf-8"))
            names = info["rosbag2_bagfile_information"]["relative_file_paths"]
            files = [directory / str(name) for name in names]
        except (OSError, yaml.YAMLError, TypeError, KeyError) as exc:
            raise BagError(directory, f"cannot read {METADATA_FILE}: {exc}") from exc
        if files and all(f.is_file() for f in files):
            return files
    files = sorted(directory.glob(f"*{SUFFIX}"), key=_file_order)
    if not files:
        raise BagError(directory, f"no {SUFFIX} file in the bag directory")
    return files


def _file_summary(mcap_path: Path):
    try:
        with open(mcap_path, "rb") as stream:
            summary = make_reader(stream).get_summary()
    except Exception as exc:
        raise BagError(mcap_path.parent, f"cannot read the summary of {mcap_path.name}: "
                                         f"{exc}") from exc
    if summary is None:
        raise BagError(mcap_path.parent, f"{mcap_path.name} has no summary (not finished)")
    return summary


def _span(start: int, end: int) -> dict:
    return {"starting_time": {"nanoseconds_since_epoch": start},
            "duration": {"nanoseconds": end - start}}


def bag_metadata(mcap_paths, ros_distro: str = ROS_DISTRO) -> dict:
    """rosbag2's metadata (version 9) of finished MCAP files (one path or a list, in order), as
    the dict that metadata.yaml holds. Raises BagError when a file has no summary."""
    paths = [Path(mcap_paths)] if isinstance(mcap_paths, (str, Path)) else \
        [Path(p) for p in mcap_paths]
    topics: dict[str, dict] = {}
    files, starts, ends = [], [], []
    for path in paths:
        summary = _file_summary(path)
        stats = summary.statistics
        count = stats.message_count if stats else 0
        start = stats.message_start_time if count else 0
        end = stats.message_end_time if count else 0
        if count:
            starts.append(start)
            ends.append(end)
        files.append({"path": path.name, **_span(start, end), "message_count": count})
        for channel_id, channel in sorted(summary.channels.items()):
            schema = summary.schemas.get(channel.schema_id)
            qos_text = channel.metadata.get("offered_qos_profiles", "")
            entry = topics.setdefault(channel.topic, {
                "topic_metadata": {
                    "name": channel.topic,
                    "type": schema.name if schema is not None else "",
                    "serialization_format": channel.message_encoding,
                    "offered_qos_profiles": yaml.safe_load(qos_text) or [] if qos_text else [],
                    "type_description_hash": channel.metadata.get("topic_type_hash", ""),
                },
                "message_count": 0})
            entry["message_count"] += stats.channel_message_counts.get(channel_id, 0) \
                if stats else 0
    start, end = (min(starts), max(ends)) if starts else (0, 0)
    return {"rosbag2_bagfile_information": {
        "version": METADATA_VERSION,
        "storage_identifier": STORAGE_IDENTIFIER,
        "relative_file_paths": [path.name for path in paths],
        **_span(start, end),
        "message_count": sum(f["message_count"] for f in files),
        "topics_with_message_count": list(topics.values()),
        "compression_format": "",
        "compression_mode": "",
        "files": files,
        "custom_data": {},
        "ros_distro": ros_distro,
    }}


def write_bag_metadata(directory, mcap_paths) -> Path:
    """Write ``directory/metadata.yaml`` for finished MCAP files (through a temporary file, so
    that a reader never sees half of it). Raises BagError."""
    directory = Path(directory)
    target = directory / METADATA_FILE
    text = yaml.safe_dump(bag_metadata(mcap_paths), sort_keys=False, default_flow_style=False)
    temporary = target.with_suffix(".yaml.tmp")
    try:
        temporary.write_text(text, encoding="utf-8")
        temporary.replace(target)
    except OSError as exc:
        raise BagError(directory, f"cannot write {METADATA_FILE}: {exc.strerror or exc}") from exc
    return target


__all__ = ["METADATA_FILE", "METADATA_VERSION", "BagError", "bag_file_path", "bag_log_files",
           "bag_metadata", "is_bag_path", "prepare_bag_directory", "write_bag_metadata"]
