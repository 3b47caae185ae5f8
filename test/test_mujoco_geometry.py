"""MujocoGeometry against MuJoCo's own computation: lengths against ten_length from mj_fwdPosition
on a fresh MjData, moment arms against central differences of MuJoCo's lengths with the dependent
joints set by the test's own evaluation of the joint equality (checked against MuJoCo's equality
residual efc_pos), velocities against ten_velocity."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

mujoco = pytest.importorskip("mujoco", reason="the mujoco extra is not installed")

from vm_ros.errors import VmRosError  # noqa: E402
from vm_ros.geometry import generalized_forces  # noqa: E402
from vm_ros.geometry.mujoco_backend import (  # noqa: E402
    ModelLoadError,
    MujocoGeometry,
    load_model,
)

# Two hinges and a slide: `follow` (slide) is coupled to `flex` by a joint equality and both have
# a reference position (qpos0 != 0); `wrist` has no range. Tendon t_a wraps over a cylinder.
# Muscle parameters (test_import_mjcf): m_a usable, m_b a negative tendon, m_c MuJoCo's default
# range.
COUPLED_MJCF = """
<mujoco model="coupled">
  <compiler angle="radian"><lengthrange mode="none"/></compiler>
  <worldbody>
    <body name="upper">
      <geom type="capsule" size="0.02" fromto="0 0 0 0 0 -0.3" mass="1"/>
      <site name="s0" pos="0.04 0 -0.05"/>
      <site name="s0b" pos="-0.03 0 -0.08"/>
      <body name="lower" pos="0 0 -0.3">
        <joint name="flex" type="hinge" axis="0 1 0" range="-1 1.8" ref="0.2"/>
        <geom type="capsule" size="0.02" fromto="0 0 0 0 0 -0.25" mass="0.5"/>
        <geom name="wrap" type="cylinder" size="0.02 0.01" quat="0.7071068 0.7071068 0 0"
              contype="0" conaffinity="0"/>
        <site name="side" pos="0.05 0 0"/>
        <site name="s1" pos="0.02 0 -0.06"/>
        <body name="slider" pos="0 0 -0.1">
          <joint name="follow" type="slide" axis="1 0 0" range="-0.1 0.1" ref="0.01"/>
          <geom type="sphere" size="0.01" mass="0.1"/>
          <site name="s2" pos="0.015 0 0"/>
        </body>
        <body name="hand" pos="0 0 -0.25">
          <joint name="wrist" type="hinge" axis="1 0 0" limited="false"/>
          <geom type="sphere" size="0.02" mass="0.2"/>
          <site name="s3" pos="0 0.02 -0.03"/>
        </body>
      </body>
    </body>
  </worldbody>
  <equality>
    <joint joint1="follow" joint2="flex" polycoef="0.004 0.02 -0.01 0.003 0.0005"/>
  </equality>
  <tendon>
    <spatial name="t_a"><site site="s0"/><geom geom="wrap" sidesite="side"/><site site="s1"/>
    </spatial>
    <spatial name="t_b"><site site="s0b"/><site site="s2"/></spatial>
    <spatial name="t_c"><site site="s0"/><site site="s2"/><site site="s3"/></spatial>
  </tendon>
  <actuator>
    <muscle name="m_a" tendon="t_a" lengthrange="0.2 0.3" range="0.6 1.4"/>
    <muscle name="m_b" tendon="t_b" lengthrange="0.15 0.3" range="0.9 1.5"/>
    <muscle name="m_c" tendon="t_c" lengthrange="0.35 0.45"/>
  </actuator>
