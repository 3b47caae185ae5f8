"""Benchmarks behind `vm-ros bench` (model, offline runs, muscle_node, joint space, the peers).

Developer-only: this package lives in the repository's bench/ folder and is not installed with
vm_ros. The installed `vm-ros bench` verb finds it in a checkout (vm_ros.cli.bench) and runs
:func:`vm_ros_bench.cli.run`; the installed vm_ros is what it measures.
"""

from __future__ import annotations

import os
from pathlib import Path

from vm_ros.child_process import module_environment

FOLDER = Path(__file__).resolve().parent.parent  # bench/, which holds this package


def child_environment() -> dict:
    """vm_ros.child_process.module_environment() with this package's folder on PYTHONPATH too,
    for a child process that runs one of these modules (``python -P -m vm_ros_bench.X``)."""
    env = module_environment()
    env["PYTHONPATH"] = os.pathsep.join(p for p in (env.get("PYTHONPATH"), str(FOLDER)) if p)
    return env
