"""vm-ros import-mjcf: the written polynomials against MuJoCo's own lengths and tendon Jacobian at
fresh poses, the recorded source, MuJoCo-way parameters recomputed from the model's own arrays,
unusable parameters flagged and replaced from --library, and the CLI's error path."""

from __future__ import annotations

import hashlib

import numpy as np
import pytest
import yaml

mujoco = pytest.importorskip("mujoco", reason="the mujoco extra is not installed")

from test_mujoco_geometry import COUPLED_MJCF, mujoco_pose  # noqa: E402

from vm_ros.cli import main  # noqa: E402
from vm_ros.geometry import load_geometry  # noqa: E402
from vm_ros.geometry.mujoco_backend import MujocoGeometry  # noqa: E402
from vm_ros.model import MuscleBank  # noqa: E402


@pytest.fixture(scope="module")
def elbow_import(tmp_path_factory):
    out = tmp_path_factory.mktemp("elbow")
    assert main(["import-mjcf", "myoelbow", "--out", str(out)]) == 0
    return out


def mujoco_truth(model, exact, poses):
    """ten_length and -ten_J through the equalities, computed by MuJoCo on a fresh MjData."""
    data = mujoco.MjData(model)
    lengths, arms = [], []
    for q in poses:
        qpos, slope = mujoco_pose(model, exact, q)
        data.qpos[:] = qpos
        mujoco.mj_fwdPosition(model, data)
        jac = np.zeros((model.ntendon, model.nv))
        mujoco.mju_sparse2dense(jac, data.ten_J, model.ten_J_rownnz, model.ten_J_rowadr,
                                model.ten_J_colind)
        jac = jac[exact.tendon_ids]
        arm = np.stack([-jac[:, model.jnt_dofadr[j]] for j in exact.joint_ids], axis=1)
        for dep, (ind, s) in slope.items():
            arm[:, list(exact.joint_ids).index(ind)] -= s * jac[:, model.jnt_dofadr[dep]]
        lengths.append(data.ten_length[exact.tendon_ids].copy())
        arms.append(arm)
    return np.array(lengths), np.array(arms)


def fit_errors(geometry_path, exact, n=300, seed=7):
    """RMS over fresh poses of (length, moment arm) per muscle, the file against MuJoCo (m)."""
    fitted = load_geometry(geometry_path)
    rng = np.random.default_rng(seed)
    poses = exact.lower + rng.random((n, len(exact.lower))) * (exact.upper - exact.lower)
    length, arm = mujoco_truth(exact.model, exact, poses)
    columns = [exact.coordinate_index(c) for c in fitted.coordinate_names]
    rows = [exact.muscle_names.index(m) for m in fitted.muscle_names]
    fit_length = np.empty((n, len(rows)))
    fit_arm = np.empty((n, len(rows), len(columns)))
    for p, q in enumerate(poses):
        out = fitted.evaluate(q[columns])
        fit_length[p], fit_arm[p] = out.length_m, out.moment_arm
    length_rms = np.sqrt(np.mean((fit_length - length[:, rows]) ** 2, axis=0))
    arm_rms = np.sqrt(np.mean((fit_arm - arm[:, rows][:, :, columns]) ** 2, axis=(0, 2)))
    return dict(zip(fitted.muscle_names, zip(length_rms, arm_rms, strict=True), strict=True))


def test_elbow_fit_against_mujoco(elbow_import):
    exact = MujocoGeometry("myoelbow")
    errors = fit_errors(elbow_import / "geometry.yaml", exact)
    assert set(errors) == set(exact.muscle_names)
    for name, (length_rms, arm_rms) in errors.items():
        assert length_rms <= 1e-4, name
        assert arm_rms <= 1e-3, name


def test_elbow_source_and_parameters(elbow_import):
    import myo_sim

    data = yaml.safe_load((elbow_import / "geometry.yaml").read_text())
    source = data["source"]
    xml = myo_sim.get_xml_path("myoelbow")
    assert source["model"] == "myoelbow" and source["file"] == str(xml)
    assert source["sha256"] == hashlib.sha256(xml.read_bytes()).hexdigest()
    assert source["mujoco"] == mujoco.__version__ and source["myo_sim"] == myo_sim.__version__
    assert data["options"]["degree_max"] == 6 and data["options"]["samples_fit"] == 1000
    assert [c["name"] for c in data["coordinates"]] == ["r_elbow_flex"]
    # the MuJoCo way, recomputed from the model's arrays
    model = myo_sim.load_model("myoelbow")
    library = yaml.safe_load((elbow_import / "muscles.yaml").read_text())["muscles"]
    for a in range(model.nu):
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_ACTUATOR, a)
        range0, range1 = model.actuator_gainprm[a, :2]
        lr0, lr1 = model.actuator_lengthrange[a]
        l0 = (lr1 - lr0) / (range1 - range0)
        assert library[name]["l0_m"] == pytest.approx(l0, rel=1e-5)
        assert library[name]["l0t_m"] == pytest.approx((lr0 - range0 * l0) / 0.964, rel=1e-5)
    bank = MuscleBank.from_config(list(library), library=elbow_import / "muscles.yaml")
    assert bank.n == 6
    summary = (elbow_import / "summary.txt").read_text()
    assert "all usable" in summary and "held-out length RMS" in summary


