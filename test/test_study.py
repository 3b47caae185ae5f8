"""vm-ros study: the study file's validation, and runs on a Dask LocalCluster bound to 127.0.0.1
(all traffic on loopback): the same table with 1 and 2 workers, resume, a run that fails, a
worker killed mid-study. Runs are short (knee extension, 0.5 s of model time)."""

from __future__ import annotations

import os
import shutil
import signal
from pathlib import Path

import numpy as np
import pytest
from conftest import require_module

from vm_ros.cli import main
from vm_ros.cli.study import offline_verbs
from vm_ros.recording.run_log import read_run
from vm_ros.report.tables import run_summary

require_module("distributed", "study")
pyarrow_parquet = require_module("pyarrow.parquet", "study")

from vm_ros.study.engine import Engine, close, run_study  # noqa: E402
from vm_ros.study.study_file import load_study  # noqa: E402

KNEE = "scenario: knee_extension"


def _study(folder: Path, body: str, name: str = "study.yaml") -> Path:
    path = folder / name
    path.write_text(f"version: 1\ninputs:\n  - {KNEE}\nsettings: {{duration: 0.5}}\n{body}")
    return path


def _run(study_path: Path, out: Path, workers: int, on_record=lambda record: None):
    client, cluster = Engine(workers=workers).open()
    try:
        assert all(address.startswith("tcp://127.0.0.1:")
                   for address in [client.scheduler.address, *client.scheduler_info()["workers"]])
        return run_study(load_study(study_path), out, client, offline_verbs(),
                         say=lambda line: None, on_record=on_record)
    finally:
        close(client, cluster)


GRID = ("start_time_ns: 0\ngrid:\n  library.vasti.fpcsa_slow: [0.2, 0.8]\n"
        "  model.energetics.recovery_kernel: [fitted_fig7, pcr_slade2006]\n")


def test_same_table_and_logs_with_one_and_two_workers(tmp_path):
    study = _study(tmp_path, GRID)
    out = tmp_path / "out"
    two = _run(study, out, workers=2)
    assert (two.ok, two.failed, two.rows) == (4, 0, 8)
    first = {p.name: p.read_bytes() for p in [out / "results.parquet", out / "results.csv",
                                              *sorted((out / "runs").glob("*.mcap"))]}
    shutil.rmtree(out / "rows")  # the same folder again, every run again, on one worker
    for path in (out / "runs").glob("*.mcap"):
        path.unlink()
    one = _run(study, out, workers=1)
    assert (one.ok, one.skipped) == (4, 0)
    again = {p.name: p.read_bytes() for p in [out / "results.parquet", out / "results.csv",
                                              *sorted((out / "runs").glob("*.mcap"))]}
    assert len(first) == 2 + 4 and again == first  # bit for bit, logs included (start time 0)

    rows = pyarrow_parquet.read_table(out / "results.parquet").to_pylist()
    assert [r["muscle"] for r in rows] == ["rectus_femoris", "vasti"] * 4
    for row in rows:  # the table holds what the run's log holds (read back independently)
        summary = {s.name: s for s in run_summary(read_run(out / "runs" / f"{row['run_id']}.mcap"))}
        assert row["all.total_energy_J"] == pytest.approx(summary[row["muscle"]].energy[-1, -1],
                                                          rel=1e-12)
        assert row["peak_force_N"] == pytest.approx(summary[row["muscle"]].peak_force, rel=1e-12)
    vasti = {(r["library.vasti.fpcsa_slow"], r["model.energetics.recovery_kernel"]): r
             for r in rows if r["muscle"] == "vasti"}
    # more slow fibres: the slow fibres' share of the energy grows
    for kernel in ("fitted_fig7", "pcr_slade2006"):
        low, high = vasti[0.2, kernel], vasti[0.8, kernel]
        assert (high["slow.total_energy_J"] / high["all.total_energy_J"]
                > low["slow.total_energy_J"] / low["all.total_energy_J"])
    # the kernel changes recovery energy only: activation and cross-bridge energy are equal
    for fraction in (0.2, 0.8):
        a, b = vasti[fraction, "fitted_fig7"], vasti[fraction, "pcr_slade2006"]
        assert a["all.cross_bridge_energy_J"] == b["all.cross_bridge_energy_J"]
        assert a["all.recovery_energy_J"] != b["all.recovery_energy_J"]


