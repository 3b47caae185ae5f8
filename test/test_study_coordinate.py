"""A study of `vm-ros coordinate` runs (input kind ``coordinate``) on a Dask LocalCluster bound to
127.0.0.1: two muscles on one coordinate (test_coordination's geometry and soleus copies), a
0.5 s motion and its target moments, a grid over the cost. The table holds what the runs' logs
hold, the same bit for bit (logs included) with 1 and 2 workers; options that do not apply to a
coordinate run are one line, exit 2."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
import yaml
from conftest import require_module
from test_coordinate_cli import _storage
from test_coordination import geometry, library

from vm_ros.cli import main
from vm_ros.cli.study import offline_verbs
from vm_ros.coordination.solver import SolverOptions
from vm_ros.geometry import write_geometry
from vm_ros.recording.run_log import read_run
from vm_ros.report.tables import run_summary

require_module("distributed", "study")
pyarrow_parquet = require_module("pyarrow.parquet", "study")

from vm_ros.study.engine import Engine, close, run_study  # noqa: E402
from vm_ros.study.study_file import load_study  # noqa: E402

MUSCLES = ("a", "b")
COSTS = ("tsianos2012", "drive2")


def _inputs(folder: Path) -> None:
    """geometry.yaml (moment arms 0.02 and 0.03 m), muscles.yaml (b with 40 % slow fibres),
    motion.mot (q = 0.05 sin(pi t / 0.5) rad over 0.5 s) and id.sto (target moment
    8 - 2 cos(pi t / 0.5) N m)."""
    write_geometry(geometry({"a": 0.02, "b": 0.03}), folder / "geometry.yaml")
    library(folder, a={}, b={"fpcsa_slow": 0.4})
    t = np.linspace(0.0, 0.5, 26)
    _storage(folder / "motion.mot", t, {"q": 0.05 * np.sin(np.pi * t / 0.5)})
    _storage(folder / "id.sto", t, {"q_moment": 8.0 - 2.0 * np.cos(np.pi * t / 0.5)})


def _study(folder: Path, settings: str = "{library: muscles.yaml, iterations: 4}",
           grid: str = f"  cost: [{', '.join(COSTS)}]\n", entry: str = "") -> Path:
    _inputs(folder)
    path = folder / "study.yaml"
    path.write_text("version: 1\ninputs:\n  - coordinate: motion.mot\n    targets: id.sto\n"
                    f"    geometry: geometry.yaml\n{entry}settings: {settings}\ngrid:\n{grid}"
                    "start_time_ns: 0\n")
    return path


def _run(study_path: Path, out: Path, workers: int):
    client, cluster = Engine(workers=workers).open()
    try:
        assert all(address.startswith("tcp://127.0.0.1:")
                   for address in [client.scheduler.address, *client.scheduler_info()["workers"]])
        return run_study(load_study(study_path), out, client, offline_verbs(),
                         say=lambda line: None)
    finally:
        close(client, cluster)


def _outputs(out: Path) -> dict:
    return {p.name: p.read_bytes() for p in [out / "results.parquet", out / "results.csv",
                                             *sorted((out / "runs").glob("*.mcap"))]}


def test_a_grid_of_costs_gives_the_logs_numbers_the_same_with_one_and_two_workers(tmp_path):
    study = _study(tmp_path)
    out = tmp_path / "out"
    two = _run(study, out, workers=2)
    assert (two.ok, two.failed, two.rows) == (2, 0, 4)
    first = _outputs(out)
    shutil.rmtree(out / "rows")  # every run again, on one worker
    for path in (out / "runs").glob("*.mcap"):
        path.unlink()
    one = _run(study, out, workers=1)
    assert (one.ok, one.skipped) == (2, 0)
    assert len(first) == 2 + 2 and _outputs(out) == first  # bit for bit, logs included

    rows = pyarrow_parquet.read_table(out / "results.parquet").to_pylist()
    assert [(r["cost"], r["muscle"]) for r in rows] == [(c, m) for c in COSTS for m in MUSCLES]
    assert all(r["input"] == "coordinate:motion.mot" and r["status"] == "ok" for r in rows)
    totals = {}
    for row in rows:  # the table holds what the run's log holds (read back independently)
        log = read_run(out / "runs" / f"{row['run_id']}.mcap")
        summary = {s.name: s for s in run_summary(log)}[row["muscle"]]
        assert row["all.total_energy_J"] == pytest.approx(summary.energy[-1, -1], rel=1e-12)
        assert row["slow.recovery_energy_J"] == pytest.approx(summary.energy[0, 2], rel=1e-12)
        assert row["peak_force_N"] == pytest.approx(summary.peak_force, rel=1e-12)
        # the run log starts the solve's lead-in before the 0.5 s motion (first pose held)
        lead_s = [float(e["lead_in_s"]) for e in log.metadata.values() if "lead_in_s" in e]
        assert lead_s == [pytest.approx(SolverOptions().lead_in_s, abs=1e-9)]
        assert row["duration_s"] == pytest.approx(0.5 + lead_s[0])
        # the grid's cost reached the solve; the solve's outputs travel in the log
        assert any(entries.get("coordination_cost") == row["cost"]
                   for entries in log.metadata.values())
        assert {"drives.sto", "forces.sto", "reserves.sto"} <= set(log.attachments)
        totals[row["cost"]] = totals.get(row["cost"], 0.0) + row["all.total_energy_J"]
    # least metabolic energy finds less of it than least squared drive, at the same moments
    assert totals["tsianos2012"] < 0.95 * totals["drive2"], totals


def test_library_changes_reach_the_solve_and_the_log(tmp_path):
    """library.b.fpcsa_slow over 0.2 and 0.8 (as --override): the log's overrides attachment
    holds it, and more slow fibres in b give b's slow fibres a larger share of its energy."""
    study = _study(tmp_path, "{library: muscles.yaml, iterations: 4, cost: drive2}",
                   "  library.b.fpcsa_slow: [0.2, 0.8]\n")
    out = tmp_path / "out"
    assert _run(study, out, workers=2).ok == 2
    rows = {r["library.b.fpcsa_slow"]: r for r in
            pyarrow_parquet.read_table(out / "results.parquet").to_pylist() if r["muscle"] == "b"}
    for fraction, row in rows.items():
        log = read_run(out / "runs" / f"{row['run_id']}.mcap")
        assert yaml.safe_load(log.attachments["overrides.yaml"]) == {"b": {"fpcsa_slow":
                                                                            fraction}}
    share = {f: r["slow.total_energy_J"] / r["all.total_energy_J"] for f, r in rows.items()}
    assert share[0.8] > share[0.2] + 0.2, share


