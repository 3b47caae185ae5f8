"""`vm-ros simulate --motion`: an OpenSim motion through a joint-space geometry into a run log with
joint_states, joint_efforts and joint_effort_commands; torques against tau = r^T F computed here;
motion units from the header; excitations from an OpenSim storage file; bad inputs are one line.

The geometry and the motion are built here (no third-party model files): hip and knee (rad),
vasti and rectus femoris from the shipped library with polynomial paths inside their valid path
ranges over the box.
"""

from __future__ import annotations

import contextlib
import io
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from vm_ros.cli import main
from vm_ros.geometry import (
    Coordinate,
    CoupledCoordinate,
    MusclePath,
    PolynomialGeometry,
    generalized_forces,
    load_geometry,
    write_geometry,
)
from vm_ros.recording.run_log import read_run

VM_ROS = str(Path(sys.executable).with_name("vm-ros"))
MS = 1_000_000
BOX = {"hip_flexion": (-0.5, 1.5), "knee_angle": (0.0, 2.0)}


def make_geometry() -> PolynomialGeometry:
    """vasti        L = 0.29 + 0.022 knee + 0.001 knee^2            (0.290-0.338 m over the box)
    rectus_femoris  L = 0.52 - 0.01 hip + 0.01 knee + 0.002 hip knee (0.505-0.543 m)
    Library valid ranges: vasti 0.286-0.338 m, rectus femoris 0.497-0.544 m."""
    coordinates = [Coordinate(name, "rad", *box) for name, box in BOX.items()]
    muscles = [
        MusclePath("vasti", ("knee_angle",), (0.0,), (1.0,), [[0], [1], [2]],
                   [0.29, 0.022, 0.001]),
        MusclePath("rectus_femoris", ("hip_flexion", "knee_angle"), (0.0, 0.0), (1.0, 1.0),
                   [[0, 0], [1, 0], [0, 1], [1, 1]], [0.52, -0.01, 0.01, 0.002]),
    ]
    return PolynomialGeometry(coordinates, muscles, backend="numpy")


def write_geometry_file(directory: Path) -> Path:
    return write_geometry(make_geometry(), directory / "leg.yaml")


def write_motion(path: Path, time, columns: dict, in_degrees: bool = True) -> Path:
    """An OpenSim .mot: header, labels, one row per frame (tab-separated)."""
    names = list(columns)
    lines = ["leg motion", "version=1", f"nRows={len(time)}", f"nColumns={len(names) + 1}",
             f"inDegrees={'yes' if in_degrees else 'no'}", "endheader",
             "\t".join(["time", *names])]
    lines += ["\t".join(repr(float(v)) for v in (t, *(columns[n][i] for n in names)))
              for i, t in enumerate(time)]
    path.write_text("\n".join(lines) + "\n")
    return path


def leg_motion(path: Path) -> Path:
    """0.2 s: hip 0 -> 30 -> 0 deg, knee -5 -> 55 deg (below the box for the first 25 ms),
    plus a column the geometry does not have."""
    t = np.linspace(0.0, 0.2, 9)
    return write_motion(path, t, {"hip_flexion": 30.0 * np.sin(np.pi * t / 0.2),
                                  "knee_angle": -5.0 + 300.0 * t, "pelvis_tx": 0.1 + 0 * t})


def simulate_leg(directory: Path, *options) -> tuple[Path, str]:
    """`vm-ros simulate --motion` of leg_motion through the leg geometry in ``directory``:
    (log, printed summary)."""
    out = directory / "leg.mcap"
    printed = _run(["simulate", "--motion", str(leg_motion(directory / "leg.mot")),
                    "--geometry", str(write_geometry_file(directory)), *options, "--out",
                    str(out)])
    return out, printed


@pytest.fixture(scope="module")
def leg_run(tmp_path_factory):
    """(geometry file, motion file, log, printed summary) of a 0.2 s run at drive 0.2."""
    directory = tmp_path_factory.mktemp("leg")
    out, printed = simulate_leg(directory, "--excitation", "0.2", "--telemetry-rate", "50")
    return directory / "leg.yaml", directory / "leg.mot", out, printed


def _run(args) -> str:
    """Run a vm-ros verb in this process; its stdout."""
    buffer = io.StringIO()
    with contextlib.redirect_stdout(buffer):
        assert main(args) == 0
    return buffer.getvalue()