def test_resume_skips_finished_runs_and_reruns_failed_and_missing(tmp_path):
    bad = tmp_path / "bad.csv"  # passes validation (the file exists), fails when it runs
    bad.write_text("time_s,vasti.excitation,vasti.path_length\n0,abc,0.2\n1,0.5,0.2\n")
    study = tmp_path / "study.yaml"
    study.write_text(f"version: 1\ninputs:\n  - {KNEE}\n  - inputs: bad.csv\nstart_time_ns: 0\n"
                     "settings: {duration: 0.5}\nruns:\n  - {dt: 0.001}\n  - {dt: 0.0005}\n")
    out = tmp_path / "out"
    executed = []
    first = _run(study, out, workers=2, on_record=executed.append)
    assert (first.ok, first.failed) == (2, 2)
    failed = [r for r in executed if r["status"] == "failed"]
    assert all("bad.csv" in r["error"] and "\n" not in r["error"] for r in failed)
    table = (out / "results.csv").read_bytes()
    ok_ids = sorted(r["run_id"] for r in executed if r["status"] == "ok")
    (out / "rows" / f"{ok_ids[0]}.json").unlink()  # one finished run goes missing
    # and its half-written log, as a worker killed mid-run leaves it
    (out / "runs" / f".{ok_ids[0]}-0badf00d.mcap").write_bytes(b"\x89MCAP0\r\n")

    executed.clear()
    second = _run(study, out, workers=2, on_record=executed.append)
    assert second.skipped == 1
    assert not list((out / "runs").glob(".*")) and (out / "runs" / f"{ok_ids[0]}.mcap").exists()
    assert sorted(r["run_id"] for r in executed) == sorted([ok_ids[0], *(r["run_id"]
                                                                          for r in failed)])
    assert (out / "results.csv").read_bytes() == table


def test_a_killed_worker_loses_no_row_and_duplicates_none(tmp_path):
    runs = 8
    study = _study(tmp_path, "grid:\n  library.vasti.fpcsa_slow: [" + ", ".join(
        f"{0.1 * (i + 1):.1f}" for i in range(runs)) + "]\n")
    out = tmp_path / "out"
    client, cluster = Engine(workers=2).open()
    killed = {}

    def kill_a_busy_worker(record):
        if killed:
            return
        busy = [address for address, keys in client.processing().items() if keys]
        address = (busy or list(client.scheduler_info()["workers"]))[0]
        killed["keys"] = client.processing().get(address, [])
        killed["pid"] = client.run(os.getpid, workers=[address])[address]
        os.kill(killed["pid"], signal.SIGKILL)

    try:
        summary = run_study(load_study(study), out, client, offline_verbs(),
                            say=lambda line: None, on_record=kill_a_busy_worker)
    finally:
        close(client, cluster)
    assert killed["pid"]
    assert (summary.ok, summary.failed) == (runs, 0)
    rows = pyarrow_parquet.read_table(out / "results.parquet").to_pylist()
    pairs = [(r["run_id"], r["muscle"]) for r in rows]
    assert len(pairs) == 2 * runs and len(set(pairs)) == len(pairs)
    assert sorted(p.stem for p in (out / "rows").glob("*.json")) == sorted({r for r, _ in pairs})
    assert not list((out / "runs").glob(".*"))  # no partial log left behind
    for key in killed["keys"]:  # what the killed worker was running finished elsewhere
        run_id = str(key).split("-")[2]
        record = [line for line in (out / "runs.csv").read_text().splitlines()
                  if line.startswith(run_id)]
        assert record and ",ok," in record[0] and f":{killed['pid']}" not in record[0]
    assert np.all(np.isfinite([r["all.total_energy_J"] for r in rows]))


