"""What the published energetics models alone cost per step of a 1000-muscle compiled run: the
thread's CPU time of ``BankModels.advance`` (all 8 models, compiled loops) over the outputs of
the bench's 100-step run (model_bench._inputs), the part of ``MuscleBank.run`` the models add.

With ``--against COMMIT`` the same call of that commit's vm_ros (its ``vm_ros`` and ``config``
taken with ``git archive`` into ~/.cache/vm_ros/against/COMMIT as the package
``vm_ros_at_COMMIT``) is timed in the same thread, the two alternating repeat by repeat, so
that a shared machine's load hits both alike; the line gives both medians and the median of
the paired ratios. Run from a checkout:

    PYTHONPATH=bench .venv/bin/python -m vm_ros_bench.models_advance_timer --against 51324c0
"""

from __future__ import annotations

import argparse
import importlib
import io
import re
import statistics
import subprocess
import sys
import tarfile
import time
from pathlib import Path

import numpy as np

import vm_ros
from vm_ros.resources import cache_home
from vm_ros_bench.model_bench import DT, _inputs, library_bank

_IMPORT = re.compile(r"^(\s*)(from|import) vm_ros\b", re.MULTILINE)


def resolved_commit(commit: str) -> str | None:
    """``commit`` (any name git takes: a hash, a branch, HEAD~1) as its full hash in the
    checkout vm_ros is imported from; None when git cannot name it there."""
    done = subprocess.run(["git", "rev-parse", "--verify", "--quiet", f"{commit}^{{commit}}"],
                          capture_output=True, text=True,
                          cwd=Path(vm_ros.__file__).resolve().parents[1])
    return done.stdout.strip() if done.returncode == 0 and done.stdout.strip() else None


def package_at(commit: str) -> str:
    """The name of the vm_ros of ``commit`` (a full hash: :func:`resolved_commit`), importable
    (made under cache_home()/against/)."""
    name = f"vm_ros_at_{commit}"
    root = cache_home() / "against" / commit
    if not (root / name).is_dir():
        archive = subprocess.run(["git", "archive", commit, "vm_ros", "config"],
                                 check=True, capture_output=True,
                                 cwd=Path(vm_ros.__file__).resolve().parents[1]).stdout
        root.mkdir(parents=True, exist_ok=True)
        with tarfile.open(fileobj=io.BytesIO(archive)) as tar:
            tar.extractall(root)
        (root / "vm_ros").rename(root / name)
        for source in (root / name).rglob("*.py"):
            source.write_text(_IMPORT.sub(rf"\1\2 {name}", source.read_text()))
    if str(root) not in sys.path:
        sys.path.insert(0, str(root))
    return name


def advance_timers(package: str, n: int, batch: int, selection: str):
    """A function timing (thread CPU, us per step) one BankModels.advance of ``package``
    (vm_ros or a copy of another commit's) over a ``batch``-step run of ``n`` muscles."""
    in_bank = importlib.import_module(f"{package}.model.energetics_models.in_bank")
    vm_state = importlib.import_module(f"{package}.model.energetics_models.vm_state")
    bank = library_bank(n, backend="numba")
    u, lp, vp = _inputs(bank, batch)
    bank.reset(lp[0], excitation=u[0])
    run = bank.run(DT, u, lp, vp)
    models = in_bank.BankModels(selection, vm_state.VmMuscleConstants.from_bank(bank))
    arrays = (np.asarray(run.time_s), run.excitation, run.effective_activation,
              run.fascicle_length, run.fascicle_velocity)

    def timed() -> float:
        models.reset()
        c0 = time.thread_time()
        models.advance(DT, *arrays)
        return 1e6 * (time.thread_time() - c0) / batch

    timed()  # caches warming
    return timed


def packages_timed(parser: argparse.ArgumentParser, against: str | None) -> list[str]:
    """["vm_ros"], and with ``against`` (a commit's name, --against) that commit's copy
    (package_at); a parser error when git cannot name it."""
    if not against:
        return ["vm_ros"]
    commit = resolved_commit(against)
    if commit is None:
        parser.error(f"--against {against}: not a commit of the checkout vm_ros is "
                     f"imported from ({Path(vm_ros.__file__).resolve().parents[1]})")
    return ["vm_ros", package_at(commit)]


def paired_medians(timers: list, repeats: int, against: str | None) -> str:
    """Each timer called ``repeats`` times, the timers alternating call by call: "median X us"
    of the first, and with ``against`` (the second's commit) "; COMMIT: Y us; paired ratio R"
    (the median of the repeats' ratios)."""
    times = [[] for _ in timers]
    for _ in range(repeats):
        for timer, series in zip(timers, times, strict=True):
            series.append(timer())
    line = f"median {statistics.median(times[0]):.1f} us"
    if against:
        ratios = [new / old for new, old in zip(*times, strict=True)]
        line += (f"; {against}: {statistics.median(times[1]):.1f} us; paired ratio "
                 f"{statistics.median(ratios):.3f}")
    return line


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--muscles", type=int, default=1000)
    parser.add_argument("--batch", type=int, default=100)
    parser.add_argument("--repeats", type=int, default=31)
    parser.add_argument("--selection", default="all")
    parser.add_argument("--against", metavar="COMMIT", help="time this commit's vm_ros too")
    args = parser.parse_args(argv)
    timers = [advance_timers(p, args.muscles, args.batch, args.selection)
              for p in packages_timed(parser, args.against)]
    print(f"models advance, {args.muscles} muscles x {args.batch} steps, thread CPU per step: "
          f"{paired_medians(timers, args.repeats, args.against)} ({args.repeats} repeats)")


if __name__ == "__main__":
    main()