def test_motion_run_logs_the_joint_channels_and_the_geometry(leg_run):
    geometry, motion, out, printed = leg_run
    run = read_run(out)
    assert run.complete
    for topic in ("/joint_states", "/joint_efforts", "/joint_effort_commands", "/excitation",
                  "/muscle_force"):
        assert topic in run.topic_types
    assert "/muscle_kinematics" not in run.series  # every muscle is joint-driven
    assert run.attachments["geometry.yaml"] == geometry.read_bytes()
    config = run.info.config
    assert config.muscles == ("vasti", "rectus_femoris")  # the geometry's, in the library
    assert config.joints == ("hip_flexion", "knee_angle") and config.geometry == geometry
    assert run.info.extra["motion_file"] == str(motion)
    states = run.get("joint_states")
    assert states.names == ("hip_flexion", "knee_angle")  # pelvis_tx: not a coordinate
    model_ns = run.model_time_ns(states.time_ns)  # log time - start_time_ns
    np.testing.assert_array_equal(model_ns, np.arange(200) * MS)  # input rate 1 kHz
    t = model_ns * 1e-9
    knee = np.interp(t, np.linspace(0, 0.2, 9), -5.0 + 300.0 * np.linspace(0, 0.2, 9))
    np.testing.assert_allclose(states.fields["position"][:, 1], np.radians(knee), atol=1e-12)
    np.testing.assert_allclose(states.fields["velocity"][:, 1], np.radians(300.0), rtol=1e-9)
    efforts, commands = run.get("joint_efforts"), run.get("joint_effort_commands")
    np.testing.assert_array_equal(run.model_time_ns(efforts.time_ns),
                                  np.arange(21) * 10 * MS)  # start + 100 Hz
    np.testing.assert_array_equal(efforts.fields["stamp_ns"], efforts.time_ns)  # stamp = log
    np.testing.assert_array_equal(commands.fields["data"], efforts.fields["effort"])
    np.testing.assert_array_equal(run.get("excitation").fields["position"], 0.2)


def test_torques_equal_r_transpose_f_at_the_logged_positions(leg_run):
    """tau = r^T F with r = -dL/dq evaluated here at the logged joint positions and F the logged
    tendon forces at the same stamp; the positions are the joint_states of the step that ends at
    the stamp, clamped into the box."""
    geometry_file, _, out, _ = leg_run
    geometry = load_geometry(geometry_file, backend="numpy")
    run = read_run(out)
    efforts, force, states = run.get("joint_efforts"), run.get("muscle_force"), \
        run.get("joint_states")
    np.testing.assert_array_equal(efforts.fields["stamp_ns"], force.fields["stamp_ns"])
    rows = [geometry.muscle_names.index(m) for m in force.names]
    for k, stamp in enumerate(efforts.fields["stamp_ns"]):
        q = efforts.fields["position"][k]
        start = run.info.timing.start_time_ns
        used_at = max(int(stamp) - MS, start)  # the step [stamp - dt, stamp); the start itself
        received = states.fields["position"][np.searchsorted(states.time_ns, used_at)]
        np.testing.assert_array_equal(q, np.clip(received, geometry.lower, geometry.upper))
        _, gradient = geometry.lengths_and_gradients(q)
        tau = generalized_forces(-gradient[rows], force.fields["effort"][k])
        np.testing.assert_allclose(efforts.fields["effort"][k], tau, rtol=1e-9, atol=1e-12)
    assert np.max(np.abs(efforts.fields["effort"][:, 1])) > 1.0  # the knee carries torque


def test_summary_has_torque_work_and_clamping_per_coordinate(leg_run):
    _, _, out, printed = leg_run
    run = read_run(out)
    effort = run.get("joint_efforts").fields["effort"]
    knee_line = next(line for line in printed.splitlines() if line.startswith("knee_angle"))
    peak = effort[np.argmax(np.abs(effort[:, 1])), 1]
    assert f"{peak:.3f}" in knee_line and f"{effort[:, 1].mean():.3f}" in knee_line
    below = int(np.sum(run.get("joint_states").fields["position"][:, 1] < 0.0))
    assert below == 17  # knee < 0 until 16.7 ms
    assert knee_line.split()[-1] == str(below)
    hip_line = next(line for line in printed.splitlines() if line.startswith("hip_flexion"))
    assert hip_line.split()[-1] == "0"
    assert "joint_clamped 17" in printed


