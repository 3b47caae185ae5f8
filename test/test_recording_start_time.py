"""Offline logs on the wall clock: log time = start time (metadata start_time_ns, the wall clock
when the run started) + model time, so that timeline tools show the date of the run; every
reader gets the model time back exactly. Recompute writes beside its input log by default."""

from __future__ import annotations

import time

import numpy as np
import pytest

from vm_ros import telemetry as tm
from vm_ros.cli import main
from vm_ros.recording.replay import paced, recorded_messages
from vm_ros.recording.run_log import RunTiming, read_run
from vm_ros.report.plots import report_bin, scenario_bin
from vm_ros.report.tables import energy_rate_table, force_table, telemetry_table

MS = 1_000_000
DAY_2023 = 1_700_000_000 * 1_000_000_000  # 2023-11-14, ns since the epoch
OUTPUTS = (tm.TOPIC_FORCE, tm.TOPIC_ENERGY_RATE, tm.TOPIC_ENERGY_RATE_TOTAL, tm.TOPIC_ENERGY_TOTAL,
           "muscle_telemetry")


def _simulate(path, *extra):
    assert main(["simulate", "--scenario", "knee_extension", "--duration", "0.2", "--out",
                 str(path), *extra]) == 0
    return path


@pytest.fixture(scope="module")
def logs(tmp_path_factory):
    """The same run on the wall clock, on a given start and on model time from 0 (as older
    vm_ros wrote it), with the wall clock around the first."""
    folder = tmp_path_factory.mktemp("start")
    before = time.time_ns()
    wall = _simulate(folder / "wall.mcap")
    after = time.time_ns()
    given = _simulate(folder / "given.mcap", "--start-time", str(DAY_2023 + 123))
    zero = _simulate(folder / "zero.mcap", "--start-time", "0")
    return {"wall": wall, "given": given, "zero": zero, "window": (before, after)}


def test_a_simulate_log_starts_at_the_wall_clock_of_its_start(logs):
    run = read_run(logs["wall"])
    start = run.info.timing.start_time_ns
    before, after = logs["window"]
    assert before <= start <= after
    assert "wall clock" in run.info.time_base
    first = min(int(s.time_ns[0]) for s in run.series.values())
    assert first == start  # the first inputs, at model time 0
    force = run.get(tm.TOPIC_FORCE)
    np.testing.assert_array_equal(force.fields["stamp_ns"], force.time_ns)  # stamp = log time
    np.testing.assert_array_equal(run.model_time_ns(force.time_ns), np.arange(1, 21) * 10 * MS)
    excitation = run.get(tm.TOPIC_EXCITATION)
    np.testing.assert_array_equal(run.model_time_ns(excitation.time_ns), np.arange(200) * MS)


def test_the_start_does_not_change_the_run(logs):
    """Same messages on model time, same values, whatever the start."""
    runs = [read_run(logs[name]) for name in ("wall", "given", "zero")]
    assert runs[1].info.timing.start_time_ns == DAY_2023 + 123
    assert runs[2].info.timing.start_time_ns == 0
    for topic in OUTPUTS + (tm.TOPIC_EXCITATION, tm.TOPIC_KINEMATICS):
        series = [run.get(topic) for run in runs]
        model_times = [run.model_time_ns(s.time_ns) for run, s in zip(runs, series, strict=True)]
        for s, t in zip(series[1:], model_times[1:], strict=True):
            np.testing.assert_array_equal(t, model_times[0], err_msg=topic)
            for key, value in series[0].fields.items():
                if key == "stamp_ns":
                    continue
                np.testing.assert_array_equal(s.fields[key], value, err_msg=f"{topic}.{key}")
    np.testing.assert_array_equal(runs[2].get(tm.TOPIC_FORCE).time_ns,
                                  np.arange(1, 21) * 10 * MS)  # start 0: log time = model time


