"""vm-ros import-osim against OpenSim's own path lengths (test/osim_models.py builds the models).

Reference values come from OpenSim at fresh random poses, with the constraints satisfied by
OpenSim itself (Coordinate.setValue with enforceConstraints), never from the importer's output.
That r of the evaluated polynomial equals -dL/dq of the same polynomial (to 1e-9 m) is checked by
the core tests (test/test_geometry.py) and not repeated here.
"""

from __future__ import annotations

import io
import math
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from vm_ros.importers.motion import read_motion

VM_ROS = str(Path(sys.executable).with_name("vm-ros"))
SMOOTH_KNEE = ("vas_pat", "ext_wrap", "flex")
HIP_KNEE = ("rf", "vas", "ham", "ilio")
STEP = 1e-5


@pytest.fixture(scope="module")
def models(osim, tmp_path_factory):
    import osim_models

    folder = tmp_path_factory.mktemp("osim_models")
    return {"knee": osim_models.build_knee(folder / "knee.osim"),
            "hip_knee": osim_models.build_hip_knee(folder / "hip_knee.osim")}


@pytest.fixture(scope="module")
def imported(models, tmp_path_factory):
    from vm_ros.importers.osim import OsimOptions, import_osim

    out = {}
    for name, path in models.items():
        folder = tmp_path_factory.mktemp(f"import_{name}")
        out[name] = import_osim(path, folder, OsimOptions(samples=300, seed=1),
                                progress=False, file=io.StringIO())
    return out


def opensim_reference(osim, model_path, poses: dict, muscles):
    """OpenSim's own L and -dL/dq (central differences, constraints assembled by OpenSim)."""
    import osim_models

    model = osim.Model(str(model_path))
    state = model.initSystem()
    names = list(poses)
    q = np.column_stack([poses[n] for n in names])
    length = np.empty((len(q), len(muscles)))
    arm = np.empty((len(q), len(muscles), len(names)))

    def at(values):
        osim_models.set_pose(model, state, dict(zip(names, values, strict=True)))
        return np.array(osim_models.lengths(model, state, muscles))

    for k, values in enumerate(q):
        length[k] = at(values)
        for j in range(len(names)):
            up, down = values.copy(), values.copy()
            up[j] += STEP
            down[j] -= STEP
            arm[k, :, j] = -(at(up) - at(down)) / (2 * STEP)
    return q, length, arm


def check_against_opensim(osim, model_path, geometry, muscles, n=60, seed=123):
    rng = np.random.default_rng(seed)
    poses = {c.name: rng.uniform(c.lower, c.upper, n) for c in geometry.coordinates}
    q, length, arm = opensim_reference(osim, model_path, poses, muscles)
    rows = [geometry.muscle_names.index(m) for m in muscles]
    for k, values in enumerate(q):
        ours, gradient = geometry.lengths_and_gradients(values)
        length[k] -= ours[rows]
        arm[k] -= -gradient[rows]
    length_rms = np.sqrt(np.mean(length ** 2, axis=0))
    arm_rms = np.sqrt(np.mean(arm ** 2, axis=(0, 2)))
    return dict(zip(muscles, length_rms, strict=True)), dict(zip(muscles, arm_rms, strict=True))


@pytest.mark.parametrize("model, muscles", [("knee", SMOOTH_KNEE), ("hip_knee", HIP_KNEE)])
def test_paths_match_opensim(osim, models, imported, model, muscles):
    """Held-out poses: length RMS <= 0.1 mm, moment-arm RMS <= 1 mm against OpenSim (the knee
    through its wrapping surface and the patella coupler)."""
    geometry = imported[model].geometry
    length_rms, arm_rms = check_against_opensim(osim, models[model], geometry, muscles)
    for name in muscles:
        assert length_rms[name] <= 1e-4, (name, length_rms[name])
        assert arm_rms[name] <= 1e-3, (name, arm_rms[name])
        assert not geometry.muscles[geometry.muscle_names.index(name)].fit.flags


