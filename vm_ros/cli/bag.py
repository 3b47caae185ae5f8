"""Bag directories (rosbag2's layout, docs/log_format.md section 1).

reindex DIR   write DIR/metadata.yaml from the directory's .mcap files, as `ros2 bag reindex`
              does: a recorder killed before finishing leaves a bag without it, which rosbag2
              readers (ros2 bag, rosbags) refuse. A last file cut short by the kill is first
              finished after its last complete record (what every vm_ros reader reads of it);
              the bytes after that record, which no reader can decode, are kept in
              <file>.cut. An existing metadata.yaml is replaced.
"""

from __future__ import annotations

import argparse
from pathlib import Path


def add_arguments(parser: argparse.ArgumentParser) -> None:
    actions = parser.add_subparsers(dest="action", metavar="ACTION", required=True)
    reindex = actions.add_parser("reindex", help="write DIR/metadata.yaml from its .mcap files")
    reindex.add_argument("directory", type=Path, metavar="DIR", help="bag directory")


def run(args) -> int:
    from vm_ros.recording.bag import METADATA_FILE
    from vm_ros.recording.reader import reindex_bag

    done = reindex_bag(args.directory)
    if done.finished is not None:
        name, moved = done.finished
        kept = f"the {moved} bytes after it kept in {name}.cut" if moved else "nothing after it"
        print(f"{name} was cut short: finished after its last complete record ({kept})")
    count = len(done.files)
    print(f"{args.directory / METADATA_FILE}: {count} file{'s' if count != 1 else ''}, "
          f"{done.message_count} messages")
    return 0
