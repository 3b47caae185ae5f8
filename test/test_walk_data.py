"""Fetching the Gait10dof18musc walk (vm_ros.validation.walk_data) from a local checkout, against
a small manifest whose hashes are computed here by hashlib."""

from __future__ import annotations

import hashlib

import pytest

from vm_ros.validation import walk_data

LF = b"time\tknee_angle_r\n0.0\t1.0\n"


@pytest.fixture
def checkout(tmp_path, monkeypatch):
    """A checkout holding one file with Windows line ends, and a manifest of that file (LF)."""
    root = tmp_path / "opensim-models"
    file = root / walk_data.PREFIX / "IK" / "walk.mot"
    file.parent.mkdir(parents=True)
    file.write_bytes(LF.replace(b"\n", b"\r\n"))
    manifest = {"motion": walk_data.WalkFile("IK/walk.mot", hashlib.sha256(LF).hexdigest(), "")}
    monkeypatch.setattr(walk_data, "FILES", manifest)
    return root


def test_fetch_from_a_checkout_restores_the_stored_line_ends(checkout, tmp_path):
    files = walk_data.fetch(str(checkout), tmp_path / "cache", log=lambda line: None)
    assert files["motion"].read_bytes() == LF
    assert walk_data.walk_files(tmp_path / "cache") == files


def test_a_file_that_differs_is_refused(checkout, tmp_path):
    (checkout / walk_data.PREFIX / "IK" / "walk.mot").write_bytes(LF + b"0.1\t2.0\n")
    with pytest.raises(walk_data.WalkDataError, match="is not the pinned"):
        walk_data.fetch(str(checkout), tmp_path / "cache", log=lambda line: None)
    assert not (tmp_path / "cache" / "IK" / "walk.mot").exists()


def test_missing_or_altered_cache_names_the_script(checkout, tmp_path):
    with pytest.raises(walk_data.WalkDataError, match="run scripts/fetch-gait-data"):
        walk_data.walk_files(tmp_path / "empty")
    walk_data.fetch(str(checkout), tmp_path / "cache", log=lambda line: None)
    (tmp_path / "cache" / "IK" / "walk.mot").write_bytes(b"changed")
    with pytest.raises(walk_data.WalkDataError, match="IK/walk.mot differ from"):
        walk_data.walk_files(tmp_path / "cache")


def test_a_source_that_is_no_copy_is_an_error(tmp_path):
    with pytest.raises(walk_data.WalkDataError, match="neither a URL, a checkout"):
        walk_data.reader(str(tmp_path))
