"""`vm-ros bench --only study`: a study on the embedded Dask LocalCluster (vm_ros.study).

- speed: a 64-run study (the knee extension, 30 s of model time; the vasti's slow-fibre fraction
  library.vasti.fpcsa_slow, 32 values from 0.1 to 0.9, x recovery kernel, 2; rectus femoris
  keeps its library mix) on 1 worker and on 2; speed-up = wall(1) / wall(2), target at
  least 1.8 on 2 cores. The workers are started and warmed (vm_ros imported, the compiled step
  loaded) before the clock starts; the cluster's start is reported apart.
- overhead per run on 1 worker: (study wall - the sum of the runs' own wall times, measured in
  the worker around the verb) / runs, against the mean run: scheduling, result transfer, the
  record written and flushed by the client; target under 5 % of a 30 s run.
- client memory over 1000 short runs (0.05 s of model time each, 2 workers): resident memory of
  this process after every record; growth from the 100th record to the last, target flat
  (at most 10 MiB: a few kB per run would show as several MiB).
- where the CPU goes (the 64-run study on 1 and 2 workers; the client's also over the short
  runs): CPU seconds per run of this process (the client, and with the embedded cluster the
  scheduler and the nannies), of the worker processes, and of the workers' task threads (the
  verb's own thread; the rest of a worker's CPU is the run's log writer thread and Dask's
  worker); the cores the 1-worker study kept busy (CPU / wall); and the speed-up bound these
  CPU times allow on 2 cores, wall(1) / (CPU of the 2-worker study / 2): a 2-worker study cannot
  finish before both cores have done its CPU work. The CPU times hold under load; the wall
  times, the speed-up and these two derived numbers only on an otherwise idle machine: Linux
  with autogroups (kernel.sched_autogroup_enabled) shares the CPU between sessions, so a
  machine loaded by other sessions gives a study about the same share whatever its number of
  workers.
--quick: 8 runs of 5 s and 200 short runs (a smoke run, not the targets).
"""

from __future__ import annotations

import os
import tempfile
import time
from pathlib import Path

SPEEDUP_TARGET = 1.8
OVERHEAD_TARGET_PERCENT = 5.0
MEMORY_GROWTH_TARGET_MIB = 10.0
MEMORY_FIRST_RECORD = 100  # growth counted from this record on (warm-up before)


def _study_file(folder: Path, name: str, fractions, kernels, duration_s: float) -> Path:
    fractions = ", ".join(f"{f:.6g}" for f in fractions)
    path = folder / f"{name}.yaml"
    path.write_text(
        f"version: 1\nname: {name}\ninputs:\n  - scenario: knee_extension\n"
        f"settings: {{duration: {duration_s!r}}}\nstart_time_ns: 0\ngrid:\n"
        f"  library.vasti.fpcsa_slow: [{fractions}]\n"
        f"  model.energetics.recovery_kernel: [{', '.join(kernels)}]\n")
    return path


def _warm() -> str:
    """Run on each worker before timing: the modules a run needs and the compiled step."""
    import vm_ros.cli.simulate  # noqa: F401
    from vm_ros.model import kernel

    kernel.warm_up()
    return "warm"


def _rss_mib() -> float:
    with open("/proc/self/status") as handle:
        for line in handle:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024
    return float("nan")


def _cpu_s(process) -> float:
    times = process.cpu_times()
    return times.user + times.system


def _thread_cpu_s(process) -> dict:
    return {thread.id: thread.user_time + thread.system_time for thread in process.threads()}


def _timed_study(study_path: Path, out: Path, workers: int, on_record=None) -> dict:
    import psutil  # a dependency of distributed

    from vm_ros.cli.study import offline_verbs
    from vm_ros.study.engine import Engine, close, run_study
    from vm_ros.study.study_file import load_study

    study = load_study(study_path)
    start = time.perf_counter()
    client, cluster = Engine(workers=workers).open()
    client.run(_warm)
    me = psutil.Process()
    worker_processes = [psutil.Process(pid) for pid in client.run(os.getpid).values()]
    cpu_before = [_cpu_s(p) for p in (me, *worker_processes)]
    threads_before = [_thread_cpu_s(p) for p in worker_processes]
    started = time.perf_counter()
    records = []

    def record(item):
        records.append(item["wall_s"] if "wall_s" in item else float("nan"))
        if on_record is not None:
            on_record(item)

    try:
        summary = run_study(study, out, client, offline_verbs(), say=lambda line: None,
                            on_record=record)
        wall = time.perf_counter() - started
        cpu = [_cpu_s(p) - before for p, before in zip((me, *worker_processes), cpu_before,
                                                        strict=True)]
        # a worker's busiest thread over the study: the task thread that ran the verb
        task_threads = [max(cpu_s - before.get(thread, 0.0) for thread, cpu_s in
                            _thread_cpu_s(p).items())
                        for p, before in zip(worker_processes, threads_before, strict=True)]
    finally:
        close(client, cluster)
    runs = max(summary.runs, 1)
    return {"workers": workers, "runs": summary.runs, "ok": summary.ok, "failed": summary.failed,
            "cluster_start_s": started - start, "wall_s": wall,
            "run_wall_sum_s": float(sum(records)), "run_wall_mean_s": float(sum(records) /
                                                                            max(len(records), 1)),
            "client_cpu_per_run_s": cpu[0] / runs, "workers_cpu_per_run_s": sum(cpu[1:]) / runs,
            "task_thread_cpu_per_run_s": sum(task_threads) / runs}


