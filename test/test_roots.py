"""vm_ros.model.roots (the model's bracketing root finder over arrays) against scipy.optimize.brentq
element by element, and the SciPy names the package uses against SciPy 1.10's."""

from __future__ import annotations

import ast
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import brentq

import vm_ros
from vm_ros.model import roots

TOL = 1e-12

# f(x; c) = 0 for several c per family; brackets with a sign change
FAMILIES = {
    "cubic": (lambda x, c: x**3 - 2.0 * x - c, np.array([0.5, 3.0, 5.0, 40.0, 55.0]), 0.0, 4.0),
    "exp": (lambda x, c: np.exp(x) - c, np.array([1e-3, 0.5, 1.0, 7.0, 1e4]), -10.0, 10.0),
    "tanh steep": (lambda x, c: np.tanh(200.0 * (x - c)), np.array([-0.7, 0.0, 0.31, 0.99]),
                   -1.0, 1.0),
    "step-like": (lambda x, c: np.arctan(1e6 * (x - c)), np.array([1e-9, 0.25, 0.5]), 0.0, 1.0),
}


@pytest.mark.parametrize("family", FAMILIES)
def test_roots_match_brentq_per_element(family):
    f, c, lower, upper = FAMILIES[family]
    calls = []

    def func(x, index):
        calls.append(index.size)
        return f(x, c[index])

    x = roots.find_root(func, np.full(c.size, lower), np.full(c.size, upper), xatol=TOL,
                        xrtol=TOL)
    expected = np.array([brentq(f, lower, upper, args=(ci,), xtol=TOL, rtol=4 * np.finfo(float).eps)
                         for ci in c])
    assert np.all(np.abs(x - expected) <= 2 * (TOL + TOL * np.abs(expected))), x - expected
    assert calls[0] == c.size and min(calls) >= 1


def test_no_sign_change_or_nan_gives_nan_and_a_zero_at_an_end_is_the_root():
    x = roots.find_root(lambda x, i: x - np.array([5.0, np.nan, 0.0, 1.0])[i],
                        np.zeros(4), np.ones(4), xatol=TOL, xrtol=TOL)
    assert np.isnan(x[0]) and np.isnan(x[1])
    assert x[2] == 0.0 and x[3] == 1.0


def test_each_element_is_evaluated_only_while_it_iterates():
    """An easy element stops early: later calls carry only the others."""
    seen = []

    def func(x, index):
        seen.append(set(index.tolist()))
        return np.where(index == 0, x - 0.5, np.tanh(50.0 * (x - 0.123456789)))

    roots.find_root(func, np.zeros(2), np.ones(2), xatol=TOL, xrtol=TOL)
    assert seen[2] == {0, 1} and seen[-1] == {1}


# Every SciPy name the installed package uses, each present in SciPy 1.10 (Debian 12's
# python3-scipy is 1.10.1; setup.py's lower bound).
# A static list, checked against SciPy 1.10.1's documentation when it was written, rather than an
# install of SciPy 1.10 in the test (minutes, and a wheel that may not build on a newer Python):
# a new SciPy import in vm_ros fails here until its name is checked and added.
SCIPY_1_10_NAMES = {
    ("scipy.integrate", "solve_ivp"),  # SciPy 1.0
    ("scipy", "integrate"),
    ("scipy.integrate", "trapezoid"),  # SciPy 1.6 (NumPy's np.trapezoid is NumPy 2.0)
    ("scipy.interpolate", "UnivariateSpline"),  # 0.x
    ("scipy.interpolate", "make_interp_spline"),  # 0.19
    ("scipy.optimize", "least_squares"),  # 0.17
    ("scipy.stats", "qmc"),  # 1.7
    ("scipy.stats.qmc", "LatinHypercube"),  # 1.7 (its rng= keyword is 1.15: seed= is used)
    ("scipy.stats.qmc", "scale"),  # 1.7
    # coordination: present in Debian 12's python3-scipy 1.10.1 (hasattr on its modules; linprog's
    # method="highs" is its default there)
    ("scipy", "optimize"),
    ("scipy", "sparse"),
    ("scipy.optimize", "linprog"),
    ("scipy.sparse", "csr_matrix"),
    ("scipy.sparse", "diags"),
    ("scipy.sparse", "identity"),
    ("scipy.sparse", "kron"),
    ("scipy.sparse", "vstack"),
    ("scipy.sparse", "linalg"),
    ("scipy.sparse.linalg", "spsolve"),
    ("scipy.sparse.csgraph", "connected_components"),
    # coordination's OSQP problems: in scipy/sparse/__init__.py, _construct.__all__ and
    # _extract.__all__ of the SciPy 1.10.1 wheel (read there)
    ("scipy.sparse", "csc_matrix"),
    ("scipy.sparse", "hstack"),
    ("scipy.sparse", "triu"),
    ("scipy.sparse", "block_diag"),
    # coordination targets' low-pass: filtfilt(b, a, x, axis, padtype='odd', padlen=3 max(len(a),
    # len(b))) and butter(N, Wn) as documented for SciPy 0.18-1.7 (docs.scipy.org), so in 1.10
    ("scipy", "signal"),
    ("scipy.signal", "butter"),
    ("scipy.signal", "filtfilt"),
}


