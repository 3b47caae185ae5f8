"""Packaging: the ament layout that `ros2 run vm_ros muscle_node` needs, for pip and colcon.

ros2run looks the package up on AMENT_PREFIX_PATH with ament_index_python, then runs the
executable file ``<prefix>/lib/vm_ros/muscle_node``, our POSIX-sh shim that execs the console
script ``<prefix>/bin/muscle_node`` (``mujoco_sim_node`` has the same kind of shim). ros2cli
is not on PyPI, so the lookup is done here exactly as ros2run does it, and the shim is run for
real.

Under ``make test`` (VM_ROS_NETNS=1) or in CI (CI set), whatever would be skipped elsewhere fails.
"""

from __future__ import annotations

import importlib.metadata
import importlib.util
import json
import os
import shutil
import subprocess
import sys
import sysconfig
import time
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
PACKAGE = "vm_ros"
STRICT = os.environ.get("VM_ROS_NETNS") == "1" or os.environ.get("CI", "").lower() not in (
    "",
    "0",
    "false",
)
COLCON_TIMEOUT_S = 90
COMPILE_TIMEOUT_S = 240  # the model step's first compile: 11-12 s idle, up to 40 s busy
EXECUTABLES = ("muscle_node", "mujoco_sim_node")  # each: resource/<name> -> lib/vm_ros/<name>


def _skip_or_fail(reason: str) -> None:
    """Skip, except under make test or CI where a skip would hide a broken install."""
    if STRICT:
        pytest.fail(f"{reason} (not skipped: CI or VM_ROS_NETNS=1 is set)")
    pytest.skip(reason)


def _install_kind() -> str:
    """How vm_ros is installed in this environment: 'regular', 'editable' or 'absent'."""
    try:
        dist = importlib.metadata.distribution(PACKAGE)
    except importlib.metadata.PackageNotFoundError:
        return "absent"
    direct_url = dist.read_text("direct_url.json")
    if direct_url and json.loads(direct_url).get("dir_info", {}).get("editable"):
        return "editable"
    return "regular"


def _ament_index():
    if importlib.util.find_spec("ament_index_python") is None:
        _skip_or_fail("ament_index_python is missing: install the [ros] extra")
    import ament_index_python

    return ament_index_python


def _is_executable_file(path: Path) -> bool:
    return path.is_file() and os.access(path, os.X_OK)


def _source_files(folder: str, pattern: str) -> list[str]:
    return sorted(p.name for p in (REPO / folder).glob(pattern))


