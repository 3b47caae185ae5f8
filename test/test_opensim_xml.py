"""OpenSim's own polynomial paths read without OpenSim (vm_ros.geometry.opensim_xml), checked
against OpenSim's evaluation of the same FunctionBasedPaths.

The reader tests need nothing; the comparisons run OpenSim 4.6's PolynomialPathFitter on the
small hip-knee model of test/osim_models.py (11 frames x 10 samples: well under a second) and
evaluate the fitted paths in OpenSim (ModOpReplacePathsWithFunctionBasedPaths).
"""

from __future__ import annotations

import io
import math

import numpy as np
import pytest

from vm_ros.errors import VmRosError
from vm_ros.geometry.fit import evaluate_path
from vm_ros.geometry.opensim_xml import (
    opensim_exponents,
    parse_function_based_paths,
    read_function_based_paths,
)


def path_xml(coefficients, dimension=2, order=2, coords="/jointset/a/qa /jointset/b/qb",
             function="MultivariatePolynomialFunction", extra=""):
    return (f'<OpenSimDocument Version="40600"><Set_FunctionBasedPath_><objects>'
            f'<FunctionBasedPath name="/forceset/m1"><coordinate_paths>{coords}'
            f"</coordinate_paths><length_function><{function}><coefficients>{coefficients}"
            f"</coefficients><dimension>{dimension}</dimension><order>{order}</order>"
            f"</{function}></length_function>{extra}</FunctionBasedPath>"
            "</objects></Set_FunctionBasedPath_></OpenSimDocument>")


def test_exponent_order_is_lexicographic_last_fastest():
    assert opensim_exponents(2, 2).tolist() == [[0, 0], [0, 1], [0, 2], [1, 0], [1, 1], [2, 0]]
    for dimension, order in ((1, 5), (3, 4), (4, 6)):
        rows = opensim_exponents(dimension, order)
        assert len(rows) == math.comb(dimension + order, order)
        assert rows.sum(axis=1).max() == order
        assert [tuple(r) for r in rows] == sorted(tuple(r) for r in rows)


def test_reader_gives_the_polynomial_as_written():
    (path,) = read_function_based_paths(path_xml("1 2 3 4 5 6"))
    assert path.name == "m1" and path.coordinates == ("qa", "qb")
    assert path.offset == (0.0, 0.0) and path.scale == (1.0, 1.0)
    a, b = 0.3, -0.7
    length, gradient = evaluate_path(path, np.array([[a, b]]))
    assert length[0] == pytest.approx(1 + 2 * b + 3 * b * b + 4 * a + 5 * a * b + 6 * a * a,
                                      rel=1e-15)
    assert gradient[0] == pytest.approx([4 + 5 * b + 12 * a, 2 + 6 * b + 5 * a], rel=1e-15)


@pytest.mark.parametrize("xml, expected", [
    (path_xml("1 2 3"), "need 6 coefficients"),
    (path_xml("1 2 3 4 5 6", function="LinearFunction"), "only MultivariatePolynomialFunction"),
    (path_xml("1 2 3 4 5 6", dimension=3), "dimension = 2"),
    (path_xml("1 x 3 4 5 6"), "could not convert"),
    ("<OpenSimDocument/>", "no FunctionBasedPath"),
    ("<OpenSimDocument>", "not valid XML"),
])
def test_reader_errors(xml, expected):
    with pytest.raises(VmRosError, match=expected):
        read_function_based_paths(xml)


def test_reader_checks_coordinates_and_notes_moment_arm_functions():
    xml = path_xml("1 2 3 4 5 6", extra="<moment_arm_functions><Constant/></moment_arm_functions>")
    with pytest.raises(VmRosError, match="unknown coordinate"):
        read_function_based_paths(xml, coordinates=["qa"])
    assert parse_function_based_paths(xml, ["qa", "qb"]).separate_moment_arms == ("m1",)


# ------------------------------------------------------------------ against OpenSim


