"""Versions of vm_ros and of the libraries a run depends on, for the log's metadata."""

from __future__ import annotations

import functools
import platform
from importlib.metadata import PackageNotFoundError, version


@functools.cache
def package_version(name: str) -> str:
    """Installed version of a distribution, or "unknown" (e.g. vm_ros from a bare source tree).
    Looked up once per process: the lookup parses the distribution's metadata file (about 1.4 ms
    each), and a node opens its run log at the model's start, when every millisecond is the
    model's (vm_ros.node.recording.NodeRunLog looks them up when it is created)."""
    try:
        return version(name)
    except PackageNotFoundError:
        return "unknown"


VM_ROS_VERSION = package_version("vm_ros")


def library_versions() -> dict[str, str]:
    """``{name: version}`` of Python, vm_ros and the numerical and MCAP libraries (each looked
    up once per process: package_version)."""
    versions = {"python": platform.python_version()}
    for name in ("vm_ros", "numpy", "scipy", "mcap", "mcap-ros2-support"):
        versions[name] = package_version(name)
    return versions
