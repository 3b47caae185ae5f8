"""Child processes run the vm_ros this process imported, never a vm_ros/ folder in the working
directory (`python -m` would put the working directory first on sys.path)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

import vm_ros
from vm_ros.child_process import module_command, module_environment


@pytest.fixture
def shadow(tmp_path):
    """A working directory with a vm_ros/ package that is not the one under test."""
    package = tmp_path / "vm_ros"
    (package / "cli").mkdir(parents=True)
    (package / "__init__.py").write_text("")
    (package / "cli" / "__init__.py").write_text("")
    (package / "cli" / "__main__.py").write_text("print('SHADOW'); raise SystemExit(3)")
    return tmp_path


@pytest.mark.parametrize("safe_path", [True, False] if sys.version_info >= (3, 11) else [False])
def test_child_imports_this_vm_ros_not_the_working_directory(shadow, safe_path):
    proc = subprocess.run(module_command("vm_ros.cli", "--help", safe_path=safe_path),
                          cwd=shadow, env=module_environment(), capture_output=True, text=True,
                          timeout=60)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "SHADOW" not in proc.stdout and "usage" in proc.stdout


def test_plain_dash_m_would_run_the_shadow(shadow):
    """The failure module_command avoids (so the test above means something)."""
    proc = subprocess.run([sys.executable, "-m", "vm_ros.cli", "--help"], cwd=shadow,
                          env=module_environment(), capture_output=True, text=True, timeout=60)
    assert proc.returncode == 3 and "SHADOW" in proc.stdout


def test_environment_puts_this_vm_ros_first():
    first = module_environment()["PYTHONPATH"].split(":")[0]
    assert Path(first) / "vm_ros" == Path(vm_ros.__file__).resolve().parent
