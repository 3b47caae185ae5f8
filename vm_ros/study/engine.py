"""Run a study on Dask distributed: the client submits one task per run that has no finished
record, records each run as its future completes and remakes the table at the end.

Where things happen:
- scheduling, retries and lost workers are Dask's: ``client.submit(execute, task,
  retries=study.retries)``; a worker that dies (SIGKILL, out of memory) has its tasks rerun on
  another by the scheduler, up to ``distributed.scheduler.allowed-failures`` times, after which
  the run is recorded as failed (KilledWorker);
- the records are written by the client (vm_ros.study.table.RecordStore) as
  ``distributed.as_completed`` yields each future, so a finished row is on the client's disk
  before anything else happens, and one file per run id means a run that ran twice is recorded
  once;
- logs are written by the workers under ``DIR/runs/`` (a folder every worker must see: the
  same machine, or a shared file system on a cluster); the half-written log of a run whose
  worker died is removed by the client once every run has finished;
- Ctrl-C (KeyboardInterrupt in the client) cancels the runs not yet finished, writes the table
  of those that did and closes the cluster;
- a file of the study folder that the client cannot write (disk full, no permission: OSError)
  stops the study the same way, with one line naming the file (StudyWriteError); the records
  written before it are kept;
- a run whose record is ok but whose log is missing from ``runs/`` is run again, its record
  replaced.

The embedded cluster (no --scheduler) is a ``LocalCluster`` of one single-threaded worker
process per CPU this process may use (default_workers), bound to 127.0.0.1, without a
dashboard, with less of Dask's periodic work and with the workers' C allocator keeping the log
chunks' buffers (EMBEDDED_CONFIG): on 2 cores the client, scheduler and nannies share the cores
with the workers. Its workers do not print Dask's "Compute Failed" report of a run that raised
(QuietWorkers): the client records the run's one-line error.
"""

from __future__ import annotations

import contextlib
import logging
import os
import signal
import sys
import uuid
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path

from distributed.diagnostics.plugin import WorkerPlugin

from vm_ros.child_process import environment_kept
from vm_ros.errors import VmRosError
from vm_ros.study.study_file import Study
from vm_ros.study.table import (
    PARAMS_DIR,
    RUNS_DIR,
    RecordStore,
    failed_record,
    write_atomically,
    write_table,
)
from vm_ros.study.task import STATUS_OK, RunTask, Verb, execute, one_line, partial_logs

LOOPBACK = "127.0.0.1"
# Dask's address schemes whose connections need TLS settings (distributed.comm.tls.* in the Dask
# configuration, https://distributed.dask.org/en/stable/tls.html)
TLS_SCHEMES = ("tls", "wss")
# Dask settings of the embedded cluster (a running cluster keeps its own): no statistical
# profiler in the workers (it samples the running task's stack every 10 ms for the dashboard,
# which the embedded cluster does not serve) and the event loops' blocked-loop check every second
# instead of every 20 ms. An idle 2-worker cluster took 0.08 cores with Dask's defaults and 0.03
# with these (client, scheduler and nannies 0.032 -> 0.015-0.019, each worker 0.023 -> 0.007;
# process CPU times over 15 s, measured on 2026-12-02 at load average 12-13). The workers' and
# nannies' memory monitor (the memory limit: pause, spill, restart) looks every second instead of
# every 100 ms, and the system monitor (CPU, memory, disk and network counters for the dashboard)
# every 2 s instead of 500 ms: an idle 2-worker cluster 0.038 -> 0.017 cores (client, scheduler
# and nannies 0.021 -> 0.009, each worker 0.0085 -> 0.004; 20 s, 2026-12-02, load average 4-6).
# The worker processes' C allocator (glibc) keeps blocks up to 4 MiB in its heap and returns free
# memory to the OS once 8 MiB of it lie at the heap's top, instead of Dask's default
# (MALLOC_TRIM_THRESHOLD_ 65536, which also fixes the mmap threshold at glibc's 128 KiB): a run's
# log is written in chunks of 1 MiB (joined, compressed, framed: several buffers of about 1 MiB
# each), and with Dask's default each of them was mapped and unmapped again, its pages faulted in
# afresh every time: 15,700 page faults per 30 s knee-extension run, 200 with these (1-worker
# study, 32 runs, 2026-12-02, load average 6.5-7.9), the workers' CPU per run 0.314-0.337 ->
# 0.289-0.293 s (system time 0.051-0.059 -> 0.011-0.015 s). Dask sets these before it spawns a
# worker (distributed.nanny.pre-spawn-environ; glibc reads them at start-up).
MALLOC_ENVIRON = {"MALLOC_MMAP_THRESHOLD_": 4 << 20, "MALLOC_TRIM_THRESHOLD_": 8 << 20}
EMBEDDED_CONFIG = {"distributed.worker.profile.enabled": False,
                   "distributed.admin.tick.interval": "1s",
                   "distributed.worker.memory.monitor-interval": "1s",
                   "distributed.admin.system-monitor.interval": "2s",
                   **{f"distributed.nanny.pre-spawn-environ.{name}": value
                      for name, value in MALLOC_ENVIRON.items()}}


