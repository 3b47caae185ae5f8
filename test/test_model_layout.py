"""The step's declared layout (vm_ros.model.layout) and phases (vm_ros.model.phases) against the
code that uses them, and the kernel run as plain Python against the NumPy step.

These tests need no Numba: the kernel's Python function (``kernel._advance_series``) runs uncompiled
with the same arguments the compiled one gets. Uncompiled it evaluates the same equation functions
in the same order on the same float64 numbers, so after 300 steps it equals the NumPy step to
rounding (measured 2026-11-30: equal to the bit, every field, scheme and recovery mode; 3.4e-15 of a
field's largest value with the earlier scalar kernel); held here to 1e-13. An error in an equation
or in the order of the phases shows up far above that.
"""

from __future__ import annotations

import dataclasses
import inspect
import pickle
import re
import types
import warnings

import numpy as np
import pytest

from vm_ros.errors import InputError
from vm_ros.model import SCHEMES, BankState, MuscleBank, Phase, StepRecord, kernel, layout
from vm_ros.model.compiled_step import CompiledStep, KernelConstants
from vm_ros.model.numpy_step import NumpyStep
from vm_ros.model.reference import absolute_scale, pack_state
from vm_ros_bench import model_bench

DT = 1e-3
RELATIVE = 1e-13


def test_kernel_signatures_follow_the_declaration():
    names = tuple(inspect.signature(kernel._advance_series).parameters)
    assert names == layout.kernel_parameters()
    if kernel.AVAILABLE:
        assert kernel.advance_series.py_func is kernel._advance_series


def test_records_and_state_follow_the_declaration():
    assert [f.name for f in dataclasses.fields(BankState)] == ["time_s", *layout.STATE_NAMES]
    assert StepRecord._fields == tuple(a.name for a in layout.OUTPUTS)
    assert [f.name for f in dataclasses.fields(KernelConstants)] == [
        a.name for a in layout.CONSTANTS
    ]
    for declared in (*layout.STATE, *layout.OUTPUTS, *layout.CONSTANTS):
        doc = {**dict.fromkeys(layout.STATE, BankState.__doc__),
               **dict.fromkeys(layout.OUTPUTS, StepRecord.__doc__)}.get(
            declared, KernelConstants.__doc__)
        assert f"| {declared.name} | " in doc and declared.unit in doc


def test_state_shapes_reset_and_set_state_come_from_the_declaration():
    bank = MuscleBank.from_config(["vasti", "soleus"], recruitment="natural", units_per_type=3,
                                  backend="numpy")
    lp = bank.l0_m + bank.l0t_m
    bank.reset(lp, excitation=0.3)
    state = bank.state
    sizes = {"n": 2, "P": 6}
    for declared in layout.STATE:
        assert getattr(state, declared.name).shape == declared.shape_for(sizes)
    assert pack_state(state).size == absolute_scale(bank, state).size
    copied = pickle.loads(pickle.dumps(state))
    np.testing.assert_array_equal(copied.sag, state.sag)
    wrong = dataclasses.replace(state, recovery_filter=np.zeros((2, 2)))
    with pytest.raises(ValueError, match=r"state\.recovery_filter has shape \(2, 2\)"):
        bank.set_state(wrong)


def test_a_missing_kernel_constant_is_an_error_naming_it():
    with pytest.raises(layout.MissingConstantError, match=r"shared\.fmin"):
        layout.table("shared", layout.S, 1, [{}])
    bank = MuscleBank.from_config(["vasti"], backend="numpy")
    p = bank.params
    generic = {f.name: getattr(p.generic, f.name) for f in dataclasses.fields(p.generic)}
    generic["viscosity"] = generic.pop("eta")  # a renamed model parameter
    renamed = types.SimpleNamespace(**{name: getattr(bank, name) for name in (
        "equations", "geometry", "recruitment", "ur", "fpcsa", "recovery_mode", "n", "n_pools")})
    renamed.params = types.SimpleNamespace(
        generic=types.SimpleNamespace(**generic), energetics=p.energetics, lumped=p.lumped,
        continuous=p.continuous, fibre=p.fibre)
    with pytest.raises(layout.MissingConstantError, match=r"shared\.eta"):
        KernelConstants.from_bank(renamed)


def _phase_labels(source: str) -> list:
    return [(int(number), name) for number, name in re.findall(r"# Phase (\d+), ([A-Z_]+)", source)]


def test_both_executors_run_every_phase_once_in_order():
    expected = [(p.value, p.name) for p in Phase]
    numpy_source = inspect.getsource(NumpyStep.advance_activation) + inspect.getsource(
        NumpyStep.step)
    assert _phase_labels(numpy_source) == expected
    kernel_source = "".join(inspect.getsource(loop) for loop in kernel.PHASE_LOOPS)
    assert _phase_labels(kernel_source) == expected


