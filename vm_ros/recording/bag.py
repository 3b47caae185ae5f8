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
readers then read the directory's ``.mcap`` files; ``vm-ros bag reindex NAME``
(vm_ros.recording.reader.reindex_bag), as ``ros2 bag reindex NAME``, writes the metadata for
rosbag2. How the readers take damaged directories: bag_files.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path, PurePosixPath
from typing import NamedTuple

import yaml
from mcap.reader import make_reader

from vm_ros.errors import ITEMS_SHOWN, VmRosError

SUFFIX = ".mcap"
METADATA_FILE = "metadata.yaml"
METADATA_VERSION = 9  # rosbag2_storage BagMetadata in ROS 2 Jazzy
STORAGE_IDENTIFIER = "mcap"
ROS_DISTRO = "jazzy"
INFO_KEY = "rosbag2_bagfile_information"
# why a bag with a file missing is not read as one log
GAP = f"the log has a gap (each remaining {SUFFIX} file is a run log of its own and reads alone)"
# LibYAML's parser where PyYAML has it (large metadata files: docs/performance.md)
_YAML_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
MAX_METADATA_DEPTH = 16  # rosbag2 metadata nests 8 levels (to a QoS profile's durations)


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


def directory_files(directory) -> list[Path]:
    """The ``*.mcap`` files of a directory, NAME_2.mcap before NAME_10.mcap."""
    return sorted(Path(directory).glob(f"*{SUFFIX}"), key=_file_order)


class BagFiles(NamedTuple):
    """The MCAP files of a bag directory that make its log, in order, and the directory's other
    ``.mcap`` files (not listed in metadata.yaml: not read)."""

    files: list
    unlisted: tuple = ()

    def note(self) -> str | None:
        """``bag runs/x: 1 .mcap file not listed in metadata.yaml, not read: y.mcap``, or None."""
        if not self.unlisted:
            return None
        count = len(self.unlisted)
        return (f"bag {self.files[0].parent}: {count} .mcap file{'s' if count != 1 else ''} not "
                f"listed in {METADATA_FILE}, not read: {', '.join(self.unlisted)}")


def _yaml_problem(exc: yaml.YAMLError) -> str:
    """A YAML error in one line: ``line 3, column 7: could not find expected ':'``."""
    mark = getattr(exc, "problem_mark", None)
    problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
    return f"line {mark.line + 1}, column {mark.column + 1}: {problem}" if mark else problem


def _nesting_depth(text: str) -> int:
    """How deeply the YAML document's mappings and sequences nest, from the parser's events
    (the parser does not recurse; building the document recurses once per level)."""
    depth = deepest = 0
    for event in yaml.parse(text, Loader=_YAML_LOADER):
        if isinstance(event, (yaml.MappingStartEvent, yaml.SequenceStartEvent)):
            depth += 1
            deepest = max(deepest, depth)
        elif isinstance(event, (yaml.MappingEndEvent, yaml.SequenceEndEvent)):
            depth -= 1
    return deepest


def _load_yaml(text: str):
    """``yaml.safe_load(text)``; raises ValueError in one line when it is not YAML or nests
    deeper than MAX_METADATA_DEPTH."""
    try:
        depth = _nesting_depth(text)
        if depth > MAX_METADATA_DEPTH:
            raise ValueError(f"nested {depth} levels deep (rosbag2 metadata nests at most "
                             f"{MAX_METADATA_DEPTH})")
        return yaml.load(text, Loader=_YAML_LOADER)  # noqa: S506 (a safe loader)
    except yaml.YAMLError as exc:
        raise ValueError(f"not valid YAML ({_yaml_problem(exc)})") from None


def _listed_names(directory: Path) -> list[str]:
    """relative_file_paths of ``directory/metadata.yaml``. Raises BagError (one line) when the
    file is not UTF-8, not YAML, nested deeper than rosbag2 metadata ever is, not rosbag2
    metadata, or names a file outside the directory."""
    def fail(reason: str):
        raise BagError(directory, f"{METADATA_FILE}: {reason}")

    try:
        data = (directory / METADATA_FILE).read_bytes()
    except OSError as exc:
        fail(f"cannot be read ({exc.strerror or exc})")
    try:
        document = _load_yaml(data.decode("utf-8"))
    except UnicodeDecodeError as exc:
        fail(f"not UTF-8 text (byte 0x{data[exc.start]:02x} at offset {exc.start})")
    except ValueError as exc:
        fail(str(exc))
    info = document.get(INFO_KEY) if isinstance(document, dict) else None
    names = info.get("relative_file_paths") if isinstance(info, dict) else None
    if not (isinstance(names, list) and names and all(isinstance(n, str) and n for n in names)):
        fail(f"no {INFO_KEY}.relative_file_paths list of file names")
    for name in names:
        path = PurePosixPath(name)
        if path.is_absolute() or ".." in path.parts or "\\" in name:
            fail(f"file path {name!r} is outside the bag directory (relative_file_paths name "
                 "files inside it)")
    return names


def check_numbering(directory: Path, files: list[Path]) -> None:
    """The recorder's files NAME_0.mcap, NAME_1.mcap... run without a gap. Raises BagError
    naming the missing ones."""
    indices = {int(f.stem[len(directory.name) + 1:]) for f in files
               if f.stem.startswith(f"{directory.name}_")
               and f.stem[len(directory.name) + 1:].isdigit()}
    missing = sorted(set(range(max(indices, default=-1) + 1)) - indices)
    if missing:
        shown = ", ".join(f"{directory.name}_{k}{SUFFIX}" for k in missing[:ITEMS_SHOWN])
        more = f" and {len(missing) - ITEMS_SHOWN} more" if len(missing) > ITEMS_SHOWN else ""
        raise BagError(directory, f"{shown}{more} missing: {GAP}")


