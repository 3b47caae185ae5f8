"""The ``vm-ros`` command: one module per verb under vm_ros.cli.

Each verb module defines ``HELP`` (one line), ``add_arguments(parser)`` and ``run(args) -> int``.
A verb whose module needs something not installed (rclpy, matplotlib) says so when run, not at
start-up, so the other verbs keep working.
"""

from __future__ import annotations

import argparse
import importlib
import sys

from vm_ros.errors import VmRosError

# verb name -> module under vm_ros.cli
VERBS = {
    "simulate": "simulate",
    "replay": "replay",
    "recompute": "recompute",
    "report": "report",
    "validate": "validate",
    "fit-w": "fit_w",
    "bench": "bench",
    "demo": "demo",
    "import-osim": "import_osim",
    "import-mjcf": "import_mjcf",
    "closed-loop": "closed_loop",
    "params": "params",
    "compare-energetics": "compare_energetics",
    "bag": "bag",
}


def _available_verbs():
    for verb, module_name in VERBS.items():
        try:
            module = importlib.import_module(f"vm_ros.cli.{module_name}")
        except ModuleNotFoundError as exc:
            if exc.name == f"vm_ros.cli.{module_name}":
                continue  # verb not implemented in this version
            raise
        yield verb, module


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="vm-ros",
        description="Virtual Muscle force and fibre-type energetics: offline tools for vm_ros.",
    )
    sub = parser.add_subparsers(dest="verb", metavar="VERB", required=True)
    for verb, module in _available_verbs():
        verb_parser = sub.add_parser(verb, help=module.HELP, description=module.__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
        module.add_arguments(verb_parser)
        verb_parser.set_defaults(_run=module.run)
    return parser


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return int(args._run(args) or 0)
    except VmRosError as exc:
        print(f"vm-ros {args.verb}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"vm-ros {args.verb}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