def test_the_run_id_hashes_the_targets_by_content(tmp_path):
    study = _study(tmp_path)
    ids = [spec.run_id for spec in load_study(study).runs]
    assert len(set(ids)) == 2
    text = (tmp_path / "id.sto").read_text()
    (tmp_path / "id.sto").write_text(text)  # written again, the same bytes: the same ids
    assert [spec.run_id for spec in load_study(study).runs] == ids
    (tmp_path / "id.sto").write_text(text.replace("\t6.0\n", "\t6.5\n", 1))
    assert not {spec.run_id for spec in load_study(study).runs} & set(ids)


@pytest.mark.parametrize("settings, grid, entry, field, words", [
    ("{library: muscles.yaml, duration: 0.5}", "  cost: [drive2]\n", "", "settings.duration",
     "duration is not a parameter of a coordinate run (its parameters: dt, library, params, "
     "cost, method"),
    ("{library: muscles.yaml}", "  recruitment: [lumped, natural]\n", "",
     "grid.recruitment[0]", "not a parameter of a coordinate run"),
    ("{library: muscles.yaml}", "  cost: [drive2, energy]\n", "", "grid.cost[1]",
     "'energy' is not one of tsianos2012, drive2"),
    ("{library: muscles.yaml}", "  iterations: [0]\n", "", "grid.iterations[0]",
     "expected an integer >= 1"),
    ("{library: muscles.yaml}", "  cost: [drive2]\n", "    excitation: 0.2\n",
     "inputs[0].excitation", "not a key of a coordinate input"),
])
def test_an_option_that_does_not_apply_to_coordinate_is_one_line_and_exit_2(
        tmp_path, capsys, settings, grid, entry, field, words):
    study = _study(tmp_path, settings, grid, entry)
    assert main(["study", "run", str(study), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and f"{study}: {field}: " in err and words in err
    assert not (tmp_path / "out").exists()


def test_a_coordinate_input_without_targets_is_one_line_and_exit_2(tmp_path, capsys):
    study = _study(tmp_path)
    study.write_text(study.read_text().replace("    targets: id.sto\n", ""))
    assert main(["study", "check", str(study)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].endswith(
        f"{study}: inputs[0]: a coordinate input needs targets: FILE")