def _assert_ament_prefix(prefix: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Assert that `prefix` is an ament prefix from which ros2run can start muscle_node."""
    marker = prefix / "share/ament_index/resource_index/packages" / PACKAGE
    assert marker.is_file(), f"ament index marker missing: {marker}"
    share = prefix / "share" / PACKAGE
    assert (share / "package.xml").read_bytes() == (REPO / "package.xml").read_bytes()
    assert _source_files("config", "*.yaml") == sorted(
        p.name for p in (share / "config").glob("*.yaml")
    )
    assert _source_files("msg_defs", "*.msg") == sorted(
        p.name for p in (share / "msg").glob("*.msg")
    )

    for name in EXECUTABLES:
        shim = prefix / "lib" / PACKAGE / name
        assert _is_executable_file(shim), f"shim missing or not executable: {shim}"
        assert shim.read_bytes() == (REPO / "resource" / name).read_bytes()
        assert _is_executable_file(prefix / "bin" / name), f"console script {name} missing"

    ament_index_python = _ament_index()
    monkeypatch.setenv("AMENT_PREFIX_PATH", str(prefix))
    assert ament_index_python.get_package_prefix(PACKAGE) == str(prefix)
    assert ament_index_python.get_package_share_directory(PACKAGE) == str(share)
    # ros2pkg.api.get_executable_paths: the executable files under <prefix>/lib/<package>
    lib_dir = Path(ament_index_python.get_package_prefix(PACKAGE)) / "lib" / PACKAGE
    executables = sorted(p.name for p in lib_dir.iterdir() if _is_executable_file(p))
    assert set(EXECUTABLES) <= set(executables)


# --- (1) pip: the venv this suite runs in is an ament prefix --------------------------------------


def test_pip_install_is_an_ament_prefix(monkeypatch):
    prefix = Path(sys.prefix)
    kind = _install_kind()
    if kind != "regular":
        _skip_or_fail(
            f"vm_ros is {kind} in {prefix}: data_files (marker, shim) exist only after a"
            " regular `pip install .`"
        )
    _assert_ament_prefix(prefix, monkeypatch)


def test_suite_runs_against_installed_package():
    """`make test` must exercise the installed copy, not the source tree on sys.path."""
    import vm_ros

    if not STRICT:
        pytest.skip("only checked under make test / CI")
    site = Path(sysconfig.get_paths()["purelib"]).resolve()
    assert Path(vm_ros.__file__).resolve().is_relative_to(site), (
        f"vm_ros imported from {vm_ros.__file__}, not from {site}: run pytest via the venv's"
        " `pytest` script (`python -m pytest` puts the working directory first on sys.path)"
    )


# --- (2) the shim ---------------------------------------------------------------------------------

FAKE_NODE = """#!/bin/sh
# stands in for the console script: prints its own path, then each argument, NUL-terminated
printf '%s\\0' "$0" "$@"
exit "${FAKE_EXIT:-0}"
"""

ARGS = ["a b", "", "*", "$HOME", "--ros-args", "-p", "publish_rate:=100.0", "-r", "__ns:=/x y"]


def _make_prefix(root: Path, shim_as_symlink: bool = False) -> Path:
    """A prefix with the real shim in lib/vm_ros and a fake bin/muscle_node."""
    prefix = root / "pre fix"  # a space in the prefix must not break the shim
    (prefix / "bin").mkdir(parents=True)
    (prefix / "lib" / PACKAGE).mkdir(parents=True)
    fake = prefix / "bin" / "muscle_node"
    fake.write_text(FAKE_NODE)
    fake.chmod(0o755)
    shim = prefix / "lib" / PACKAGE / "muscle_node"
    if shim_as_symlink:  # as colcon --symlink-install lays it out: a link into the build tree
        target = root / "elsewhere" / "muscle_node"
        target.parent.mkdir()
        shutil.copy2(REPO / "resource/muscle_node", target)
        shim.symlink_to(target)
    else:
        shutil.copy2(REPO / "resource/muscle_node", shim)
    return prefix


def _run(argv: list[str], cwd: Path, **env: str) -> subprocess.CompletedProcess:
    return subprocess.run(argv, cwd=cwd, capture_output=True, timeout=10, env={**os.environ, **env})


@pytest.mark.parametrize("name", EXECUTABLES)
def test_shim_source(name):
    shim = REPO / "resource" / name
    text = shim.read_text()
    assert text.startswith("#!/bin/sh\n")
    assert 'prefix=$(cd "$(dirname "$0")/../.." && pwd)' in text
    assert f'exec "$prefix/bin/{name}" "$@"' in text
    assert os.access(shim, os.X_OK), f"resource/{name} must be executable in the repository"
    assert (REPO / "resource" / PACKAGE).read_bytes() == b""
    # the other shims differ from muscle_node's only in the name
    muscle_node = (REPO / "resource/muscle_node").read_text()
    assert text == muscle_node.replace("muscle_node", name)


@pytest.mark.parametrize("shim_as_symlink", [False, True], ids=["copy", "symlink"])
@pytest.mark.parametrize("invocation", ["absolute", "relative"])
def test_shim_execs_console_script_with_arguments(tmp_path, shim_as_symlink, invocation):
    prefix = _make_prefix(tmp_path, shim_as_symlink)
    if invocation == "absolute":
        cwd, shim = tmp_path, str(prefix / "lib" / PACKAGE / "muscle_node")
    else:
        cwd, shim = prefix / "lib", f"{PACKAGE}/muscle_node"
    proc = _run([shim, *ARGS], cwd)
    assert proc.returncode == 0, proc.stderr.decode()
    called, *args = proc.stdout.decode().split("\0")[:-1]
    assert Path(called).resolve() == (prefix / "bin" / "muscle_node").resolve()
    assert args == ARGS


def test_shim_passes_exit_status_through(tmp_path):
    prefix = _make_prefix(tmp_path)
    proc = _run([str(prefix / "lib" / PACKAGE / "muscle_node")], tmp_path, FAKE_EXIT="3")
    assert proc.returncode == 3


# --- (3) colcon -----------------------------------------------------------------------------------

COPY_IGNORE = shutil.ignore_patterns(
    ".git",
    ".venv*",
    "build",
    "install",
    "log",
    "*.egg-info",
    "__pycache__",
    ".pytest_cache",
    ".ruff_cache",
    "out",
    "*.mcap",
)


def _colcon_venv() -> Path:
    """The venv holding colcon, made (or found up to date) by scripts/colcon-venv."""
    venv = Path(os.environ.get("VM_ROS_COLCON_VENV", REPO / ".venv-colcon"))
    proc = subprocess.run(
        [str(REPO / "scripts/colcon-venv"), str(venv)], capture_output=True, text=True, timeout=600
    )
    assert proc.returncode == 0, f"scripts/colcon-venv failed:\n{proc.stdout}{proc.stderr}"
    return venv


@pytest.mark.parametrize("mode", ["install", "symlink-install"])
def test_colcon_build_gives_an_ament_prefix(tmp_path, monkeypatch, mode):
    venv = _colcon_venv()
    workspace = tmp_path / "ws"
    shutil.copytree(REPO, workspace / "src" / PACKAGE, ignore=COPY_IGNORE, symlinks=True)
    env = {
        key: value
        for key, value in os.environ.items()
        if key not in {"VIRTUAL_ENV", "PYTHONPATH", "AMENT_PREFIX_PATH", "COLCON_PREFIX_PATH"}
    }
    env["PATH"] = f"{venv / 'bin'}{os.pathsep}{env.get('PATH', '')}"
    env["COLCON_HOME"] = str(tmp_path / "colcon_home")  # no user defaults.yaml
    # An empty Numba cache of its own: the plain install compiles the model step into it
    # (setup.py InstallAndWarm); the symlink install (setup.py develop) does not warm.
    env["NUMBA_CACHE_DIR"] = str(tmp_path / "numba_cache")
    argv = [str(venv / "bin" / "colcon"), "build", "--base-paths", "src"]
    if mode == "symlink-install":
        argv.append("--symlink-install")

    start = time.monotonic()
    proc = subprocess.run(
        argv, cwd=workspace, env=env, capture_output=True, text=True,
        timeout=COLCON_TIMEOUT_S + (COMPILE_TIMEOUT_S if mode == "install" else 0),
    )
    elapsed = time.monotonic() - start
    print(f"colcon build ({mode}): {elapsed:.1f} s")
    assert proc.returncode == 0, f"colcon build failed:\n{proc.stdout}\n{proc.stderr}"

    prefix = workspace / "install" / PACKAGE
    if mode == "symlink-install":
        assert (prefix / "lib" / PACKAGE / "muscle_node").is_symlink()
    else:
        _assert_build_warmed_the_cache(venv, prefix, env)
    _assert_ament_prefix(prefix, monkeypatch)


def _assert_build_warmed_the_cache(venv: Path, prefix: Path, env: dict) -> None:
    """After `colcon build`, the installed copy finds its model step in Numba's disk cache
    (Numba's own index lookup, in a new process with the build's NUMBA_CACHE_DIR)."""
    sites = sorted(prefix.glob("lib/python*/site-packages"))
    assert sites, f"no site-packages under {prefix}"
    check = ("from vm_ros.model import jit, kernel; "
             "print(jit.cache_root(), jit.in_disk_cache(kernel.advance_series))")
    proc = subprocess.run(
        [str(venv / "bin" / "python"), "-c", check], env=dict(env, PYTHONPATH=str(sites[0])),
        capture_output=True, text=True, timeout=COLCON_TIMEOUT_S,
    )
    assert proc.returncode == 0, proc.stderr
    root, cached = proc.stdout.split()
    assert Path(root) == Path(env["NUMBA_CACHE_DIR"]), proc.stdout
    assert cached == "True", f"colcon build left no compiled model step in {root}"