def test_degrees_and_radians_headers_give_the_same_radians(tmp_path):
    geometry = write_geometry_file(tmp_path)
    t = np.array([0.0, 0.1])
    positions = {}
    for in_degrees, value in ((True, 30.0), (False, np.pi / 6)):
        motion = write_motion(tmp_path / f"{in_degrees}.mot", t, {
            "hip_flexion": [value, value], "knee_angle": [value, value]}, in_degrees)
        out = tmp_path / f"{in_degrees}.mcap"
        _run(["simulate", "--motion", str(motion), "--geometry", str(geometry), "--duration",
              "0.01", "--telemetry-rate", "0", "--out", str(out)])
        positions[in_degrees] = read_run(out).get("joint_states").fields["position"]
    for values in positions.values():
        np.testing.assert_allclose(values, 0.5235987755982988, rtol=1e-15)
    assert round(float(positions[True][0, 0]), 4) == 0.5236


def test_excitations_from_an_opensim_storage_file(tmp_path):
    """Columns as OpenSim writes controls: /forceset/NAME (Moco), NAME|excitation (reporter
    outputs); a reserve actuator's column is ignored and named."""
    geometry = write_geometry_file(tmp_path)
    motion = write_motion(tmp_path / "still.mot", [0.0, 0.1], {"hip_flexion": [10.0, 10.0],
                                                                "knee_angle": [20.0, 20.0]})
    controls = tmp_path / "controls.sto"
    controls.write_text("controls\nversion=1\nnRows=2\nnColumns=4\ninDegrees=no\nendheader\n"
                        "time\t/forceset/vasti\trectus_femoris|excitation\tknee_reserve\n"
                        "0.0\t0.0\t0.5\t1.0\n0.1\t1.0\t0.5\t1.0\n")
    out = tmp_path / "controls.mcap"
    printed = _run(["simulate", "--motion", str(motion), "--geometry", str(geometry),
                    "--excitations", str(controls), "--duration", "0.1", "--telemetry-rate",
                    "0", "--out", str(out)])
    run = read_run(out)
    excitation = run.get("excitation")
    t = run.model_time_ns(excitation.time_ns) * 1e-9
    np.testing.assert_allclose(excitation.fields["position"][:, 0], t / 0.1, atol=1e-12)
    np.testing.assert_array_equal(excitation.fields["position"][:, 1], 0.5)
    assert "columns not used: knee_reserve" in printed


def _error_of(args) -> str:
    proc = subprocess.run([VM_ROS, "simulate", *args], capture_output=True, text=True,
                          timeout=60)
    assert proc.returncode == 2, proc.stderr
    assert "Traceback" not in proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    return lines[0]


def test_bad_inputs_are_one_line_and_exit_2(tmp_path):
    geometry = write_geometry_file(tmp_path)
    motion = leg_motion(tmp_path / "leg.mot")
    no_knee = write_motion(tmp_path / "hip.mot", [0.0, 0.1], {"hip_flexion": [0.0, 10.0]})
    excitations = tmp_path / "u.csv"
    excitations.write_text("time_s,vasti,rectus_femoris,vastus_intermedius\n0,0.1,0.1,0.1\n")
    out = str(tmp_path / "x.mcap")
    cases = [
        (["--motion", str(no_knee), "--geometry", str(geometry)],
         "no column for coordinate(s) knee_angle"),
        (["--motion", str(motion), "--geometry", str(geometry), "--hold", "ankle_angle=0"],
         "ankle_angle: not a coordinate of the geometry"),
        (["--motion", str(motion), "--geometry", str(geometry), "--joint-map",
          "{knee: ankle_angle}"], "unknown coordinate 'ankle_angle'"),
        (["--motion", str(motion)], "--motion needs --geometry"),
        (["--motion", str(motion), "--geometry", str(geometry), "--excitations",
          str(excitations)], "'vastus_intermedius' is not a muscle of the run"),
    ]
    for args, expected in cases:
        line = _error_of([*args, "--out", out])
        assert line.startswith("vm-ros simulate: error:") and expected in line, line
    assert not Path(out).exists()