</mujoco>
"""


@pytest.fixture(scope="module")
def coupled_path(tmp_path_factory):
    path = tmp_path_factory.mktemp("mjcf") / "coupled.xml"
    path.write_text(COUPLED_MJCF)
    return path


@pytest.fixture(scope="module")
def elbow():
    return MujocoGeometry("myoelbow")


@pytest.fixture(scope="module")
def legs():
    return MujocoGeometry("myolegs")


def mujoco_pose(model, geometry, q):
    """qpos with the coordinates at q and every joint-equality dependent joint set from
    eq_data (the test's own evaluation: q1 - q1_ref = sum a_k (q2 - q2_ref)^k), others at
    qpos0; and dqvel_dependent/dq for the chain rule."""
    qpos = model.qpos0.copy()
    for joint, value in zip(geometry.joint_ids, q, strict=True):
        qpos[model.jnt_qposadr[joint]] = value
    slope = {}
    for e in range(model.neq):  # the models here have no chains of couplings
        if model.eq_type[e] != mujoco.mjtEq.mjEQ_JOINT or not model.eq_active0[e]:
            continue
        dep, ind = model.eq_obj1id[e], model.eq_obj2id[e]
        a = model.eq_data[e, :5]
        x = qpos[model.jnt_qposadr[ind]] - model.qpos0[model.jnt_qposadr[ind]]
        qpos[model.jnt_qposadr[dep]] = model.qpos0[model.jnt_qposadr[dep]] + np.polynomial \
            .polynomial.polyval(x, a)
        slope[int(dep)] = (int(ind), np.polynomial.polynomial.polyval(
            x, np.polynomial.polynomial.polyder(a)))
    return qpos, slope


def mujoco_lengths(model, data, geometry, q):
    data.qpos[:] = mujoco_pose(model, geometry, q)[0]
    mujoco.mj_fwdPosition(model, data)
    return data.ten_length[geometry.tendon_ids].copy()


def random_poses(geometry, n, seed):
    rng = np.random.default_rng(seed)
    margin = 0.02 * (geometry.upper - geometry.lower)
    return geometry.lower + margin + rng.random((n, len(geometry.lower))) * (
        geometry.upper - geometry.lower - 2 * margin)


def check_against_mujoco(geometry, n_poses=5, h=1e-6, seed=1):
    model = geometry.model
    data = mujoco.MjData(model)
    for q in random_poses(geometry, n_poses, seed):
        out = geometry.evaluate(q)
        np.testing.assert_allclose(out.length_m, mujoco_lengths(model, data, geometry, q),
                                   rtol=0, atol=1e-12)
        gradient = np.empty_like(out.moment_arm)
        for j in range(len(q)):
            step = np.zeros(len(q))
            step[j] = h
            gradient[:, j] = (mujoco_lengths(model, data, geometry, q + step)
                              - mujoco_lengths(model, data, geometry, q - step)) / (2 * h)
        np.testing.assert_allclose(out.moment_arm, -gradient, rtol=0, atol=1e-7)
        assert np.abs(out.moment_arm).max() > 1e-3


def test_elbow_lengths_and_moment_arms_match_mujoco(elbow):
    assert elbow.coordinate_names == ("r_elbow_flex",)
    assert elbow.muscle_names == ("TRIlong", "TRIlat", "TRImed", "BIClong", "BICshort", "BRA")
    assert elbow.coupled == ()
    lower, upper = elbow.model.jnt_range[elbow.joint_ids[0]]
    assert (elbow.lower[0], elbow.upper[0]) == (lower, upper)
    check_against_mujoco(elbow)
    # biceps and brachialis flex (r > 0 on r_elbow_flex), the triceps extend
    r = elbow.evaluate([1.0]).moment_arm[:, 0]
    assert np.all(r[:3] < 0) and np.all(r[3:] > 0)


def test_coupled_model_follows_the_equality(coupled_path):
    g = MujocoGeometry(coupled_path)
    assert g.coordinate_names == ("flex", "wrist")
    assert [c.name for c in g.coupled] == ["follow"]
    assert g.coupled[0].follows == ("flex",)
    assert g.crossed == {"m_a": ("flex",), "m_b": ("flex",), "m_c": ("flex", "wrist")}
    assert (g.lower[1], g.upper[1]) == (-math.pi, math.pi)
    assert any("wrist" in note and "unlimited" in note for note in g.notes)
    assert g.source["sha256"] and g.source["file"].endswith("coupled.xml")
    # our dependent position satisfies MuJoCo's own equality residual
    g.set_pose([1.3, 0.4])
    data = mujoco.MjData(g.model)
    data.qpos[:] = g.data.qpos
    mujoco.mj_forward(g.model, data)
    equality = data.efc_type[:data.nefc] == mujoco.mjtConstraint.mjCNSTR_EQUALITY
    assert equality.sum() == 1
    assert abs(data.efc_pos[:data.nefc][equality][0]) < 1e-15
    assert abs(data.qpos[g.model.jnt_qposadr[1]] - g.model.qpos0[1]) > 1e-3  # moved, ref kept
    check_against_mujoco(g, n_poses=8)


FOLLOW_POLYCOEF = (0.004, 0.02, -0.01, 0.003, 0.0005)   # COUPLED_MJCF's equality, a0..a4


def test_coupling_table_is_the_equality_polynomial(coupled_path, legs):
    """follow = 0.01 + sum a_k (flex - 0.2)^k (refs 0.01 m and 0.2 rad), at 201 points over
    flex's box; myolegs' knee couplings against mujoco_pose's evaluation of eq_data."""
    (follow,) = MujocoGeometry(coupled_path).coupled
    assert follow.unit == "m" and len(follow.follows_values) == 201
    flex = np.array(follow.follows_values)
    assert (flex[0], flex[-1]) == (-1.0, 1.8)
    expected = 0.01 + sum(a * (flex - 0.2) ** k for k, a in enumerate(FOLLOW_POLYCOEF))
    np.testing.assert_allclose(follow.values, expected, rtol=0, atol=1e-15)
    knee = legs.coordinate_index("knee_angle_r")
    model = legs.model
    for c in legs.coupled:
        if c.follows != ("knee_angle_r",):
            continue
        assert c.unit == ("rad" if "rotation" in c.name else "m"), c.name
        adr = model.jnt_qposadr[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, c.name)]
        for i in (0, 77, 200):
            q = (legs.lower + legs.upper) / 2
            q[knee] = c.follows_values[i]
            assert c.values[i] == pytest.approx(mujoco_pose(model, legs, q)[0][adr], abs=1e-15)