@dataclass(frozen=True)
class Engine:
    """Where runs execute: ``scheduler`` (address of a running Dask scheduler) or an embedded
    LocalCluster of ``workers`` processes (default: one per core)."""

    scheduler: str | None = None
    workers: int | None = None

    def open(self):
        """(client, cluster or None); close both with :func:`close`. VmRosError when the
        scheduler's address is not one Dask can connect to (:func:`check_scheduler_address`)."""
        import dask
        from distributed import Client, LocalCluster

        if self.scheduler:
            return Client(check_scheduler_address(self.scheduler)), None
        # the nannies hand EMBEDDED_CONFIG to the workers, and set its pre-spawn-environ in this
        # process's own environment too (Dask's Nanny): put back after the start, so that this
        # process's later children (a node, another bench section) do not inherit it
        with environment_kept(MALLOC_ENVIRON), dask.config.set(EMBEDDED_CONFIG):
            cluster = LocalCluster(n_workers=self.workers or default_workers(),
                                   threads_per_worker=1, processes=True, host=LOOPBACK,
                                   dashboard_address=None, silence_logs=logging.ERROR)
            client = Client(cluster)
        client.register_plugin(QuietWorkers())
        return client, cluster


def default_workers() -> int:
    """The CPUs this process may run on (its affinity mask, where the OS keeps one: taskset, a
    batch job's or container's cpuset), else every CPU of the machine."""
    if hasattr(os, "sched_getaffinity"):
        return len(os.sched_getaffinity(0))
    return os.cpu_count() or 1


def check_scheduler_address(address: str) -> str:
    """``address`` as Dask writes it (``tcp://`` when no scheme is given), checked with Dask's
    own parser before connecting; VmRosError naming --scheduler otherwise: no scheme Dask
    knows, no port, or a TLS scheme without Dask's TLS settings."""
    from distributed.comm.addressing import get_address_host_port, normalize_address, parse_address
    from distributed.security import Security

    try:
        full = normalize_address(address)
        get_address_host_port(full)
    except ValueError as error:
        raise VmRosError(f"--scheduler {address}: {error}; give the scheduler's address as "
                         "tcp://HOST:PORT") from None
    if (parse_address(full)[0] in TLS_SCHEMES
            and Security().get_connection_args("client")["ssl_context"] is None):
        raise VmRosError(f"--scheduler {address}: a TLS address needs Dask's TLS settings "
                         "(distributed.comm.tls.ca-file, .client.cert, .client.key in the Dask "
                         "configuration); or give a tcp://HOST:PORT address")
    return full


class QuietWorkers(WorkerPlugin):
    """The embedded cluster's workers (and those the nannies restart) ignore SIGINT: Ctrl-C in
    the terminal reaches the whole process group, and it is the client that stops the study
    and closes the cluster. They leave out Dask's multi-line "Compute Failed" report (the
    exception's repr, the traceback) of a run that raised: the client records its one-line
    error, and the terminal is the user's (dask/distributed#6882 asks for a setting)."""

    def setup(self, worker) -> None:
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        logging.getLogger("distributed.worker").addFilter(_not_a_task_error)


def _not_a_task_error(record: logging.LogRecord) -> bool:
    return not str(record.msg).startswith("Compute Failed")


class StudyWriteError(VmRosError):
    """A file of the study folder could not be written (disk full, no permission): the study
    stops, keeping the records written before."""


@contextlib.contextmanager
def writing(what) -> Iterator[None]:
    """OSError in the block -> StudyWriteError naming ``what`` (a file of the study folder)."""
    try:
        yield
    except OSError as error:
        raise StudyWriteError(f"writing {what} failed: {error}") from None


def close(client, cluster) -> None:
    client.close()
    if cluster is not None:
        cluster.close()


@dataclass
class StudySummary:
    """What ``run_study`` did: runs in the study, skipped (finished before), ok and failed now,
    not finished (interrupted), table rows."""

    runs: int
    skipped: int = 0
    ok: int = 0
    failed: int = 0
    interrupted: int = 0
    rows: int = 0

    def line(self) -> str:
        text = (f"{self.runs} runs: {self.skipped} finished before, {self.ok} ok, "
                f"{self.failed} failed")
        if self.interrupted:
            text += f", {self.interrupted} not finished (interrupted)"
        return f"{text}; {self.rows} table rows"


