"""vm-ros study's faults: a finished run whose log went missing, bad --out and --scheduler, a
study folder that cannot be written, a run that raises (Dask's retries, then its one-line error),
a run with no step, the embedded cluster's size. Dask runs on a LocalCluster bound to 127.0.0.1
(all traffic on loopback), the runs are short (knee extension, 0.5 s of model time)."""

from __future__ import annotations

import errno
import os
from pathlib import Path

import pytest
from conftest import require_module

from vm_ros.cli import main
from vm_ros.cli import simulate as simulate_verb
from vm_ros.cli.study import offline_verbs

require_module("distributed", "study")
require_module("pyarrow", "study")

from vm_ros.study import table  # noqa: E402
from vm_ros.study.engine import Engine, close, run_study  # noqa: E402
from vm_ros.study.study_file import load_study  # noqa: E402
from vm_ros.study.task import RunTask, Verb, execute, one_line  # noqa: E402

KNEE = "scenario: knee_extension"
TWO_RUNS = "start_time_ns: 0\ngrid:\n  dt: [0.001, 0.002]\n"


def _study(folder: Path, body: str) -> Path:
    path = folder / "study.yaml"
    path.write_text(f"version: 1\ninputs:\n  - {KNEE}\nsettings: {{duration: 0.5}}\n{body}")
    return path


def _run(study_path: Path, out: Path, verbs=None, say=lambda line: None,
         on_record=lambda record: None):
    client, cluster = Engine(workers=1).open()
    try:
        return run_study(load_study(study_path), out, client, verbs or offline_verbs(),
                         say=say, on_record=on_record)
    finally:
        close(client, cluster)


def test_a_finished_run_whose_log_is_missing_runs_again_and_its_row_is_replaced(tmp_path):
    study, out = _study(tmp_path, TWO_RUNS), tmp_path / "out"
    first = _run(study, out)
    assert (first.ok, first.rows) == (2, 4)
    table_before = (out / "results.csv").read_bytes()
    logs = sorted((out / "runs").glob("*.mcap"))
    lost = logs[0].stem
    logs[0].unlink()

    said, executed = [], []
    second = _run(study, out, say=said.append, on_record=executed.append)
    assert [r["run_id"] for r in executed] == [lost]
    assert (second.skipped, second.ok) == (1, 1)
    assert "1 finished before, 1 to run" in said[0] and "log is missing" in said[0]
    assert logs[0].is_file()
    assert sorted(p.stem for p in (out / "rows").glob("*.json")) == sorted(p.stem for p in logs)
    assert (out / "results.csv").read_bytes() == table_before  # the row replaced, not doubled