def test_moment_arm_sign_is_opensims(osim, models, imported):
    """The written geometry's r (-dL/dq, the --help's convention) against OpenSim's own
    computeMomentArm, on paths without wrapping: same sign and value."""
    import osim_models

    geometry = imported["hip_knee"].geometry
    model = osim.Model(str(models["hip_knee"]))
    state = model.initSystem()
    hip = model.getCoordinateSet().get("hip_flexion")
    knee = model.getCoordinateSet().get("knee_angle")
    for q in ([0.3, -0.4], [1.2, -1.5], [-0.2, -0.1]):
        osim_models.set_pose(model, state, {"hip_flexion": q[0], "knee_angle": q[1]})
        arm = geometry.evaluate(np.array(q)).moment_arm
        for name in ("ilio", "ham"):
            muscle = model.getMuscles().get(name)
            row = geometry.muscle_names.index(name)
            theirs = [muscle.computeMomentArm(state, c) for c in (hip, knee)]
            np.testing.assert_allclose(arm[row], theirs, atol=1e-4, err_msg=name)
    assert arm[geometry.muscle_names.index("ilio"), 0] > 0.005  # a hip flexor: r > 0


def test_crossed_coordinates(imported):
    crossed = {m.name: m.coordinates for m in imported["hip_knee"].geometry.muscles}
    assert crossed == {"rf": ("hip_flexion", "knee_angle"), "vas": ("knee_angle",),
                       "ham": ("hip_flexion", "knee_angle"), "ilio": ("hip_flexion",)}


def test_coupled_coordinate_is_not_an_input(imported):
    geometry = imported["knee"].geometry
    assert geometry.coordinate_names == ("knee_angle",)
    (coupled,) = geometry.coupled
    assert coupled.name == "patella_angle" and coupled.follows == ("knee_angle",)
    assert "CoordinateCouplerConstraint" in coupled.note


def test_coupling_function_is_stored_over_the_drivers_box(imported):
    """patella_angle = 0.02 q^2 + 0.55 q (osim_models.PATELLA_COUPLING), at 201 points over
    the knee's box, read back from the written file."""
    from osim_models import PATELLA_COUPLING

    from vm_ros.geometry.file import load_geometry

    geometry = load_geometry(imported["knee"].written["geometry"])
    (coupled,) = geometry.coupled
    (knee,) = geometry.coordinates
    assert coupled.unit == "rad" and len(coupled.follows_values) == 201
    assert (coupled.follows_values[0], coupled.follows_values[-1]) == (knee.lower, knee.upper)
    q = np.array(coupled.follows_values)
    np.testing.assert_allclose(coupled.values, np.polyval(PATELLA_COUPLING, q), rtol=0,
                               atol=1e-12)
    between = (q[:-1] + q[1:]) / 2   # linear in between: within h^2/8 * 0.04 of the quadratic
    assert np.abs(coupled.value(between) - np.polyval(PATELLA_COUPLING, between)).max() \
        <= (q[1] - q[0]) ** 2 / 8 * 0.04 * 1.001


def test_simulate_checks_a_patella_column_against_the_coupling(imported, tmp_path):
    """A motion whose patella column is the coupler's function of its knee column: no warning,
    the note that the column is not an input; the same with the patella 2 deg off in one frame:
    the warning, and with --strict exit 2 with that one line."""
    from osim_models import PATELLA_COUPLING

    written = imported["knee"].written
    t = np.linspace(0.0, 0.2, 11)
    knee = np.linspace(-1.5, -0.2, 11)
    patella = np.degrees(np.polyval(PATELLA_COUPLING, knee))
    header = "knee\nversion=1\ninDegrees=yes\nendheader\ntime\tknee_angle\tpatella_angle\n"
    good, bad = tmp_path / "good.mot", tmp_path / "bad.mot"
    for path, column in ((good, patella), (bad, patella + np.where(np.arange(11) == 4, 2, 0))):
        rows = np.column_stack([t, np.degrees(knee), column])
        path.write_text(header + "".join("\t".join(repr(float(v)) for v in row) + "\n"
                                         for row in rows))
    common = ["simulate", "--geometry", str(written["geometry"]), "--library",
              str(written["library"]), "--muscles", "vas_pat,flex", "--telemetry-rate", "0"]
    ok = subprocess.run([VM_ROS, *common, "--motion", str(good), "--strict", "--out",
                         str(tmp_path / "good.mcap")], capture_output=True, text=True,
                        timeout=120)
    assert ok.returncode == 0 and "warning" not in ok.stderr, ok.stderr
    assert (f"motion {good}: column patella_angle is a dependent coordinate of the geometry (it "
            "follows knee_angle): not an input, its values are not used (it agrees with the "
            "coupling within 1 deg)") in ok.stdout
    strict = subprocess.run([VM_ROS, *common, "--motion", str(bad), "--strict", "--out",
                             str(tmp_path / "bad.mcap")], capture_output=True, text=True,
                            timeout=120)
    assert strict.returncode == 2 and len(strict.stderr.strip().splitlines()) == 1, strict.stderr
    found = re.search(f"motion {re.escape(str(bad))}: column patella_angle disagrees with the "
                      r"geometry's coupling to knee_angle by up to (\S+) deg \(more than 1 deg\): "
                      r"at 0.08 s it has (\S+) deg, the coupling (\S+) deg", strict.stderr)
    assert found, strict.stderr
    # the table is linear between its points: within 5.5e-7 rad (3.2e-5 deg) of the quadratic
    expected = (2.0, patella[4] + 2.0, patella[4])
    np.testing.assert_allclose([float(v) for v in found.groups()], expected, rtol=0, atol=1e-4)


