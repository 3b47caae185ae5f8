"""Every code block of README.md and docs/ runs as written.

Each fenced block names its language: ``python`` and ``sh`` blocks are run (python with this
interpreter, sh with ``bash -e``, both with the venv's commands first on PATH, in a fresh folder);
``yaml`` blocks are parsed, and one whose first line is a comment naming a file (``# node.yaml``)
is written into that folder for the document's other blocks; ``text`` blocks are synopses or
printed output, not commands. An HTML comment on the line before a fence says what a block needs:

    <!-- doc-test: needs FILE ... -->       files (or folders) this test provides, built here from
                                            nothing but the extras, or copied from the walk that
                                            scripts/fetch-gait-data caches (FIXTURES; skipped
                                            without it); ``ROS`` asks for rclpy in a
                                            loopback-only namespace
    <!-- doc-test: runs until stopped: N --> a service (a node): it must still be running, or have
                                            exited 0, after N s; it is then stopped with SIGTERM
    <!-- doc-test: not run: REASON -->       only for the reasons in NOT_RUN

Several parts are separated by ';' (``needs elbow/ ROS; runs until stopped: 20``).

A block that fails shows its output. The run of the README's three examples is what a new user
types. Whether a number quoted in the prose names the command that produced it is a rule of
review, not checked here (test_docs.py checks cited documents and tables against the config).
"""

from __future__ import annotations

import math
import os
import re
import shutil
import signal
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
import yaml

ROOT = Path(__file__).resolve().parents[1]
DOCUMENTS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
LANGUAGES = ("python", "sh", "yaml", "text")
NOT_RUN = {  # the only reasons a block may give for not running here
    "it is the command that runs this test suite",
    "installs packages from the package index, which the test namespace cannot reach",
    "runs on the hosts of a cluster",  # test_study.py runs --scheduler on a local one
    "needs a Slurm cluster and dask-jobqueue",
    "needs a Kubernetes cluster and dask-kubernetes",
}
BIN = str(Path(sys.executable).parent)
FENCE = re.compile(r"^```([^\n`]*)\n(.*?)^```[ \t]*$", re.MULTILINE | re.DOTALL)
MARK = re.compile(r"<!--\s*doc-test:\s*(.*?)\s*-->\s*$")


@dataclass(frozen=True)
class Block:
    document: Path
    line: int
    language: str
    code: str
    mark: str

    @property
    def name(self) -> str:
        return f"{self.document.relative_to(ROOT)}:{self.line}"

    def part(self, prefix: str) -> str | None:
        """The mark's part that starts with ``prefix`` (parts are separated by ';'), without it."""
        for part in self.mark.split(";"):
            if part.strip().startswith(prefix):
                return part.strip().removeprefix(prefix).strip()
        return None

    @property
    def needs(self) -> list[str]:
        return (self.part("needs ") or "").split()


def _blocks() -> list[Block]:
    blocks = []
    for document in DOCUMENTS:
        text = document.read_text()
        for match in FENCE.finditer(text):
            before = text[:match.start()].rstrip("\n").rsplit("\n", 1)[-1]
            mark = MARK.search(before)
            blocks.append(Block(document, text.count("\n", 0, match.start()) + 1,
                                match.group(1).strip(), match.group(2),
                                mark.group(1) if mark else ""))
    return blocks


BLOCKS = _blocks()
RUN = [b for b in BLOCKS if b.language in ("python", "sh") and b.part("not run:") is None]


def test_every_block_names_its_language_and_a_known_mark():
    problems = [f"{b.name}: language {b.language!r} is not one of {', '.join(LANGUAGES)}"
                for b in BLOCKS if b.language not in LANGUAGES]
    for b in BLOCKS:
        reason = b.part("not run:")
        if reason is not None and reason not in NOT_RUN:
            problems.append(f"{b.name}: 'not run' for a reason not in NOT_RUN: {reason!r}")
        unknown = [n for n in b.needs if n not in FIXTURES]
        if unknown:
            problems.append(f"{b.name}: needs {unknown}, which FIXTURES does not provide")
    assert not problems, "\n".join(problems)
    assert len(RUN) >= 8  # the README's three examples and the docs' blocks are collected


def test_blocks_not_run_parse():
    """A python or sh block that is not run is still valid code (compile, bash -n)."""
    for block in (b for b in BLOCKS if b.language in ("python", "sh") and b not in RUN):
        if block.language == "python":
            compile(block.code, block.name, "exec")
        else:
            proc = subprocess.run(["bash", "-n", "-c", block.code], capture_output=True,
                                  text=True, timeout=60)
            assert proc.returncode == 0, f"{block.name}: {proc.stderr}"


# how a command or a program starts; a text block whose first line that is not a comment
# starts so, without synopsis brackets ([--OPTION]), is something to run fenced as text: skipped
COMMAND_STARTS = ("vm-ros ", "python", "make ", "scripts/", "ros2 ", "dask ", "pip ", "from ",
                  "import ", "colcon ", "source ")


