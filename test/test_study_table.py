"""The study file and the results table without Dask: a column for every parameter the study
changes, the run id over the shipped files a run reads and the vm_ros version, errors at the
exact place of the field, the inputs' muscles checked against the library before anything runs."""

from __future__ import annotations

import shutil

import pytest
import yaml
from conftest import require_module

from vm_ros.cli import main
from vm_ros.resources import config_dir
from vm_ros.study import study_file
from vm_ros.study.study_file import StudyError, load_study
from vm_ros.study.table import RESULT_COLUMNS, RecordStore, table_rows

KNEE = "scenario: knee_extension"


def _study(folder, body: str, inputs: str = f"  - {KNEE}\n", name: str = "study.yaml"):
    path = folder / name
    path.write_text(f"version: 1\ninputs:\n{inputs}{body}")
    return path


def _records(study, folder) -> RecordStore:
    """An ok record of one muscle for every run (the numbers do not matter here)."""
    store = RecordStore(folder)
    for spec in study.runs:
        store.write({"run_id": spec.run_id, "status": "ok", "error": "",
                     "rows": [{"muscle": "vasti", "duration_s": 0.5}], "worker": "w"})
    return store


SETTINGS = ("settings:\n  duration: 0.5\n  energetics_models: all\n  recruitment: natural\n"
            "  library.vasti.fpcsa_slow: 0.3\n  model.energetics.recovery_kernel: pcr_slade2006\n"
            "grid:\n  dt: [0.001, 0.002]\n")


def test_every_parameter_of_settings_has_its_column_after_the_varied_ones(tmp_path):
    study = load_study(_study(tmp_path, SETTINGS))
    columns, types, rows = table_rows(study, _records(study, tmp_path / "out"))
    given = ["duration", "energetics_models", "recruitment", "library.vasti.fpcsa_slow",
             "model.energetics.recovery_kernel"]
    assert columns[:2 + 1 + len(given)] == ["run_id", "input", "dt", *given]
    assert columns[2 + 1 + len(given)] == RESULT_COLUMNS[0]
    assert [types[c] for c in given] == ["double", "string", "string", "double", "string"]
    assert [r["dt"] for r in rows] == [0.001, 0.002]
    for row in rows:  # the values the file gives, in every row
        assert (row["duration"], row["energetics_models"], row["recruitment"],
                row["library.vasti.fpcsa_slow"], row["model.energetics.recovery_kernel"]) == (
            0.5, "all", "natural", 0.3, "pcr_slade2006")


def test_a_parameter_of_one_change_set_only_is_empty_in_the_others(tmp_path):
    study = load_study(_study(tmp_path, "settings: {duration: 0.5}\nruns:\n  - {dt: 0.001}\n"
                                        "  - {recruitment: natural}\n"))
    columns, types, rows = table_rows(study, _records(study, tmp_path / "out"))
    assert columns[2:5] == ["dt", "recruitment", "duration"]
    assert (types["dt"], types["recruitment"]) == ("double", "string")
    assert [(r["dt"], r["recruitment"], r["duration"]) for r in rows] == [
        (0.001, None, 0.5), (None, "natural", 0.5)]


def test_the_table_files_have_the_settings_columns(tmp_path):
    pq = require_module("pyarrow.parquet", "study")
    from vm_ros.study.table import write_table

    study = load_study(_study(tmp_path, SETTINGS))
    out = tmp_path / "out"
    _records(study, out)
    assert write_table(study, out) == 2
    first = (out / "results.parquet").read_bytes(), (out / "results.csv").read_bytes()
    table = pq.read_table(out / "results.parquet")
    assert str(table.schema.field("library.vasti.fpcsa_slow").type) == "double"
    assert table.column("energetics_models").to_pylist() == ["all", "all"]
    assert (out / "results.csv").read_text().splitlines()[0].startswith(
        "run_id,input,dt,duration,energetics_models,recruitment,library.vasti.fpcsa_slow,"
        "model.energetics.recovery_kernel,muscle,")
    assert write_table(load_study(tmp_path / "study.yaml"), out) == 2  # the same bytes again
    assert ((out / "results.parquet").read_bytes(), (out / "results.csv").read_bytes()) == first


# --- run id ------------------------------------------------------------------------------------


def _ids(path) -> list[str]:
    return [spec.run_id for spec in load_study(path).runs]


@pytest.fixture
def own_config(tmp_path, monkeypatch):
    """A copy of the shipped configuration, used through VM_ROS_CONFIG_DIR."""
    folder = tmp_path / "config"
    shutil.copytree(config_dir(), folder)
    monkeypatch.setenv("VM_ROS_CONFIG_DIR", str(folder))
    return folder


def _append(path, text: str) -> None:
    path.write_text(path.read_text() + text)


@pytest.mark.parametrize("name", ["model.yaml", "muscles.yaml"])
def test_the_run_id_changes_with_the_default_files_a_run_reads(tmp_path, own_config, name):
    study = _study(tmp_path, "settings: {duration: 0.5}\ngrid:\n  dt: [0.001, 0.002]\n")
    before = _ids(study)
    assert _ids(study) == before and len(set(before)) == 2  # the same study, the same ids
    _append(own_config / name, "\n# a changed default\n")
    after = _ids(study)
    assert not set(after) & set(before)
    _append(own_config / name, "")
    assert _ids(study) == after


