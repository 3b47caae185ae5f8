"""MuscleBank behaviour: API, inputs, robustness, and the physiology that must emerge."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from vm_ros.errors import InputError
from vm_ros.model import SCHEMES, MuscleBank, load_model_params
from vm_ros.model.params import SLOW

DT = 1e-3
MUSCLES = ["vasti", "rectus_femoris", "soleus", "biceps_long_head"]


def rest_path_length(bank, l=1.0, force_f0=0.0):
    """Path length putting the fascicle at ``l`` L0 with the tendon near ``force_f0``."""
    from vm_ros.model.curves import tendon_length_at_force

    g = bank.params.generic
    return bank.l0_m * l + bank.l0t_m * tendon_length_at_force(max(force_f0, 1e-3), g.ct, g.kt,
                                                               g.lrt)


def run(bank, seconds, u, lp, vp=None):
    outs = []
    for _ in range(int(round(seconds / DT))):
        outs.append(bank.step(DT, u, lp, vp))
    return outs


def test_api_shapes_and_units():
    bank = MuscleBank.from_config(MUSCLES)
    n = len(MUSCLES)
    assert bank.names == tuple(MUSCLES)
    assert bank.f0.shape == (n,) and np.all(bank.f0 > 0)
    # F0 = 31.8 N/cm^2 * mass / (1.06 g/cm^3 * L0)
    assert bank.f0 == pytest.approx(31.8e4 * bank.mass_kg / (1060.0 * bank.l0_m))
    lp = rest_path_length(bank)
    bank.reset(path_length=lp)
    out = bank.step(DT, excitation=np.full(n, 0.5), path_length=lp)
    assert out.time_s == pytest.approx(DT)
    for name in ("force", "fascicle_length", "fascicle_velocity", "mechanical_power"):
        assert getattr(out, name).shape == (n,)
    assert out.energy_rate.total.shape == (n,)
    assert out.energy_rate_by_fibre.total.shape == (n, 2)
    assert out.firing_rate_f05.shape == (n, 2)
    assert out.fascicle_length == pytest.approx(out.length_l0 * bank.l0_m)


def test_step_before_reset_is_a_clear_error():
    bank = MuscleBank.from_config(["soleus"])
    with pytest.raises(RuntimeError, match="reset"):
        bank.step(DT, [0.1], [0.3])


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"excitation": [np.nan, 0.1]}, "excitation"),
        ({"excitation": [0.1, 0.2, 0.3]}, "excitation"),
        ({"path_length": [np.inf, 0.3]}, "path_length"),
        ({"path_length": [-0.1, 0.3]}, "path_length"),
        ({"path_velocity": [0.0, np.nan]}, "path_velocity"),
    ],
)
def test_bad_inputs_raise_and_leave_state_untouched(kwargs, name):
    bank = MuscleBank.from_config(["vasti", "soleus"])
    lp = rest_path_length(bank)
    bank.reset(lp)
    bank.step(DT, [0.3, 0.3], lp)
    before = bank.state
    args = {"excitation": [0.5, 0.5], "path_length": lp, "path_velocity": None, **kwargs}
    with pytest.raises(InputError) as info:
        bank.step(DT, **args)
    assert info.value.name == name
    after = bank.state
    for f in dataclasses.fields(before):
        assert np.array_equal(getattr(before, f.name), getattr(after, f.name))
    with pytest.raises(InputError):
        bank.step(0.0, [0.5, 0.5], lp)


@pytest.mark.parametrize("backend", ["numba", "numpy"])
def test_a_restore_point_is_left_as_it_was_and_restores_the_run(backend):
    """restore_point() is the state object itself (no copy): step and run must replace the
    state, never write into it, so that set_state() can go back to it (muscle_node does before
    a batch)."""
    bank = MuscleBank.from_config(["vasti", "soleus"], backend=backend)
    lp = rest_path_length(bank)
    bank.reset(lp)
    bank.step(DT, [0.3, 0.3], lp)
    point, copy = bank.restore_point(), bank.state
    u = np.tile([0.6, 0.2], (20, 1))
    first = bank.run(DT, u, np.tile(lp, (20, 1)))
    bank.step(DT, [0.9, 0.9], lp)
    for f in dataclasses.fields(copy):
        assert np.array_equal(getattr(point, f.name), getattr(copy, f.name)), f.name
    bank.set_state(point)
    again = bank.run(DT, u, np.tile(lp, (20, 1)))
    assert np.array_equal(again.force, first.force)


def test_drive_is_clipped_to_unit_interval():
    bank = MuscleBank.from_config(["soleus"])
    lp = rest_path_length(bank)
    bank.reset(lp)
    out = bank.step(DT, [7.0], lp)
    assert out.excitation[0] == 1.0
    out = bank.step(DT, [-3.0], lp)
    assert out.excitation[0] == 0.0


@pytest.mark.parametrize("scheme", SCHEMES)
def test_no_nan_over_a_grid_of_drive_length_and_velocity(scheme):
    bank = MuscleBank.from_config(["vasti", "first_dorsal_interosseous", "soleus"],
                                  recruitment=scheme, units_per_type=4)
    base = rest_path_length(bank)
    for u in (0.0, 0.05, 0.3, 0.7, 1.0):
        for l_factor in (0.6, 1.0, 1.35):
            for v_l0 in (-8.0, -1.0, 0.0, 2.0):
                lp = base + (l_factor - 1.0) * bank.l0_m
                bank.reset(lp, excitation=np.full(3, u))
                vp = v_l0 * bank.l0_m
                for k in range(40):
                    out = bank.step(DT, np.full(3, u), lp + k * DT * vp, vp)
                values = [out.force, out.contractile_force, out.fascicle_length,
                          out.energy_rate_by_fibre.as_array(), out.mechanical_power]
                assert all(np.all(np.isfinite(v)) for v in values), (u, l_factor, v_l0)
                assert np.all(out.force >= 0) and np.all(out.energy_rate.total >= 0)


@pytest.mark.parametrize("scheme", SCHEMES)
def test_tetanic_isometric_force_at_l0_approaches_f0(scheme):
    bank = MuscleBank.from_config(MUSCLES, recruitment=scheme, units_per_type=20)
    lp = rest_path_length(bank, l=1.0, force_f0=0.95)
    out = bank.reset(lp, excitation=np.ones(len(MUSCLES)))
    # Af(f = fmax = 2 f0.5, L = 1) = 1 - exp(-(2/(0.56*2.1))^2.1) = 0.953; sag 0.96 in fast
    assert np.all(np.abs(out.length_l0 - 1.0) < 0.03)
    assert np.all(out.force / bank.f0 > 0.92) and np.all(out.force / bank.f0 < 1.03)


@pytest.mark.parametrize("scheme", SCHEMES)
def test_steady_isometric_force_is_monotone_in_drive(scheme):
    bank = MuscleBank.from_config(MUSCLES, recruitment=scheme, units_per_type=10)
    lp = rest_path_length(bank, l=1.0, force_f0=0.5)
    forces = np.array([bank.reset(lp, excitation=np.full(len(MUSCLES), u)).force
                       for u in np.linspace(0, 1, 51)])
    assert np.all(np.diff(forces, axis=0) >= -1e-9 * bank.f0)
    assert np.all(forces[-1] > 20 * forces[0])


def _with_fibre(params, **changes):
    return dataclasses.replace(params, fibre=dataclasses.replace(params.fibre, **changes))


def test_sag_is_visible_in_fast_fibre_force_at_low_rates():
    params = load_model_params()
    no_sag = _with_fibre(params, as1=np.ones(2), as2=np.ones(2))
    overrides = {"vastus_lateralis": {"fpcsa_slow": 0.0}}
    traces = []
    for p in (params, no_sag):
        bank = MuscleBank.from_config(["vastus_lateralis"], recruitment="natural", params=p,
                                      overrides=overrides, units_per_type=10)
        lp = rest_path_length(bank, force_f0=0.1)
        bank.reset(lp)
        traces.append(np.array([o.force[0] for o in run(bank, 0.8, [0.1], lp)]))
    with_sag, without = traces
    # S starts at aS1 = 1.76 and decays to aS2 = 0.96 (tau 43 ms) once f_eff > 0.1 f0.5: force
    # rises faster than without sag, peaks, then sags to below the no-sag plateau (by ~4 %:
    # Af at the low rate scales with (S f)^nf, and 0.96^2.1 = 0.92).
    assert with_sag[80] > 1.5 * without[80]
    assert with_sag.max() > 1.005 * with_sag[-1]
    assert with_sag[-1] < 0.97 * without[-1]


def test_yield_lowers_slow_fibre_force_when_stretched_at_submaximal_drive():
    params = load_model_params()
    no_yield = _with_fibre(params, cy=np.zeros(2))
    overrides = {"soleus": {"fpcsa_slow": 1.0}}
    results = []
    for p in (params, no_yield):
        bank = MuscleBank.from_config(["soleus"], params=p, recruitment="natural",
                                      overrides=overrides, units_per_type=10)
        lp = rest_path_length(bank, force_f0=0.2)
        bank.reset(lp, excitation=[0.3])
        amplitude, freq = 0.05 * bank.l0_m[0], 2.0
        for k in range(1000):
            t = k * DT
            bank.step(DT, [0.3], lp + amplitude * np.sin(2 * np.pi * freq * t),
                      [amplitude * 2 * np.pi * freq * np.cos(2 * np.pi * freq * t)])
        out = bank.step(DT, [0.3], lp)
        results.append((out.force[0], bank.state.yield_factor[0, 0]))
    (f_yield, y), (f_plain, y_plain) = results
    assert y < 0.9 and y_plain == pytest.approx(1.0)
    assert f_yield < 0.95 * f_plain


def test_pure_slow_and_pure_fast_muscles_work_in_every_scheme():
    for scheme in SCHEMES:
        for fs in (0.0, 1.0):
            bank = MuscleBank.from_config(["soleus"], recruitment=scheme, units_per_type=5,
                                          overrides={"soleus": {"fpcsa_slow": fs}})
            lp = rest_path_length(bank, force_f0=0.5)
            bank.reset(lp)
            out = run(bank, 0.5, [0.8], lp)[-1]
            assert np.isfinite(out.force[0]) and out.force[0] > 0.3 * bank.f0[0]
            absent = 1 if fs == 1.0 else 0
            assert out.effective_activation[0, absent] == 0.0
            assert out.energy_rate_by_fibre.total[0, absent] == 0.0
            assert out.energy_rate_by_fibre.total[0, 1 - absent] > 0.0


def test_lumped_slow_fibres_are_recruited_first():
    bank = MuscleBank.from_config(["vasti"])
    lp = rest_path_length(bank, force_f0=0.3)
    out = bank.reset(lp, excitation=[0.3])  # below U2 = 0.8 * 0.5 = 0.4 (vasti ~50 % slow)
    assert bank.fpcsa[0, SLOW] * bank.ur[0] > 0.3
    assert out.effective_activation[0, 0] > 0 and out.effective_activation[0, 1] == 0.0


def test_replicated_copies_step_as_their_originals():
    """A bank of 3 copies of two muscles, given each copy its own drive, gives every copy the
    force of the original muscle stepped alone at that drive."""
    bank = MuscleBank.from_config(["soleus", "tibialis_anterior"])
    copies = bank.replicated(3)
    assert copies.names == bank.names * 3
    drives = np.array([0.1, 0.2, 0.5, 0.6, 0.9, 1.0])
    lengths = np.tile(rest_path_length(bank), 3)
    copies.reset(path_length=lengths, excitation=drives)
    together = copies.run(1e-3, np.tile(drives, (20, 1)), np.tile(lengths, (20, 1))).force[-1]
    for copy in range(3):
        part = slice(2 * copy, 2 * copy + 2)
        bank.reset(path_length=lengths[part], excitation=drives[part])
        alone = bank.run(1e-3, np.tile(drives[part], (20, 1)),
                         np.tile(lengths[part], (20, 1))).force[-1]
        np.testing.assert_allclose(together[part], alone, rtol=1e-12, atol=1e-9)