def test_more_mistakes_are_one_line_and_exit_2(tmp_path):
    """Mistakes a first user makes with files and options: each one line naming the fix, exit 2,
    no log written (a usage error too: argparse's usage is not printed first)."""
    geometry = write_geometry_file(tmp_path)
    motion = leg_motion(tmp_path / "leg.mot")
    one_frame = write_motion(tmp_path / "one.mot", [0.0], {"hip_flexion": [0.0],
                                                           "knee_angle": [10.0]})
    backwards = write_motion(tmp_path / "back.mot", [0.0, 0.2, 0.1],
                             {"hip_flexion": [0, 1, 2], "knee_angle": [10, 20, 30]})
    not_storage = tmp_path / "walk.csv"
    not_storage.write_text("time,hip_flexion,knee_angle\n0,0,10\n0.1,1,20\n")
    header = "controls\nversion=1\ninDegrees=no\nendheader\ntime\tvasti\trectus_femoris\n"
    nan_drive = tmp_path / "nan.sto"
    nan_drive.write_text(header + "0\tnan\t0.1\n0.2\t0.2\t0.1\n")
    text_drive = tmp_path / "text.sto"
    text_drive.write_text(header + "0\tabc\t0.1\n0.2\t0.2\t0.1\n")
    with_geometry = ["--geometry", str(geometry)]
    cases = [
        (["--motion", str(tmp_path / "missing.mot"), *with_geometry], "cannot read"),
        (["--motion", str(motion), "--geometry", str(motion)], "not a vm_ros geometry file"),
        (["--motion", str(motion), "--geometry", str(tmp_path / "missing.yaml")],
         "missing.yaml: cannot read the geometry file"),  # no "field '-' = None"
        (["--motion", str(not_storage), *with_geometry], "not an OpenSim .mot/.sto file"),
        (["--motion", str(backwards), *with_geometry], "times must increase strictly"),
        (["--motion", str(one_frame), *with_geometry], "a single time: give --duration S"),
        (["--motion", str(motion), *with_geometry, "--excitations", str(nan_drive)],
         "non-finite values"),
        (["--motion", str(motion), *with_geometry, "--excitations", str(text_drive)],
         "a data row is not numbers"),
        (["--motion", str(motion), *with_geometry, "--hold", "knee_angle=10deg", "--hold",
          "knee_angle=20deg"], "--hold knee_angle: given twice"),
        (["--motion", str(motion), *with_geometry, "--excitation", "nan"],
         "--excitation must be a finite number"),
        (["--motion", str(motion), *with_geometry, "--duration", "-1"],
         "--duration must be > 0"),
        (["--motion", str(motion), *with_geometry, "--excitation", "high"],
         "argument --excitation: invalid float value: 'high' (usage: vm-ros simulate --help)"),
    ]
    out = tmp_path / "x.mcap"
    for args, expected in cases:
        line = _error_of([*args, "--out", str(out)])
        assert line.startswith("vm-ros simulate: error:") and expected in line, (args, line)
    assert not out.exists()


def test_an_option_is_taken_only_by_its_whole_name(tmp_path):
    """argparse's prefix matching took ``--durat`` for ``--duration`` (and a misspelt
    ``--body-mas`` for ``--body-mass``): now an unrecognised argument, one line, exit 2."""
    out = tmp_path / "x.mcap"
    proc = subprocess.run([VM_ROS, "simulate", "--scenario", "knee_extension", "--durat", "1",
                           "--out", str(out)], capture_output=True, text=True, timeout=60)
    lines = proc.stderr.strip().splitlines()
    assert proc.returncode == 2 and len(lines) == 1, proc.stderr
    assert "unrecognized arguments: --durat 1" in lines[0]
    assert not out.exists()


def _controls(path: Path, times, vasti, rectus=None) -> Path:
    """An OpenSim controls file (CMC's form: NAME columns) for the leg's two muscles."""
    rectus = vasti if rectus is None else rectus
    rows = "".join(f"{t!r}\t{u!r}\t{r!r}\n" for t, u, r in zip(times, vasti, rectus, strict=True))
    path.write_text("controls\nversion=1\ninDegrees=no\nendheader\n"
                    f"time\tvasti\trectus_femoris\n{rows}")
    return path


def _simulate(args) -> subprocess.CompletedProcess:
    return subprocess.run([VM_ROS, "simulate", *args], capture_output=True, text=True,
                          timeout=120)


