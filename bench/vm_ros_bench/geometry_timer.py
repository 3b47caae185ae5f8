"""What one compiled ``PolynomialGeometry.evaluate(q, qdot)`` of the myolegs geometry costs: the
thread's CPU time per call over blocks of calls cycling through the joint bench's poses (the
poses and velocities of ``joint_bench.bench_geometry``), the call ``vm-ros bench --only joint``
times in its row 'geometry evaluate compiled', without the rest of the joint section.

The geometry is the joint bench's import (``joint_bench.import_myolegs``, made once under
cache_home()/geometry-timer/ when ``--geometry`` names no file; needs the mujoco extra). With
``--against COMMIT`` the same call of that commit's vm_ros (models_advance_timer.package_at)
is timed in the same thread, the two alternating block by block, so that a shared machine's
load hits both alike; the line gives both medians and the median of the paired ratios. Run
from a checkout:

    PYTHONPATH=bench .venv/bin/python -m vm_ros_bench.geometry_timer --against 01d8dc3
"""

from __future__ import annotations

import argparse
import importlib
import time
from pathlib import Path

import numpy as np

from vm_ros.resources import cache_home
from vm_ros_bench.joint_bench import POSES, QDOT_MAX, import_myolegs
from vm_ros_bench.models_advance_timer import packages_timed, paired_medians


def evaluate_timer(package: str, geometry_file: Path, calls: int):
    """A function timing (thread CPU, us per call) ``calls`` compiled evaluate(q, qdot) calls of
    ``package``'s geometry (vm_ros or a copy of another commit's) at the bench's poses."""
    geometry = importlib.import_module(f"{package}.geometry").load_geometry(
        geometry_file, backend="compiled")
    rng = np.random.default_rng(0)  # bench_geometry's poses and velocities
    n_q = len(geometry.coordinates)
    q = geometry.lower + (geometry.upper - geometry.lower) * rng.random((POSES, n_q))
    qdot = QDOT_MAX * (2 * rng.random((POSES, n_q)) - 1)
    poses = list(zip(q, qdot, strict=True))
    evaluate = geometry.evaluate

    def timed() -> float:
        c0 = time.thread_time()
        for k in range(calls):
            evaluate(*poses[k % POSES])
        return 1e6 * (time.thread_time() - c0) / calls

    timed()  # compilation, caches
    return timed


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--geometry", type=Path, help="a geometry file (default: the joint "
                        "bench's myolegs import, made once)")
    parser.add_argument("--calls", type=int, default=2000, help="calls per block")
    parser.add_argument("--repeats", type=int, default=15, help="blocks of each")
    parser.add_argument("--against", metavar="COMMIT", help="time this commit's vm_ros too")
    args = parser.parse_args(argv)
    geometry_file = args.geometry or Path(import_myolegs(
        cache_home() / "geometry-timer" / "myolegs")["geometry"])
    timers = [evaluate_timer(p, geometry_file, args.calls)
              for p in packages_timed(parser, args.against)]
    print(f"geometry evaluate compiled, {geometry_file}, thread CPU per call: "
          f"{paired_medians(timers, args.repeats, args.against)} ({args.repeats} blocks of "
          f"{args.calls} calls)")


if __name__ == "__main__":
    main()
