"""`vm-ros params`: the model's (and a muscle's) parameters with value in SI, unit as written, tag
and source; a bad muscle name or unit is one line on stderr and exit 2."""

from __future__ import annotations

import csv
import io
import subprocess
import sys

import pytest
import yaml

from vm_ros.cli import main
from vm_ros.model.params import load_model_params, load_muscle_library
from vm_ros.model.units import UNITS
from vm_ros.resources import config_dir


def _run(capsys, *argv):
    code = main(["params", *argv])
    out, err = capsys.readouterr()
    return code, out, err


def test_default_lists_every_model_parameter_with_its_source(capsys):
    code, out, err = _run(capsys)
    assert code == 0 and err == ""
    lines = {line.split()[0]: line for line in out.splitlines()[2:]}
    params = load_model_params()
    assert set(lines) == set(params.info)
    for name, info in params.info.items():
        assert lines[name].rstrip().endswith(info.source), name


def test_csv_gives_si_values_and_units_as_written(capsys):
    code, out, _ = _run(capsys, "--format", "csv")
    assert code == 0
    rows = {r["parameter"]: r for r in csv.DictReader(io.StringIO(out))}
    tf1 = rows["fibre_type_parameters.tf1"]
    assert (tf1["value"], tf1["SI unit"], tf1["unit in file"], tf1["tag"]) == (
        "slow 0.0343; fast 0.0206", "s", "ms", "L")
    tension = rows["generic.specific_tension"]
    assert float(tension["value"]) == pytest.approx(318_000.0)  # 31.8 N/cm^2
    assert (tension["SI unit"], tension["unit in file"]) == ("Pa", "N/cm^2")
    assert rows["recruitment.lumped.cap_recruitment_at_full"]["value"] == "true"
    assert rows["energetics.recovery_mode"]["value"] == "static"


def test_muscle_table_from_the_library(capsys):
    code, out, _ = _run(capsys, "--muscle", "vasti", "--format", "csv")
    assert code == 0
    rows = {r["parameter"]: r for r in csv.DictReader(io.StringIO(out))}
    entry = load_muscle_library()["vasti"]
    for field in ("mass_kg", "l0_m", "l0t_m", "fpcsa_slow", "path_length_max_m"):
        row = rows[f"muscles.vasti.{field}"]
        assert float(row["value"]) == entry[field]
        assert row["source"] == entry["source"][field]
    assert rows["muscles.vasti.mass_kg"]["SI unit"] == "kg"


def test_markdown_table(capsys):
    code, out, _ = _run(capsys, "--format", "markdown")
    lines = out.splitlines()
    assert code == 0
    assert lines[0].startswith("| parameter | value |") and lines[1].startswith("|---|")
    assert len(lines) == 2 + len(load_model_params().info)


def test_list_muscles(capsys):
    code, out, _ = _run(capsys, "--list-muscles")
    assert code == 0
    assert [line.split()[0] for line in out.splitlines()] == list(load_muscle_library())


def test_units_lists_the_table(capsys):
    code, out, _ = _run(capsys, "--units")
    # columns of 12 characters: unit, SI, factor (units such as "J/(kg K)" hold spaces)
    rows = {line[:12].strip(): (line[14:26].strip(), line[28:40].strip())
            for line in out.splitlines()[1:]}
    assert code == 0 and set(rows) == set(UNITS)
    assert rows["ms"] == ("s", "0.001")
    assert rows["N/cm^2"] == ("Pa", "10000")
    assert rows["kJ/(kg K)"] == ("J/(kg K)", "1000")


@pytest.mark.parametrize(("name", "near"), [("bicep", "biceps_long_head"), ("soleos", "soleus"),
                                            ("zzz", "no near match")])
def test_bad_muscle_is_one_line_with_near_matches(capsys, name, near):
    code, out, err = _run(capsys, "--muscle", name)
    assert code == 2 and out == ""
    assert len(err.strip().splitlines()) == 1
    assert name in err and near in err and "Traceback" not in err


def test_unit_typo_in_a_model_file_is_one_line(tmp_path, capsys):
    data = yaml.safe_load((config_dir() / "model.yaml").read_text())
    data["fibre_type_parameters"]["tf1"]["unit"] = "msec"
    path = tmp_path / "model.yaml"
    path.write_text(yaml.safe_dump(data))
    code, out, err = _run(capsys, "--params", str(path))
    assert code == 2 and out == ""
    assert len(err.strip().splitlines()) == 1
    assert str(path) in err and "fibre_type_parameters.tf1.unit" in err and "'msec'" in err


def test_command_runs_as_a_process_and_survives_a_closed_pipe():
    command = [sys.executable, "-m", "vm_ros.cli", "params"]
    done = subprocess.run(command, capture_output=True, text=True, timeout=60, check=False)
    assert done.returncode == 0 and done.stderr == ""
    assert "fibre_type_parameters.tf1" in done.stdout
    help_text = subprocess.run([*command, "--help"], capture_output=True, text=True,
                               timeout=60, check=False).stdout
    assert "--muscle" in help_text and "unit" in help_text
    reader_gone = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    reader_gone.stdout.close()  # as `vm-ros params | head -1` once head has exited
    _, stderr = reader_gone.communicate(timeout=60)
    assert reader_gone.returncode == 0 and stderr == b""