def prepare(study: Study, out_dir: Path) -> None:
    """The study folder: runs/, params/ (model files of model.* changes, by content) and a copy
    of the study file."""
    out_dir = Path(out_dir)
    with writing(out_dir / RUNS_DIR):
        (out_dir / RUNS_DIR).mkdir(parents=True, exist_ok=True)
    params = out_dir / PARAMS_DIR
    for spec in study.runs:
        if spec.params_text is not None and not (params / spec.params_name).exists():
            with writing(params / spec.params_name):
                params.mkdir(exist_ok=True)
                write_atomically(params / spec.params_name, spec.params_text.encode())
    with writing(out_dir / "study.yaml"):
        write_atomically(out_dir / "study.yaml", study.path.read_bytes())


def missing_logs(runs: list[RunTask], finished: Mapping[str, dict]) -> list[str]:
    """Ids of the finished runs whose log is not in runs/ (deleted, moved): to run again."""
    return [task.run_id for task in runs
            if task.run_id in finished and not Path(task.log_path).exists()]


def _write_table(study: Study, out_dir: Path) -> int:
    with writing(f"the table in {out_dir} (results.parquet, results.csv, runs.csv)"):
        return write_table(study, out_dir)


def tasks(study: Study, out_dir: Path, verbs: Mapping[str, Verb]) -> list[RunTask]:
    out_dir = Path(out_dir).resolve()
    found = []
    for spec in study.runs:
        argv = list(spec.argv)
        if spec.params_text is not None:
            argv += ["--params", str(out_dir / PARAMS_DIR / spec.params_name)]
        found.append(RunTask(spec.run_id, verbs[spec.verb], tuple(argv),
                             str(out_dir / RUNS_DIR / f"{spec.run_id}.mcap"),
                             study.start_time_ns))
    return found


def run_study(study: Study, out_dir: Path, client, verbs: Mapping[str, Verb],
              say: Callable[[str], None] = print,
              on_record: Callable[[dict], None] = lambda record: None) -> StudySummary:
    """Run the study's runs that have no finished record on ``client`` with ``verbs`` (name ->
    Verb: simulate, recompute); record each as it completes (``on_record`` is called after),
    then write the table. KeyboardInterrupt cancels what is left, writes the table and is
    re-raised; so is StudyWriteError (a record or the table could not be written)."""
    from distributed import as_completed

    out_dir = Path(out_dir)
    prepare(study, out_dir)
    store = RecordStore(out_dir)
    every = tasks(study, out_dir, verbs)
    finished = store.finished(study)
    lost = missing_logs(every, finished)
    for run_id in lost:
        del finished[run_id]
    todo = [task for task in every if task.run_id not in finished]
    summary = StudySummary(len(study.runs), skipped=len(finished))
    say(f"study {study.name}: {len(study.runs)} runs, {len(finished)} finished before, "
        f"{len(todo)} to run" + (f" ({len(lost)} of them finished before but their log is "
                                 "missing from runs/)" if lost else ""))
    session = uuid.uuid4().hex[:8]  # keys unique to this session on a shared scheduler
    futures = {client.submit(execute, task, key=f"vm_ros-run-{task.run_id}-{session}",
                             retries=study.retries, pure=False): task for task in todo}
    try:
        for done, future in enumerate(as_completed(futures), start=1):
            task = futures.pop(future)  # nothing of a finished run is kept
            try:
                record = future.result()
            except Exception as error:  # raised after Dask's retries, or KilledWorker
                record = failed_record(task.run_id, one_line(error))
            future.release()
            with writing(store.path(task.run_id)):
                store.write(record)
            ok = record["status"] == STATUS_OK
            summary.ok += ok
            summary.failed += not ok
            say(f"[{done}/{len(todo)}] {task.run_id} {record['status']}"
                + (f": {record['error']}" if record.get("error") else ""))
            on_record(record)
    except KeyboardInterrupt:
        client.cancel(list(futures))  # those not finished
        summary.interrupted = len(todo) - summary.ok - summary.failed
        try:
            summary.rows = _write_table(study, out_dir)
        except StudyWriteError as error:
            print(f"vm-ros study: {error}", file=sys.stderr)
        print(f"vm-ros study: interrupted; {summary.line()}", file=sys.stderr)
        raise
    except StudyWriteError:
        client.cancel(list(futures))
        with contextlib.suppress(StudyWriteError):  # the table of the records kept, if it can
            _write_table(study, out_dir)
        raise
    for task in todo:  # every run of the session has finished: no worker writes these any more
        for partial in partial_logs(task):
            partial.unlink(missing_ok=True)
    summary.rows = _write_table(study, out_dir)
    return summary