@pytest.mark.parametrize("body, field", [
    ("grid:\n  dt: [0.001, -1]\n", "grid.dt[1]"),
    ("grid:\n  recruitment: [lumped, clumped]\n", "grid.recruitment[1]"),
    ("runs:\n  - {model.energetics.no_such_constant: 1}\n", "model.energetics.no_such_constant"),
    ("runs:\n  - {model.generic.fmax: -2.0}\n", "model constant"),
    ("grid:\n  library.vasti.no_such_field: [1]\n", "no_such_field"),
    ("grid:\n  stiffness: [1]\n", "unknown parameter 'stiffness'"),
    ("gird:\n  dt: [0.001]\n", "gird: unknown key"),
])
def test_a_bad_study_file_is_one_line_naming_the_field_and_exit_2(tmp_path, capsys, body, field):
    study = _study(tmp_path, body)
    assert main(["study", "run", str(study), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and field in err and str(study) in err
    assert not (tmp_path / "out").exists()  # nothing ran, nothing was written


def test_the_verb_on_a_running_scheduler_then_the_report(tmp_path, capsys):
    from distributed import LocalCluster

    study = _study(tmp_path, "grid:\n  dt: [0.001, 0.002]\n")
    with LocalCluster(n_workers=1, threads_per_worker=1, host="127.0.0.1",
                      dashboard_address=None) as cluster:
        assert main(["study", "run", str(study), "--out", str(tmp_path / "out"),
                     "--scheduler", cluster.scheduler_address]) == 0
    out = capsys.readouterr().out
    assert "2 runs: 0 finished before, 2 ok, 0 failed; 4 table rows" in out
    assert main(["study", "report", str(tmp_path / "out")]) == 0
    printed = capsys.readouterr().out.splitlines()
    assert printed[0].split()[:3] == ["run_id", "input", "dt"]
    assert len(printed) == 1 + 4 + 2  # header, a row per run and muscle, the count, the plot
    assert printed[-1] == f"plot: {tmp_path / 'out' / 'main_effects.png'}"
    assert (tmp_path / "out" / "main_effects.png").stat().st_size > 10_000


def test_ctrl_c_stops_the_study_keeping_what_finished(tmp_path):
    """SIGINT to the command's process group (as Ctrl-C in a terminal): exit 130, the records
    and table of the runs that finished, nothing of the others."""
    import subprocess
    import sys
    import time

    dts = [round(0.001 + 0.0001 * k, 4) for k in range(12)]  # 12 runs of 60 s of model time,
    study = _study(tmp_path, f"grid:\n  dt: {dts}\n")       # so SIGINT lands mid-study
    study.write_text(study.read_text().replace("duration: 0.5", "duration: 60.0"))
    out = tmp_path / "out"
    command = [str(Path(sys.executable).parent / "vm-ros"), "study", "run", str(study), "--out",
               str(out), "--workers", "1"]
    process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                               text=True, start_new_session=True,
                               preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    deadline = time.monotonic() + 240
    while not list((out / "rows").glob("*.json")) and time.monotonic() < deadline \
            and process.poll() is None:
        time.sleep(0.2)
    finished = {p.stem for p in (out / "rows").glob("*.json")}
    assert finished, "no run finished within 240 s: SIGINT would not land mid-study"
    os.killpg(process.pid, signal.SIGINT)
    stdout, stderr = process.communicate(timeout=120)
    assert process.returncode == 130, stderr
    assert "interrupted" in stderr and "Traceback" not in stderr
    kept = {p.stem for p in (out / "rows").glob("*.json")}
    # every run that had finished before the signal is kept, the others are stopped
    assert finished <= kept and len(kept) < len(dts)
    # each kept run has its whole log (a run whose log was complete but whose record was not
    # yet written when the signal came may leave its log too: `study run` again reruns it)
    assert kept <= {p.stem for p in (out / "runs").glob("*.mcap")}
    rows = pyarrow_parquet.read_table(out / "results.parquet").to_pylist()
    assert {r["run_id"] for r in rows} == kept and all(r["status"] == "ok" for r in rows)


def test_a_full_disk_fails_that_run_alone_with_its_one_line_error(tmp_path, monkeypatch):
    """Each run on the worker (here in this process): the one whose log hits ENOSPC is failed
    with the writer's error, the other one is ok; no partial log is left."""
    from test_recording_writer import FailingFile

    from vm_ros.recording.writer import McapRecorder
    from vm_ros.study.task import RunTask, execute

    full, room = tmp_path / "full", tmp_path / "room"
    full.mkdir(), room.mkdir()
    opener = McapRecorder.__init__.__kwdefaults__["opener"]
    monkeypatch.setitem(McapRecorder.__init__.__kwdefaults__, "opener", lambda path: (
        FailingFile(limit=4096) if path.parent == full else opener(path)))
    verb = offline_verbs()["simulate"]
    argv = ("--scenario", "knee_extension", "--duration", "0.5")
    failed = execute(RunTask("a" * 16, verb, argv, str(full / "a.mcap"), 0))
    ok = execute(RunTask("b" * 16, verb, argv, str(room / "b.mcap"), 0))
    assert failed["status"] == "failed" and failed["rows"] == []
    assert "No space left on device" in failed["error"] and "\n" not in failed["error"]
    assert not [p for p in full.iterdir() if p.suffix == ".mcap"]
    assert ok["status"] == "ok" and [r["muscle"] for r in ok["rows"]] == ["rectus_femoris",
                                                                          "vasti"]
    assert (room / "b.mcap").is_file()


def test_a_run_writes_its_own_log_the_bytes_simulate_writes(tmp_path):
    """A study run writes its log in its own thread (study.task.LOG_WRITER, no writer thread
    beside it on the worker's core): the same file, byte for byte, as `vm-ros simulate` with the
    same options, start time and chunk flushing (by size alone) and its default writer
    thread."""
    import threading

    from vm_ros.study.task import FLUSH_INTERVAL_S, LOG_WRITER, RunTask, execute

    assert LOG_WRITER == "caller"
    argv = ("--scenario", "knee_extension", "--duration", "0.5")
    threads = []
    real_start = threading.Thread.start

    def start(thread):
        threads.append(thread.name)
        return real_start(thread)

    threading.Thread.start = start
    try:
        record = execute(RunTask("c" * 16, offline_verbs()["simulate"], argv,
                                 str(tmp_path / "study.mcap"), 0))
    finally:
        threading.Thread.start = real_start
    assert record["status"] == "ok"
    assert not [name for name in threads if name.startswith("mcap-recorder")]
    assert main(["simulate", *argv, "--start-time", "0", "--flush-interval",
                 repr(FLUSH_INTERVAL_S), "--out", str(tmp_path / "simulate.mcap")]) == 0
    assert (tmp_path / "study.mcap").read_bytes() == (tmp_path / "simulate.mcap").read_bytes()


def test_without_the_study_extra_the_verb_names_it(tmp_path, capsys, monkeypatch):
    import vm_ros.study

    monkeypatch.setattr(vm_ros.study, "EXTRA_MODULES", ("no_such_module_vm_ros",))
    assert main(["study", "run", str(_study(tmp_path, GRID)), "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and 'pip install "vm_ros[study]"' in err


def test_workers_get_the_allocator_settings_and_this_process_keeps_its_own(monkeypatch):
    """The embedded cluster's workers see MALLOC_ENVIRON (glibc reads it at their start); the
    process that opened the cluster keeps its own environment for its later children."""
    from vm_ros.study.engine import MALLOC_ENVIRON

    for name in MALLOC_ENVIRON:
        monkeypatch.delenv(name, raising=False)
    client, cluster = Engine(workers=1).open()
    try:
        seen = client.run(lambda: {name: os.environ.get(name) for name in MALLOC_ENVIRON})
    finally:
        close(client, cluster)
    assert [dict(v) for v in seen.values()] == [{name: str(value) for name, value
                                                 in MALLOC_ENVIRON.items()}]
    assert not any(name in os.environ for name in MALLOC_ENVIRON)
