"""`vm-ros coordinate` end to end on a one-coordinate geometry file: outputs written, drives
readable as excitations, the run log (with a lead-in) recomputed exactly, bad inputs one line
and exit 2."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from test_coordination import geometry, library

from vm_ros.geometry import write_geometry
from vm_ros.offline.excitations import load_excitations
from vm_ros.recording.run_log import read_run
from vm_ros.storage import read_columns

VM_ROS = str(Path(sys.executable).with_name("vm-ros"))


def _storage(path: Path, time, columns: dict, in_degrees: str = "no") -> Path:
    names = list(columns)
    lines = ["file", "version=1", f"nRows={len(time)}", f"nColumns={len(names) + 1}",
             f"inDegrees={in_degrees}", "endheader", "\t".join(["time", *names])]
    lines += ["\t".join(repr(float(v)) for v in (t, *(columns[n][i] for n in names)))
              for i, t in enumerate(time)]
    path.write_text("\n".join(lines) + "\n")
    return path


def _inputs(tmp_path: Path, amplitude: float = 0.05, in_degrees: str = "no") -> list[str]:
    """Geometry (q in [-0.6, 0.6] rad), library, motion q = amplitude sin(pi t / 0.6) over
    0.6 s (37 frames; the header's inDegrees as given) and inverse-dynamics targets."""
    geo = write_geometry(geometry({"a": 0.02, "b": 0.03}), tmp_path / "geometry.yaml")
    lib = library(tmp_path, a={}, b={"fpcsa_slow": 0.4})
    t = np.linspace(0.0, 0.6, 37)
    motion = _storage(tmp_path / "motion.mot", t, {"q": amplitude * np.sin(np.pi * t / 0.6)},
                      in_degrees)
    targets = _storage(tmp_path / "id.sto", t, {"q_moment": 8.0 - 2.0 * np.cos(np.pi * t / 0.6),
                                                "pelvis_tx_force": 0 * t})
    return ["--geometry", str(geo), "--library", lib, "--motion", str(motion), "--targets",
            str(targets)]


def _run(*args) -> subprocess.CompletedProcess:
    return subprocess.run([VM_ROS, *args], capture_output=True, text=True, timeout=900)


def test_outputs_drives_as_excitations_and_an_exact_recompute(tmp_path):
    out = tmp_path / "out"
    done = _run("coordinate", *_inputs(tmp_path), "--iterations", "4", "--out", str(out),
                "--speed", "1.0", "--body-mass", "70", "--lead-in", "0.2")
    assert done.returncode == 0, done.stderr
    for name in ("drives.sto", "forces.sto", "reserves.sto", "coordination.mcap",
                 "coordination.png", "motion.sto"):
        assert (out / name).is_file(), name
    assert "reserve RMS" in done.stdout and "cost of transport" in done.stdout
    assert "pelvis_tx_force" in done.stdout   # named as left to the reserves
    drives = load_excitations(out / "drives.sto", ("a", "b"))
    assert drives.values.shape[1] == 2 and np.all((drives.values >= 0) & (drives.values <= 1))
    assert drives.time_s[0] == pytest.approx(-0.2)   # the lead-in's drives, before the motion
    time, columns, _ = read_columns(out / "forces.sto", "forces")
    assert set(columns) == {"a", "b"} and len(time) == 37
    again = _run("recompute", str(out / "coordination.mcap"), "--out",
                 str(tmp_path / "again.mcap"))
    assert again.returncode == 0, again.stderr
    assert "exact: the recomputed outputs equal the recorded ones" in again.stdout


def test_receding_method_refuses_options_of_the_three_stages(tmp_path):
    done = _run("coordinate", *_inputs(tmp_path), "--method", "receding", "--smoothness", "10",
                "--out", str(tmp_path / "out"))
    assert done.returncode == 2
    assert done.stderr.strip().splitlines()[-1].endswith(
        "--smoothness does not act on the receding-horizon method (--method receding: 2 "
        "muscles x 37 target frames); leave it out, or use --method trajectory")


def test_receding_method_writes_the_same_outputs_and_recomputes_exactly(tmp_path):
    """--method receding: the run starts receding.lead_in (0.3 s) before the motion, its drives
    at every model step; the run log's forces and energy are reproduced by recompute."""
    out = tmp_path / "out"
    done = _run("coordinate", *_inputs(tmp_path), "--method", "receding", "--out", str(out))
    assert done.returncode == 0, done.stderr
    assert "method: receding" in done.stdout and "reserve RMS" in done.stdout
    drives = load_excitations(out / "drives.sto", ("a", "b"))
    assert drives.time_s[0] == pytest.approx(-0.3)
    metadata = read_run(out / "coordination.mcap").metadata   # the run log names its method
    assert any(entries.get("coordination_method") == "receding (--method receding)"
               for entries in metadata.values()), metadata
    assert np.diff(drives.time_s) == pytest.approx(np.full(len(drives.time_s) - 1, 0.001))
    again = _run("recompute", str(out / "coordination.mcap"), "--out",
                 str(tmp_path / "again.mcap"))
    assert again.returncode == 0, again.stderr
    assert "exact: the recomputed outputs equal the recorded ones" in again.stdout


def test_bad_inputs_are_one_line_errors(tmp_path):
    inputs = _inputs(tmp_path)
    for extra, words in ((["--muscle-weight", "a:2"], "MUSCLE=WEIGHT"),
                         (["--muscle-weight", "zz=2"], "zz"),
                         (["--speed", "-1"], "--speed"),
                         (["--dt", "0"], "--dt must be > 0"),
                         (["--targets-lowpass", "-6"], "--targets-lowpass"),
                         (["--targets-lowpass", "40"], "Nyquist")):
        done = _run("coordinate", *inputs, *extra, "--out", str(tmp_path / "x"))
        assert done.returncode == 2, (extra, done.stderr)
        lines = done.stderr.strip().splitlines()
        assert len(lines) == 1 and words in lines[0], (extra, done.stderr)


# Motion mistakes as cases (issue 27): (motion amplitude, its header's inDegrees, options) ->
# exit code and the one line on stderr ({motion}: the motion file). Each is found before the
# solve: nothing is written.
MOTION_CASES = {
    "degrees in a file that says radians": (
        (30.0, "no", []), 2,
        "vm-ros coordinate: error: motion {motion}: the header says inDegrees=no but q reaches "
        "30, beyond a full turn in radians: the file is in degrees; set inDegrees=yes"),
    "radians in a file that says degrees, --strict": (
        (0.05, "yes", ["--strict"]), 2,
        "vm-ros coordinate: error: motion {motion}: the header says inDegrees=yes but every "
        "rotational column stays within +-0.05 deg; if the file is in radians, set "
        "inDegrees=no (an error with --strict)"),
    "frames outside the geometry's box (+-0.6 rad), --strict": (
        (0.7, "no", ["--strict"]), 2,
        "vm-ros coordinate: error: motion {motion}: q outside the geometry's range -0.6 to 0.6 "
        "rad in 13 of 37 frames (at worst 0.7 rad): clamped to it (an error with --strict)"),
}


@pytest.mark.parametrize("case", MOTION_CASES)
def test_motion_mistakes_are_one_line_errors_before_the_solve(case, tmp_path):
    (amplitude, in_degrees, options), code, line = MOTION_CASES[case]
    out = tmp_path / "out"
    done = _run("coordinate", *_inputs(tmp_path, amplitude, in_degrees), *options,
                "--iterations", "2", "--out", str(out))
    assert done.returncode == code, done.stderr
    assert done.stderr.strip().splitlines() == [line.format(motion=tmp_path / "motion.mot")]
    assert done.stdout == "" and not out.exists(), "found before the solve: nothing written"


def test_motion_warning_is_repeated_after_the_summary(tmp_path):
    """Radians in a file that says degrees, without --strict: the solve runs (exit 0), the
    warning is printed once when found and is the last thing the summary says."""
    out = tmp_path / "out"
    done = _run("coordinate", *_inputs(tmp_path, 0.05, "yes"), "--iterations", "2", "--out",
                str(out))
    assert done.returncode == 0, done.stderr
    text = (f"motion {tmp_path / 'motion.mot'}: the header says inDegrees=yes but every "
            "rotational column stays within +-0.05 deg; if the file is in radians, set "
            "inDegrees=no")
    assert done.stderr.count(text) == 1
    assert done.stdout.strip().splitlines()[-2:] == [
        "1 input warning(s), the numbers above depend on them (--strict makes them errors):",
        f"  {text}"]
    assert (out / "drives.sto").is_file()
