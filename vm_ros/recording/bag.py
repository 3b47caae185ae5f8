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

A process killed before the log is finished leaves the directory without metadata.yaml: the vm_ros
readers then read the directory's ``.mcap`` file; ``ros2 bag reindex NAME`` rebuilds the
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
    except OSError as exc:
        raise BagError(directory, f"cannot create the directory: {exc.strerror or exc}") from exc
    return bag_file_path(directory)


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
    files = sorted(directory.glob(f"*{SUFFIX}"))
    if not files:
        raise BagError(directory, f"no {SUFFIX} file in the bag directory")
    return files


def bag_metadata(mcap_path, ros_distro: str = ROS_DISTRO) -> dict:
    """rosbag2's metadata (version 9) of one finished MCAP file, as the dict that
    metadata.yaml holds. Raises BagError when the file has no summary."""
    mcap_path = Path(mcap_path)
    try:
        with open(mcap_path, "rb") as stream:
            summary = make_reader(stream).get_summary()
    except Exception as exc:
        raise BagError(mcap_path.parent, f"cannot read the summary of {mcap_path.name}: "
                                         f"{exc}") from exc
    if summary is None:
        raise BagError(mcap_path.parent, f"{mcap_path.name} has no summary (not finished)")
    stats = summary.statistics
    count = stats.message_count if stats else 0
    start = stats.message_start_time if stats and count else 0
    duration = (stats.message_end_time - stats.message_start_time) if stats and count else 0
    topics = []
    for channel_id, channel in sorted(summary.channels.items()):
        schema = summary.schemas.get(channel.schema_id)
        qos_text = channel.metadata.get("offered_qos_profiles", "")
        topics.append({
            "topic_metadata": {
                "name": channel.topic,
                "type": schema.name if schema is not None else "",
                "serialization_format": channel.message_encoding,
                "offered_qos_profiles": yaml.safe_load(qos_text) or [] if qos_text else [],
                "type_description_hash": channel.metadata.get("topic_type_hash", ""),
            },
            "message_count": stats.channel_message_counts.get(channel_id, 0) if stats else 0,
        })
    return {"rosbag2_bagfile_information": {
        "version": METADATA_VERSION,
        "storage_identifier": STORAGE_IDENTIFIER,
        "relative_file_paths": [mcap_path.name],
        "duration": {"nanoseconds": duration},
        "starting_time": {"nanoseconds_since_epoch": start},
        "message_count": count,
        "topics_with_message_count": topics,
        "compression_format": "",
        "compression_mode": "",
        "files": [{"path": mcap_path.name,
                   "starting_time": {"nanoseconds_since_epoch": start},
                   "duration": {"nanoseconds": duration},
                   "message_count": count}],
        "custom_data": {},
        "ros_distro": ros_distro,
    }}


def write_bag_metadata(directory, mcap_path) -> Path:
    """Write ``directory/metadata.yaml`` for a finished MCAP file (through a temporary file, so
    that a reader never sees half of it). Raises BagError."""
    directory = Path(directory)
    target = directory / METADATA_FILE
    text = yaml.safe_dump(bag_metadata(mcap_path), sort_keys=False, default_flow_style=False)
    temporary = target.with_suffix(".yaml.tmp")
    try:
        temporary.write_text(text, encoding="utf-8")
        temporary.replace(target)
    except OSError as exc:
        raise BagError(directory, f"cannot write {METADATA_FILE}: {exc.strerror or exc}") from exc
    return target


__all__ = ["METADATA_FILE", "METADATA_VERSION", "BagError", "bag_file_path", "bag_log_files",
           "bag_metadata", "is_bag_path", "prepare_bag_directory", "write_bag_metadata"]