def test_excitations_that_miss_the_motion_are_an_error_and_a_partial_cover_warns(tmp_path):
    """A controls file on another time axis than the motion (0.5-0.7 s against 0-0.2 s) used to
    be held at its first row for the whole run; now it is an error, and so is the reverse
    (controls from 0 s, a motion from 0.5 s). One that covers the run in
    part (from 0.1 s) is used on the motion's axis, with a warning printed when found and again
    after the summary; --strict makes that warning an error."""
    geometry = write_geometry_file(tmp_path)
    t = np.linspace(0.0, 0.2, 9)
    motion = write_motion(tmp_path / "in_box.mot", t, {"hip_flexion": 30.0 * np.sin(
        np.pi * t / 0.2), "knee_angle": 5.0 + 300.0 * t})
    common = ["--motion", str(motion), "--geometry", str(geometry), "--telemetry-rate", "0"]
    late = _controls(tmp_path / "late.sto", [0.5, 0.7], [0.2, 0.8])
    line = _error_of([*common, "--excitations", str(late), "--out", str(tmp_path / "a.mcap")])
    assert "cover 0.5-0.7 s, the run 0-0.2 s: no overlap" in line, line
    # the reverse: controls from 0 s against a motion from 0.5 s
    t_late = 0.5 + t
    late_motion = write_motion(tmp_path / "late.mot", t_late, {"hip_flexion": 30.0 * np.sin(
        np.pi * t / 0.2), "knee_angle": 5.0 + 300.0 * t})
    early = _controls(tmp_path / "early.sto", [0.0, 0.2], [0.2, 0.8])
    line = _error_of(["--motion", str(late_motion), "--geometry", str(geometry), "--excitations",
                      str(early), "--out", str(tmp_path / "b.mcap")])
    assert "cover 0-0.2 s, the run 0.5-0.7 s: no overlap" in line, line

    part = _controls(tmp_path / "part.sto", [0.1, 0.3], [0.2, 0.6])
    out = tmp_path / "part.mcap"
    proc = _simulate([*common, "--excitations", str(part), "--out", str(out)])
    assert proc.returncode == 0, proc.stderr
    warning = "the drives hold their first row for the 0.1 s before 0.1 s"
    assert f"vm-ros simulate: warning: excitations {part} cover 0.1-0.3 s" in proc.stderr
    assert warning in proc.stderr
    tail = proc.stdout.strip().splitlines()
    assert tail[-2].startswith("1 input warning(s)") and warning in tail[-1], proc.stdout
    logged = read_run(out).get("excitation")
    t = read_run(out).model_time_ns(logged.time_ns) * 1e-9
    expected = np.interp(t, [0.1, 0.3], [0.2, 0.6])  # held at 0.2 before 0.1 s
    np.testing.assert_allclose(logged.fields["position"][:, 0], expected, atol=1e-12)

    strict = _error_of([*common, "--excitations", str(part), "--strict", "--out",
                        str(tmp_path / "s.mcap")])
    assert warning in strict and strict.endswith("(an error with --strict)"), strict
    assert not (tmp_path / "s.mcap").exists()


def test_out_of_box_frames_are_reported_in_the_motions_unit_with_both_ends(tmp_path):
    """leg_motion's knee starts at -5 deg, below the box [0, 2] rad = [0, 114.592] deg."""
    geometry = write_geometry_file(tmp_path)
    motion = leg_motion(tmp_path / "leg.mot")
    proc = _simulate(["--motion", str(motion), "--geometry", str(geometry), "--telemetry-rate",
                      "0", "--out", str(tmp_path / "x.mcap")])
    assert proc.returncode == 0, proc.stderr
    assert (f"motion {motion}: knee_angle outside the geometry's range 0 to "
            f"{np.degrees(2.0):.6g} deg in 1 of 9 frames (at worst -5 deg)") in proc.stderr
    assert "hip_flexion outside" not in proc.stderr
    strict = _simulate(["--motion", str(motion), "--geometry", str(geometry), "--strict",
                        "--out", str(tmp_path / "y.mcap")])
    assert strict.returncode == 2 and "knee_angle outside" in strict.stderr


def test_hold_takes_a_unit_and_a_value_inside_the_box(tmp_path):
    geometry = write_geometry_file(tmp_path)
    motion = write_motion(tmp_path / "hip.mot", [0.0, 0.1], {"hip_flexion": [0.0, 10.0]})
    common = ["--motion", str(motion), "--geometry", str(geometry), "--duration", "0.01",
              "--telemetry-rate", "0"]
    for hold, expected in (("knee_angle=30", "no unit is given: a unit of knee_angle (rad); "
                            "write it with one of rad, deg, e.g. knee_angle=30deg"),
                           ("knee_angle=0.3m", "'m' is not a unit of knee_angle"),
                           ("knee_angle=30rad", "outside the geometry's range of knee_angle, "
                            "0 to 2 rad"),
                           ("knee_angle=thirty", "expected COORDINATE=VALUE with a unit")):
        line = _error_of([*common, "--hold", hold, "--out", str(tmp_path / "x.mcap")])
        assert expected in line, line
    for hold, radians in (("knee_angle=30deg", np.radians(30.0)), ("knee_angle=0.5rad", 0.5)):
        out = tmp_path / f"{hold}.mcap"
        _run(["simulate", *common, "--hold", hold, "--out", str(out)])
        knee = read_run(out).get("joint_states").fields["position"][:, 1]
        np.testing.assert_allclose(knee, radians, rtol=1e-15)


