"""Target joint moments (vm_ros.coordination.targets) against independent numbers: hand-written
inverse-dynamics files with OpenSim's time offsets, and inverse dynamics of pendulums whose
torque is m g l sin(q) + I qdd (MuJoCo, OpenSim)."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from vm_ros.coordination.targets import (
    JointMomentTargets,
    TargetsError,
    align_to_frames,
    content_above,
    load_targets,
    lowpass_targets,
)
from vm_ros.errors import VmRosError
from vm_ros.geometry.paths import Coordinate
from vm_ros.node.motion_inputs import JointMotion

GRAVITY = 9.81   # m/s^2, set in the models below
MASS = 2.0       # kg, the pendulum's point mass
LENGTH = 0.5     # m, hinge to mass
INERTIA = 1e-4   # kg m^2, the mass's own inertia about its centre (each axis)


def _geometry(*names_units):
    return SimpleNamespace(coordinates=tuple(Coordinate(n, u, -3.0, 3.0)
                                             for n, u in names_units), coupled=(),
                           coordinate_names=tuple(n for n, _ in names_units))


def _motion(time, columns: dict, source="walk.mot", start_s=0.0):
    q = np.column_stack(list(columns.values()))
    return JointMotion(source, tuple(columns), np.asarray(time) - time[0], q, np.zeros_like(q),
                       start_s)


def _write_sto(path, labels, rows):
    lines = ["Inverse Dynamics Generalized Forces", "version=1", f"nRows={len(rows)}",
             f"nColumns={len(labels)}", "inDegrees=no", "endheader", "\t".join(labels)]
    lines += ["\t".join(f"{v:.10f}" for v in row) for row in rows]
    path.write_text("\n".join(lines) + "\n")
    return path


def test_storage_rows_offset_like_opensim_are_the_motion_frames(tmp_path):
    """ID rows that start at -5e-7 s and drift by up to 1.5e-6 s are taken row for row (no
    interpolation mixes neighbours); the pelvis column, which no coordinate takes, is kept."""
    frames = np.arange(6) / 60.0
    drift = np.array([-5e-7, 3e-7, 1.5e-6, -1.5e-6, 0.0, 1e-6])
    knee = np.array([-43.8, -44.2, -36.5, 10.0, 25.0, -3.0])
    pelvis = np.array([2.0, -23.2, -9.5, 1.0, 0.5, 0.0])
    path = _write_sto(tmp_path / "id.sto", ["time", "pelvis_tilt_moment", "knee_angle_r_moment"],
                      np.column_stack([frames + drift, pelvis, knee]))
    motion = _motion(frames, {"knee_angle_r": np.zeros(6)})
    targets = load_targets(str(path), geometry=_geometry(("knee_angle_r", "rad")), motion=motion)
    assert targets.coordinates == ("knee_angle_r",)
    np.testing.assert_allclose(targets.moments_nm[:, 0], knee, rtol=0, atol=1e-9)
    np.testing.assert_allclose(targets.times_s, frames, atol=1e-12)
    assert targets.unmatched == ("pelvis_tilt_moment",)
    np.testing.assert_allclose(targets.unmatched_nm[:, 0], pelvis, atol=1e-9)
    assert any("pelvis_tilt_moment" in note for note in targets.notes)
    assert targets.peak_nm()[0] == pytest.approx(44.2)


def test_storage_at_another_rate_is_interpolated_on_the_motion_axis(tmp_path):
    """A 50 Hz moment 3 t + 1 (N) of a translational coordinate, on a motion at 120 Hz that
    starts at 0.2 s in its own file: the frames get 3 (0.2 + t) + 1 exactly (linear)."""
    rows = np.arange(0.0, 1.0001, 0.02)
    path = _write_sto(tmp_path / "id.sto", ["time", "slider_force"],
                      np.column_stack([rows, 3 * rows + 1]))
    own = 0.2 + np.arange(0, 60) / 120.0
    motion = _motion(own, {"slider": np.zeros(60)}, start_s=0.2)
    targets = load_targets(f"sto:{path}", geometry=_geometry(("slider", "m")), motion=motion)
    np.testing.assert_allclose(targets.moments_nm[:, 0], 3 * own + 1, atol=1e-9)
    np.testing.assert_allclose(targets.times_s, own, atol=1e-12)


def test_align_to_frames_does_not_snap_rows_half_a_frame_away():
    """Rows 0.3 frame off are interpolated, not snapped: values of a line stay on the line."""
    frames = np.arange(5) * 0.01
    rows = np.arange(-1, 6) * 0.01 + 0.003
    np.testing.assert_allclose(align_to_frames(rows, 2 * rows, frames, "x")[:, 0], 2 * frames,
                               atol=1e-12)


@pytest.mark.parametrize("labels, unit, message", [
    (["time", "hip_moment"], "rad", "no column knee_moment for coordinate knee"),
    (["time", "knee_force"], "rad", "it has knee_force, but knee is rotational"),
    (["time", "knee_moment", "knee_moment"], "rad", "knee_moment appear twice"),
])
def test_storage_columns_that_do_not_fit_are_one_line_errors(tmp_path, labels, unit, message):
    path = _write_sto(tmp_path / "id.sto", labels, [[0.0] + [1.0] * (len(labels) - 1),
                                                    [1.0] + [1.0] * (len(labels) - 1)])
    motion = _motion(np.array([0.0, 1.0]), {"knee": np.zeros(2)})
    with pytest.raises(VmRosError, match=message) as info:
        load_targets(str(path), geometry=_geometry(("knee", unit)), motion=motion)
    assert "\n" not in str(info.value)


def test_storage_that_does_not_cover_the_motion_is_an_error(tmp_path):
    path = _write_sto(tmp_path / "id.sto", ["time", "knee_moment"], [[0.0, 1.0], [0.5, 2.0]])
    motion = _motion(np.linspace(0.0, 1.0, 11), {"knee": np.zeros(11)})
    with pytest.raises(TargetsError, match="cover 0 to 0.5 s, the motion 0 to 1 s"):
        load_targets(str(path), geometry=_geometry(("knee", "rad")), motion=motion)


def test_storage_with_times_that_go_back_is_an_error(tmp_path):
    path = _write_sto(tmp_path / "id.sto", ["time", "knee_moment"],
                      [[0.0, 1.0], [0.5, 2.0], [0.4, 2.0]])
    motion = _motion(np.array([0.0, 0.4]), {"knee": np.zeros(2)})
    with pytest.raises(VmRosError, match=r"times must increase strictly \(row 3 does not"):
        load_targets(str(path), geometry=_geometry(("knee", "rad")), motion=motion)


@pytest.mark.parametrize("spec, message", [
    ("no/such/file.sto", "neither a file nor a source"),
    ("opensim-id:", "expected MODEL.osim"),
    ("opensim-id:model.txt", "expected MODEL.osim"),
    ("opensim-id:missing.osim", "no such file missing.osim"),
    ("opensim-id:missing.osim,lowpass=-6", "is not a positive frequency"),
    ("opensim-id:missing.osim,cutoff=6", "unknown option 'cutoff'"),
])
def test_bad_specs_are_one_line_errors(spec, message):
    motion = _motion(np.array([0.0, 1.0]), {"knee": np.zeros(2)})
    with pytest.raises(TargetsError, match=message) as info:
        load_targets(spec, geometry=_geometry(("knee", "rad")), motion=motion)
    assert "\n" not in str(info.value)


def _pendulum_motion(source, n=201, duration=2.0, amplitude=0.6, start_s=0.0):
    """q = A sin(pi t): (JointMotion, q, qdd)."""
    time = np.linspace(0.0, duration, n)
    q = amplitude * np.sin(np.pi * time)
    qdot = amplitude * np.pi * np.cos(np.pi * time)
    qdd = -amplitude * np.pi ** 2 * np.sin(np.pi * time)
    motion = JointMotion(str(source), ("swing",), time, q[:, None], qdot[:, None], start_s)
    return motion, q, qdd


def _expected_torque(q, qdd):
    """The hinge torque that moves a point-like mass MASS at LENGTH below the hinge."""
    return (MASS * LENGTH ** 2 + INERTIA) * qdd + MASS * GRAVITY * LENGTH * np.sin(q)


PENDULUM_MJCF = """
<mujoco model="pendulum">
  <option gravity="0 0 -{g}"/>
  <worldbody>
    <body name="base" pos="0 0 1">
      {root}
      <inertial pos="0 0 0" mass="{base_mass}" diaginertia="0.01 0.01 0.01"/>
      <site name="origin" pos="0.05 0 0"/>
      <body name="bob">
        <joint name="swing" type="hinge" axis="0 1 0" range="-1.5 1.5"/>
        <inertial pos="0 0 -{l}" mass="{m}" diaginertia="{i} {i} {i}"/>
        <site name="insertion" pos="0.05 0 -0.2"/>
      </body>
    </body>
  </worldbody>
  <tendon><spatial name="front"><site site="origin"/><site site="insertion"/></spatial></tendon>
  <actuator><muscle name="front" tendon="front"/></actuator>