def _uncompiled(bank) -> CompiledStep:
    """The kernel as plain Python, fed by the same glue as the compiled one."""
    return CompiledStep(KernelConstants.from_bank(bank), bank.n,
                        advance_series=kernel._advance_series)


def _assert_equal_to_rounding(a, b, name):
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    scale = float(np.max(np.abs(b))) if b.size else 0.0
    np.testing.assert_allclose(a, b, rtol=0.0, atol=RELATIVE * scale + 1e-300, err_msg=name)


@pytest.mark.parametrize("recovery_mode", ["static", "dynamic"])
@pytest.mark.parametrize("scheme", SCHEMES)
def test_uncompiled_kernel_equals_numpy_step(scheme, recovery_mode):
    units = 3 if scheme == "natural" else None
    bank = model_bench.library_bank(4, scheme, "numpy", units, recovery_mode=recovery_mode)
    lp0 = bank.l0_m + bank.l0t_m
    bank.reset(lp0, excitation=np.full(bank.n, 0.2))
    python_kernel = _uncompiled(bank)
    state = bank.state
    phase = np.arange(bank.n)
    for k in range(300):
        u = 0.5 + 0.6 * np.sin(0.02 * k + phase)  # exceeds [0, 1]: the clipping too
        lp = lp0 + 0.015 * np.sin(0.05 * k + phase)
        vp = 0.015 * 0.05 / DT * np.cos(0.05 * k + phase)
        out = bank.step(DT, u, lp, vp)
        state, record = python_kernel.step(state, DT, u, lp, vp)
    for declared in layout.STATE:
        _assert_equal_to_rounding(getattr(state, declared.name),
                                  getattr(bank.state, declared.name), declared.name)
    for name, value in record._asdict().items():
        _assert_equal_to_rounding(value, getattr(out.record, name), name)
    assert state.time_s == bank.time_s
    assert np.max(out.force / bank.f0) > 0.2  # the comparison covered active states


