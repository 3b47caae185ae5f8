"""`vm-ros report`: CSV tables and PNG plots of a run log."""

from __future__ import annotations

import argparse
import csv
import sys

import numpy as np
import pytest

from vm_ros.cli import main
from vm_ros.cli import report as report_verb
from vm_ros.errors import VmRosError
from vm_ros.recording.run_log import read_run

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
    for name in ("force", "drive", "kinematics", "energy_rectus_femoris", "energy_vasti",
                 "energy_partition", "totals"):
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
    from vm_ros.recording.summary import summarize, summary_records, summary_table

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
