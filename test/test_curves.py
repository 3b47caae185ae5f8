"""Curves and activation relations against docs/model.md section 9's numbers and limits.

Expected values are computed by hand from the published constants (written out here), not taken
from the code's output.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from vm_ros.model import MuscleBank, curves
from vm_ros.model import activation as act
from vm_ros.model.params import FAST, SLOW, load_model_params, load_muscle_library

P = load_model_params()
F, G = P.fibre, P.generic


def test_force_length_is_one_at_optimum_and_falls_both_sides_asymmetrically():
    for t in (SLOW, FAST):
        assert curves.force_length_cheng2000(1.0, F.omega[t], F.beta[t], F.rho[t]) == 1.0
        short = curves.force_length_cheng2000(0.8, F.omega[t], F.beta[t], F.rho[t])
        long = curves.force_length_cheng2000(1.2, F.omega[t], F.beta[t], F.rho[t])
        assert short < 1 and long < 1 and abs(short - long) > 0.01


def test_force_length_matches_hand_value():
    # slow at L = 1.2: exp(-|(1.2^2.30 - 1)/1.12|^1.62)
    expected = math.exp(-abs((1.2**2.30 - 1) / 1.12) ** 1.62)
    assert curves.force_length_cheng2000(1.2, F.omega[SLOW], F.beta[SLOW], F.rho[SLOW]) == (
        pytest.approx(expected, rel=1e-12)
    )


def _fv(v, l, t):
    return curves.force_velocity_cheng2000(
        v, l, F.vmax[t], F.cv0[t], F.cv1[t], F.av0[t], F.av1[t], F.av2[t], F.bv[t],
        G.fv_denominator_min,
    )


@pytest.mark.parametrize("l", [0.7, 1.0, 1.3])
def test_force_velocity_is_one_when_isometric(l):
    for t in (SLOW, FAST):
        assert _fv(0.0, l, t) == pytest.approx(1.0, abs=1e-15)


@pytest.mark.parametrize(("t", "v_half"), [(SLOW, -1.00), (FAST, -1.67)])
def test_half_force_velocity_matches_the_published_value(t, v_half):
    # V0.5 = Vmax / (cV0 + cV1 + 2) at L = 1 (docs/model.md section 9): FV(V0.5) = 0.5
    assert F.vmax[t] / (F.cv0[t] + F.cv1[t] + 2) == pytest.approx(v_half, abs=0.005)
    assert _fv(v_half, 1.0, t) == pytest.approx(0.5, abs=0.003)


def test_force_velocity_zero_at_vmax_and_above_one_when_lengthening():
    for t in (SLOW, FAST):
        assert _fv(F.vmax[t], 1.0, t) == pytest.approx(0.0, abs=1e-12)
        assert _fv(0.5, 1.0, t) > 1.0


def test_fast_fv_denominator_guard_keeps_values_finite_at_short_lengths():
    v = np.linspace(-30, 0, 301)
    values = _fv(v[:, None], np.array([0.4, 0.5, 0.6])[None, :], FAST)
    assert np.all(np.isfinite(values))
    assert np.all(np.abs(values) < 100)


def test_activation_frequency_at_unit_rate_is_0509():
    for t in (SLOW, FAST):
        af = curves.activation_frequency_brown1999(1.0, 1.0, 1.0, 1.0, F.af[t], F.nf0[t], F.nf1[t])
        assert af == pytest.approx(1 - math.exp(-((1 / (0.56 * 2.1)) ** 2.1)), rel=1e-12)
        assert af == pytest.approx(0.509, abs=0.0005)


def test_activation_frequency_monotone_in_rate_and_zero_at_rest():
    f = np.linspace(0, 3, 61)
    af = curves.activation_frequency_brown1999(f, 1.0, 1.0, 1.0, F.af[SLOW], F.nf0[SLOW],
                                               F.nf1[SLOW])
    assert af[0] == 0.0
    assert np.all(np.diff(af) > 0)


def test_nf_zero_length_is_clamped():
    # nf = 0 at L = nf1/(nf1-nf0): 1.72 slow, 2.75 fast
    for t, l_zero in ((SLOW, 1.724), (FAST, 2.75)):
        assert F.nf1[t] / (F.nf1[t] - F.nf0[t]) == pytest.approx(l_zero, abs=0.001)
        l_max = act.activation_length_max(F.nf0[t], F.nf1[t], G.l_activation_max_fraction)
        # the clamp never binds in the physiological range: beyond every library muscle's Lmax
        longest = float(MuscleBank.from_config(list(load_muscle_library())).lmax.max())
        assert longest < l_max < l_zero
        # 5 % inside the published nf-zero length (docs/model.md section 3), where nf > 0 and
        # Af is a proper fraction; at l_zero itself nf = 0 and Af is not defined
        assert l_max == pytest.approx(0.95 * l_zero, abs=0.002)
        af = curves.activation_frequency_brown1999(1.0, l_max, 1.0, 1.0, F.af[t], F.nf0[t],
                                                   F.nf1[t])
        assert 0.0 < af < 1.0
        # by hand: nf = 2.1 + nf1 (1/l_max - 1), Af = 1 - exp(-(1 / (0.56 nf))^nf)
        assert af == pytest.approx({SLOW: 0.76673, FAST: 0.70916}[t], abs=1e-4)


def test_the_step_clips_the_activation_length_to_the_published_limits():
    from vm_ros.model import MuscleBank

    equations = MuscleBank.from_config(["vasti"], backend="numpy").equations
    pools = equations.pool_length(np.array([0.1, 5.0]))
    slow = equations.recruitment.fibre_index == SLOW
    # l_activation_min 0.3; 0.95 x 5/2.9 (slow) and 0.95 x 3.3/1.2 (fast)
    np.testing.assert_allclose(pools[0], 0.3)
    np.testing.assert_allclose(pools[1], np.where(slow, 0.95 * 5 / 2.9, 0.95 * 3.3 / 1.2))


def test_tendon_force_is_f0_at_l0t_and_inverse_is_consistent():
    assert curves.tendon_force_cheng2000(1.0, G.ct, G.kt, G.lrt) == pytest.approx(1.0, abs=0.002)
    for force in (0.01, 0.5, 1.0, 2.0):
        l_se = curves.tendon_length_at_force(force, G.ct, G.kt, G.lrt)
        assert curves.tendon_force_cheng2000(l_se, G.ct, G.kt, G.lrt) == pytest.approx(force)


def test_tendon_and_passive_elements_do_not_overflow():
    l_se = np.array([-5.0, 0.0, 1.0, 5.0, 50.0])
    assert np.all(np.isfinite(curves.tendon_force_cheng2000(l_se, G.ct, G.kt, G.lrt)))
    l = np.array([0.0, 0.1, 1.0, 3.0, 30.0])
    assert np.all(np.isfinite(curves.passive_parallel_elastic_cheng2000(
        l, 0.0, 1.3, G.c1, G.k1, G.lr1, G.eta)))
    pe2 = curves.thick_filament_compression_cheng2000(l, G.c2, G.k2, G.lr2)
    assert np.all(np.isfinite(pe2)) and np.all(pe2 <= 0)
    assert pe2[2] == 0.0  # no compression at L0


def test_firing_envelope_linear_from_fmin_to_fmax():
    uth = 0.32
    assert act.firing_envelope(0.31, uth, 0.5, 2.0) == 0.0
    assert act.firing_envelope(uth, uth, 0.5, 2.0) == pytest.approx(0.5)
    assert act.firing_envelope(1.0, uth, 0.5, 2.0) == pytest.approx(2.0)
    assert act.firing_envelope(0.66, uth, 0.5, 2.0) == pytest.approx(0.5 + 1.5 * 0.34 / 0.68)


def test_rise_is_faster_than_fall_at_l0():
    for t in (SLOW, FAST):
        rise = act.rise_fall_time_constant(1.0, 1.0, 0.5, 1.0, 0.5, F.tf1[t], F.tf2[t], F.tf3[t],
                                           F.tf4[t])
        fall = act.rise_fall_time_constant(0.0, 0.0, 0.5, 1.0, 0.5, F.tf1[t], F.tf2[t], F.tf3[t],
                                           F.tf4[t])
        # rise at f_env = 0 is Tf1 (34.3 / 20.6 ms); fall is Tf3 + Tf4 Af (47.0 / 28.2 ms + ...)
        assert rise == pytest.approx(F.tf1[t] + F.tf2[t])
        assert act.rise_fall_time_constant(0.0, 1.0, 0.5, 1.0, 0.0, F.tf1[t], F.tf2[t], F.tf3[t],
                                           F.tf4[t]) == pytest.approx(F.tf1[t])
        assert F.tf1[t] < fall


@pytest.mark.parametrize("t", [SLOW, FAST])
def test_firing_rate_rises_faster_than_it_falls_at_low_rates(t):
    """Brown & Loeb 2000: at a low rate (f_env = fmin) the rise/fall filter reaches half its
    target sooner than it decays to half (Tf1 L^2 + Tf2 fmin < Tf3 + Tf4 Af)."""
    dt, f_target = 1e-4, G.fmin

    def half_time(f_env, start):
        f_int = f_eff = start
        for k in range(20000):
            af = curves.activation_frequency_brown1999(f_eff, 1.0, 1.0, 1.0, F.af[t], F.nf0[t],
                                                       F.nf1[t])
            tf = act.rise_fall_time_constant(f_env, f_int, f_eff, 1.0, af, F.tf1[t], F.tf2[t],
                                             F.tf3[t], F.tf4[t])
            f_int, f_eff = act.cascade_step(f_int, f_eff, f_env, tf, dt)
            if abs(f_eff - start) >= 0.5 * f_target:
                return k * dt
        raise AssertionError("did not reach half")

    assert half_time(f_target, 0.0) < 0.97 * half_time(0.0, f_target)


def test_lag_step_matches_closed_form():
    y = act.lag_step(0.0, 1.0, 0.05, 0.01)
    assert y == pytest.approx(1 - math.exp(-0.2), rel=1e-14)


def test_cascade_step_matches_two_stage_closed_form():
    # y1 = 1 - e^{-t/T}; y2 = 1 - (1 + t/T) e^{-t/T} from rest, target 1
    tau, t = 0.04, 0.03
    y1, y2 = act.cascade_step(0.0, 0.0, 1.0, tau, t)
    assert y1 == pytest.approx(1 - math.exp(-t / tau), rel=1e-14)
    assert y2 == pytest.approx(1 - (1 + t / tau) * math.exp(-t / tau), rel=1e-14)
    # composing steps equals one long step (exact for constant target and tau)
    a = (0.2, 0.1)
    for _ in range(10):
        a = act.cascade_step(*a, 1.0, tau, t / 10)
    b = act.cascade_step(0.2, 0.1, 1.0, tau, t)
    assert a == pytest.approx(b, rel=1e-12)


def test_yield_and_sag_targets():
    assert act.yield_target(0.0, F.cy[SLOW], F.vy[SLOW]) == 1.0
    assert act.yield_target(10.0, F.cy[SLOW], F.vy[SLOW]) == pytest.approx(1 - 0.35, abs=1e-6)
    assert act.yield_target(10.0, F.cy[FAST], F.vy[FAST]) == 1.0
    assert act.sag_target(0.05, F.as1[FAST], F.as2[FAST], F.sag_rate_threshold[FAST]) == 1.76
    assert act.sag_target(1.0, F.as1[FAST], F.as2[FAST], F.sag_rate_threshold[FAST]) == 0.96
    assert act.sag_target(1.0, F.as1[SLOW], F.as2[SLOW], F.sag_rate_threshold[SLOW]) == 1.0


def test_time_constants_are_loaded_in_seconds():
    assert F.tf1[SLOW] == pytest.approx(0.0343)
    assert F.ts[FAST] == pytest.approx(0.043)
    assert F.ty[SLOW] == pytest.approx(0.2)
    assert G.specific_tension == pytest.approx(31.8e4)
    assert G.muscle_density == pytest.approx(1060.0)


def _central_difference(f, x, h):
    return (f(x + h) - f(x - h)) / (2.0 * h)


@pytest.mark.parametrize("t", [SLOW, FAST])
def test_slopes_match_central_differences(t):
    """The analytic slopes the step's Jacobian uses equal central differences of the curves
    (relative 1e-6; away from the kinks at V = 0 and at the FV denominator bound)."""
    g = P.generic
    l = np.linspace(0.55, 1.6, 23)
    fl = lambda x: curves.force_length_cheng2000(x, F.omega[t], F.beta[t], F.rho[t])  # noqa: E731
    _, dfl = curves.force_length_and_slope_cheng2000(l, F.omega[t], F.beta[t], F.rho[t])
    np.testing.assert_allclose(dfl, _central_difference(fl, l, 1e-6), rtol=1e-6, atol=1e-8)
    fv_args = (F.vmax[t], F.cv0[t], F.cv1[t], F.av0[t], F.av1[t], F.av2[t], F.bv[t],
               g.fv_denominator_min)
    for v in (-3.0, -0.7, -0.05, 0.05, 0.4, 2.0):
        dv, dl = curves.force_velocity_slopes_cheng2000(v, l, *fv_args)
        num_dv = _central_difference(lambda x: curves.force_velocity_cheng2000(x, l, *fv_args),
                                     v, 1e-7)
        num_dl = _central_difference(lambda x, v=v: curves.force_velocity_cheng2000(v, x, *fv_args),
                                     l, 1e-7)
        np.testing.assert_allclose(dv, num_dv, rtol=1e-6, atol=1e-8)
        np.testing.assert_allclose(dl, num_dl, rtol=1e-6, atol=1e-8)
    lmax = 1.3
    pe1 = lambda x: curves.passive_parallel_elastic_cheng2000(x, 0.0, lmax, g.c1, g.k1, g.lr1,  # noqa: E731
                                                               g.eta)
    np.testing.assert_allclose(
        curves.passive_parallel_elastic_and_slope_cheng2000(l, 0.0, lmax, g.c1, g.k1, g.lr1,
                                                            g.eta)[1],
        _central_difference(pe1, l, 1e-6), rtol=1e-6, atol=1e-8)
    short = np.linspace(0.3, 0.69, 9)  # PE2 acts below Lr2 = 0.70
    pe2 = lambda x: curves.thick_filament_compression_cheng2000(x, g.c2, g.k2, g.lr2)  # noqa: E731
    np.testing.assert_allclose(
        curves.thick_filament_compression_and_slope_cheng2000(short, g.c2, g.k2, g.lr2)[1],
        _central_difference(pe2, short, 1e-7), rtol=1e-6, atol=1e-8)
    assert np.all(curves.thick_filament_compression_and_slope_cheng2000(l[l > 0.71], g.c2, g.k2,
                                                                        g.lr2)[1] == 0.0)
    l_se = np.linspace(0.94, 1.03, 19)
    fse = lambda x: curves.tendon_force_cheng2000(x, g.ct, g.kt, g.lrt)  # noqa: E731
    np.testing.assert_allclose(curves.tendon_force_and_stiffness_cheng2000(l_se, g.ct, g.kt,
                                                                           g.lrt)[1],
                               _central_difference(fse, l_se, 1e-8), rtol=1e-6, atol=1e-6)


def test_logistic_is_finite_and_symmetric_for_large_arguments():
    x = np.array([-1e4, -50.0, 0.0, 50.0, 1e4])
    e = np.exp(-np.abs(x))
    y = curves.logistic_from_exp(x, e)
    assert np.all(np.isfinite(y))
    np.testing.assert_allclose(y + curves.logistic_from_exp(-x, e), 1.0, rtol=1e-15)
    assert y[2] == 0.5