def _scipy_names(source: str) -> set[tuple[str, str]]:
    """(module, name) of every ``from scipy... import name`` and of every attribute read from a
    SciPy module imported so (``qmc.scale``) or with ``import scipy...``."""
    tree = ast.parse(source)
    names, modules = set(), {}
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and (node.module or "").split(".")[0] == "scipy":
            for alias in node.names:
                names.add((node.module, alias.name))
                modules[alias.asname or alias.name] = f"{node.module}.{alias.name}"
        elif isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.split(".")[0] == "scipy":
                    names.add((alias.name, ""))
                    modules[alias.asname or alias.name] = alias.name
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and ast.unparse(node.value) in modules:
            names.add((modules[ast.unparse(node.value)], node.attr))
    return names


def test_the_package_uses_only_scipy_names_that_scipy_1_10_has():
    used = {}
    for path in sorted(Path(vm_ros.__file__).parent.rglob("*.py")):
        for name in _scipy_names(path.read_text(encoding="utf-8")):
            used.setdefault(name, path.name)
    assert used, "no SciPy import found: the scan is broken"
    unknown = {name: where for name, where in used.items() if name not in SCIPY_1_10_NAMES}
    assert not unknown, f"SciPy names not checked against SciPy 1.10: {unknown}"


def test_the_scan_sees_module_attributes_and_elementwise():
    source = ("from scipy.optimize import elementwise\nfrom scipy.stats import qmc\n"
              "import scipy.linalg as la\nqmc.Sobol(2)\nla.solve(a, b)\n")
    assert _scipy_names(source) == {("scipy.optimize", "elementwise"), ("scipy.stats", "qmc"),
                                    ("scipy.stats.qmc", "Sobol"), ("scipy.linalg", ""),
                                    ("scipy.linalg", "solve")}


# NumPy names that are new in NumPy 2.x (the NumPy 2.0 and 2.1 release notes: the array-API
# names and np.trapezoid; np.bool came back in 2.0 after its removal in 1.24): Debian 12's
# python3-numpy is 1.24.2, setup.py's lower bound 1.24, so the package must not read them.
NUMPY_2_ONLY = {"trapezoid", "concat", "permute_dims", "pow", "acos", "acosh", "asin", "asinh",
                "atan", "atan2", "atanh", "bitwise_left_shift", "bitwise_right_shift",
                "bitwise_invert", "vecdot", "matrix_transpose", "unique_all", "unique_counts",
                "unique_inverse", "unique_values", "isdtype", "astype", "cumulative_sum",
                "cumulative_prod", "long", "ulong", "bool", "unstack"}


def _numpy_attributes(source: str) -> set[str]:
    """Every attribute read from a name bound by ``import numpy`` (``np.trapezoid``)."""
    tree = ast.parse(source)
    aliases = {alias.asname or alias.name for node in ast.walk(tree)
               if isinstance(node, ast.Import) for alias in node.names
               if alias.name == "numpy"}
    return {node.attr for node in ast.walk(tree) if isinstance(node, ast.Attribute)
            and isinstance(node.value, ast.Name) and node.value.id in aliases}


def test_the_package_uses_no_numpy_name_that_numpy_1_24_lacks():
    used = {}
    for path in sorted(Path(vm_ros.__file__).parent.rglob("*.py")):
        for name in _numpy_attributes(path.read_text(encoding="utf-8")) & NUMPY_2_ONLY:
            used.setdefault(name, path.name)
    assert not used, f"NumPy 2 names (Debian 12 has NumPy 1.24): {used}"
    assert _numpy_attributes("import numpy as np\nnp.trapezoid(y, x)\n") == {"trapezoid"}
