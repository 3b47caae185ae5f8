"""vm_ros.geometry core: polynomial paths, exact moment arms, clamping, torques, the file.

References are independent of the evaluator under test: a slow scalar evaluation written here
from the formula, central finite differences, closed-form polynomials, and the power identity.
"""

from __future__ import annotations

import json
import math
import re

import numpy as np
import pytest

from vm_ros.errors import ConfigError, InputError
from vm_ros.geometry import (
    Coordinate,
    CoupledCoordinate,
    FitReport,
    MusclePath,
    PolynomialGeometry,
    generalized_forces,
    load_geometry,
    write_geometry,
)
from vm_ros.geometry import kernel as geometry_kernel
from vm_ros.geometry.file import dumps, loads
from vm_ros.geometry.fit import fit_path
from vm_ros.geometry.polynomial import total_degree_exponents

BACKENDS = ["numpy"] + (["compiled"] if geometry_kernel.available() else [])


def scalar_length(path: MusclePath, values: dict) -> float:
    """L = sum_t c_t prod_j ((q_j - offset_j) / scale_j) ** e_tj, one term at a time."""
    total = 0.0
    for coefficient, exponents in zip(path.coefficients, path.exponents, strict=True):
        term = float(coefficient)
        for name, offset, scale, e in zip(path.coordinates, path.offset, path.scale, exponents,
                                          strict=True):
            term *= ((values[name] - offset) / scale) ** int(e)
        total += term
    return total


def random_geometry(seed=0, n_muscles=12, backend="numpy",
                    fitted=False, widest=3) -> PolynomialGeometry:
    """Random polynomials, muscle i crossing 1 + i % ``widest`` of the 4 coordinates;
    ``fitted``: each maps its box onto x in [-1, 1] as a fit does, so that the paths stay
    physical (0.3-0.4 m give or take ~0.1 m: a file that loads)."""
    rng = np.random.default_rng(seed)
    coordinates = [Coordinate("hip_flexion", "rad", -0.5, 1.8),
                   Coordinate("knee_angle", "rad", -2.0, 0.1),
                   Coordinate("ankle_angle", "rad", -0.7, 0.5),
                   Coordinate("pelvis_tx", "m", -0.2, 0.2)]
    names = [c.name for c in coordinates]
    boxes = {c.name: (c.lower, c.upper) for c in coordinates}
    muscles = []
    for i in range(n_muscles):
        k = 1 + i % widest
        crossed = tuple(rng.choice(names, size=k, replace=False))
        exponents = total_degree_exponents(k, 2 + i % 5)
        coefficients = rng.normal(scale=0.01, size=len(exponents))
        coefficients[0] = 0.3 + 0.1 * rng.random()
        offset = tuple(rng.normal(scale=0.3, size=k))
        scale = tuple(0.5 + rng.random(k))
        if fitted:
            offset = tuple((boxes[c][0] + boxes[c][1]) / 2 for c in crossed)
            scale = tuple((boxes[c][1] - boxes[c][0]) / 2 for c in crossed)
        muscles.append(MusclePath(f"muscle_{i}", crossed, offset, scale, exponents,
                                  coefficients))
    return PolynomialGeometry(coordinates, muscles, backend=backend)


def random_pose(geometry, rng) -> np.ndarray:
    return geometry.lower + (geometry.upper - geometry.lower) * rng.random(len(geometry.lower))


def test_total_degree_basis_counts_and_order():
    for k in range(1, 5):
        for degree in range(0, 7):
            exponents = total_degree_exponents(k, degree)
            assert len(exponents) == math.comb(degree + k, k)
            assert len({tuple(row) for row in exponents}) == len(exponents)
            assert np.all(np.diff(exponents.sum(axis=1)) >= 0)
            assert exponents[0].sum() == 0


@pytest.mark.parametrize("backend", BACKENDS)
def test_lengths_equal_scalar_evaluation(backend):
    geometry = random_geometry(backend=backend)
    rng = np.random.default_rng(1)
    for _ in range(20):
        q = random_pose(geometry, rng)
        values = dict(zip(geometry.coordinate_names, q, strict=True))
        length, _ = geometry.lengths_and_gradients(q)
        expected = [scalar_length(m, values) for m in geometry.muscles]
        np.testing.assert_allclose(length, expected, rtol=1e-13, atol=1e-15)


