"""Command lines that run one of vm_ros's modules in a child Python process, with the vm_ros that
this process imported (the installed package), never a ``vm_ros/`` folder in the working
directory.

``python -m vm_ros.node`` puts the working directory first on ``sys.path``: started from a source
checkout, the child would run the source tree while this process runs the installed package.
``-P`` (Python 3.11+) leaves the working directory out; on 3.10 the same is done by dropping
``sys.path[0]`` before running the module. The environment puts this process's vm_ros first, so
that a vm_ros reached through PYTHONPATH (a colcon prefix) is the child's too.

    subprocess.Popen(module_command("vm_ros.node", "--ros-args", ...), env=module_environment())
"""

from __future__ import annotations

import contextlib
import os
import sys
from pathlib import Path

import vm_ros

SAFE_PATH_FLAG = sys.version_info >= (3, 11)  # python -P


def module_command(module: str, *args: str, safe_path: bool = SAFE_PATH_FLAG) -> list[str]:
    """``python -P -m MODULE ARGS`` (or its Python 3.10 equivalent when ``safe_path`` is
    False)."""
    if safe_path:
        return [sys.executable, "-P", "-m", module, *args]
    code = ("import runpy, sys; del sys.path[0]; "
            f"runpy.run_module({module!r}, run_name='__main__', alter_sys=True)")
    return [sys.executable, "-c", code, *args]


def module_environment() -> dict:
    """This environment with the folder holding this process's vm_ros first on PYTHONPATH."""
    env = dict(os.environ)
    root = str(Path(vm_ros.__file__).resolve().parent.parent)
    env["PYTHONPATH"] = os.pathsep.join(p for p in (root, env.get("PYTHONPATH")) if p)
    return env


# Fast DDS over UDP alone, for processes inside a loopback-only network namespace. With
# ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST rmw_fastrtps adds Fast DDS's shared-memory transport
# whatever FASTDDS_BUILTIN_TRANSPORTS says; that transport checks a peer's port the first time it
# sends to it and, when a listener of that port was verified idle, sleeps healthy_check_timeout_ms
# / 3 (333 ms) holding its participant's send lock: every publish of that process waits
# (Fast DDS 2.14 SharedMemGlobal.hpp, Port::healthy_check; docs/closed_loop.md). SUBNET leaves the
# transports to Fast DDS, which takes UDPv4 alone from FASTDDS_BUILTIN_TRANSPORTS; the namespace
# has no interface but loopback, and the static peer finds the others without multicast.
UDP_ONLY_ENVIRONMENT = {"ROS_AUTOMATIC_DISCOVERY_RANGE": "SUBNET", "ROS_STATIC_PEERS": "127.0.0.1",
                        "FASTDDS_BUILTIN_TRANSPORTS": "UDPv4"}


def node_environment() -> dict:
    """module_environment() with Fast DDS over UDP alone (UDP_ONLY_ENVIRONMENT): for the nodes
    the demos start inside their loopback-only namespace."""
    return module_environment() | UDP_ONLY_ENVIRONMENT


@contextlib.contextmanager
def environment_kept(names):
    """Within the block, a library may set the environment variables ``names`` in this process
    (OpenSim's import, Dask's nannies); at its end they are put back as they were, so that this
    process's later children do not inherit them."""
    saved = {name: os.environ.get(name) for name in names}
    try:
        yield
    finally:
        for name, value in saved.items():
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value


def loopback_only(command: list) -> list:
    """``command`` inside a new network namespace with only loopback (as scripts/netns-run), in
    the caller's ROS_DOMAIN_ID (42 without one: a test worker's own domain stays its own)."""
    script = ("set -e; ip link set lo up; "
              "export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST ROS_DOMAIN_ID=${ROS_DOMAIN_ID:-42} "
              "FASTDDS_BUILTIN_TRANSPORTS=UDPv4 VM_ROS_NETNS=1; exec \"$@\"")
    return ["unshare", "-n", "bash", "-c", script, "netns-run", *command]


__all__ = ["UDP_ONLY_ENVIRONMENT", "environment_kept", "loopback_only", "module_command",
           "module_environment", "node_environment"]
