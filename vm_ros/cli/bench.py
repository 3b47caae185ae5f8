"""Benchmark the model, offline runs and muscle_node from a checkout of vm_ros.

The benchmarks are for developers: they live in the repository's bench/ folder (the package
vm_ros_bench) and are not installed with vm_ros. This verb finds them (vm_ros_bench importable
already, or bench/vm_ros_bench in the working directory or one of its parents, or beside the
environment this vm_ros is installed in: a .venv made in the checkout) and runs them against the
installed vm_ros; without a checkout it says so in one line.
"""

from __future__ import annotations

import importlib
import importlib.util
import sys
from pathlib import Path

PACKAGE = "vm_ros_bench"
NEEDS_CHECKOUT = ("the benchmarks are not installed with vm_ros: run vm-ros bench in a checkout "
                  "of its repository (they live in its bench/ folder)")


def checkout_candidates() -> list[Path]:
    """Where a checkout is looked for: the working directory and its parents, then the folder
    that holds this Python environment (a .venv made inside the checkout)."""
    cwd = Path.cwd().resolve()
    return [cwd, *cwd.parents, Path(sys.prefix).resolve().parent]


def find_benchmarks(candidates) -> Path | None:
    """The first ``candidate/bench`` folder that holds the vm_ros_bench package, or None."""
    for candidate in candidates:
        folder = Path(candidate) / "bench"
        if (folder / PACKAGE / "__init__.py").is_file():
            return folder
    return None


def benchmarks():
    """vm_ros_bench.cli (its folder put on sys.path when found in a checkout), or None."""
    if importlib.util.find_spec(PACKAGE) is None:
        folder = find_benchmarks(checkout_candidates())
        if folder is None:
            return None
        sys.path.insert(0, str(folder))
    return importlib.import_module(f"{PACKAGE}.cli")


def add_arguments(parser) -> None:
    """The benchmarks' arguments; without a checkout, one error line and exit status 2 (whatever
    the arguments: none of them can be checked without the benchmarks)."""
    module = benchmarks()
    if module is None:
        parser.exit(2, f"{parser.prog}: error: {NEEDS_CHECKOUT}\n")
    parser.description = module.__doc__
    module.add_arguments(parser)


def run(args) -> int:
    return benchmarks().run(args)