def test_jumping_path_is_flagged(imported):
    geometry = imported["knee"].geometry
    fit = geometry.muscles[geometry.muscle_names.index("cond")].fit
    assert "discontinuous" in fit.flags


def test_library_loads_and_follows_the_rules(osim, models, imported):
    from vm_ros.model.bank import MuscleBank
    from vm_ros.model.params import load_model_params

    result = imported["hip_knee"]
    bank = MuscleBank.from_config(list(HIP_KNEE), library=result.written["library"],
                                  backend="numpy")
    g = load_model_params().generic
    model = osim.Model(str(models["hip_knee"]))
    model.initSystem()
    for i, name in enumerate(HIP_KNEE):
        muscle = model.getMuscles().get(name)
        f0, l0 = muscle.getMaxIsometricForce(), muscle.getOptimalFiberLength()
        assert bank.geometry.l0[i] == pytest.approx(l0, rel=1e-6)
        assert bank.geometry.l0t[i] == pytest.approx(muscle.getTendonSlackLength() / 0.964,
                                                     rel=1e-5)
        mass = f0 * g.muscle_density * l0 / 60e4          # default: 60 N/cm^2
        assert bank.geometry.mass[i] == pytest.approx(mass, rel=1e-5)
        assert bank.geometry.f0[i] == pytest.approx(f0 * 31.8 / 60.0, rel=1e-5)
        assert bank.geometry.lmax[i] >= 1.1 - 1e-6 and bank.geometry.lmax[i] <= 1.4 + 1e-6
    text = Path(result.written["library"]).read_text()
    assert "pennation dropped" in text and "specific tension 60 N/cm^2" in text


def test_geometry_file_round_trips_exactly(imported, tmp_path):
    from vm_ros.geometry.file import geometry_to_dict, load_geometry, write_geometry

    first = load_geometry(imported["knee"].written["geometry"])
    second = load_geometry(write_geometry(first, tmp_path / "again.yaml"))
    assert geometry_to_dict(first) == geometry_to_dict(second)
    for a, b in zip(first.muscles, second.muscles, strict=True):
        assert a.coefficients.tobytes() == b.coefficients.tobytes()
        assert np.array_equal(a.exponents, b.exponents)
    source = first.source
    assert source["model"] == "knee_wrap_patella" and len(source["sha256"]) == 64
    assert source["opensim_version"].startswith("4.6")


def test_motion_box_and_degrees(osim, models, tmp_path):
    from vm_ros.importers.osim import OsimOptions, import_osim

    motion = tmp_path / "walk.mot"
    knee_deg = np.linspace(-60.0, -10.0, 21)
    rows = "\n".join(f"{t:.3f}\t{h:.4f}\t{k:.4f}" for t, h, k in
                     zip(np.linspace(0, 1, 21), np.linspace(0.0, 30.0, 21), knee_deg, strict=True))
    motion.write_text("walk\nversion=1\nnRows=21\nnColumns=3\ninDegrees=yes\nendheader\n"
                      f"time\thip_flexion\tknee_angle\n{rows}\n")
    result = import_osim(models["hip_knee"], tmp_path / "out",
                         OsimOptions(samples=200, motions=(motion,), margin_deg=5.0),
                         progress=False, file=io.StringIO())
    box = {c.name: (c.lower, c.upper) for c in result.geometry.coordinates}
    assert box["knee_angle"] == pytest.approx((math.radians(-65.0), math.radians(-5.0)))
    assert box["hip_flexion"] == pytest.approx((math.radians(-5.0), math.radians(35.0)))