@pytest.mark.parametrize("backend", BACKENDS)
def test_moment_arm_is_minus_derivative_of_evaluated_length(backend):
    """r = -dL/dq of the evaluated polynomial, by central differences (h = 1e-5), to 1e-9 m."""
    geometry = random_geometry(backend=backend)
    rng = np.random.default_rng(2)
    h = 1e-5
    for _ in range(20):
        q = random_pose(geometry, rng)
        # inside the box, so clamping does not interfere with the differences
        q = np.clip(q, geometry.lower + 2 * h, geometry.upper - 2 * h)
        out = geometry.evaluate(q)
        for j in range(len(q)):
            step = np.zeros_like(q)
            step[j] = h
            values_plus = dict(zip(geometry.coordinate_names, q + step, strict=True))
            values_minus = dict(zip(geometry.coordinate_names, q - step, strict=True))
            derivative = np.array([(scalar_length(m, values_plus) - scalar_length(m, values_minus))
                                   / (2 * h) for m in geometry.muscles])
            np.testing.assert_allclose(out.moment_arm[:, j], -derivative, rtol=0, atol=1e-9)


@pytest.mark.parametrize("backend", BACKENDS)
def test_joint_power_equals_muscle_power(backend):
    geometry = random_geometry(backend=backend)
    rng = np.random.default_rng(3)
    for _ in range(20):
        q = random_pose(geometry, rng)
        qdot = rng.normal(scale=3.0, size=len(q))
        force = rng.uniform(0, 2000, size=len(geometry.muscle_names))
        out = geometry.evaluate(q, qdot)
        tau = generalized_forces(out.moment_arm, force)
        joint_power = float(tau @ out.qdot)
        muscle_power = -float(force @ out.velocity_m_per_s)
        assert joint_power == pytest.approx(muscle_power, rel=1e-9, abs=1e-12)
        # velocity is the chain rule of the exact gradient
        np.testing.assert_allclose(out.velocity_m_per_s, -out.moment_arm @ qdot, rtol=1e-12,
                                   atol=1e-15)


def test_compiled_and_numpy_evaluators_agree():
    if not geometry_kernel.available():
        pytest.skip("Numba is not available (VM_ROS_NUMBA=0 or not installed): only the NumPy "
                    "evaluator exists")
    numpy_geometry = random_geometry(n_muscles=40, backend="numpy")
    compiled_geometry = random_geometry(n_muscles=40, backend="compiled")
    assert compiled_geometry.backend == "compiled"
    rng = np.random.default_rng(4)
    for _ in range(10):
        q = random_pose(numpy_geometry, rng)
        a, b = numpy_geometry.evaluate(q, q), compiled_geometry.evaluate(q, q)
        np.testing.assert_allclose(a.length_m, b.length_m, rtol=1e-14, atol=0)
        np.testing.assert_allclose(a.moment_arm, b.moment_arm, rtol=1e-12, atol=1e-16)


