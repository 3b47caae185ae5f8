"""Linters run as tests: ruff over the whole repository (settings in pyproject.toml)."""

import re
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


def _ruff() -> Path:
    ruff = Path(sys.executable).with_name("ruff")
    if not ruff.exists():
        pytest.fail(f"ruff not found next to {sys.executable}: install the [dev] extra")
    return ruff


def test_ruff_check_is_clean():
    proc = subprocess.run(
        [str(_ruff()), "check", "--no-cache", "."],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 0, f"ruff check found problems:\n{proc.stdout}{proc.stderr}"


def test_no_formatter_markers():
    """The code is formatted by hand (aligned equations and tables, ruff check's line length);
    no formatter runs on it, so `fmt: skip` / `fmt: off` markers would only suggest one does."""
    marker = re.compile(r"#\s*fmt:\s*(skip|off|on)\b")
    found = [
        f"{path.relative_to(REPO)}:{number}"
        for folder in ("vm_ros", "test", "scripts")
        for path in sorted((REPO / folder).rglob("*.py"))
        for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1)
        if marker.search(line)
    ]
    assert not found, f"formatter markers in: {', '.join(found)}"