def test_cli_end_to_end(osim, models, tmp_path):
    out = tmp_path / "cli"
    done = subprocess.run([VM_ROS, "import-osim", str(models["knee"]), "--out", str(out),
                           "--samples", "150", "--specific-tension", "vm"],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert (out / "geometry.yaml").is_file() and (out / "muscles.yaml").is_file()
    assert "VM F0 = 1 x the model's F0" in done.stdout
    assert "cond" in done.stdout and "discontinuous" in done.stdout


def run_cli(argv, capsys) -> tuple[int, str, str]:
    """vm-ros in this process (the subprocess start-up costs about a second per call)."""
    from vm_ros.cli import main

    code = main(argv)
    captured = capsys.readouterr()
    return code, captured.out, captured.err


@pytest.mark.parametrize("content, suffix, expected", [
    (None, ".osim", "no such file"),
    ("hello", ".txt", "not an .osim file"),
    ("not xml at all", ".osim", "not valid XML"),
    ("<OpenSimDocument><Other/></OpenSimDocument>", ".osim", "no <OpenSimDocument><Model>"),
])
def test_cli_bad_model_is_one_line(osim, tmp_path, capsys, content, suffix, expected):
    path = tmp_path / f"model{suffix}"
    if content is not None:
        path.write_text(content)
    code, _, err = run_cli(["import-osim", str(path), "--out", str(tmp_path / "o")], capsys)
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1 and expected in lines[0]


def test_cli_model_opensim_rejects_is_one_line_without_traceback(osim, tmp_path):
    path = tmp_path / "model.osim"   # valid XML, but the joint's frames do not exist
    path.write_text('<OpenSimDocument Version="40000"><Model name="bad"><JointSet><objects>'
                    '<PinJoint name="j"><socket_parent_frame>/nowhere</socket_parent_frame>'
                    '<socket_child_frame>/bodyset/none</socket_child_frame></PinJoint>'
                    '</objects></JointSet></Model></OpenSimDocument>')
    done = subprocess.run([VM_ROS, "import-osim", str(path), "--out", str(tmp_path / "o")],
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 2, done.stderr
    assert len(done.stderr.strip().splitlines()) == 1 and "Traceback" not in done.stderr
    assert "OpenSim cannot load the model" in done.stderr


def test_cli_unknown_motion_coordinate_is_one_line(osim, models, tmp_path, capsys):
    motion = tmp_path / "bad.mot"
    motion.write_text("x\ninDegrees=no\nendheader\ntime\tknee_angle\tnot_a_coordinate\n"
                      "0\t-0.5\t0.1\n")
    code, _, err = run_cli(["import-osim", str(models["knee"]), "--out", str(tmp_path / "o"),
                            "--motion", str(motion)], capsys)
    assert code == 2 and len(err.strip().splitlines()) == 1
    assert "unknown coordinate 'not_a_coordinate'" in err


def test_cli_out_under_a_file_is_one_line(osim, models, tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("")
    code, _, err = run_cli(["import-osim", str(models["knee"]), "--out", str(blocker / "o"),
                            "--samples", "20"], capsys)
    assert code == 2 and len(err.strip().splitlines()) == 1 and "cannot make the folder" in err


def test_cli_without_opensim_says_how_to_install(tmp_path, capsys, monkeypatch):
    from vm_ros.importers import osim as importer

    def missing():
        raise importer.VmRosError(importer.NEEDS_OPENSIM)

    monkeypatch.setattr(importer, "load_opensim", missing)
    path = tmp_path / "m.osim"
    path.write_text("<OpenSimDocument><Model/></OpenSimDocument>")
    code, _, err = run_cli(["import-osim", str(path), "--out", str(tmp_path / "o")], capsys)
    assert code == 2
    assert err.strip() == ('vm-ros import-osim: error: needs the opensim extra: '
                           'pip install ".[opensim]"')


# ------------------------------------------------------------------ held coordinates


def held_variant(osim, build, path, locked=(), ranges=None, default=None):
    """A test model (osim_models ``build``) with the coordinates ``locked`` locked, ``ranges``
    ({name: (min, max)}) given those ranges; ``default`` (name, value)."""
    model = osim.Model(str(build(path.with_name(f"{path.stem}-base.osim"))))
    coordinates = model.updCoordinateSet()
    for name, value in [default] if default else []:
        coordinates.get(name).setDefaultValue(value)
    for name in locked:
        coordinates.get(name).setDefaultLocked(True)
    for name, (lower, upper) in (ranges or {}).items():
        coordinates.get(name).setRangeMin(lower)
        coordinates.get(name).setRangeMax(upper)
    model.finalizeConnections()
    model.initSystem()
    model.printToXML(str(path))
    return path


def test_cli_every_coordinate_locked_is_one_line(osim, tmp_path, capsys):
    import osim_models

    path = held_variant(osim, osim_models.build_hip_knee, tmp_path / "locked.osim",
                        locked=("hip_flexion", "knee_angle"))
    code, _, err = run_cli(["import-osim", str(path), "--out", str(tmp_path / "o")], capsys)
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert "every coordinate is held, none is left to sample" in err
    assert "hip_flexion: locked at 0 rad, unlock it (<locked>false</locked>)" in err
    assert "knee_angle: locked at 0 rad" in err


def test_cli_coupled_coordinate_of_a_locked_one_is_one_line(osim, tmp_path, capsys):
    """The knee model's patella follows the knee angle: with the knee locked nothing is free."""
    import osim_models

    path = held_variant(osim, osim_models.build_knee, tmp_path / "knee.osim",
                        locked=("knee_angle",))
    code, _, err = run_cli(["import-osim", str(path), "--out", str(tmp_path / "o")], capsys)
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert ("patella_angle: follows the held knee_angle through CoordinateCouplerConstraint "
            "patella_coupler") in err


def test_cli_reversed_range_is_one_line(osim, tmp_path, capsys):
    import osim_models

    path = held_variant(osim, osim_models.build_hip_knee, tmp_path / "reversed.osim",
                        ranges={"knee_angle": (0.1, -2.0)})
    code, _, err = run_cli(["import-osim", str(path), "--out", str(tmp_path / "o"),
                            "--samples", "40"], capsys)
    assert code == 2 and err.strip().splitlines() == [
        "vm-ros import-osim: error: coordinate knee_angle: its range in the model [0.1, -2] is "
        "not an interval to sample; give it <range>min max</range> with finite min < max"]


@pytest.mark.parametrize("held", ["locked", "zero_range"])
def test_held_knee_imports_the_hip_at_the_held_knee_angle(osim, tmp_path, held):
    """Knee locked at its default -0.7 rad, or given the range [-0.7, -0.7] (its default 0
    outside it): the hip muscles are fitted with the knee at -0.7 rad, checked against OpenSim
    with the knee set there; vas (knee only) is skipped, naming the held knee."""
    import osim_models

    from vm_ros.importers.osim import OsimOptions, import_osim

    knee = -0.7
    options = ({"locked": ("knee_angle",), "default": ("knee_angle", knee)} if held == "locked"
               else {"ranges": {"knee_angle": (knee, knee)}})
    path = held_variant(osim, osim_models.build_hip_knee, tmp_path / "held.osim", **options)
    printed = io.StringIO()
    result = import_osim(path, tmp_path / "out", OsimOptions(samples=200, seed=2),
                         progress=False, file=printed)
    geometry = result.geometry
    assert geometry.coordinate_names == ("hip_flexion",)
    assert result.skipped == {"vas": "crosses no free coordinate (constant length with "
                                     "knee_angle held)"}
    assert "held at one value, not inputs: knee_angle: " in printed.getvalue()
    assert list(geometry.source["held_coordinates"]) == ["knee_angle"]
    muscles = ["rf", "ham", "ilio"]
    hip = np.random.default_rng(5).uniform(*osim_models.HIP_RANGE, 40)
    q, length, arm = opensim_reference(osim, path, {"hip_flexion": hip,
                                                    "knee_angle": np.full(40, knee)}, muscles)
    rows = [geometry.muscle_names.index(m) for m in muscles]
    for k, values in enumerate(q):
        ours, gradient = geometry.lengths_and_gradients(values[:1])
        np.testing.assert_allclose(ours[rows], length[k], atol=1e-4)
        np.testing.assert_allclose(-gradient[rows, 0], arm[k, :, 0], atol=1e-3)
    # the knee angle matters to rf: held at 0 rad instead, rf would be > 5 mm off
    _, straight, _ = opensim_reference(osim, path.with_name("held-base.osim"),
                                       {"hip_flexion": hip[:1], "knee_angle": [0.0]}, ["rf"])
    assert abs(straight[0, 0] - length[0, 0]) > 5e-3


# ------------------------------------------------------------------ motion files (no OpenSim)


def test_motion_reader_state_paths_and_radians(tmp_path):
    path = tmp_path / "states.sto"
    path.write_text("states\nversion=1\ninDegrees=no\nendheader\n"
                    "time\t/jointset/knee/knee_angle/value\t/jointset/knee/knee_angle/speed\t"
                    "/forceset/vas/activation\n0.0\t-0.5\t1.0\t0.2\n0.1\t-0.4\t1.0\t0.3\n")
    motion = read_motion(path)
    assert motion.names == ("knee_angle",) and not motion.in_degrees
    assert motion.to_si({"knee_angle"}).ravel().tolist() == [-0.5, -0.4]


@pytest.mark.parametrize("word, degrees", [("YES", True), ("Yes", True), ("No", False)])
def test_motion_reader_in_degrees_ignores_case(tmp_path, word, degrees):
    path = tmp_path / "ik.mot"
    path.write_text(f"ik\ninDegrees={word}\nendheader\ntime q\n0 90\n")
    assert read_motion(path).to_si({"q"}).item() == (math.pi / 2 if degrees else 90.0)


def test_cli_motion_in_degrees_maybe_is_one_line(tmp_path, capsys):
    """Read before OpenSim is loaded: the model file only has to exist."""
    model = tmp_path / "m.osim"
    model.write_text("<OpenSimDocument><Model/></OpenSimDocument>")
    motion = tmp_path / "ik.mot"
    motion.write_text("ik\ninDegrees=maybe\nendheader\ntime\tknee_angle\n0\t-30\n")
    code, _, err = run_cli(["import-osim", str(model), "--out", str(tmp_path / "o"),
                            "--motion", str(motion)], capsys)
    assert code == 2 and err.strip().splitlines() == [
        f"vm-ros import-osim: error: motion {motion}: header 'inDegrees=maybe' is neither yes "
        "(degrees) nor no (radians); write one of them"]


def test_motion_reader_degrees_convert_rotational_only(tmp_path):
    path = tmp_path / "ik.mot"
    path.write_text("ik\ninDegrees=yes\nendheader\ntime pelvis_tx knee_angle\n0 0.5 -90\n")
    values = read_motion(path).to_si({"knee_angle"})
    assert values.tolist() == [[0.5, -math.pi / 2]]


@pytest.mark.parametrize("text, expected", [
    ("a\nendheader\ntime\tq\n0\t1\n", "inDegrees"),
    ("inDegrees=no\ntime\tq\n0\t1\n", "endheader"),
    ("inDegrees=no\nendheader\nq\ttime\n0\t1\n", "first column must be 'time'"),
    ("inDegrees=no\nendheader\ntime\tq\n0\tx\n", "not numbers"),
    ("inDegrees=maybe\nendheader\ntime\tq\n0\t1\n", "'inDegrees=maybe' is neither yes"),
    # OpenSim's Storage reads 'true' as radians: ambiguous, refused rather than guessed
    ("inDegrees=true\nendheader\ntime\tq\n0\t1\n", "'inDegrees=true' is neither yes"),
    ("inDegrees=\nendheader\ntime\tq\n0\t1\n", "'inDegrees=' is neither yes"),
])
def test_motion_reader_errors(tmp_path, text, expected):
    from vm_ros.errors import VmRosError

    path = tmp_path / "bad.mot"
    path.write_text(text)
    with pytest.raises(VmRosError, match=expected):
        read_motion(path)
