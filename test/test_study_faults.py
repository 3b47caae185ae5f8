"""vm-ros study's faults: a run with no step, a run's one-line error."""

from __future__ import annotations

import pytest

from vm_ros.cli.study import offline_verbs

pytest.importorskip("distributed")
pytest.importorskip("pyarrow")

from vm_ros.study.task import RunTask, execute, one_line  # noqa: E402


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