def test_compiled_slots_written_out_give_the_bits_of_the_loop_over_slots():
    """The compiled evaluator with SLOTS slots written out (muscles padded to them) against the
    loop over however many slots a muscle has (kernel.evaluate_wide, used for wider geometries):
    the same products and sums in the same order, so the same bits; a geometry with a muscle
    crossing more than SLOTS coordinates takes the loop and agrees with NumPy."""
    if not geometry_kernel.available():
        pytest.skip("Numba is not available: only the NumPy evaluator exists")
    geometry = random_geometry(seed=3, n_muscles=30, backend="compiled", widest=4)
    evaluate_wide = geometry_kernel._compile()[3]
    wide = geometry_kernel._wide_arrays(geometry.packed)
    rng = np.random.default_rng(5)
    # more poses than evaluate_many takes together: a full block, then part of one
    poses = np.array([random_pose(geometry, rng)
                      for _ in range(geometry_kernel.POSE_BLOCK + 21)])
    many = geometry.evaluate_many(poses, poses)
    lengths = geometry.lengths_many(poses)
    for i, q in enumerate(poses):
        out = many.row(i)
        length, gradient = evaluate_wide(q, *wide, geometry.packed.max_degree)
        one = geometry.evaluate(q, q)
        for a, b in ((one.length_m, length), (one.moment_arm, -gradient),
                     (out.length_m, length), (out.moment_arm, -gradient),
                     (lengths[i], length)):
            assert a.tobytes() == b.tobytes()
    names = [f"q{j}" for j in range(geometry_kernel.SLOTS + 2)]
    coordinates = [Coordinate(name, "rad", -1.0, 1.0) for name in names]
    muscles = [MusclePath("wide", tuple(names), (0.1,) * len(names), (1.3,) * len(names),
                          total_degree_exponents(len(names), 3),
                          0.01 * rng.normal(size=len(total_degree_exponents(len(names), 3))))]
    compiled = PolynomialGeometry(coordinates, muscles, backend="compiled")
    numpy_geometry = PolynomialGeometry(coordinates, muscles, backend="numpy")
    for q in rng.uniform(-1, 1, (5, len(names))):
        a, b = numpy_geometry.evaluate(q, q), compiled.evaluate(q, q)
        np.testing.assert_allclose(a.length_m, b.length_m, rtol=1e-13, atol=1e-16)
        np.testing.assert_allclose(a.moment_arm, b.moment_arm, rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(compiled.evaluate_many(q[None], q[None]).moment_arm[0],
                                   b.moment_arm, rtol=0, atol=0)


def test_compiled_groups_of_muscles_give_the_bits_of_the_loop_over_slots():
    """The one-pose evaluator takes muscles with the same exponent rows side by side (at most
    LANES of them to a group; a polynomial of degree above GROUP_DEGREE goes through
    evaluate_many): at every pose the bits of the loop over a muscle's slots
    (kernel.evaluate_wide), for groups of more than LANES muscles, groups split between them,
    and a degree above GROUP_DEGREE."""
    if not geometry_kernel.available():
        pytest.skip("Numba is not available: only the NumPy evaluator exists")
    lanes, degree = geometry_kernel.LANES, geometry_kernel.GROUP_DEGREE
    # random_geometry's muscles repeat their width and degree every 20 muscles
    crowded = random_geometry(seed=11, n_muscles=20 * (lanes + 3), backend="compiled", widest=4)
    rng = np.random.default_rng(13)
    names = [c.name for c in crowded.coordinates]
    high = PolynomialGeometry(crowded.coordinates, [
        MusclePath(f"high_{i}", tuple(names[:k]), (0.1,) * k, (1.9,) * k,
                   total_degree_exponents(k, degree + 1),
                   0.01 * rng.normal(size=len(total_degree_exponents(k, degree + 1))))
        for i, k in enumerate((1, 3, 3, 4))], backend="compiled")
    evaluate_wide = geometry_kernel._compile()[3]
    for geometry in (crowded, high):
        wide = geometry_kernel._wide_arrays(geometry.packed)
        poses = np.array([random_pose(geometry, rng) for _ in range(7)])
        many = geometry.evaluate_many(poses, poses)
        for i, q in enumerate(poses):
            length, gradient = evaluate_wide(q, *wide, geometry.packed.max_degree)
            one = geometry.evaluate(q, q)
            for a, b in ((one.length_m, length), (one.moment_arm, -gradient),
                         (many.row(i).moment_arm, -gradient)):
                assert a.tobytes() == b.tobytes()
    groups = np.diff(geometry_kernel._slot_arrays(crowded.packed)[4][:, 0])
    assert groups.max() == lanes and groups.min() == 3


def test_outside_the_box_is_clamped_not_extrapolated():
    geometry = random_geometry()
    inside = (geometry.lower + geometry.upper) / 2
    q = inside.copy()
    q[1] = geometry.upper[1] + 0.5          # far outside, above
    q[3] = geometry.lower[3] - 1.0          # far outside, below
    qdot = np.ones(4)
    out = geometry.evaluate(q, qdot)
    assert out.clamped.tolist() == [False, True, False, True]
    expected_q = inside.copy()
    expected_q[1], expected_q[3] = geometry.upper[1], geometry.lower[3]
    np.testing.assert_array_equal(out.q, expected_q)
    np.testing.assert_array_equal(out.qdot, [1.0, 0.0, 1.0, 0.0])
    at_edge = geometry.evaluate(expected_q)
    np.testing.assert_array_equal(out.length_m, at_edge.length_m)


@pytest.mark.parametrize("bad", [[0.0, 0.0, 0.0], [0.0, np.nan, 0.0, 0.0],
                                 [0.0, np.inf, 0.0, 0.0]])
def test_bad_pose_raises_input_error(bad):
    geometry = random_geometry()
    with pytest.raises(InputError):
        geometry.evaluate(np.array(bad))


def test_fit_reproduces_a_polynomial_path_exactly():
    """A path that is itself a degree-3 polynomial of two coordinates is recovered to rounding,
    with its moment arms (the fit uses lengths and gradients)."""
    rng = np.random.default_rng(5)
    lower, upper = np.array([-1.0, -2.0]), np.array([1.5, 0.2])

    def length(q):
        a, b = q[:, 0], q[:, 1]
        return 0.35 + 0.02 * a - 0.03 * b + 0.004 * a * b - 0.002 * b ** 3 + 0.001 * a ** 2 * b

    def gradient(q):
        a, b = q[:, 0], q[:, 1]
        return np.stack([0.02 + 0.004 * b + 0.002 * a * b,
                         -0.03 + 0.004 * a - 0.006 * b ** 2 + 0.001 * a ** 2], axis=1)

    q_fit = lower + (upper - lower) * rng.random((60, 2))
    q_test = lower + (upper - lower) * rng.random((40, 2))
    path = fit_path("m", ("a", "b"), lower, upper, q_fit, length(q_fit), gradient(q_fit),
                    q_test, length(q_test), gradient(q_test), degrees=(3,))
    assert path.fit.length_max_m < 1e-12
    assert path.fit.moment_arm_max_m < 1e-11
    assert path.fit.poses_fit == 60 and path.fit.poses_held_out == 40


def test_fit_of_a_smooth_nonpolynomial_path_meets_the_issue_tolerances():
    """A smooth cosine-wrap-like path over a knee range: <= 0.1 mm length RMS and <= 1 mm
    moment-arm RMS on held-out poses (the fit chooses the degree)."""
    rng = np.random.default_rng(6)
    lower, upper = np.array([-2.0]), np.array([0.1])

    def length(q):
        return 0.45 + 0.04 * np.cos(q[:, 0] + 0.3) - 0.01 * q[:, 0]

    def gradient(q):
        return (-0.04 * np.sin(q[:, 0] + 0.3) - 0.01)[:, None]

    q_fit = lower + (upper - lower) * rng.random((80, 1))
    q_test = lower + (upper - lower) * rng.random((50, 1))
    path = fit_path("m", ("knee",), lower, upper, q_fit, length(q_fit), gradient(q_fit),
                    q_test, length(q_test), gradient(q_test))
    assert path.fit.length_rms_m <= 1e-4
    assert path.fit.moment_arm_rms_m <= 1e-3


def knee_tx_table():
    """A coupling table over knee_angle's box: knee_tx = 0.004 sin(knee_angle) m."""
    knee = np.linspace(-2.0, 0.1, 201)
    return tuple(knee), tuple(0.004 * np.sin(knee))


def test_coupling_table_is_linear_between_its_points_and_nan_outside():
    knee, tx = knee_tx_table()
    coupled = CoupledCoordinate("knee_tx", ("knee_angle",), "", "m", knee, tx)
    assert coupled.has_function
    assert not CoupledCoordinate("patella_angle", ("knee_angle",)).has_function
    np.testing.assert_array_equal(coupled.value(knee), tx)
    middle = (knee[10] + knee[11]) / 2
    assert coupled.value(middle) == pytest.approx((tx[10] + tx[11]) / 2, rel=1e-12)
    # linear interpolation of 0.004 sin at a 0.0105 rad spacing: within h^2/8 * 0.004
    q = np.linspace(-2.0, 0.1, 999)
    assert np.abs(coupled.value(q) - 0.004 * np.sin(q)).max() <= 0.0105 ** 2 / 8 * 0.004
    assert np.isnan(coupled.value([-2.01, 0.11])).all()


def with_fit_reports(geometry: PolynomialGeometry) -> PolynomialGeometry:
    muscles = [MusclePath(m.name, m.coordinates, m.offset, m.scale, m.exponents, m.coefficients,
                          FitReport(1e-6 * i, 2e-6, 3e-5, 1e-4, 100, 50,
                                    ("discontinuous",) if i == 2 else ()))
               for i, m in enumerate(geometry.muscles)]
    return PolynomialGeometry(
        geometry.coordinates, muscles,
        coupled=[CoupledCoordinate("patella_angle", ("knee_angle",), "coupler: spline"),
                 CoupledCoordinate("knee_tx", ("knee_angle",), "coupler: table", "m",
                                   *knee_tx_table())],
        source={"model": "test", "sha256": "00ff"}, options={"degree": 6, "samples": 1000})


def test_geometry_file_round_trips_exactly(tmp_path):
    geometry = with_fit_reports(random_geometry(fitted=True))
    path = write_geometry(geometry, tmp_path / "geometry.yaml")
    again = load_geometry(path)
    assert again.coordinates == geometry.coordinates
    assert again.coupled == geometry.coupled
    assert again.source == geometry.source and again.options == geometry.options
    for a, b in zip(geometry.muscles, again.muscles, strict=True):
        assert (a.name, a.coordinates, a.offset, a.scale, a.fit) == \
            (b.name, b.coordinates, b.offset, b.scale, b.fit)
        np.testing.assert_array_equal(a.exponents, b.exponents)
        assert a.coefficients.tobytes() == b.coefficients.tobytes()   # bit for bit
    assert dumps(again) == dumps(geometry)
    q = (geometry.lower + geometry.upper) / 3
    assert geometry.evaluate(q).length_m.tobytes() == again.evaluate(q).length_m.tobytes()



def test_a_geometry_text_is_parsed_once_then_read_from_the_cache(tmp_path, monkeypatch):
    """The parsed-data cache (vm_ros.geometry.file): the first read keeps the data, the next
    read of the same text takes them from the cache (a marked entry shows it), with the values
    and types of PyYAML's pure-Python safe loader; a changed text is parsed anew, a broken
    entry is parsed over and rewritten, data JSON cannot give back equal are not kept."""
    import yaml

    from vm_ros.geometry import file as geometry_file

    folder = tmp_path / "parsed"
    monkeypatch.setattr(geometry_file, "parsed_cache_dir", lambda: folder)
    text = dumps(with_fit_reports(random_geometry(fitted=True)))
    reference = yaml.load(text, Loader=yaml.SafeLoader)
    assert repr(geometry_file.parsed(text)) == repr(reference)   # parsed, kept
    (entry,) = folder.iterdir()
    assert repr(geometry_file.parsed(text)) == repr(reference)   # from the cache
    entry.write_text('{"marked": 1}')
    assert geometry_file.parsed(text) == {"marked": 1}
    entry.write_text('{"marked": ')                               # broken: parsed again
    assert repr(geometry_file.parsed(text)) == repr(reference)
    assert repr(json.loads(entry.read_text())) == repr(reference)
    changed = text.replace("format: vm_ros.geometry", "format: other")
    assert geometry_file.parsed(changed)["format"] == "other"
    assert len(list(folder.iterdir())) == 2
    assert geometry_file.parsed("{1: a}") == {1: "a"}           # a key JSON would make "1"
    assert len(list(folder.iterdir())) == 2
    one, again = loads(text), geometry_file.geometry_from_dict(reference)   # cached, parsed
    for a, b in zip(one.muscles, again.muscles, strict=True):
        assert a.coefficients.tobytes() == b.coefficients.tobytes()

@pytest.mark.parametrize("mutate, field", [
    (lambda d: d.update(format="other"), "format"),
    (lambda d: d.update(version=99), "version"),
    (lambda d: d.update(coordinates="x"), "coordinates"),
    (lambda d: d["coordinates"][0].update(unit="deg"), "coordinates[0]"),
    (lambda d: d["coordinates"][0].update(lower=5.0), "coordinates[0]"),
    (lambda d: d["muscles"][0].pop("coefficients"), "muscles[0]"),
    (lambda d: d["muscles"][0].update(coefficients=[1.0]), "muscles[0]"),
    (lambda d: d["muscles"][0].update(coordinates=["nope"]), "muscles"),
    (lambda d: d["muscles"].append(dict(d["muscles"][0])), "muscles"),
    (lambda d: d["muscles"][0]["exponents"][1].__setitem__(0, 1.7), "muscles[0]"),
    (lambda d: d["muscles"][0]["exponents"].__setitem__(1, [1] * 9), "muscles[0]"),
    (lambda d: d["muscles"][0]["exponents"][1].__setitem__(0, 2 ** 63), "muscles[0]"),
    (lambda d: d["muscles"][0].update(offset=[float("nan")] * len(d["muscles"][0]["offset"])),
     "muscles[0]"),
    (lambda d: d.update(source=[1, 2]), "source"),
    (lambda d: d.update(coupled_coordinates=[{"name": "knee_angle", "follows": []}]), "muscles"),
    (lambda d: d.update(coupled_coordinates=[{"name": "p", "follows": ["nope"]}]), "muscles"),
    (lambda d: d.update(coupled_coordinates=[
        {"name": "p", "follows": ["knee_angle"], "unit": "rad", "follows_values": [0.0, 1.0],
         "values": [0.0]}]), "coupled_coordinates[0]"),
    (lambda d: d.update(coupled_coordinates=[
        {"name": "p", "follows": ["knee_angle"], "unit": "rad", "follows_values": [1.0, 0.0],
         "values": [0.0, 1.0]}]), "coupled_coordinates[0]"),
    (lambda d: d.update(coupled_coordinates=[
        {"name": "p", "follows": ["knee_angle"], "unit": "deg", "follows_values": [0.0, 1.0],
         "values": [0.0, 1.0]}]), "coupled_coordinates[0]"),
    (lambda d: d.update(coupled_coordinates=[
        {"name": "p", "follows": ["knee_angle", "hip_flexion"], "unit": "rad",
         "follows_values": [0.0, 1.0], "values": [0.0, 1.0]}]), "coupled_coordinates[0]"),
    (lambda d: d.update(coupled_coordinates=[
        {"name": "p", "follows": ["knee_angle"], "values": [0.0, 1.0]}]),
     "coupled_coordinates[0]"),
])
def test_bad_geometry_files_name_the_field(mutate, field):
    import yaml

    data = yaml.safe_load(dumps(random_geometry(fitted=True)))
    mutate(data)
    with pytest.raises(ConfigError) as info:
        loads(yaml.safe_dump(data), "bad.yaml")
    assert info.value.field == field
    assert "\n" not in str(info.value)


def test_unreadable_geometry_files(tmp_path):
    with pytest.raises(ConfigError, match="cannot read"):
        load_geometry(tmp_path / "missing.yaml")
    (tmp_path / "bad.yaml").write_text("muscles: [\n")
    with pytest.raises(ConfigError, match="not valid YAML"):
        load_geometry(tmp_path / "bad.yaml")


# --- the load check: every path physical over the whole box --------------------------------------

ELBOW = Coordinate("elbow_flexion", "rad", 0.5, 2.0)


def elbow_geometry(trilong_low: float, trilong_high: float) -> PolynomialGeometry:
    """BIClong L = 0.3 - 0.05 q (0.2-0.275 m); TRIlong linear in q through ``trilong_low`` m at
    q = 0.5 rad and ``trilong_high`` m at q = 2.0 rad (the box's ends)."""
    slope = (trilong_high - trilong_low) / 1.5
    return PolynomialGeometry([ELBOW], [
        MusclePath("BIClong", ("elbow_flexion",), (0.0,), (1.0,), [[0], [1]], [0.3, -0.05]),
        MusclePath("TRIlong", ("elbow_flexion",), (0.0,), (1.0,), [[0], [1]],
                   [trilong_low - 0.5 * slope, slope])])


def load_error(geometry, path) -> ConfigError:
    write_geometry(geometry, path)
    with pytest.raises(ConfigError) as info:
        load_geometry(path)
    assert "\n" not in str(info.value) and str(path) in str(info.value)
    return info.value


@pytest.mark.parametrize(("low", "high", "shown"), [
    (-0.014, 0.017, "path length -0.014 m at elbow_flexion=0.5 rad"),  # bad at one end only
    (-0.03, -0.01, "path length -0.03 m at elbow_flexion=0.5 rad"),    # bad everywhere
    (0.2, 0.0, "path length 0 m at elbow_flexion=2 rad"),
    (0.0005, 0.3, "path length 0.0005 m at elbow_flexion=0.5 rad"),    # > 0 but within 1 mm
    (0.3, 150.0, "path length 150 m at elbow_flexion=2 rad"),
], ids=["negative-at-one-end", "negative", "zero", "below-1-mm", "150-m"])
def test_a_geometry_with_a_non_physical_path_somewhere_in_its_box_is_refused(tmp_path, low,
                                                                              high, shown):
    """The node's model needs every path length > 0 m; the file is refused naming the muscle
    and the pose, in one line."""
    error = load_error(elbow_geometry(low, high), tmp_path / "elbow.yaml")
    assert error.field == "muscles[1]" and error.value == "TRIlong"
    assert f"muscle TRIlong: {shown}; must be in [0.001, 100] m" in str(error)


def test_absurd_coefficients_are_refused(tmp_path):
    """1e308 m coefficients evaluate to inf: the file is refused at the coefficient."""
    geometry = elbow_geometry(0.1, 0.2)
    huge = MusclePath("TRIlong", ("elbow_flexion",), (0.0,), (1.0,), [[0], [1]], [1e308, 1e308])
    error = load_error(PolynomialGeometry([ELBOW], [geometry.muscles[0], huge]),
                       tmp_path / "huge.yaml")
    assert error.field == "muscles[1]"
    assert "muscle TRIlong: coefficient 0 is 1e+308 m; each must be finite with abs(c) <= " \
        "1000 m" in str(error)
    within = MusclePath("TRIlong", ("elbow_flexion",), (0.0,), (1.0,), [[0], [1]], [1000.0, -1.0])
    error = load_error(PolynomialGeometry([ELBOW], [geometry.muscles[0], within]),
                       tmp_path / "long.yaml")
    assert "path length 999.5 m at elbow_flexion=0.5 rad" in str(error)  # coefficients pass


def test_the_check_names_every_coordinate_of_the_pose(tmp_path):
    """A muscle over two coordinates, shortest at (hip 1.5, knee 0): only the end poses of
    each coordinate and random poses are sampled, so the reported pose is the sampled one
    nearest that corner, and it names both coordinates."""
    coordinates = [Coordinate("hip_flexion", "rad", -0.5, 1.5),
                   Coordinate("knee_angle", "rad", 0.0, 2.0)]
    path = MusclePath("vasti", ("hip_flexion", "knee_angle"), (0.0, 0.0), (1.0, 1.0),
                      [[0, 0], [1, 0], [0, 1]], [-0.1, -0.1, 0.1])   # L = 0.1 (knee - hip - 1)
    error = load_error(PolynomialGeometry(coordinates, [path]), tmp_path / "two.yaml")
    pose = re.search(r"path length (\S+) m at hip_flexion=(\S+) rad, knee_angle=(\S+) rad",
                     str(error))
    length, hip, knee = (float(v) for v in pose.groups())
    assert length == pytest.approx(0.1 * (knee - hip - 1.0), abs=1e-6) and length < 0
    assert length <= 0.1 * (0.0 - 0.5 - 1.0) + 1e-9  # no better than the hip's end pose


def test_fitted_geometries_and_their_ranges_load(tmp_path):
    """The check passes physical files unchanged (the same object as without it)."""
    geometry = random_geometry(fitted=True)
    again = load_geometry(write_geometry(geometry, tmp_path / "ok.yaml"))
    assert dumps(again) == dumps(geometry)


def test_simulate_motion_with_a_non_physical_geometry_exits_2_with_one_line(tmp_path):
    """`vm-ros simulate --motion` reads the geometry with the same loader: one line, exit 2,
    no run log."""
    import subprocess
    import sys
    from pathlib import Path

    geometry = write_geometry(elbow_geometry(-0.014, 0.017), tmp_path / "elbow.yaml")
    motion = tmp_path / "elbow.mot"
    motion.write_text("elbow\nversion=1\nnRows=2\nnColumns=2\ninDegrees=yes\nendheader\n"
                      "time\telbow_flexion\n0.0\t30.0\n0.1\t90.0\n")
    out = tmp_path / "run.mcap"
    vm_ros = str(Path(sys.executable).with_name("vm-ros"))
    proc = subprocess.run([vm_ros, "simulate", "--motion", str(motion), "--geometry",
                           str(geometry), "--out", str(out)], capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("vm-ros simulate: error: "), proc.stderr
    assert str(geometry) in lines[0] and \
        "muscle TRIlong: path length -0.014 m at elbow_flexion=0.5 rad" in lines[0]
    assert not out.exists()