def test_a_default_file_the_study_replaces_is_not_in_the_run_id(tmp_path, own_config):
    (tmp_path / "model.yaml").write_bytes((own_config / "model.yaml").read_bytes())
    (tmp_path / "muscles.yaml").write_bytes((own_config / "muscles.yaml").read_bytes())
    study = _study(tmp_path, "settings: {duration: 0.5, params: model.yaml, "
                             "library: muscles.yaml}\n")
    before = _ids(study)
    _append(own_config / "model.yaml", "\n# a changed default\n")
    _append(own_config / "muscles.yaml", "\n# a changed default\n")
    assert _ids(study) == before
    _append(tmp_path / "model.yaml", "\n# the study's own file changed\n")
    assert _ids(study) != before


def test_the_energetics_constants_are_in_the_id_of_runs_with_published_models(tmp_path,
                                                                              own_config):
    study = _study(tmp_path, "settings: {duration: 0.5}\nruns:\n  - {energetics_models: all}\n"
                             "  - {energetics_models: none}\n  - {dt: 0.001}\n")
    with_models, without, default = _ids(study)
    _append(own_config / "energetics_models.yaml", "\n# a changed constant\n")
    assert _ids(study) == [_ids(study)[0], without, default] and _ids(study)[0] != with_models


def test_the_run_id_changes_with_the_vm_ros_version(tmp_path, monkeypatch):
    study = _study(tmp_path, "settings: {duration: 0.5}\n")
    before = _ids(study)
    monkeypatch.setattr(study_file, "VM_ROS_VERSION", "0.0.0+another")
    assert _ids(study) != before


# --- errors at their place ---------------------------------------------------------------------


@pytest.mark.parametrize("body, field", [
    ("grid:\n  model.energetics.recovery_kernel: [fitted_fig7, nosuch]\n",
     "grid.model.energetics.recovery_kernel[1]"),
    ("settings:\n  library.vasti.fpcsa_slow: 7\n", "settings.library.vasti.fpcsa_slow"),
    ("runs:\n  - {dt: 0.001}\n  - {model.generic.no_such_constant: 1}\n",
     "runs[1].model.generic.no_such_constant"),
    # fmax below the file's fmin: the error is in fmin, the change at fault is fmax
    ("grid:\n  model.generic.fmax: [1.0, -2.0]\n  model.energetics.recovery_kernel: "
     "[fitted_fig7]\n", "grid.model.generic.fmax[1]"),
    ("grid:\n  dt: [0.001]\n  library.vasti.no_such_field: [1]\n",
     "grid.library.vasti.no_such_field[0]"),
    ("runs:\n  - {library.nosuch.fpcsa_slow: 0.5}\n", "runs[0].library.nosuch.fpcsa_slow"),
])
def test_a_model_or_library_error_names_its_exact_place(tmp_path, body, field):
    with pytest.raises(StudyError) as caught:
        load_study(_study(tmp_path, "settings: {duration: 0.5}\n" * ("settings" not in body)
                          + body))
    assert caught.value.field == field
    assert "\n" not in str(caught.value)


def test_the_verb_prints_the_place_on_one_line_and_exits_2(tmp_path, capsys):
    study = _study(tmp_path, "grid:\n  model.energetics.recovery_kernel: [fitted_fig7, nosuch]\n")
    assert main(["study", "check", str(study)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert f"{study}: grid.model.energetics.recovery_kernel[1]: " in err


# --- the inputs' muscles -----------------------------------------------------------------------


def test_a_muscle_not_in_the_library_fails_before_anything_runs(tmp_path, capsys):
    study = _study(tmp_path, "settings: {duration: 0.5}\n",
                   inputs=f"  - {KNEE}\n  - {{{KNEE}, muscles: [vasti, nosuch]}}\n")
    with pytest.raises(StudyError) as caught:
        load_study(study)
    assert caught.value.field == "inputs[1].muscles[1]"
    assert "'nosuch'" in caught.value.reason and "scenario:knee_extension" in caught.value.reason
    assert main(["study", "run", str(study), "--out", str(tmp_path / "out")]) == 2
    assert len(capsys.readouterr().err.strip().splitlines()) == 1
    assert not (tmp_path / "out").exists()


def test_the_muscles_are_checked_against_the_library_of_each_run(tmp_path):
    library = yaml.safe_load((config_dir() / "muscles.yaml").read_text())
    (tmp_path / "muscles_copy.yaml").write_text(yaml.safe_dump(library))
    library["muscles"] = {"vasti": library["muscles"]["vasti"]}
    (tmp_path / "vasti_only.yaml").write_text(yaml.safe_dump(library))
    inputs = f"  - {{{KNEE}, muscles: [rectus_femoris]}}\n"
    assert len(load_study(_study(tmp_path, "settings: {duration: 0.5}\n", inputs)).runs) == 1
    with pytest.raises(StudyError) as caught:
        load_study(_study(tmp_path, "settings: {duration: 0.5}\ngrid:\n  library: "
                                    "[muscles_copy.yaml, vasti_only.yaml]\n", inputs))
    assert caught.value.field == "inputs[0].muscles[0]"
    assert "vasti_only.yaml" in caught.value.reason