def test_units_that_cannot_be_the_declared_ones_are_errors(tmp_path):
    """Degrees in a file that says radians; drives in percent, in a file, a CSV of inputs and
    --excitation."""
    geometry = write_geometry_file(tmp_path)
    t = np.linspace(0.0, 0.2, 9)
    degrees_as_radians = write_motion(tmp_path / "rad.mot", t, {
        "hip_flexion": 30.0 * np.sin(np.pi * t / 0.2), "knee_angle": 5.0 + 300.0 * t},
        in_degrees=False)
    motion = leg_motion(tmp_path / "leg.mot")
    common = ["--geometry", str(geometry), "--out", str(tmp_path / "x.mcap")]
    line = _error_of(["--motion", str(degrees_as_radians), *common])
    assert ("says inDegrees=no but knee_angle reaches 65, beyond a full turn in radians: the "
            "file is in degrees; set inDegrees=yes") in line, line
    percent = _controls(tmp_path / "pct.sto", [0.0, 0.2], [2.0, 50.0], [1.0, 1.0])
    line = _error_of(["--motion", str(motion), "--excitations", str(percent), *common])
    assert ("drive 50 for vasti at 0.2 s: drives are fractions in [0, 1]; if the values are "
            "percent, divide them by 100") in line, line
    line = _error_of(["--motion", str(motion), "--excitation", "50", *common])
    assert "--excitation: drive 50 for every muscle: drives are fractions in [0, 1]" in line
    line = _error_of(["--motion", str(motion), "--excitation", "-0.1", *common])
    assert "drive -0.1 for every muscle" in line and "percent" not in line
    inputs = tmp_path / "inputs.csv"
    inputs.write_text("time_s,vasti.excitation,vasti.path_length\n0,10,0.3\n1,20,0.3\n")
    line = _error_of(["--inputs", str(inputs), "--out", str(tmp_path / "x.mcap")])
    assert "drive 20 for vasti at 1 s" in line and "divide them by 100" in line, line


def test_a_degrees_file_with_radian_sized_angles_warns(tmp_path):
    geometry = write_geometry_file(tmp_path)
    t = np.linspace(0.0, 0.2, 9)
    motion = write_motion(tmp_path / "small.mot", t, {"hip_flexion": 0.5 * t,
                                                      "knee_angle": 0.2 + 5.0 * t})
    proc = _simulate(["--motion", str(motion), "--geometry", str(geometry), "--telemetry-rate",
                      "0", "--out", str(tmp_path / "x.mcap")])
    assert proc.returncode == 0, proc.stderr
    assert "says inDegrees=yes but every rotational column stays within +-1.2 deg" in proc.stderr


def test_velocities_from_the_motions_speed_columns_or_a_smoothing_spline(tmp_path):
    """A knee that starts at rest, 30 (1 - cos(2 pi t)) deg at 100 Hz: the logged velocity at
    t = 0 is the true 0 within 0.2 deg/s (numpy.gradient's one-sided difference gave 5.9 deg/s)
    and within 0.5 % of the peak elsewhere. A states file's speed columns are used as they are
    (here a speed unlike the positions' derivative, 0.25 rad/s)."""
    geometry = write_geometry_file(tmp_path)
    t = np.round(np.arange(0.0, 1.0 + 1e-9, 0.01), 10)
    knee = 30.0 * (1.0 - np.cos(2 * np.pi * t))
    motion = write_motion(tmp_path / "rest.mot", t, {"hip_flexion": 0 * t + 10.0,
                                                     "knee_angle": knee})
    out = tmp_path / "rest.mcap"
    _run(["simulate", "--motion", str(motion), "--geometry", str(geometry), "--input-rate",
          "100", "--telemetry-rate", "0", "--out", str(out)])
    velocity = np.degrees(read_run(out).get("joint_states").fields["velocity"][:, 1])
    true = 30.0 * 2 * np.pi * np.sin(2 * np.pi * t[:len(velocity)])
    assert abs(velocity[0]) < 0.2, velocity[:3]
    np.testing.assert_allclose(velocity, true, atol=0.005 * np.max(true))

    states = tmp_path / "states.sto"
    rows = "".join(f"{s!r}\t0.2\t0.25\t{0.5 + 0.1 * s!r}\t0.0\n" for s in (0.0, 0.05, 0.1))
    states.write_text("states\nversion=1\ninDegrees=no\nendheader\n"
                      "time\t/jointset/hip/hip_flexion/value\t/jointset/hip/hip_flexion/speed\t"
                      f"/jointset/knee/knee_angle/value\t/jointset/knee/knee_angle/speed\n{rows}")
    out = tmp_path / "states.mcap"
    _run(["simulate", "--motion", str(states), "--geometry", str(geometry), "--telemetry-rate",
          "0", "--out", str(out)])
    velocity = read_run(out).get("joint_states").fields["velocity"]
    np.testing.assert_array_equal(velocity[:, 0], 0.25)
    np.testing.assert_array_equal(velocity[:, 1], 0.0)