def bag_files(directory) -> BagFiles:
    """The MCAP files of a bag directory, in order: metadata.yaml's relative_file_paths, or
    without it (a recorder killed before finishing) the directory's ``*.mcap`` files by name;
    with metadata.yaml, the directory's other ``.mcap`` files are not read (as by rosbag2) but
    named in ``unlisted``. Raises BagError (one line) when metadata.yaml cannot be used (see
    _listed_names), a file it lists is missing, the recorder's numbered files have a gap, or
    there is no file."""
    directory = Path(directory)
    present = directory_files(directory)
    if (directory / METADATA_FILE).is_file():
        names = _listed_names(directory)
        files = [directory / name for name in names]
        missing = [name for name in names if not (directory / name).is_file()]
        if missing:
            raise BagError(directory, f"{METADATA_FILE} lists {', '.join(missing[:ITEMS_SHOWN])}"
                                      f", missing from the directory: {GAP}")
        listed = {f.resolve() for f in files}
        unlisted = tuple(f.name for f in present if f.resolve() not in listed)
    else:
        files, unlisted = present, ()
    if not files:
        raise BagError(directory, f"no {SUFFIX} file in the bag directory")
    check_numbering(directory, files)
    return BagFiles(files, unlisted)


def bag_log_files(directory) -> list[Path]:
    """``bag_files(directory).files``."""
    return bag_files(directory).files


class FileStats(NamedTuple):
    """What metadata.yaml says of one MCAP file: its channels as (mcap Channel, schema name,
    messages), its message count, and its first and last log time (ns; 0 without messages)."""

    channels: list
    message_count: int
    start_ns: int
    end_ns: int


def summary_stats(mcap_path) -> FileStats:
    """FileStats from a finished file's summary section. Raises BagError when it has none."""
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
    counts = stats.channel_message_counts if stats else {}
    count = stats.message_count if stats else 0
    schemas = summary.schemas
    return FileStats([(channel, schemas[channel.schema_id].name
                       if channel.schema_id in schemas else "", counts.get(channel_id, 0))
                      for channel_id, channel in sorted(summary.channels.items())],
                     count, stats.message_start_time if count else 0,
                     stats.message_end_time if count else 0)


def _qos_profiles(path: Path, channel) -> list:
    """A channel's offered_qos_profiles metadata (YAML text) as a list. Raises BagError."""
    text = channel.metadata.get("offered_qos_profiles", "")
    try:
        profiles = _load_yaml(text) if text else []
    except ValueError as exc:
        raise BagError(path.parent, f"{path.name}: channel {channel.topic}: "
                                    f"offered_qos_profiles {exc}") from None
    return profiles or []


def _span(start: int, end: int) -> dict:
    return {"starting_time": {"nanoseconds_since_epoch": start},
            "duration": {"nanoseconds": end - start}}


def bag_metadata(mcap_paths, ros_distro: str = ROS_DISTRO,
                 file_stats: Callable[[Path], FileStats] = summary_stats) -> dict:
    """rosbag2's metadata (version 9) of MCAP files (one path or a list, in order), as the dict
    that metadata.yaml holds; ``file_stats`` reads each file (default: its summary section, so
    the files must be finished). Raises BagError."""
    paths = [Path(mcap_paths)] if isinstance(mcap_paths, (str, Path)) else \
        [Path(p) for p in mcap_paths]
    topics: dict[str, dict] = {}
    files, starts, ends = [], [], []
    for path in paths:
        stats = file_stats(path)
        if stats.message_count:
            starts.append(stats.start_ns)
            ends.append(stats.end_ns)
        files.append({"path": path.name, **_span(stats.start_ns, stats.end_ns),
                      "message_count": stats.message_count})
        for channel, type_name, count in stats.channels:
            entry = topics.setdefault(channel.topic, {
                "topic_metadata": {
                    "name": channel.topic,
                    "type": type_name,
                    "serialization_format": channel.message_encoding,
                    "offered_qos_profiles": _qos_profiles(path, channel),
                    "type_description_hash": channel.metadata.get("topic_type_hash", ""),
                },
                "message_count": 0})
            entry["message_count"] += count
    start, end = (min(starts), max(ends)) if starts else (0, 0)
    return {INFO_KEY: {
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


def write_bag_metadata(directory, mcap_paths,
                       file_stats: Callable[[Path], FileStats] = summary_stats) -> Path:
    """Write ``directory/metadata.yaml`` for MCAP files (bag_metadata; through a temporary
    file, so that a reader never sees half of it). Raises BagError."""
    directory = Path(directory)
    target = directory / METADATA_FILE
    text = yaml.safe_dump(bag_metadata(mcap_paths, file_stats=file_stats), sort_keys=False,
                          default_flow_style=False)
    temporary = target.with_suffix(".yaml.tmp")
    try:
        temporary.write_text(text, encoding="utf-8")
        temporary.replace(target)
    except OSError as exc:
        raise BagError(directory, f"cannot write {METADATA_FILE}: {exc.strerror or exc}") from exc
    return target


__all__ = ["METADATA_FILE", "METADATA_VERSION", "BagError", "BagFiles", "FileStats",
           "bag_file_path", "bag_files", "bag_log_files", "bag_metadata", "check_numbering",
           "directory_files", "is_bag_path", "prepare_bag_directory", "summary_stats",
           "write_bag_metadata"]