def test_uncompiled_series_equals_uncompiled_steps():
    bank = model_bench.library_bank(2, "lumped", "numpy", recovery_mode="dynamic")
    lp0 = bank.l0_m + bank.l0t_m
    bank.reset(lp0, excitation=np.full(bank.n, 0.3))
    k = 20
    u = np.linspace(0.1, 0.9, k)[:, None] * np.ones(bank.n)
    lp = np.tile(lp0, (k, 1))
    vp = np.zeros((k, bank.n))
    status, end, series, length, _, snapshots = _uncompiled(bank).series(
        bank.state, DT, u, lp, vp, snapshot_every=6)
    assert status == 0
    assert [len(a) for a in snapshots] == [3] * len(layout.STATE)  # steps 6, 12, 18 of 20
    stepper, state = _uncompiled(bank), bank.state
    for row in range(k):
        state, record = stepper.step(state, DT, u[row], lp[row], vp[row])
        np.testing.assert_array_equal(length[row], state.fascicle_length_m)
        if (row + 1) % 6 == 0:
            for declared, snapshot in zip(layout.STATE, snapshots, strict=True):
                np.testing.assert_array_equal(snapshot[(row + 1) // 6 - 1],
                                              getattr(state, declared.name), declared.name)
    np.testing.assert_array_equal(series.row(-1).force, record.force)
    np.testing.assert_array_equal(end.energy_j, state.energy_j)


@pytest.mark.parametrize("backend", ["numba", "numpy"])
def test_run_snapshots_are_the_states_step_reaches(backend):
    """run(..., snapshot_every=m): the state at the end of steps m, 2m, ... is the state that
    repeated step() reaches there, to the bit, and the snapshots' times are the steps' times."""
    if backend == "numba" and not kernel.AVAILABLE:
        pytest.skip("Numba is not installed: no compiled back end")
    bank = model_bench.library_bank(3, "lumped", backend, recovery_mode="dynamic")
    lp0 = bank.l0_m + bank.l0t_m
    k = 50
    u = 0.5 + 0.5 * np.sin(0.1 * np.arange(k))[:, None] * np.ones(bank.n)
    lp = lp0 + 0.01 * np.sin(0.07 * np.arange(k))[:, None]
    vp = np.gradient(lp, DT, axis=0)
    bank.reset(lp0)
    run = bank.run(DT, u, lp, vp, snapshot_every=7)
    assert run.snapshots.energy_j.shape == (7, bank.n, 2, 3)  # k // 7
    bank.reset(lp0)
    for row in range(k):
        bank.step(DT, u[row], lp[row], vp[row])
        if (row + 1) % 7 == 0:
            j = (row + 1) // 7 - 1
            assert run.snapshots.time_s[j] == bank.time_s
            for name in layout.STATE_NAMES:
                np.testing.assert_array_equal(getattr(run.snapshots, name)[j],
                                              getattr(bank.state, name), name)
    assert bank.run(DT, u, lp, vp).snapshots is None
    for bad in (-1, 1.5, True):
        with pytest.raises(InputError, match="snapshot_every"):
            bank.run(DT, u, lp, vp, snapshot_every=bad)


def test_old_fiber_names_warn_and_return_the_fibre_fields():
    bank = MuscleBank.from_config(["vasti"], backend="numpy")
    lp = bank.l0_m + bank.l0t_m
    bank.reset(lp, excitation=0.5)
    out = bank.step(DT, 0.5, lp)
    trajectory = bank.run(DT, np.full((3, 1), 0.5), np.tile(lp, (3, 1)))
    pairs = ((out, "energy_rate_by_fiber", "energy_rate_by_fibre"),
             (out, "energy_by_fiber", "energy_by_fibre"),
             (trajectory, "energy_rate_by_fiber", "energy_rate_by_fibre"))
    for record, old, new in pairs:
        with pytest.warns(DeprecationWarning, match=new):
            value = getattr(record, old)
        np.testing.assert_array_equal(value.as_array(), getattr(record, new).as_array())
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        _ = out.energy_rate_by_fibre, trajectory.energy_rate_by_fibre


def test_the_kernel_reads_polynomials_padded_to_a_fixed_length():
    """W_S's coefficients reach the kernel padded with leading zeros to POLY_TERMS (it reads them
    as a tuple of that length): the same values by Horner's rule; a longer one is refused."""
    from vm_ros.model.recruitment import polyval_horner

    coefficients = [1.56, -1.20, 0.884]
    padded = layout.padded_polynomial(coefficients)
    assert padded.shape == (layout.POLY_TERMS,)
    u = np.linspace(0.0, 1.0, 11)
    np.testing.assert_array_equal(polyval_horner(tuple(padded), u),
                                  polyval_horner(coefficients, u))
    with pytest.raises(ValueError, match="at most 8"):
        layout.padded_polynomial(np.ones(layout.POLY_TERMS + 1))


def test_one_function_maps_length_and_velocity_to_the_fibre_type_curves():
    """curves.fibre_type_curves[_and_slopes] is the one (L, V) -> FL, FV mapping: the NumPy
    step's, the published models' inputs and the kernel (uncompiled on its packed rows, and
    compiled by Numba) give the same values; FL(1) = FV(0) = 1 for both types."""
    from vm_ros.model import curves, mechanics
    from vm_ros.model.energetics_models.vm_state import fibre_curves

    bank = MuscleBank.from_config(["vasti"], backend="numpy")
    p = bank.params
    v, l = np.meshgrid(np.linspace(-6.0, 4.0, 11), np.linspace(0.4, 1.8, 29), indexing="ij")
    activity = np.array([[0.4, 0.7]])
    _, fl, fv = mechanics.contractile_force_normalised(l, v, activity, 1.3, p.fibre, p.generic)
    fl1, fv0 = curves.fibre_type_curves(np.ones((1, 1)), np.zeros((1, 1)),
                                        layout.type_columns(p.fibre),
                                        p.generic.fv_denominator_min)
    np.testing.assert_array_equal(np.concatenate([fl1, fv0], axis=None), [1.0] * 4)
    published = fibre_curves(l, v, p.fibre, p.generic)
    np.testing.assert_array_equal(published[0], fl)
    np.testing.assert_array_equal(published[1], fv)
    c = KernelConstants.from_bank(bank)
    s, rows, _ = kernel._tables_as_tuples(c.shared, c.fibre_type, c.w_slow_poly)
    terms = np.array([kernel._fibre_terms(a, b, 1.3, rows, s) for a, b in
                      zip(l.ravel(), v.ravel(), strict=True)])
    at = {"fl": (kernel.FL_SLOW, kernel.FL_FAST), "fv": (kernel.FV_SLOW, kernel.FV_FAST)}
    for name, expected in (("fl", fl), ("fv", fv)):
        got = terms[:, at[name]].reshape(expected.shape)
        _assert_equal_to_rounding(got, expected, f"uncompiled kernel {name}")
    if not kernel.AVAILABLE:
        return
    import numba

    @numba.njit
    def compiled(ls, vs, row, minimum):
        out = np.empty((ls.size, 5))
        for i in range(ls.size):
            out[i] = curves.fibre_type_curves_and_slopes(ls[i], vs[i], row, minimum)
        return out

    for t in (0, 1):
        got = compiled(l.ravel(), v.ravel(), rows[t], s[layout.S.fv_denominator_min])
        want = curves.fibre_type_curves_and_slopes(
            l.ravel(), v.ravel(), tuple(c.fibre_type[t]), p.generic.fv_denominator_min)
        for k in range(5):
            _assert_equal_to_rounding(got[:, k], want[k], f"compiled term {k} of type {t}")
