"""Batch studies: many offline runs (inputs x parameter changes) on Dask distributed, one results
table (Parquet and CSV), resumable and robust to failed runs and lost workers.

    study = load_study("config/studies/fig7_slow_fraction.yaml")   # validated, nothing runs
    client, cluster = Engine().open()                               # vm_ros.study.engine
    summary = run_study(study, Path("out/fig7"), client, verbs)     # verbs: vm_ros.cli.study

Modules: ``study_file`` (the study file and its runs), ``task`` (one run on a worker: the verb's own
runner and log writer, handed in by the command line), ``table`` (rows of finished
runs on disk, the consolidated table), ``engine`` (Dask client and cluster, submission, resume,
faults), ``report`` (main-effect plots and the printed table). docs/studies.md has the file
format.

The study extra (``pip install "vm_ros[study]"``: dask[distributed] and pyarrow) is needed for
``engine`` and ``table``; ``study_file`` needs neither.
"""

from __future__ import annotations

from importlib.util import find_spec

from vm_ros.errors import VmRosError

EXTRA_MODULES = ("distributed", "pyarrow")


def require_extra() -> None:
    """VmRosError (one line, exit 2) naming the extra to install when a module of it is
    missing."""
    missing = [name for name in EXTRA_MODULES if find_spec(name) is None]
    if missing:
        raise VmRosError(f"studies need the study extra ({', '.join(missing)} not installed): "
                         "pip install \"vm_ros[study]\"")