def _first_code_line(code: str) -> str:
    return next((line for line in code.splitlines() if line.strip() and
                 not line.startswith("#")), "")


def test_no_command_is_fenced_as_text():
    commands = [b.name for b in BLOCKS if b.language == "text" and "[--" not in b.code and
                _first_code_line(b.code).startswith(COMMAND_STARTS)]
    assert not commands, f"commands fenced as text (fence them as sh or python): {commands}"


def test_yaml_blocks_parse():
    for block in (b for b in BLOCKS if b.language == "yaml"):
        assert yaml.safe_load(block.code) is not None, block.name


# --- what blocks need ----------------------------------------------------------------------------


def _osim():
    return pytest.importorskip("osim_models", reason='the OpenSim examples need the opensim extra')


def _motion(path: Path) -> Path:
    """1 s of a walking-like hip and knee at 100 Hz, in degrees, inside MyModel's box."""
    t = np.round(np.arange(0.0, 1.0 + 1e-9, 0.01), 10)
    hip = 20.0 + 20.0 * np.sin(2 * np.pi * t)
    knee = -50.0 + 35.0 * np.sin(2 * np.pi * t + 1.0)
    rows = "".join(f"{a:.4f}\t{h:.6f}\t{k:.6f}\n" for a, h, k in zip(t, hip, knee, strict=True))
    path.write_text(f"ik_walk\nversion=1\nnRows={len(t)}\nnColumns=3\ninDegrees=yes\nendheader\n"
                    f"time\thip_flexion\tknee_angle\n{rows}")
    return path


def _controls(path: Path) -> Path:
    """Drives of MyModel's four muscles on ik_walk's time axis (CMC's column names)."""
    t = np.linspace(0.0, 1.0, 51)
    muscles = ("rf", "vas", "ham", "ilio")
    rows = "".join("\t".join([f"{s:.4f}"] + [f"{0.2 + 0.15 * math.sin(2 * math.pi * s + k):.6f}"
                                             for k in range(len(muscles))]) + "\n" for s in t)
    path.write_text(f"controls\nversion=1\ninDegrees=no\nendheader\ntime\t{chr(9).join(muscles)}"
                    f"\n{rows}")
    return path


def _run(args, cwd: Path, timeout: float = 600) -> None:
    proc = subprocess.run(args, cwd=cwd, capture_output=True, text=True, timeout=timeout,
                          env=_env())
    assert proc.returncode == 0, f"{args}: {proc.stdout[-2000:]}{proc.stderr[-3000:]}"


def _fitted_paths(folder: Path) -> Path:
    """MyModel_FunctionBasedPathSet.xml, from OpenSim's PolynomialPathFitter on ik_walk."""
    osim = _osim().osim
    model, motion = _built(folder, "MyModel.osim"), _built(folder, "ik_walk.mot")
    fitter = osim.PolynomialPathFitter()
    fitter.setModel(osim.ModelProcessor(str(model)))
    table = osim.TableProcessor(str(motion))
    table.append(osim.TabOpUseAbsoluteStateNames())
    fitter.setCoordinateValues(table)
    fitter.setOutputDirectory(str(folder / "fitted"))
    fitter.setMaximumPolynomialOrder(4)
    fitter.setNumSamplesPerFrame(5)
    fitter.setNumParallelThreads(1)
    fitter.run()
    (written,) = (folder / "fitted").glob("*_FunctionBasedPathSet.xml")  # <model name>_...
    return written.rename(folder / "MyModel_FunctionBasedPathSet.xml")


def _walk_file(name: str, opensim: bool = False):
    """A FIXTURES builder: the walk's file ``name`` (vm_ros.validation.walk_data.FILES),
    copied from the cache scripts/fetch-gait-data fills (skipped when it has not been run, or
    with ``opensim`` when the opensim extra is not installed)."""

    def copy(folder: Path) -> Path:
        from vm_ros.validation.walk_data import WalkDataError, walk_files

        if opensim:
            _osim()
        try:
            source = walk_files()[name]
        except WalkDataError as exc:
            pytest.skip(str(exc))
        return Path(shutil.copy(source, folder / source.name))

    return copy


def _walk_model(folder: Path) -> Path:
    """out/model/: the walk's model imported at its own F0 (README's import-osim line)."""
    _run([f"{BIN}/vm-ros", "import-osim", str(_built(folder, "subject01.osim")), "--motion",
          str(_built(folder, "subject01_walk_IK.mot")), "--specific-tension", "60",
          "--strength", "model", "--out", str(folder / "out" / "model")], folder)
    return folder / "out" / "model"