@pytest.fixture(scope="module")
def coupled_path(tmp_path_factory):
    path = tmp_path_factory.mktemp("mjcf") / "coupled.xml"
    path.write_text(COUPLED_MJCF)
    return path


def test_coupled_model_flags_and_user_library(coupled_path, tmp_path, capsys):
    user = tmp_path / "user.yaml"
    user.write_text(yaml.safe_dump({"muscles": {"m_b": {
        "mass_kg": 0.05, "l0_m": 0.06, "l0t_m": 0.1, "path_length_max_m": 0.19,
        "fpcsa_slow": 0.4, "source": {"all": "test"}}}}))
    out = tmp_path / "out"
    assert main(["import-mjcf", str(coupled_path), "--out", str(out), "--samples", "600",
                 "--library", str(user)]) == 0
    text = capsys.readouterr().out
    assert "WARNING: 2 of 3 muscles have unusable MuJoCo parameters" in text
    assert "m_b:" in text and "negative tendon" in text and "replaced from --library" in text
    assert "m_c:" in text and "default range" in text and "REPLACE IT" in text
    library = yaml.safe_load((out / "muscles.yaml").read_text())["muscles"]
    assert list(library) == ["m_a", "m_b", "m_c"]
    assert library["m_b"]["l0_m"] == 0.06 and library["m_a"]["l0_m"] == pytest.approx(0.125)
    assert "(--library): m_b" in (out / "muscles.yaml").read_text()
    MuscleBank.from_config(["m_a", "m_b", "m_c"], library=out / "muscles.yaml")
    geometry = load_geometry(out / "geometry.yaml")
    assert geometry.coordinate_names == ("flex", "wrist")
    assert [(c.name, c.follows) for c in geometry.coupled] == [("follow", ("flex",))]
    # the coupling written with it: follow = 0.01 + sum a_k (flex - 0.2)^k (refs, polycoef)
    (follow,) = geometry.coupled
    flex = np.array(follow.follows_values)
    assert follow.unit == "m" and (flex[0], flex[-1], len(flex)) == (-1.0, 1.8, 201)
    expected = 0.01 + np.polynomial.polynomial.polyval(flex - 0.2,
                                                       [0.004, 0.02, -0.01, 0.003, 0.0005])
    np.testing.assert_allclose(follow.values, expected, rtol=0, atol=1e-15)
    # m_b crosses flex only through the coupled slide joint: smooth, fitted to MuJoCo closely;
    # m_a (wrapping onset) and m_c (an unlimited hinge, full turn) as well as their reports say
    exact = MujocoGeometry(coupled_path)
    errors = fit_errors(out / "geometry.yaml", exact)
    assert errors["m_b"][0] <= 1e-5 and errors["m_b"][1] <= 1e-4
    for muscle in geometry.muscles:
        length_rms, arm_rms = errors[muscle.name]
        assert length_rms <= 1.5 * muscle.fit.length_rms_m + 1e-6, muscle.name
        assert arm_rms <= 1.5 * muscle.fit.moment_arm_rms_m + 1e-6, muscle.name


