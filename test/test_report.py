"""`vm-ros report`: CSV tables and PNG plots of a run log."""

from __future__ import annotations

import argparse
import csv
import shutil
import sys
from types import SimpleNamespace

import numpy as np
import pytest

from vm_ros.cli import main
from vm_ros.cli import report as report_verb
from vm_ros.errors import VmRosError
from vm_ros.recording.run_log import read_run
from vm_ros.report import plots as report_plots
from vm_ros.report.tables import Table

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def logs(tmp_path_factory):
    folder = tmp_path_factory.mktemp("report")
    with_telemetry, without = folder / "knee.mcap", folder / "knee-bare.mcap"
    for path, rate in ((with_telemetry, "100"), (without, "0")):
        assert main(["simulate", "--scenario", "knee_extension", "--duration", "0.3", "--out",
                     str(path), "--telemetry-rate", rate]) == 0
    return with_telemetry, without


def _csv(path):
    with open(path, newline="") as handle:
        rows = list(csv.reader(handle))
    return rows[0], rows[1:]


def test_report_writes_documented_tables_and_plots(logs, tmp_path, capsys):
    out = tmp_path / "report"
    assert main(["report", str(logs[0]), "--out", str(out), "--bin", "0.1"]) == 0
    assert "rectus_femoris" in capsys.readouterr().out
    for name in ("force", "drive", "kinematics", "energy_muscles", "energy_rate",
                 "energy_partition", "totals", "summary"):
        data = (out / f"{name}.png").read_bytes()
        assert data.startswith(PNG_MAGIC) and len(data) > 5000, name
    header, rows = _csv(out / "forces.csv")
    assert header[:3] == ["time_s", "rectus_femoris.force_N", "vasti.force_N"]
    assert "vasti.fascicle_velocity_m_per_s" in header and len(rows) == 30
    run = read_run(logs[0])
    np.testing.assert_allclose(np.array(rows, dtype=float)[:, 2],
                               run.get("muscle_force").fields["effort"][:, 1])
    header, rows = _csv(out / "energy_rate.csv")
    assert header[1] == "rectus_femoris.slow.activation_W" and len(header) == 1 + 2 * 12
    header, rows = _csv(out / "summary.csv")
    last_energy = run.get("muscle_telemetry").fields["energy"][-1]
    vasti_all = next(r for r in rows if r[:2] == ["vasti", "all"])
    assert float(vasti_all[header.index("total_energy_J")]) == pytest.approx(last_energy[-1])
    assert (out / "telemetry.csv").exists() and (out / "totals.csv").exists()


def test_without_telemetry_energy_is_integrated(logs, tmp_path, capsys):
    out = tmp_path / "bare"
    assert main(["report", str(logs[1]), "--out", str(out), "--no-plots"]) == 0
    assert not list(out.glob("*.png")) and not (out / "telemetry.csv").exists()
    header, rows = _csv(out / "summary.csv")
    total = sum(float(r[header.index("total_energy_J")]) for r in rows if r[1] == "all")
    recorded = read_run(logs[1]).get("energy_total")
    # trapezoid over the published rates from the first output: close to the energy counter
    # difference over the same span
    span = recorded.fields["data"][-1] - recorded.fields["data"][0]
    assert total == pytest.approx(span, rel=0.05)
    assert all(r[header.index("mechanical_work_J")] in ("nan", "") for r in rows)


def test_missing_matplotlib_is_a_clear_error(logs, tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "matplotlib", None)  # import matplotlib -> ImportError
    parser = argparse.ArgumentParser()
    report_verb.add_arguments(parser)
    with pytest.raises(VmRosError, match="needs matplotlib.*--no-plots"):
        report_verb.run(parser.parse_args([str(logs[0]), "--out", str(tmp_path / "r")]))


def test_efficiency_is_na_when_net_work_is_not_positive():
    from vm_ros.report.summary import summarize, summary_records, summary_table

    energy = np.zeros((3, 3, 4))
    energy[:, -1, -1] = [10.0, 20.0, 40.0]
    rows = summarize(("shortening", "lengthening", "isometric"), np.ones((4, 3)), energy,
                     [2.5, -5.0, 0.0])
    assert rows[0].efficiency == pytest.approx(0.25)
    assert np.isnan(rows[1].efficiency) and np.isnan(rows[2].efficiency)
    table = summary_table(rows)
    lines = table.splitlines()
    first = {line.split()[0]: i for i, line in enumerate(lines) if line.split()}

    def efficiency_cell(name):  # the muscle's "all" row: two lines below its name
        return lines[first[name] + 2].split()[-1]

    assert efficiency_cell("shortening") == "25.0"
    assert efficiency_cell("lengthening") == "n/a" and efficiency_cell("isometric") == "n/a"
    all_muscles = next(line for line in lines if line.startswith("all muscles"))
    assert all_muscles.split()[-1] == "n/a"  # net work 2.5 - 5.0 < 0
    assert "-" + "50.0" not in table and "eff n/a: net mechanical work not positive" in table
    records = [r for r in summary_records(rows) if r["fibre"] == "all"]
    assert [r["efficiency"] for r in records] == [pytest.approx(0.25), "", ""]