def test_a_column_for_a_dependent_coordinate_is_named_as_not_used(tmp_path):
    geometry = make_geometry()
    coupled = PolynomialGeometry(geometry.coordinates, geometry.muscles,
                                 [CoupledCoordinate("patella_angle", ("knee_angle",))],
                                 backend="numpy")
    geometry_file = write_geometry(coupled, tmp_path / "coupled.yaml")
    motion = write_motion(tmp_path / "m.mot", [0.0, 0.1], {
        "hip_flexion": [10.0, 10.0], "knee_angle": [20.0, 30.0], "patella_angle": [5.0, 6.0]})
    printed = _run(["simulate", "--motion", str(motion), "--geometry", str(geometry_file),
                    "--telemetry-rate", "0", "--out", str(tmp_path / "m.mcap")])
    assert (f"motion {motion}: column patella_angle is a dependent coordinate of the geometry "
            "(it follows knee_angle): not an input, its values are not used") in printed


def half_knee_geometry_file(directory: Path) -> Path:
    """The leg geometry with patella_angle = knee_angle / 2 (a table over the knee's box)."""
    geometry = make_geometry()
    knee = np.linspace(*BOX["knee_angle"], 201)
    coupled = PolynomialGeometry(geometry.coordinates, geometry.muscles, [CoupledCoordinate(
        "patella_angle", ("knee_angle",), "half the knee", "rad", tuple(knee),
        tuple(knee / 2))], backend="numpy")
    return write_geometry(coupled, directory / "coupled.yaml")


def test_a_dependent_column_that_disagrees_with_the_coupling_warns(tmp_path):
    """patella_angle = knee_angle / 2 (a table over the knee's box); a radians motion whose
    patella column is 0.05 rad off at t = 0.1 s: one input warning in rad, repeated after the
    summary; the column still is not an input (the run's joint_states hold the knee only)."""
    geometry_file = half_knee_geometry_file(tmp_path)
    t = np.linspace(0.0, 0.2, 5)
    knee_motion = 0.2 + 4.0 * t
    motion = write_motion(tmp_path / "m.mot", t, {
        "hip_flexion": 0 * t, "knee_angle": knee_motion,
        "patella_angle": knee_motion / 2 + np.where(t == 0.1, 0.05, 0.0)}, in_degrees=False)
    out = tmp_path / "m.mcap"
    proc = _simulate(["--motion", str(motion), "--geometry", str(geometry_file),
                      "--telemetry-rate", "0", "--out", str(out)])
    assert proc.returncode == 0, proc.stderr
    warning = (f"motion {motion}: column patella_angle disagrees with the geometry's coupling to "
               "knee_angle by up to 0.05 rad (more than 0.0174533 rad): at 0.1 s it has 0.35 "
               "rad, the coupling 0.3 rad; the column is not used, the paths follow the "
               "coupling")
    assert f"vm-ros simulate: warning: {warning}" in proc.stderr
    tail = proc.stdout.strip().splitlines()
    assert tail[-2].startswith("1 input warning(s)") and warning in tail[-1], proc.stdout
    assert "is a dependent coordinate" not in proc.stdout
    assert read_run(out).get("joint_states").names == ("hip_flexion", "knee_angle")


def _in_box_motion(path: Path, in_degrees: bool = True, scale: float = 1.0) -> Path:
    """0.2 s of hip 0 -> 30 -> 0 deg and knee 5 -> 65 deg (inside the box) at 9 frames;
    ``scale`` multiplies the angles."""
    t = np.linspace(0.0, 0.2, 9)
    return write_motion(path, t, {"hip_flexion": scale * 30.0 * np.sin(np.pi * t / 0.2),
                                  "knee_angle": scale * (5.0 + 300.0 * t)}, in_degrees)