def bench_study(quick: bool = False, progress=print) -> dict:
    """The three measurements above (module docstring)."""
    n_fractions, duration_s = (4, 5.0) if quick else (32, 30.0)
    short_runs = 200 if quick else 1000
    fractions = [0.1 + 0.8 * i / (n_fractions - 1) for i in range(n_fractions)]
    kernels = ("fitted_fig7", "pcr_slade2006")
    result: dict = {"load_average_start": os.getloadavg()}
    with tempfile.TemporaryDirectory(prefix="vm_ros-bench-study-") as tmp:
        folder = Path(tmp)
        grid = _study_file(folder, "speed", fractions, kernels, duration_s)
        for workers in (1, 2):
            progress(f"study: {len(fractions) * 2} runs of {duration_s:g} s on {workers} "
                     "worker(s) ...")
            result[f"workers_{workers}"] = _timed_study(grid, folder / f"speed-{workers}", workers)
        one, two = result["workers_1"], result["workers_2"]
        result["speedup"] = one["wall_s"] / two["wall_s"]
        overhead = (one["wall_s"] - one["run_wall_sum_s"]) / one["runs"]
        result["overhead_per_run_s"] = overhead
        result["overhead_percent_of_run"] = 100.0 * overhead / one["run_wall_mean_s"]
        one_cpu, two_cpu = (item["client_cpu_per_run_s"] + item["workers_cpu_per_run_s"]
                            for item in (one, two))
        result["cores_busy_1_worker"] = one_cpu * one["runs"] / one["wall_s"]
        result["speedup_cpu_bound"] = one["wall_s"] / (two_cpu * two["runs"] / 2)
        result["tables_equal"] = ((folder / "speed-1" / "results.parquet").read_bytes()
                                  == (folder / "speed-2" / "results.parquet").read_bytes())

        progress(f"study: client memory over {short_runs} short runs on 2 workers ...")
        many = _study_file(folder, "memory", [0.1 + 0.8 * i / (short_runs - 1)
                                              for i in range(short_runs)], kernels[:1], 0.05)
        samples: list[float] = []
        memory = _timed_study(many, folder / "memory", 2,
                              on_record=lambda record: samples.append(_rss_mib()))
        first = samples[min(MEMORY_FIRST_RECORD, len(samples)) - 1]
        memory.update(rss_first_mib=samples[0], rss_at_first_counted_mib=first,
                      rss_last_mib=samples[-1], rss_max_mib=max(samples),
                      growth_mib=samples[-1] - first,
                      rss_every_100_mib=samples[99::100])
        result["memory"] = memory
    result["load_average_end"] = os.getloadavg()
    return result


def csv_rows(r: dict, add) -> None:
    """bench.csv rows of :func:`bench_study` (``add`` as in vm_ros.cli.bench)."""
    one, two, memory = r["workers_1"], r["workers_2"], r["memory"]
    case = f"{one['runs']} runs, knee extension"
    load = f"load {r['load_average_start'][0]:.1f} -> {r['load_average_end'][0]:.1f}"
    for item in (one, two):
        add("study", f"{case}, {item['workers']} worker(s)", "wall", item["wall_s"], "s")
        add("study", f"{case}, {item['workers']} worker(s)", "cluster start", item[
            "cluster_start_s"], "s")
    add("study", f"{case} ({load})", "speed-up 2 workers / 1", r["speedup"], "ratio",
        f">= {SPEEDUP_TARGET:g}", r["speedup"] >= SPEEDUP_TARGET)
    add("study", f"{case}, 1 worker", "overhead per run", r["overhead_per_run_s"], "s")
    add("study", f"{case}, 1 worker", "overhead / mean run", r["overhead_percent_of_run"], "%",
        f"< {OVERHEAD_TARGET_PERCENT:g} %", r["overhead_percent_of_run"] < OVERHEAD_TARGET_PERCENT)
    for item in (one, two):
        where = f"{case}, {item['workers']} worker(s)"
        add("study", where, "CPU per run: client, scheduler, nannies", item[
            "client_cpu_per_run_s"], "s")
        add("study", where, "CPU per run: workers", item["workers_cpu_per_run_s"], "s")
        add("study", where, "CPU per run: workers' task threads", item[
            "task_thread_cpu_per_run_s"], "s")
    add("study", f"{case}, 1 worker ({load})", "cores busy (CPU / wall)", r["cores_busy_1_worker"],
        "cores")
    add("study", f"{case} ({load})", "speed-up bound of the CPU times on 2 cores",
        r["speedup_cpu_bound"], "ratio")
    add("study", case, "table equal, 1 and 2 workers", r["tables_equal"], "", "True",
        r["tables_equal"])
    add("study", f"{memory['runs']} short runs, 2 workers", "client RSS growth after record "
        f"{MEMORY_FIRST_RECORD}", memory["growth_mib"], "MiB",
        f"<= {MEMORY_GROWTH_TARGET_MIB:g} MiB", memory["growth_mib"] <= MEMORY_GROWTH_TARGET_MIB)
    add("study", f"{memory['runs']} short runs, 2 workers", "CPU per run: client, scheduler, "
        "nannies", memory["client_cpu_per_run_s"], "s")
    add("study", f"{memory['runs']} short runs, 2 workers", "client RSS at the end",
        memory["rss_last_mib"], "MiB")
