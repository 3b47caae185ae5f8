"""The one import pipeline (vm_ros.importers.pipeline) with an analytic path source: a new source
supplies its paths and parameter mapping only, and gets crossing, fit, flags and files."""

import io

import numpy as np
import pytest
import yaml

from vm_ros.geometry import load_geometry
from vm_ros.importers.common import (
    FitOptions,
    ImportChoices,
    ImportedMuscle,
    specific_tension_option,
)
from vm_ros.importers.pipeline import PathSource, SampleBox, import_paths

JUMP_AT = 0.5       # rad: the "jump" path is 5 mm longer above this elbow angle


def analytic(q):
    """(L (4,), dL/dq (4, 2)) of four paths over (elbow rad, slide m)."""
    a, b = q
    length = np.array([0.30 - 0.02 * a, 0.25 + 0.01 * a * a + 0.5 * b, 0.20,
                       0.30 - 0.02 * a + (0.005 if a > JUMP_AT else 0.0)])
    gradient = np.array([[-0.02, 0.0], [0.02 * a, 0.5], [0.0, 0.0], [-0.02, 0.0]])
    return length, gradient


class Analytic(PathSource):
    muscle_names = ("lin", "quad", "none", "jump")
    origin = "analytic paths"
    sweep_extremes = True     # the sweeps run to the box's ends: extremes exact

    def __init__(self):
        self.extremes = None

    def box(self, rng):
        return SampleBox(("elbow", "slide"), ("rad", "m"), np.array([-1.0, 0.0]),
                         np.array([1.0, 0.1]))

    def poses(self, box, n, rng):
        return box.lower + rng.random((n, 2)) * (box.upper - box.lower)

    def lengths_and_gradients(self, q, wrt=None):
        length, gradient = analytic(q)
        return length, gradient if wrt is None else gradient[:, wrt]

    def skip_reason(self, name):
        return "constant length"

    def record(self, skipped, box):
        return {"model": "analytic", "muscles_skipped": skipped}, {"seed": 0}, []

    def imported(self, names, path_min, path_max):
        self.extremes = dict(zip(names, zip(path_min, path_max, strict=True), strict=True))
        return [ImportedMuscle(n, 500.0, 0.1, 0.2, lo, hi) for n, lo, hi in
                zip(names, path_min, path_max, strict=True)]

    def title(self, geometry, seconds):
        return f"analytic import: {len(geometry.muscles)} muscles"


@pytest.fixture(scope="module")
def result(tmp_path_factory):
    out = tmp_path_factory.mktemp("analytic")
    source = Analytic()
    printed = io.StringIO()
    result = import_paths(source, out, FitOptions(degree=3, samples=200),
                          ImportChoices(specific_tension_option("rajagopal")), file=printed)
    return source, result, out, printed.getvalue()


def test_crossing_skip_and_flags(result):
    _, imported, out, printed = result
    geometry = load_geometry(out / "geometry.yaml")
    assert geometry.muscle_names == ("lin", "quad", "jump")
    crossed = {m.name: m.coordinates for m in geometry.muscles}
    assert crossed == {"lin": ("elbow",), "quad": ("elbow", "slide"), "jump": ("elbow",)}
    assert imported.skipped == {"none": "constant length"}
    assert "skipped 1 muscle(s) that cross no coordinate: none" in printed
    flags = {m.name: m.fit.flags for m in geometry.muscles}
    assert "discontinuous" in flags["jump"] and "poor_fit" in flags["jump"]
    assert flags["lin"] == () and flags["quad"] == ()


def test_fitted_paths_reproduce_the_analytic_ones(result):
    _, _, out, _ = result
    geometry = load_geometry(out / "geometry.yaml")
    rng = np.random.default_rng(3)
    for q in np.column_stack([rng.uniform(-1, 1, 50), rng.uniform(0, 0.1, 50)]):
        length, gradient = geometry.lengths_and_gradients(q)
        exact, exact_gradient = analytic(q)
        np.testing.assert_allclose(length[:2], exact[:2], atol=1e-9)
        np.testing.assert_allclose(gradient[:2], exact_gradient[:2], atol=1e-8)


def test_extremes_and_library(result):
    source, _, out, _ = result
    low, high = source.extremes["lin"]
    assert (low, high) == pytest.approx((0.28, 0.32), abs=1e-12)   # 0.30 -+ 0.02, elbow -1..1
    library = yaml.safe_load((out / "muscles.yaml").read_text())["muscles"]
    assert list(library) == ["lin", "quad", "jump"]
    assert library["lin"]["l0_m"] == 0.1 and "analytic paths" in library["lin"]["source"]["l0_m"]
