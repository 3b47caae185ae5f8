"""Where the shipped configuration lives (source checkout, `pip install .` and colcon alike), and
vm_ros's folder of caches."""

from __future__ import annotations

import os
import sys
from pathlib import Path

from vm_ros.errors import VmRosError

_MARKER = "model.yaml"


def config_dir() -> Path:
    """Return the directory holding the shipped config YAML files.

    Order: ``$VM_ROS_CONFIG_DIR``; the source tree's ``config/`` (beside the package); the install
    prefix's ``share/vm_ros/config`` (found from this module's location, which covers colcon
    prefixes, then from ``sys.prefix``, which covers a pip venv).
    """
    candidates = []
    if os.environ.get("VM_ROS_CONFIG_DIR"):
        candidates.append(Path(os.environ["VM_ROS_CONFIG_DIR"]))
    package_dir = Path(__file__).resolve().parent
    candidates.append(package_dir.parent / "config")
    # <prefix>/lib/pythonX.Y/site-packages/vm_ros -> <prefix>
    if len(package_dir.parents) > 3:
        candidates.append(package_dir.parents[3] / "share" / "vm_ros" / "config")
    candidates.append(Path(sys.prefix) / "share" / "vm_ros" / "config")
    for candidate in candidates:
        if (candidate / _MARKER).is_file():
            return candidate
    raise VmRosError(
        "vm_ros configuration not found; looked in: "
        + ", ".join(str(c) for c in candidates)
        + " (set VM_ROS_CONFIG_DIR to the folder holding model.yaml)"
    )


def cache_home() -> Path:
    """vm_ros's folder of caches: ``$XDG_CACHE_HOME/vm_ros`` (XDG_CACHE_HOME defaults to
    ~/.cache)."""
    return Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "vm_ros"