def test_older_logs_read_on_model_time():
    """A start of 0 (older offline logs) or an unknown start leaves the log time as it is."""
    times = np.array([0, 10 * MS], dtype=np.int64)
    for start in (0, None):
        np.testing.assert_array_equal(RunTiming(start_time_ns=start).model_time_ns(times), times)
    assert RunTiming(start_time_ns=DAY_2023).model_time_ns(DAY_2023 + 7) == 7


def test_the_report_tables_do_not_depend_on_the_start(logs):
    wall, zero = read_run(logs["wall"]), read_run(logs["zero"])
    for table in (force_table, energy_rate_table, telemetry_table):
        a, b = table(wall), table(zero)
        assert a.columns == b.columns
        np.testing.assert_array_equal(a.data, b.data, err_msg=a.name)


def test_replay_paces_on_the_log_times_from_the_first(logs):
    now = [0.0]
    waits = []

    def sleep(seconds):
        waits.append(seconds)
        now[0] += seconds

    messages = paced(recorded_messages(logs["wall"], {"/muscle_force"}), rate=1.0,
                     clock=lambda: now[0], sleep=sleep)
    times = [m.log_time_ns for m in messages]
    assert len(times) == 20 and times[0] > DAY_2023
    assert waits == pytest.approx([0.01] * 19)  # 10 ms apart, the first at once


def test_recompute_keeps_the_start_and_reproduces_the_run(logs, tmp_path, capsys):
    out = tmp_path / "again.mcap"
    assert main(["recompute", str(logs["wall"]), "--out", str(out)]) == 0
    assert "exact: the recomputed outputs equal the recorded ones" in capsys.readouterr().out
    original, again = read_run(logs["wall"]), read_run(out)
    assert again.info.timing.start_time_ns == original.info.timing.start_time_ns
    for topic in OUTPUTS + (tm.TOPIC_EXCITATION,):
        np.testing.assert_array_equal(again.get(topic).time_ns, original.get(topic).time_ns)
    assert again.info.extra["scenario"] == "knee_extension"  # carried for the report's bins
    assert scenario_bin(again) == ("knee_extension", 1.0)
    assert report_bin(again, 180.0, 0.01)[0] == 1.0
    assert again.info.extra["versions"]  # this run's, written by RunInfo


def test_recompute_writes_beside_the_input_log(logs, tmp_path, monkeypatch, capsys):
    runs = tmp_path / "runs"
    runs.mkdir()
    source = runs / "knee.mcap"
    source.write_bytes(logs["zero"].read_bytes())
    bag = runs / "bag"
    _simulate(bag, "--start-time", "0")
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    assert main(["recompute", "../runs/knee.mcap"]) == 0
    assert main(["recompute", str(bag)]) == 0
    printed = capsys.readouterr().out
    assert not (elsewhere / "out").exists()
    made = sorted(p.name for p in runs.glob("*-recomputed-*.mcap"))
    assert [name.split("-recomputed-")[0] for name in made] == ["bag", "knee"]
    for name in made:
        stamp = name.split("-recomputed-")[1].removesuffix(".mcap")
        assert len(stamp) == len("20250101-120000") and stamp.replace("-", "").isdigit()
        assert f"log: ../runs/{name}" in printed or f"log: {runs / name}" in printed
        assert read_run(runs / name).info.extra["recomputed_from"]


@pytest.mark.parametrize("verb, words", [
    ("simulate", "default out/<scenario or file>-<date>-<time>.mcap under the current directory"),
    ("recompute", "default beside the input log"),
])
def test_help_states_the_default_folder(verb, words, capsys):
    with pytest.raises(SystemExit):
        main([verb, "--help"])
    assert words in " ".join(capsys.readouterr().out.split())


@pytest.mark.parametrize("value", ["-5", "soon", "1.5"])
def test_a_bad_start_time_is_a_one_line_error(value, tmp_path, capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(["simulate", "--duration", "0.01", "--start-time", value, "--out",
              str(tmp_path / "x.mcap")])
    assert exit_info.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith("vm-ros simulate: error: argument --start-time: ")
    assert not (tmp_path / "x.mcap").exists()