@pytest.mark.parametrize("options, named", [
    (["--out", "a_file"], "--out"),
    (["--out", "out", "--scheduler", "nonsense"], "--scheduler nonsense"),
    (["--out", "out", "--scheduler", "tcp://127.0.0.1"], "--scheduler"),
    (["--out", "out", "--scheduler", "foo://127.0.0.1:8786"], "--scheduler"),
    (["--out", "out", "--scheduler", "tls://127.0.0.1:1"], "TLS"),
])
def test_a_bad_out_or_scheduler_is_one_line_and_exit_2(tmp_path, capsys, monkeypatch, options,
                                                       named):
    monkeypatch.chdir(tmp_path)
    study = _study(tmp_path, TWO_RUNS)
    Path("a_file").write_text("kept\n")
    assert main(["study", "run", str(study), *options]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and named in err, err
    assert not Path("out").exists() and Path("a_file").read_text() == "kept\n"


def _full_disk(fails):
    """table.write_atomically raising ENOSPC for the paths ``fails(path)`` names."""
    real = table.write_atomically

    def write(path, data):
        if fails(Path(path)):
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        real(path, data)
    return write


@pytest.mark.parametrize("what", ["records", "table"])
def test_a_study_folder_that_cannot_be_written_stops_with_one_line(tmp_path, capsys,
                                                                   monkeypatch, what):
    """The client's disk fills up after the first record (or when the table is written): one
    line naming the file and the OS error, exit 1; the records written before are kept."""
    study = _study(tmp_path, "grid:\n  dt: [0.001, 0.0011, 0.0012]\n")
    out = tmp_path / "out"
    records = []

    def fails(path):
        if what == "table":
            return path.name.startswith("results") or path.name == "runs.csv"
        if path.parent.name == "rows" and not records:
            records.append(path)
            return False
        return True

    monkeypatch.setattr(table, "write_atomically", _full_disk(fails))
    assert main(["study", "run", str(study), "--out", str(out), "--workers", "1"]) == 1
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "No space left on device" in err, err
    kept = sorted((out / "rows").glob("*.json"))
    if what == "table":
        assert "the table in" in err and len(kept) == 3
    else:
        assert len(kept) == 1 and kept == records
        failed = err.split("writing ")[1].split(" failed")[0]
        assert Path(failed).parent == out / "rows" and Path(failed).suffix == ".json"
    assert not (out / "results.parquet").exists()


def _flaky_run(args, on_outcome=None):
    """`vm-ros simulate`, except that a run with dt 2 ms raises an unexpected exception (not a
    VmRosError) every time it starts; each start is counted in attempts.txt of the study
    folder."""
    if args.dt != 0.002:
        return simulate_verb.run(args, on_outcome=on_outcome)
    with open(Path(args.out).parent.parent / "attempts.txt", "a") as attempts:
        attempts.write(f"{os.getpid()}\n")
    b"\xad".decode()  # UnicodeDecodeError, as a binary inputs CSV raised it


def test_a_run_that_raises_is_retried_by_dask_then_recorded_with_its_line(tmp_path, capfd):
    """Dask runs it 1 + retries times, then the client records it failed with its one-line
    error, which has text (the exception's text was lost on its way back from the worker); the
    worker prints no "Compute Failed" report; the other run is ok."""
    study = _study(tmp_path, TWO_RUNS + "retries: 2\n")
    out = tmp_path / "out"
    verbs = {"simulate": Verb("simulate", simulate_verb.add_arguments, _flaky_run)}
    records = []
    summary = _run(study, out, verbs=verbs, on_record=records.append)
    assert (summary.ok, summary.failed) == (1, 1)
    assert len((out / "attempts.txt").read_text().splitlines()) == 1 + 2
    failed = next(r for r in records if r["status"] == "failed")
    assert failed["error"] == ("UnicodeDecodeError: 'utf-8' codec can't decode byte 0xad in "
                               "position 0: invalid start byte")
    assert "Compute Failed" not in capfd.readouterr().err
    assert not any("Compute Failed" in p.read_text() for p in (out / "runs").glob("*.txt"))


def test_a_run_without_a_step_fails_and_the_printed_log_is_the_final_one(tmp_path):
    """dt longer than the run: failed with a one-line reason, no rows, no log. A run that
    finished: runs/<id>.txt names its log, not the temporary file it was written to."""
    verb = offline_verbs()["simulate"]
    no_step = execute(RunTask("d" * 16, verb, ("--scenario", "knee_extension", "--duration",
                                               "0.2", "--dt", "5"), str(tmp_path / "d.mcap"), 0))
    assert no_step["status"] == "failed" and no_step["rows"] == []
    assert "no step" in no_step["error"] and "--dt 5" in no_step["error"]
    assert "\n" not in no_step["error"]
    assert not [p for p in tmp_path.iterdir() if p.suffix == ".mcap"]

    final = tmp_path / ("e" * 16 + ".mcap")
    ok = execute(RunTask("e" * 16, verb, ("--scenario", "knee_extension", "--duration", "0.2"),
                         str(final), 0))
    assert ok["status"] == "ok" and final.is_file()
    printed = final.with_suffix(".txt").read_text()
    assert f"log: {final} (" in printed and f".{final.stem}-" not in printed


def test_the_embedded_cluster_has_a_worker_per_cpu_this_process_may_use(monkeypatch):
    if not hasattr(os, "sched_getaffinity"):
        pytest.skip("no CPU affinity on this OS")
    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: {0})
    monkeypatch.setattr(os, "cpu_count", lambda: 3)
    client, cluster = Engine().open()
    try:
        assert len(client.scheduler_info()["workers"]) == 1
    finally:
        close(client, cluster)



def test_an_exception_that_lost_its_text_on_its_way_back_is_still_one_line_of_text():
    """Dask carries a worker's exception back pickled with tblib: a UnicodeDecodeError arrives
    with its args but an empty text."""
    import tblib.pickling_support
    from distributed.protocol import pickle

    try:
        b"\xad".decode()
    except UnicodeDecodeError as error:
        raised = error
    tblib.pickling_support.install(raised)
    carried = pickle.loads(pickle.dumps(raised))
    assert str(carried) == ""
    assert one_line(carried) == ("UnicodeDecodeError: 'utf-8' codec can't decode byte 0xad in "
                                 "position 0: invalid start byte")
    assert one_line(KeyError()) == "KeyError: KeyError()"


def test_the_report_piped_into_a_reader_that_leaves_ends_quietly(tmp_path):
    """`vm-ros study report DIR | head -1`: once the reader has gone, no BrokenPipeError
    traceback, exit 0 (vm_ros.cli.main, for every verb)."""
    import subprocess
    import sys

    out = tmp_path / "out"
    assert _run(_study(tmp_path, TWO_RUNS), out).ok == 2
    reader_gone = subprocess.Popen([sys.executable, "-m", "vm_ros.cli", "study", "report",
                                    str(out)], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                   env={**os.environ, "PYTHONUNBUFFERED": "1"})  # line by line
    reader_gone.stdout.readline()
    reader_gone.stdout.close()  # as `| head -1`: one line read, then gone
    _, stderr = reader_gone.communicate(timeout=120)
    assert reader_gone.returncode == 0 and b"Traceback" not in stderr, stderr.decode()