@pytest.fixture(scope="module")
def fitted(osim, tmp_path_factory):
    """(model path, FunctionBasedPath XML) from OpenSim's PolynomialPathFitter."""
    import osim_models

    folder = tmp_path_factory.mktemp("path_fitter")
    model_path = osim_models.build_hip_knee(folder / "hip_knee.osim")
    table = osim.TimeSeriesTable()
    labels = osim.StdVectorString()
    for label in ("hip_flexion", "knee_angle"):
        labels.append(label)
    table.setColumnLabels(labels)
    for t in np.linspace(0.0, 1.0, 11):
        row = osim.RowVector(2)
        row[0], row[1] = 0.5 + 0.4 * math.sin(6 * t), -1.0 + 0.5 * math.cos(6 * t)
        table.appendRow(float(t), row)
    table.addTableMetaDataString("inDegrees", "no")
    processor = osim.TableProcessor(table)
    processor.append(osim.TabOpUseAbsoluteStateNames())
    fitter = osim.PolynomialPathFitter()
    fitter.setModel(osim.ModelProcessor(str(model_path)))
    fitter.setCoordinateValues(processor)
    fitter.setOutputDirectory(str(folder))
    fitter.setMaximumPolynomialOrder(5)
    fitter.setNumSamplesPerFrame(10)
    fitter.setNumParallelThreads(1)
    fitter.run()
    return model_path, folder / "hip_knee_FunctionBasedPathSet.xml"


def opensim_with_fitted_paths(osim, model_path, xml):
    processor = osim.ModelProcessor(str(model_path))
    processor.append(osim.ModOpReplacePathsWithFunctionBasedPaths(str(xml)))
    model = processor.process()
    return model, model.initSystem()


def test_lengths_and_moment_arms_equal_opensims_evaluation(osim, fitted):
    model_path, xml = fitted
    paths = read_function_based_paths(xml, ["hip_flexion", "knee_angle"])
    assert {p.name for p in paths} == {"rf", "vas", "ham", "ilio"}
    model, state = opensim_with_fitted_paths(osim, model_path, xml)
    coordinates = model.getCoordinateSet()
    rng = np.random.default_rng(7)
    for q in rng.uniform([-0.3, -1.8], [1.4, 0.0], (40, 2)):
        coordinates.get("hip_flexion").setValue(state, q[0], False)
        coordinates.get("knee_angle").setValue(state, q[1], False)
        model.realizePosition(state)
        for path in paths:
            muscle = model.getMuscles().get(path.name)
            length, gradient = evaluate_path(
                path, np.array([[q[0] if c == "hip_flexion" else q[1]
                                 for c in path.coordinates]]))
            assert abs(length[0] - muscle.getLength(state)) <= 1e-12
            for j, name in enumerate(path.coordinates):
                arm = muscle.getPath().computeMomentArm(state, coordinates.get(name))
                assert abs(-gradient[0, j] - arm) <= 1e-9, (path.name, name)


def test_term_order_matches_opensims_function(osim):
    """Each single-term OpenSim MultivariatePolynomialFunction is the monomial of our row."""
    x = np.array([0.3, -0.7, 1.3])
    rows = opensim_exponents(3, 3)
    for t, row in enumerate(rows):
        coefficients = osim.Vector(len(rows), 0.0)
        coefficients.set(t, 1.0)
        function = osim.MultivariatePolynomialFunction(coefficients, 3, 3)
        value = function.calcValue(osim.Vector(x.tolist()))
        assert value == pytest.approx(float(np.prod(x ** row)), rel=1e-14, abs=1e-15)


def test_function_based_paths_import_writes_a_geometry(osim, fitted, tmp_path):
    from vm_ros.geometry.file import load_geometry
    from vm_ros.importers.osim import OsimOptions, import_function_based_paths

    model_path, xml = fitted
    result = import_function_based_paths(model_path, xml, tmp_path, OsimOptions(held_out=40),
                                         progress=False, file=io.StringIO())
    geometry = load_geometry(result.written["geometry"])
    assert geometry.coordinate_names == ("hip_flexion", "knee_angle")
    assert geometry.source["function_based_paths"] == xml.name
    model, state = opensim_with_fitted_paths(osim, model_path, xml)
    coordinates = model.getCoordinateSet()
    q = np.array([0.4, -0.9])
    coordinates.get("hip_flexion").setValue(state, q[0], False)
    coordinates.get("knee_angle").setValue(state, q[1], False)
    model.realizePosition(state)
    lengths, _ = geometry.lengths_and_gradients(q)
    expected = [model.getMuscles().get(n).getLength(state) for n in geometry.muscle_names]
    assert np.max(np.abs(lengths - expected)) <= 1e-12
    for m in geometry.muscles:          # fitted around the frames only, checked over the box
        assert m.fit.poses_held_out == 40 and m.fit.poses_fit == 0