def test_a_joint_driven_by_a_fixed_joint_is_set_from_its_polynomial(tmp_path):
    """flex fixed at qpos0 + 0.1 by a driverless equality, follow driven by flex: follow sits at
    0.01 + p(0.1), not at qpos0, and t_b's length is MuJoCo's at that pose."""
    path = tmp_path / "fixed_driver.xml"
    path.write_text(COUPLED_MJCF.replace(
        "</equality>", '<joint joint1="flex" polycoef="0.1 0 0 0 0"/></equality>'))
    g = MujocoGeometry(path)
    assert g.coordinate_names == ("wrist",)
    assert {c.name: c.follows for c in g.coupled} == {"flex": (), "follow": ()}
    model, data = g.model, mujoco.MjData(g.model)
    follow = 0.01 + sum(a * 0.1 ** k for k, a in enumerate(FOLLOW_POLYCOEF))
    for wrist in (-1.0, 0.5):
        data.qpos[:] = [0.3, follow, wrist]
        mujoco.mj_fwdPosition(model, data)
        out = g.evaluate([wrist])
        np.testing.assert_allclose(out.length_m, data.ten_length[g.tendon_ids], rtol=0,
                                   atol=1e-12)
        assert g.data.qpos[1] == pytest.approx(follow, abs=1e-15)
    # follow left at qpos0 (0.01 m) would put t_b more than 1 mm off
    data.qpos[:] = [0.3, 0.01, 0.5]
    mujoco.mj_fwdPosition(model, data)
    assert abs(data.ten_length[g.tendon_ids[1]] - out.length_m[1]) > 1e-3


def test_legs_knee_couplings(legs):
    names = legs.coordinate_names
    assert "knee_angle_r" in names and "knee_angle_translation2_r" not in names
    coupled = {c.name: c.follows for c in legs.coupled}
    assert coupled["knee_angle_beta_rotation1_r"] == ("knee_angle_r",)
    assert len(coupled) == 14
    # sample only the right knee and ankle (others mid-box) to keep the differences cheap
    q = (legs.lower + legs.upper) / 2
    knee, ankle = legs.coordinate_index("knee_angle_r"), legs.coordinate_index("ankle_angle_r")
    model, data = legs.model, mujoco.MjData(legs.model)
    h = 1e-6
    for knee_angle in (0.2, 1.0, 1.9):
        q[knee] = knee_angle
        out = legs.evaluate(q)
        np.testing.assert_allclose(out.length_m, mujoco_lengths(model, data, legs, q), atol=1e-12)
        for j in (knee, ankle):
            step = np.zeros(len(q))
            step[j] = h
            fd = (mujoco_lengths(model, data, legs, q + step)
                  - mujoco_lengths(model, data, legs, q - step)) / (2 * h)
            np.testing.assert_allclose(out.moment_arm[:, j], -fd, rtol=0, atol=1e-7)
    # the coupling matters: without the dependent joints' share the knee moment arms differ
    jac = legs.tendons.jacobian(legs.data)
    direct = -jac[:, legs.dof_addresses[knee]]
    assert np.abs(direct - out.moment_arm[:, knee]).max() > 1e-3