def test_cli_bad_model_is_one_line(tmp_path, capsys):
    code = main(["import-mjcf", "myoelbowz", "--out", str(tmp_path)])
    err = capsys.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1
    assert "myoelbowz" in err and "Traceback" not in err
    bad = tmp_path / "bad.xml"
    bad.write_text("<mujoco><worldbody><body></mujoco>")
    assert main(["import-mjcf", str(bad), "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "cannot compile" in err


def test_wrap_jump_is_flagged(tmp_path, capsys):
    """Beyond flex = 1.9 rad tendon t_a jumps to the other side of its wrapping cylinder: the
    import flags it (secant vs MuJoCo's exact slope) instead of passing the fit off as good."""
    path = tmp_path / "jump.xml"
    path.write_text(COUPLED_MJCF.replace('range="-1 1.8" ref="0.2"', 'range="-1 2.2" ref="0.2"'))
    assert main(["import-mjcf", str(path), "--out", str(tmp_path / "out"), "--samples",
                 "300", "--muscle", "m_a"]) == 0
    assert "!! m_a:" in capsys.readouterr().out
    fit = load_geometry(tmp_path / "out" / "geometry.yaml").muscles[0].fit
    assert "discontinuous" in fit.flags


# --- joints held at one value, and zero-width ranges ----------------------------------------

FIX_WRIST = '<joint joint1="wrist" polycoef="0.8 0 0 0 0"/>'   # wrist = qpos0 + 0.8 rad
FIX_FLEX = '<joint joint1="flex" polycoef="0.1 0 0 0 0"/>'


def _variant(tmp_path, text, name="variant.xml"):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_every_crossed_joint_held_is_one_line(tmp_path, capsys):
    path = _variant(tmp_path, COUPLED_MJCF.replace("</equality>",
                                                   FIX_FLEX + FIX_WRIST + "</equality>"))
    assert main(["import-mjcf", str(path), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1, err
    assert "every joint its muscles cross is held, none is left to sample" in err
    assert "flex: fixed by joint equality 'equality1' (no joint2)" in err
    assert "follow: follows the held flex (joint equality 'equality0')" in err
    assert "wrist: fixed by joint equality 'equality2'" in err


def test_zero_width_range_is_one_line(tmp_path, capsys):
    """MuJoCo compiles range="0.3 0.3" as an unlimited joint: refused, not sampled over a turn."""
    path = _variant(tmp_path, COUPLED_MJCF.replace('range="-1 1.8" ref="0.2"',
                                                   'range="0.3 0.3" ref="0.2"'))
    assert not mujoco.MjModel.from_xml_path(str(path)).jnt_limited[0]
    assert main(["import-mjcf", str(path), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1, err
    assert "joint 'flex' has the range [0.3, 0.3], which MuJoCo reads as no range" in err


def _tendon_lengths(model, flex, wrist):
    """MuJoCo's ten_length with flex at each value, follow set from its equality (the test's own
    polynomial), wrist at ``wrist``: independent of the importer and its backend."""
    data = mujoco.MjData(model)
    coefficients = model.eq_data[0, :5]
    out = []
    for q in flex:
        qpos = model.qpos0.copy()
        qpos[0] = q
        qpos[1] = model.qpos0[1] + np.polynomial.polynomial.polyval(q - model.qpos0[0],
                                                                    coefficients)
        qpos[2] = wrist
        data.qpos[:] = qpos
        mujoco.mj_fwdPosition(model, data)
        out.append(data.ten_length.copy())
    return np.array(out)


def test_held_wrist_imports_flex_at_the_held_wrist_angle(tmp_path, capsys):
    path = _variant(tmp_path, COUPLED_MJCF.replace("</equality>", FIX_WRIST + "</equality>"))
    out = tmp_path / "out"
    assert main(["import-mjcf", str(path), "--out", str(out), "--samples", "300"]) == 0
    assert "held at one value, not inputs: wrist: fixed by joint equality 'equality1'" \
        in capsys.readouterr().out
    geometry = load_geometry(out / "geometry.yaml")
    assert geometry.coordinate_names == ("flex",)
    assert geometry.muscle_names == ("m_a", "m_b", "m_c")
    assert "wrist" in geometry.source["held_joints"]
    model = mujoco.MjModel.from_xml_path(str(path))
    assert [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j) for j in range(3)] == [
        "flex", "follow", "wrist"]
    flex = np.random.default_rng(3).uniform(-1.0, 1.8, 50)
    truth = _tendon_lengths(model, flex, 0.8)[:, 2]            # t_c, m_c's tendon
    fitted = np.array([geometry.evaluate([q]).length_m[2] for q in flex])
    assert np.sqrt(np.mean((fitted - truth) ** 2)) <= 1e-4
    # the wrist matters to m_c: held at qpos0 (0 rad) instead, it would be > 1 mm off
    assert np.min(np.abs(_tendon_lengths(model, flex, 0.0)[:, 2] - truth)) > 1e-3


def test_strength_model_keeps_mujocos_f0_and_the_masses(tmp_path, capsys):
    """--strength model: each muscle's VM F0 is MuJoCo's own (gainprm[2], read here with MuJoCo),
    the masses those of the default import; --strength 0.5 halves it; a bad word is one line."""
    import mujoco
    from myo_sim import load_spec

    with_model = tmp_path / "model"
    assert main(["import-mjcf", "myoelbow", "--out", str(with_model), "--samples", "200",
                 "--strength", "model"]) == 0
    half = tmp_path / "half"
    assert main(["import-mjcf", "myoelbow", "--out", str(half), "--samples", "200",
                 "--strength", "0.5"]) == 0
    default = tmp_path / "default"
    assert main(["import-mjcf", "myoelbow", "--out", str(default), "--samples", "200"]) == 0
    model = load_spec("myoelbow").compile()
    names = ["BIClong", "BRA"]
    force = [model.actuator_gainprm[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, n), 2]
             for n in names]
    banks = {p.name: MuscleBank.from_config(names, library=p / "muscles.yaml", backend="numpy")
             for p in (with_model, half, default)}
    np.testing.assert_allclose(banks["model"].f0, force, rtol=1e-8)
    np.testing.assert_allclose(banks["half"].f0, 0.5 * np.array(force), rtol=1e-8)
    np.testing.assert_allclose(banks["default"].f0, 31.8 / 60.0 * np.array(force), rtol=1e-8)
    np.testing.assert_array_equal(banks["model"].mass_kg, banks["default"].mass_kg)
    assert "specific_tension_pa" not in (default / "muscles.yaml").read_text()
    capsys.readouterr()
    assert main(["import-mjcf", "myoelbow", "--out", str(tmp_path / "x"),
                 "--strength", "strong"]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "--strength 'strong'" in err