# --- time bins, panels, summary page, default folder ---------------------------------------

@pytest.mark.parametrize(("span_s", "expected_s"), [
    (180.0, 1.0),  # 180 / 200 = 0.9 -> 1: 180 bins
    (4.0, 0.02),  # 0.02 exactly: 200 bins
    (50.0, 0.5),  # 0.25 -> 0.5 (the 1-2-5 steps skip 0.25): 100 bins
    (0.3, 0.002),  # 0.0015 -> 0.002
    (1000.0, 5.0),  # 5 -> 5
    (3000.0, 20.0),  # 15 -> 20
])
def test_default_bin_from_length_is_the_next_1_2_5_step(span_s, expected_s):
    assert report_plots.bin_from_length(span_s) == pytest.approx(expected_s, rel=1e-12)
    assert 80 <= span_s / expected_s <= 200


def _fake_run(scenario=None):
    extra = {"scenario": scenario} if scenario else {}
    return SimpleNamespace(info=SimpleNamespace(extra=extra))


def test_default_bin_comes_from_the_scenario_then_the_length():
    bin_s, reason = report_plots.report_bin(_fake_run("knee_extension"), 179.99, 0.01)
    assert bin_s == 1.0 and "knee_extension" in reason  # config/scenarios.yaml energy_bin
    # too short for ten of the scenario's bins: from the length, and said so
    bin_s, reason = report_plots.report_bin(_fake_run("knee_extension"), 5.0, 0.01)
    assert bin_s == 0.05 and "not used" in reason
    # a scenario without energy_bin, and no scenario at all: from the length
    assert report_plots.report_bin(_fake_run("isometric_ramp"), 3.99, 0.01)[0] == 0.02
    assert report_plots.report_bin(_fake_run(), 180.0, 0.001)[0] == 1.0
    # a bin not longer than the sample interval: no binning
    assert report_plots.report_bin(_fake_run(), 0.29, 0.01)[0] == 0.0
    assert report_plots.report_bin(_fake_run("knee_extension"), 180.0, 0.01, 0.25)[0] == 0.25
    with pytest.raises(VmRosError, match="--bin"):
        report_plots.report_bin(_fake_run(), 180.0, 0.01, -1.0)


def test_simulate_log_names_its_scenario_for_the_bin(logs):
    assert report_plots.scenario_bin(read_run(logs[0])) == ("knee_extension", 1.0)


def test_bin_stats_against_hand_values():
    t = np.arange(6) * 0.5  # 0 .. 2.5 s, bins of 1 s: [0, 0.5], [1, 1.5], [2, 2.5]
    centres, mean, low, high = report_plots.bin_stats(t, np.array([1, 3, 2, 2, 0, 10.0]), 1.0)
    np.testing.assert_allclose(centres, [0.5, 1.5, 2.5])
    np.testing.assert_allclose(mean, [2, 2, 5])
    np.testing.assert_allclose(low, [1, 2, 0])
    np.testing.assert_allclose(high, [3, 2, 10])


def _synthetic_forces(names, span_s, dt=0.01):
    t = np.arange(0.0, span_s, dt)
    columns, blocks = ["time_s"], [t]
    for k, m in enumerate(names):
        columns += [f"{m}.force_N", f"{m}.fascicle_length_m", f"{m}.fascicle_velocity_m_per_s"]
        blocks += [100 * (k + 1) * (np.sin(2 * np.pi * t) > 0), 0.1 + 0 * t, 0 * t]
    return Table("forces", columns, np.column_stack(blocks))


@pytest.mark.parametrize(("names", "span_s", "columns"), [
    (("a", "b", "c"), 2.0, 1), (("a", "b"), 30.0, 2), (("only",), 30.0, 2)])
def test_one_force_panel_per_muscle(names, span_s, columns):
    plt = report_verb._pyplot()
    table = _synthetic_forces(names, span_s)
    fig = report_plots.force_figure(plt, table, names, 1.0, "1 s (test)")
    axes = np.array(fig.axes).reshape(len(names), columns)  # rows: muscles; long runs: detail
    assert [ax.get_ylabel().split()[0] for ax in axes[:, 0]] == list(names)
    fig = report_plots.kinematics_figure(plt, table, names, 1.0, "1 s (test)")
    assert len(fig.axes) == 2 * len(names) * columns
    plt.close("all")


def test_default_folder_is_beside_the_log_and_help_says_so(logs, tmp_path, capsys):
    log = tmp_path / "runs" / "knee.mcap"
    log.parent.mkdir()
    shutil.copy(logs[0], log)
    assert main(["report", str(log)]) == 0
    printed = capsys.readouterr().out
    out = tmp_path / "runs" / "knee-report"
    assert f"report: {out}" in printed
    assert "plot bins: no binning" in printed  # 0.29 s at 100 Hz: 0.002 s <= 0.01 s samples
    data = (out / "summary.png").read_bytes()
    assert data.startswith(PNG_MAGIC) and len(data) > 20000
    with pytest.raises(SystemExit):
        main(["report", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "<log name>-report/ beside the log" in text
    assert "energy_bin" in text and "1-2-5" in text