def test_velocity_is_mujoco_ten_velocity_and_power_balances(coupled_path):
    g = MujocoGeometry(coupled_path)
    model, data = g.model, mujoco.MjData(g.model)
    q, qdot = np.array([0.7, -0.3]), np.array([1.5, -2.0])
    out = g.evaluate(q, qdot)
    qpos, slope = mujoco_pose(model, g, q)
    data.qpos[:] = qpos
    data.qvel[:] = 0
    for joint, rate in zip(g.joint_ids, qdot, strict=True):
        data.qvel[model.jnt_dofadr[joint]] = rate
    for dep, (ind, s) in slope.items():
        data.qvel[model.jnt_dofadr[dep]] = s * data.qvel[model.jnt_dofadr[ind]]
    mujoco.mj_forward(model, data)
    np.testing.assert_allclose(out.velocity_m_per_s, data.ten_velocity[g.tendon_ids],
                               rtol=0, atol=1e-12)
    force = np.array([100.0, 40.0, 250.0])
    tau = generalized_forces(out.moment_arm, force)
    assert float(tau @ qdot) == pytest.approx(-float(force @ out.velocity_m_per_s), abs=1e-12)


def test_clamping_like_the_polynomial_back_end(elbow):
    upper = elbow.upper[0]
    out = elbow.evaluate([upper + 0.3], [2.0])
    assert out.clamped.tolist() == [True] and out.q[0] == upper and out.qdot[0] == 0
    assert np.all(out.velocity_m_per_s == 0)
    np.testing.assert_array_equal(out.length_m, elbow.evaluate([upper]).length_m)
    free = MujocoGeometry(elbow.model, clamp=False).evaluate([upper + 0.3], [2.0])
    assert not free.clamped.any() and np.all(free.velocity_m_per_s != 0)


def test_subset_and_bad_sources(elbow):
    sub = MujocoGeometry(elbow.model, muscles=["BRA", "TRIlong"])
    assert sub.muscle_names == ("BRA", "TRIlong")
    np.testing.assert_array_equal(sub.evaluate([1.0]).length_m,
                                  elbow.evaluate([1.0]).length_m[[5, 0]])
    with pytest.raises(ModelLoadError, match="no muscle"):
        MujocoGeometry(elbow.model, muscles=["deltoid"])
    with pytest.raises(ModelLoadError, match="not an MJCF file or a myo-sim model name"):
        MujocoGeometry("no_such_model")
    with pytest.raises(VmRosError, match="no such MJCF file"):
        MujocoGeometry("/nonexistent/model.xml")


def test_a_bare_myo_sim_name_wins_unless_the_argument_is_a_path_to_a_model_file(tmp_path,
                                                                              monkeypatch):
    """A folder, or a file, named like a myo-sim model in the working directory does not hide
    the model; written as a path, the file is used (a folder is no MJCF file); a bare name that
    myo-sim does not know is a file when there is one. Each says which it used."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "myoelbow").mkdir()
    named = load_model("myoelbow")
    assert named.kind == "myo-sim" and named.name == "myoelbow"
    assert named.describe().startswith("myo-sim ") and "'myoelbow'" in named.describe()
    assert MujocoGeometry("myoelbow").origin == named.describe()
    with pytest.raises(ModelLoadError, match=r"no such MJCF file \(a folder\)"):
        load_model("./myoelbow")
    (tmp_path / "myoelbow").rmdir()
    (tmp_path / "myoelbow").write_text(COUPLED_MJCF)
    assert load_model("myoelbow").kind == "myo-sim"
    as_path = load_model(Path("myoelbow").resolve())
    assert as_path.kind == "MJCF file" and as_path.model.nu == 3
    assert as_path.describe() == f"MJCF file {tmp_path.resolve() / 'myoelbow'}"
    (tmp_path / "my_model").write_text(COUPLED_MJCF)  # no extension, not a myo-sim name
    assert load_model("my_model").kind == "MJCF file"
    with pytest.raises(ModelLoadError, match="not an MJCF file or a myo-sim model name"):
        load_model("no_such_model")