FIXTURES = {
    "subject01.osim": _walk_file("model", opensim=True),
    "subject01_walk_IK.mot": _walk_file("motion"),
    "subject01_walk_ID.sto": _walk_file("inverse_dynamics"),
    "out/model/": _walk_model,
    "MyModel.osim": lambda folder: _osim().build_hip_knee(folder / "MyModel.osim"),
    "ik_walk.mot": lambda folder: _motion(folder / "ik_walk.mot"),
    "controls.sto": lambda folder: _controls(folder / "controls.sto"),
    "leg/": lambda folder: _run([f"{BIN}/vm-ros", "import-osim", str(_built(
        folder, "MyModel.osim")), "--out", str(folder / "leg"), "--motion", str(_built(
            folder, "ik_walk.mot")), "--samples", "300"], folder) or folder / "leg",
    "MyModel_FunctionBasedPathSet.xml": _fitted_paths,
    "elbow/": lambda folder: _run([f"{BIN}/vm-ros", "import-mjcf", "myoelbow", "--out",
                                   str(folder / "elbow")], folder) or folder / "elbow",
    "ROS": lambda folder: None,
}


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    """One folder of everything FIXTURES built, each built once."""
    return tmp_path_factory.mktemp("doc_fixtures")


_BUILT: dict[str, Path] = {}


def _built(folder: Path, name: str) -> Path:
    if name not in _BUILT:
        made = FIXTURES[name](folder)
        _BUILT[name] = Path(made) if made is not None else folder / name
    return _BUILT[name]


def _env() -> dict:
    env = dict(os.environ)
    env["PATH"] = f"{BIN}{os.pathsep}{env.get('PATH', '')}"
    env.setdefault("MPLBACKEND", "Agg")
    return env


def _provide(block: Block, built: Path, folder: Path) -> None:
    if "ROS" in block.needs:
        pytest.importorskip("rclpy", reason="the ROS examples need the ros extra")
        if os.environ.get("VM_ROS_NETNS") != "1":
            pytest.skip("ROS blocks run only in a loopback-only namespace (scripts/netns-run)")
    for name in block.needs:
        if name == "ROS":
            continue
        source = _built(built, name)
        target = folder / name.rstrip("/")
        if source.is_dir():
            shutil.copytree(source, target)
        else:
            shutil.copy(source, target)
    for other in BLOCKS:  # the document's named YAML files
        first = other.code.split("\n", 1)[0]
        if other.document == block.document and other.language == "yaml" and \
                first.startswith("# ") and first.endswith(".yaml"):
            (folder / first[2:].strip()).write_text(other.code)


def _command(block: Block) -> list[str]:
    if block.language == "python":
        return [sys.executable, "-c", block.code]
    return ["bash", "-e", "-o", "pipefail", "-c", block.code]


BLOCK_TIMEOUT_S = 900


def _run_to_the_end(block: Block, tmp_path) -> tuple[int, str, str]:
    """(exit status, stdout, stderr) of the block run in its own session. A block still running
    after BLOCK_TIMEOUT_S fails the test naming the processes of its session that were alive
    (the ones a block starts in the background hold its output open), and they are killed, so
    that none outlives the test."""
    proc = subprocess.Popen(_command(block), cwd=tmp_path, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=_env(),
                            start_new_session=True)
    try:
        out, err = proc.communicate(timeout=BLOCK_TIMEOUT_S)
    except subprocess.TimeoutExpired:
        alive = _session_processes(proc.pid)
        os.killpg(proc.pid, signal.SIGKILL)
        out, err = proc.communicate(timeout=60)
        pytest.fail(f"{block.name}: still running after {BLOCK_TIMEOUT_S} s; alive: "
                    f"{alive}\n{out[-3000:]}\n{err[-3000:]}")
    if proc.returncode == 0 and _session_processes(proc.pid):  # background processes left
        os.killpg(proc.pid, signal.SIGKILL)
    return proc.returncode, out, err


def _session_processes(session: int) -> list[str]:
    """'pid command' of the live processes of session ``session`` (from /proc)."""
    alive = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
            if int(fields[3]) == session and fields[0] != "Z":  # session id, state
                command = (stat.parent / "cmdline").read_bytes().replace(b"\0", b" ")
                alive.append(f"{stat.parent.name} {command.decode(errors='replace')[:200]}")
        except (OSError, IndexError, ValueError):
            continue  # the process ended meanwhile
    return alive


@pytest.mark.slow
@pytest.mark.parametrize("block", RUN, ids=[b.name for b in RUN])
def test_block_runs(block, built, tmp_path):
    _provide(block, built, tmp_path)
    service = block.part("runs until stopped:")
    if service is None:
        returncode, out, err = _run_to_the_end(block, tmp_path)
        assert returncode == 0, f"{block.name}:\n{out[-3000:]}\n{err[-3000:]}"
        return
    proc = subprocess.Popen(_command(block), cwd=tmp_path, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=_env(),
                            start_new_session=True)
    deadline = time.monotonic() + float(service)
    while proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.2)
    running = proc.poll() is None
    if running:
        os.killpg(proc.pid, signal.SIGTERM)
    out, err = proc.communicate(timeout=60)
    assert running or proc.returncode == 0, f"{block.name} exited {proc.returncode}:\n{err[-3000:]}"
    assert "Traceback" not in err, f"{block.name}:\n{err[-3000:]}"