def _coupled_motion(directory: Path) -> list[str]:
    """patella_angle = knee_angle / 2 in the geometry; the motion's column 3 deg off at 0.1 s."""
    geometry_file = half_knee_geometry_file(directory)
    t = np.linspace(0.0, 0.2, 5)
    knee_deg = 10.0 + 200.0 * t
    motion = write_motion(directory / "coupled.mot", t, {
        "hip_flexion": 0 * t, "knee_angle": knee_deg,
        "patella_angle": knee_deg / 2 + np.where(t == 0.1, 3.0, 0.0)})
    return ["--motion", str(motion), "--geometry", str(geometry_file)]


def _input_table(directory: Path) -> list[str]:
    """A CSV of inputs over 0-0.2 s, run for 0.3 s."""
    inputs = directory / "inputs.csv"
    inputs.write_text("time_s,vasti.excitation,vasti.path_length\n0,0.1,0.3\n0.2,0.2,0.31\n")
    return ["--inputs", str(inputs), "--duration", "0.3"]


# every kind of input warning (vm_ros.cli.runs.InputWarnings: simulate's source.check), each
# alone: (the run's options from a folder, what its one warning must say)
WARNING_CASES = {
    "motion frames outside the box": (
        lambda d: ["--motion", str(leg_motion(d / "leg.mot")), "--geometry",
                   str(write_geometry_file(d))],
        f"knee_angle outside the geometry's range 0 to {np.degrees(2.0):.6g} deg in 1 of 9 "
        "frames (at worst -5 deg): clamped to it"),
    "degrees header, radian-sized angles": (
        lambda d: ["--motion", str(_in_box_motion(d / "small.mot", scale=0.018)), "--geometry",
                   str(write_geometry_file(d))],
        "the header says inDegrees=yes but every rotational column stays within +-1.17 deg; if "
        "the file is in radians, set inDegrees=no"),
    "a run longer than its motion": (
        lambda d: ["--motion", str(_in_box_motion(d / "m.mot")), "--geometry",
                   str(write_geometry_file(d)), "--duration", "0.3"],
        "span 0.2 s, the run 0.3 s: their last row is held for the last 0.1 s"),
    "a run longer than its input table": (
        _input_table, "span 0.2 s, the run 0.3 s: their last row is held for the last 0.1 s"),
    "a dependent column off its coupling": (
        _coupled_motion,
        "column patella_angle disagrees with the geometry's coupling to knee_angle by up to 3 "
        "deg (more than 1 deg): at 0.1 s it has 18 deg, the coupling 15 deg"),
    "excitations over part of the run": (
        lambda d: ["--motion", str(_in_box_motion(d / "m.mot")), "--geometry",
                   str(write_geometry_file(d)), "--excitations",
                   str(_controls(d / "part.sto", [0.1, 0.3], [0.2, 0.6]))],
        "cover 0.1-0.3 s, the run 0-0.2 s: the drives hold their first row for the 0.1 s before "
        "0.1 s"),
}


@pytest.mark.parametrize("kind", WARNING_CASES)
def test_each_input_warning_is_repeated_at_the_end_and_an_error_with_strict(kind, tmp_path,
                                                                            capsys):
    """Without --strict: exit 0, the warning printed when found (stderr) and repeated as the
    summary's last line under '1 input warning(s)'; with --strict: exit 2, that warning as the
    one line on stderr, no log."""
    make_args, expected = WARNING_CASES[kind]
    args = ["simulate", *make_args(tmp_path), "--telemetry-rate", "0"]
    strict_out = tmp_path / "strict.mcap"
    assert main([*args, "--strict", "--out", str(strict_out)]) == 2
    printed = capsys.readouterr()
    lines = printed.err.strip().splitlines()
    assert len(lines) == 1 and expected in lines[0], printed.err
    prefix, suffix = "vm-ros simulate: error: ", " (an error with --strict)"
    assert lines[0].startswith(prefix) and lines[0].endswith(suffix), lines[0]
    warning = lines[0].removeprefix(prefix).removesuffix(suffix)
    assert not strict_out.exists()

    assert main([*args, "--out", str(tmp_path / "run.mcap")]) == 0
    printed = capsys.readouterr()
    assert f"vm-ros simulate: warning: {warning}\n" in printed.err, printed.err
    tail = printed.out.strip().splitlines()
    assert tail[-2] == ("1 input warning(s), the numbers above depend on them (--strict makes "
                        "them errors):"), printed.out
    assert tail[-1] == f"  {warning}", printed.out