</mujoco>
"""


def _mjcf(tmp_path, root="", base_mass=1.0):
    path = tmp_path / "pendulum.xml"
    path.write_text(PENDULUM_MJCF.format(g=GRAVITY, l=LENGTH, m=MASS, i=INERTIA, root=root,
                                         base_mass=base_mass))
    return path


def test_mujoco_inverse_dynamics_of_a_pendulum_is_m_g_l_sin_q_plus_i_qdd(tmp_path):
    pytest.importorskip("mujoco", reason="the mujoco extra is not installed")
    path = _mjcf(tmp_path)
    motion, q, qdd = _pendulum_motion(path)
    targets = load_targets(f"mujoco:{path}", geometry=None, motion=motion)
    expected = _expected_torque(q, qdd)
    peak = np.abs(expected).max()
    # qacc is the derivative of a smoothing spline of qvel: exact inside, looser at the ends
    inner = slice(10, -10)
    assert np.abs(targets.moments_nm[inner, 0] - expected[inner]).max() < 0.002 * peak
    assert np.abs(targets.moments_nm[:, 0] - expected).max() < 0.02 * peak
    assert targets.unmatched == ()


def test_mujoco_free_root_forces_are_the_residual_holding_the_model(tmp_path):
    """Held still at 0.4 rad under a free root: the hinge needs m g l sin(0.4) and the root's
    vertical force carries the whole weight (base 1 kg + bob), reported as unmatched."""
    pytest.importorskip("mujoco", reason="the mujoco extra is not installed")
    path = _mjcf(tmp_path, root='<freejoint name="root"/>', base_mass=1.0)
    time = np.linspace(0.0, 1.0, 11)
    motion = JointMotion(str(path), ("swing",), time, np.full((11, 1), 0.4), np.zeros((11, 1)))
    geometry = SimpleNamespace(source={"file": str(path)})
    targets = load_targets("mujoco", geometry=geometry, motion=motion)
    np.testing.assert_allclose(targets.moments_nm[:, 0],
                               MASS * GRAVITY * LENGTH * math.sin(0.4), rtol=1e-6)
    assert targets.unmatched == tuple(f"root[{k}]" for k in range(6))
    np.testing.assert_allclose(targets.unmatched_nm[:, 2], (1.0 + MASS) * GRAVITY, rtol=1e-6)
    assert any("residual that holds the model in space" in n for n in targets.notes)


def test_mujoco_without_a_model_named_is_an_error():
    pytest.importorskip("mujoco", reason="the mujoco extra is not installed")
    motion = _motion(np.array([0.0, 1.0]), {"knee": np.zeros(2)})
    with pytest.raises(TargetsError, match="names no MuJoCo model"):
        load_targets("mujoco", geometry=SimpleNamespace(source={}), motion=motion)


def _osim_pendulum(osim, path):
    model = osim.Model()
    model.setName("pendulum")
    model.setGravity(osim.Vec3(0, -GRAVITY, 0))
    bob = osim.Body("bob", MASS, osim.Vec3(0, -LENGTH, 0),
                    osim.Inertia(INERTIA, INERTIA, INERTIA))
    model.addBody(bob)
    joint = osim.PinJoint("hinge", model.getGround(), osim.Vec3(0, 1, 0), osim.Vec3(0), bob,
                          osim.Vec3(0), osim.Vec3(0))
    joint.upd_coordinates(0).setName("swing")
    model.addJoint(joint)
    model.finalizeConnections()
    model.initSystem()
    model.printToXML(str(path))
    return path


def test_opensim_inverse_dynamics_of_a_pendulum(tmp_path):
    """OpenSim's InverseDynamicsTool on a pin-joint pendulum (z axis, gravity along -y) and a
    motion file in degrees: m g l sin(q) + I qdd."""
    from vm_ros.importers.osim import load_opensim

    try:
        osim = load_opensim()
    except VmRosError:
        pytest.skip("the opensim extra is not installed")
    model = _osim_pendulum(osim, tmp_path / "pendulum.osim")
    motion_file = tmp_path / "swing.mot"
    motion, q, qdd = _pendulum_motion(motion_file, n=401)
    lines = ["swing", "version=1", f"nRows={len(q)}", "nColumns=2", "inDegrees=yes",
             "endheader", "time\tswing"]
    lines += [f"{t:.8f}\t{np.degrees(v):.10f}" for t, v in zip(motion.time_s, q, strict=True)]
    motion_file.write_text("\n".join(lines) + "\n")
    targets = load_targets(f"opensim-id:{model}", geometry=_geometry(("swing", "rad")),
                           motion=motion)
    expected = _expected_torque(q, qdd)
    peak = np.abs(expected).max()
    inner = slice(20, -20)   # OpenSim's splines of the coordinates are looser at the ends
    assert np.abs(targets.moments_nm[inner, 0] - expected[inner]).max() < 0.005 * peak
    assert targets.source == f"opensim-id:{model}"


def test_opensim_id_of_the_walk_reproduces_its_reference_output(tmp_path):
    """OpenSim's InverseDynamicsTool run here with the walk's ground reactions and its setup's
    6 Hz filter gives the hip, knee and ankle moments of opensim-models' reference ID file
    (when scripts/fetch-gait-data has fetched the walk)."""
    from vm_ros.importers.motion import read_motion
    from vm_ros.importers.osim import load_opensim
    from vm_ros.validation.walk_data import WalkDataError, walk_files

    try:
        files = walk_files()
        load_opensim()
    except (WalkDataError, VmRosError) as exc:
        pytest.skip(str(exc))
    names = [f"{joint}_{side}" for side in "rl" for joint in ("hip_flexion", "knee_angle",
                                                                 "ankle_angle")]
    geometry = _geometry(*((n, "rad") for n in names))
    motion = JointMotion.from_motion(read_motion(files["motion"]), geometry, names, {})
    reference = load_targets(str(files["inverse_dynamics"]), geometry=geometry, motion=motion)
    ours = load_targets(f"opensim-id:{files['model']},{files['grf_loads']},lowpass=6",
                        geometry=geometry, motion=motion)
    np.testing.assert_allclose(ours.moments_nm, reference.moments_nm, rtol=0,
                               atol=1e-3 * reference.peak_nm().max())
    assert reference.unmatched == ("pelvis_tilt_moment", "pelvis_tx_force", "pelvis_ty_force",
                                   "lumbar_extension_moment")


def _butterworth_filtfilt_gain(f_hz, cutoff_hz, order=2):
    """Amplitude gain of a Butterworth low-pass run forward and backward, from its magnitude
    |H|^2 = 1 / (1 + (f / f_c)^(2 order)) of the analogue prototype (bilinear warping at
    60 Hz sampling moves it by less than the tolerances below)."""
    return 1.0 / (1.0 + (f_hz / cutoff_hz) ** (2 * order))


def test_lowpass_keeps_a_slow_sine_and_removes_a_fast_one():
    """A 1 Hz sine of 100 N m plus a 20 Hz sine of 10 N m at 60 frames/s, low-passed at 6 Hz:
    away from the ends the result is the 1 Hz sine within 0.5 N m (its gain 0.9992, the 20 Hz
    one's 0.008); content_above gives the 20 Hz sine's RMS, 10 / sqrt(2), within 5 %."""
    t = np.arange(0, 4.0, 1 / 60)
    slow, fast = 100 * np.sin(2 * np.pi * t), 10 * np.sin(2 * np.pi * 20 * t)
    targets = JointMomentTargets(t, ("q",), (slow + fast)[:, None], "made up",
                                 ("pelvis_tx",), (slow + fast)[:, None])
    out = lowpass_targets(targets, 6.0, 2)
    middle = slice(60, -60)
    assert _butterworth_filtfilt_gain(20, 6) < 0.01 < 0.999 < _butterworth_filtfilt_gain(1, 6)
    np.testing.assert_allclose(out.moments_nm[middle, 0], slow[middle], atol=0.5)
    np.testing.assert_allclose(out.unmatched_nm, out.moments_nm)
    assert "low-passed at 6 Hz" in out.notes[-1]
    assert content_above(t, (slow + fast)[:, None], 6.0, 2)[0] == pytest.approx(
        10 / np.sqrt(2), rel=0.05)


@pytest.mark.parametrize("times, cutoff, message", [
    (np.r_[0:1:1 / 60, 1.5], 6.0, "uniformly spaced"),
    (np.arange(0, 1, 1 / 60), 31.0, "Nyquist"),
    (np.arange(0, 8 / 60, 1 / 60), 6.0, "too few"),
])
def test_lowpass_of_frames_it_cannot_filter_is_a_one_line_error(times, cutoff, message):
    targets = JointMomentTargets(times, ("q",), np.ones((len(times), 1)), "made up")
    with pytest.raises(TargetsError, match=message):
        lowpass_targets(targets, cutoff, 2)
    assert content_above(times, np.ones((len(times), 1)), cutoff, 2) is None
