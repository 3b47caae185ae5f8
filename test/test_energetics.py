"""Energetics (Tsianos 2012 STEPs 1-7, Appendix B) against published numbers and the paper.

Expected numbers are those of docs/model.md section 9 or computed here from the published
constants, never copied from the code's output.
"""

from __future__ import annotations

import numpy as np
import pytest

from vm_ros.errors import ConfigError
from vm_ros.model import MuscleBank, load_model_params
from vm_ros.model import energetics as en
from vm_ros.model.curves import tendon_length_at_force
from vm_ros.model.params import FAST, RECOVERY_KERNELS, SLOW

P = load_model_params()
E = P.energetics
DT = 1e-3


def barclay(v, t):
    """E_tet(V) written out from the published coefficients."""
    e = {SLOW: (-76.6, -792.0, 124.0, 0.72), FAST: (145.0, -3322.0, 1530.0, 1.45)}[t]
    return (e[0] * v**2 + e[1] * v + e[2]) / (e[3] - v)


def test_constants_match_spec_section_9():
    e_tet0 = en.tetanic_energy_rate_barclay1996(0.0, E.e1, E.e2, E.e3, E.e4)
    assert e_tet0 == pytest.approx([172.2, 1055.2], abs=0.05)
    e_a = en.activation_tetanic_rate_tsianos2012(E.e3, E.e4, E.activation_fraction)
    assert e_a == pytest.approx([56.8, 348.2], abs=0.05)
    e_xb0 = en.cross_bridge_tetanic_rate_tsianos2012(0.0, E.e1, E.e2, E.e3, E.e4,
                                                     E.activation_fraction, P.fibre.vmax)
    assert e_xb0 == pytest.approx([115.4, 707.0], abs=0.05)


@pytest.mark.parametrize(("t", "crossing"), [(SLOW, 0.134), (FAST, 0.452)])
def test_cross_bridge_rate_reaches_zero_at_the_lengthening_crossing(t, crossing):
    def xb(v):
        return en.cross_bridge_tetanic_rate_tsianos2012(
            v, E.e1[t], E.e2[t], E.e3[t], E.e4[t], E.activation_fraction, P.fibre.vmax[t])

    assert xb(crossing - 0.005) > 0
    assert xb(crossing + 0.005) == 0.0
    assert np.all(xb(np.linspace(crossing + 0.01, 5.0, 50)) == 0.0)
    # linear from V = 0 with the tangent of E_tet, slope (e2 e4 + e3)/e4^2, down to zero
    e = {SLOW: (-792.0, 124.0, 0.72), FAST: (-3322.0, 1530.0, 1.45)}[t]
    exact = -xb(0.0) / ((e[0] * e[2] + e[1]) / e[2] ** 2)
    assert exact == pytest.approx(crossing, abs=0.0005)
    assert xb(0.5 * exact) == pytest.approx(0.5 * xb(0.0), rel=1e-9)


@pytest.mark.parametrize("t", [SLOW, FAST])
def test_fig2_tetanic_initial_energy_at_l0_equals_barclay(t):
    """Full activation, FL = 1: E_a + E_xb (per kg dry) equals E_tet(V) for V <= 0."""
    v = np.linspace(P.fibre.vmax[t], 0.0, 25)
    one = np.ones_like(v)
    e_act, e_xb = en.initial_energy_rates_tsianos2012(
        one, one, one, v, 1.0, E.e1[t], E.e2[t], E.e3[t], E.e4[t], E.activation_fraction,
        P.fibre.vmax[t])
    assert e_act + e_xb == pytest.approx(barclay(v, t), rel=1e-12)
    # E_a is 33 % of E_i isometric (the paper: 30-40 %), independent of V
    assert e_act[-1] / (e_act[-1] + e_xb[-1]) == pytest.approx(0.33)
    assert np.ptp(e_act) == 0.0


def rest_path(bank, l=1.0, force_f0=0.95):
    g = bank.params.generic
    return bank.l0_m * l + bank.l0t_m * tendon_length_at_force(force_f0, g.ct, g.kt, g.lrt)


def pure_bank(fpcsa_slow, recovery_mode="static", muscle="vastus_lateralis", **kw):
    return MuscleBank.from_config([muscle], overrides={muscle: {"fpcsa_slow": fpcsa_slow}},
                                  recovery_mode=recovery_mode, **kw)


@pytest.mark.parametrize(("fs", "ratio"), [(1.0, 1.5), (0.0, 1.0)])
def test_isometric_tetanic_partition(fs, ratio):
    bank = pure_bank(fs)
    out = bank.reset(rest_path(bank), excitation=[1.0])
    r = out.energy_rate
    e_i = r.activation[0] + r.cross_bridge[0]
    # E_a : E_xb : E_rec = 0.33 : 0.67 : R (FL(L) within 0.1 % of 1 here)
    assert abs(out.length_l0[0] - 1.0) < 0.02
    assert r.activation[0] / e_i == pytest.approx(0.33, abs=0.003)
    assert r.recovery[0] / e_i == pytest.approx(ratio, rel=1e-12)
    assert r.total[0] == pytest.approx(r.activation[0] + r.cross_bridge[0] + r.recovery[0])
    # STEP 7: W = M m_wet E; E_i per kg dry = Acteff * E_tet(0)
    acteff = out.effective_activation[0].sum()
    e_tet0 = barclay(0.0, SLOW if fs == 1.0 else FAST)
    assert e_i == pytest.approx(0.25 * bank.mass_kg[0] * acteff * e_tet0, rel=0.003)


def test_activation_energy_does_not_depend_on_velocity_or_length():
    bank = MuscleBank.from_config(["biceps_long_head"])
    rates = []
    for l, v_l0 in ((1.0, 0.0), (0.8, 0.0), (1.2, 0.0), (1.0, -2.0), (1.0, 0.4)):
        lp = rest_path(bank, l=l, force_f0=0.3)
        bank.reset(lp, excitation=[0.6])
        vp = v_l0 * bank.l0_m
        for k in range(200):
            out = bank.step(DT, [0.6], lp + k * DT * vp, vp)
        rates.append((out.energy_rate.activation[0], out.energy_rate.cross_bridge[0]))
    activation = np.array(rates)[:, 0]
    cross_bridge = np.array(rates)[:, 1]
    assert np.ptp(activation) <= 1e-9 * activation[0]
    assert np.ptp(cross_bridge) > 0.1 * cross_bridge[0]  # the cross-bridge part does move


def test_fig3_energy_falls_on_both_sides_of_l0_asymmetrically():
    bank = MuscleBank.from_config(["biceps_long_head"])
    g = bank.params.generic
    totals = {}
    for l in (0.7, 1.0, 1.3):
        # hold the fascicle at l: path = l L0 + tendon at the force it will carry
        lp = rest_path(bank, l=l, force_f0=0.5)
        out = bank.reset(lp, excitation=[1.0])
        for _ in range(3):  # re-place the path for the force actually carried
            f = out.force[0] / bank.f0[0]
            lp = bank.l0_m * l + bank.l0t_m * tendon_length_at_force(f, g.ct, g.kt, g.lrt)
            out = bank.reset(lp, excitation=[1.0])
        assert out.length_l0[0] == pytest.approx(l, abs=0.01)
        totals[l] = out.energy_rate.total[0]
    assert totals[0.7] < totals[1.0] and totals[1.3] < totals[1.0]
    drop_short, drop_long = totals[1.0] - totals[0.7], totals[1.0] - totals[1.3]
    assert abs(drop_short - drop_long) > 0.05 * totals[1.0]


def test_fig3_energy_rises_with_drive_and_with_shortening_speed():
    bank = MuscleBank.from_config(["vastus_lateralis"])
    lp = rest_path(bank, force_f0=0.3)
    by_drive = [bank.reset(lp, excitation=[u]).energy_rate for u in (0.2, 0.5, 0.8, 1.0)]
    assert np.all(np.diff([r.activation[0] for r in by_drive]) > 0)
    assert np.all(np.diff([r.cross_bridge[0] for r in by_drive]) > 0)
    by_speed = []
    for v_l0 in (0.0, -0.5, -1.5, -3.0):
        bank.reset(lp, excitation=[1.0])
        vp = v_l0 * bank.l0_m
        for k in range(60):
            out = bank.step(DT, [1.0], lp + k * DT * vp, vp)
        by_speed.append(out.energy_rate.cross_bridge[0])
    assert np.all(np.diff(by_speed) > 0)
    assert by_speed[-1] > 2 * by_speed[0]


def test_fig3_fast_fibres_consume_over_five_times_slow_at_equal_isometric_force():
    per_newton = {}
    for fs in (1.0, 0.0):
        bank = pure_bank(fs)
        lp = rest_path(bank, force_f0=0.5)
        out = bank.reset(lp, excitation=[0.7])
        initial = out.energy_rate.activation[0] + out.energy_rate.cross_bridge[0]
        per_newton[fs] = initial / out.force[0]
    # the paper: "more than five times as much energy per unit time ... for the same force"
    assert per_newton[0.0] / per_newton[1.0] > 5.0


def test_mechanical_power_sign_and_work():
    bank = MuscleBank.from_config(["vastus_lateralis"])
    lp = rest_path(bank, force_f0=0.3)
    bank.reset(lp, excitation=[0.8])
    vp = -1.0 * bank.l0_m  # path shortening at 1 L0/s
    work = 0.0
    for k in range(200):
        out = bank.step(DT, [0.8], lp + k * DT * vp, vp)
        work += DT * out.mechanical_power[0]
    assert out.fascicle_velocity[0] < 0 and out.mechanical_power[0] > 0
    assert out.mechanical_power[0] == pytest.approx(
        -out.contractile_force[0] * out.fascicle_velocity[0])
    assert out.mechanical_work[0] == pytest.approx(work, rel=1e-12)
    # efficiency is reported as data, not clamped: mechanical power below total rate here
    assert out.mechanical_power[0] < out.energy_rate.total[0]


@pytest.mark.parametrize("kernel", RECOVERY_KERNELS)
def test_dynamic_recovery_rises_towards_r_times_initial_and_integrates_to_r(kernel):
    """Constant initial rate: E_rec(t) = R E_i (1 - (td e^{-t/td} - tr e^{-t/tr})/(td - tr));
    after the activity stops, the recovery energy released over a long rest brings the total to
    (1 + R) times the initial energy. For every recovery kernel of the model file."""
    tr, td = E.kernel_taus(kernel)
    e_i, r = 10.0, 1.5
    states = np.zeros((1, 2))
    taus = en.recovery_filter_taus(tr, td)
    dt, rec_energy, init_energy = 0.5, 0.0, 0.0
    for k in range(1, 241):  # 120 s of constant initial rate
        states = en.recovery_filter_step(states, np.array([e_i]), taus, dt)
        rate = en.dynamic_recovery_rate(states, r, tr, td)[0]
        t = k * dt
        expected = r * e_i * (1 - (td * np.exp(-t / td) - tr * np.exp(-t / tr)) / (td - tr))
        assert rate == pytest.approx(expected, rel=1e-9)
        rec_energy += dt * rate
        init_energy += dt * e_i
    assert 0 < rate < r * e_i
    for _ in range(int(20 * td / dt)):  # rest: 20 decay time constants
        states = en.recovery_filter_step(states, np.array([0.0]), taus, dt)
        rec_energy += dt * en.dynamic_recovery_rate(states, r, tr, td)[0]
    assert rec_energy == pytest.approx(r * init_energy, rel=0.01)


def kernel_step_integral(t, r, tr, td):
    """H(t) = integral_0^t h: R (1 - (td e^{-t/td} - tr e^{-t/tr})/(td - tr)), zero for t < 0."""
    t = np.maximum(t, 0.0)
    return r * (1.0 - (td * np.exp(-t / td) - tr * np.exp(-t / tr)) / (td - tr))


def test_kernel_impulse_response_integrates_to_r_by_quadrature():
    """h(t) = R (e^{-t/td} - e^{-t/tr})/(td - tr) of each kernel integrates to R (scipy quad)
    and its peak is where dh/dt = 0: t* = tr td ln(td/tr)/(td - tr)."""
    from scipy.integrate import quad

    for kernel in RECOVERY_KERNELS:
        tr, td = E.kernel_taus(kernel)
        def h(t, tr=tr, td=td):
            return 1.5 * (np.exp(-t / td) - np.exp(-t / tr)) / (td - tr)
        integral, _ = quad(h, 0.0, np.inf)
        assert integral == pytest.approx(1.5, rel=1e-8), kernel
        peak = tr * td * np.log(td / tr) / (td - tr)
        assert h(peak) > max(h(0.99 * peak), h(1.01 * peak)), kernel


@pytest.mark.parametrize("kernel", RECOVERY_KERNELS)
@pytest.mark.parametrize("backend", ["numpy", "auto"])
def test_bank_recovery_is_the_selected_kernel_convolved_with_the_initial_rate(kernel, backend):
    """5 s at constant drive, slow fibres (R = 1.5): the bank's recovery rate at each second is
    sum_j E_i(j) [H(t - t_(j-1)) - H(t - t_j)], E_i held over each step, H the kernel's integral
    written out here. Both back ends; the kernel is chosen by name in the parameters."""
    params = P.with_energetics(recovery_kernel=kernel)
    tr, td = params.energetics.kernel_taus(kernel)
    bank = pure_bank(1.0, recovery_mode="dynamic", params=params, backend=backend)
    lp = rest_path(bank, force_f0=0.3)
    bank.reset(lp, excitation=[0.5])
    steps = 5_000  # covers the rise of both kernels (tr 1 s and 10 s), where they differ most
    run = bank.run(DT, np.full((steps, 1), 0.5), np.full((steps, 1), lp), np.zeros((steps, 1)))
    rates = run.energy_rate.as_array()[:, 0]  # (steps, 4): activation, cross-bridge, recovery
    initial = rates[:, 0] + rates[:, 1]
    edges = DT * np.arange(steps + 1)
    for k in range(999, steps, 1000):
        t = edges[k + 1]
        weights = (kernel_step_integral(t - edges[: k + 1], 1.5, tr, td)
                   - kernel_step_integral(t - edges[1 : k + 2], 1.5, tr, td))
        assert rates[k, 2] == pytest.approx(weights @ initial[: k + 1], rel=1e-6), (kernel, t)


@pytest.mark.parametrize(("entry", "value", "field"), [
    ("recovery_kernel", "leijendekker1990", "energetics.recovery_kernel"),
    ("pcr_slade2006_tau_rise", 50.0, "energetics.pcr_slade2006_tau_rise"),
    ("fitted_fig7_tau_rise", 0.0, "energetics.fitted_fig7_tau_rise"),
])
def test_bad_recovery_kernel_is_a_one_line_config_error(tmp_path, entry, value, field):
    import yaml

    from vm_ros.resources import config_dir

    data = yaml.safe_load((config_dir() / "model.yaml").read_text())
    data["energetics"][entry]["value"] = value
    path = tmp_path / "model.yaml"
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(ConfigError) as info:
        load_model_params(path)
    assert info.value.field == field and "\n" not in str(info.value)
    unknown = P.with_energetics(recovery_kernel="leijendekker1990").energetics
    with pytest.raises(ConfigError, match="recovery_kernel"):
        unknown.kernel_taus()


def test_dynamic_recovery_in_the_bank_total_is_one_plus_r_times_initial():
    bank = pure_bank(1.0, recovery_mode="dynamic")  # slow: R = 1.5
    lp = rest_path(bank, force_f0=0.3)
    bank.reset(lp, excitation=[0.5])
    for _ in range(2000):  # 2 s of activity at 1 ms
        bank.step(DT, [0.5], lp)
    for _ in range(8000):  # long rest at a coarse step: the implicit step allows it
        out = bank.step(1.0, [0.0], lp)
    e = out.energy_by_fibre
    initial = e.activation[0, SLOW] + e.cross_bridge[0, SLOW]
    assert e.recovery[0, SLOW] == pytest.approx(1.5 * initial, rel=0.01)
    assert e.total[0, SLOW] == pytest.approx(2.5 * initial, rel=0.01)


def test_bookkeeping_components_add_up_and_integrals_match_a_reference():
    from vm_ros.model.reference import solve_reference

    bank = MuscleBank.from_config(["vasti", "soleus"], recovery_mode="dynamic")
    lp0 = rest_path(bank, force_f0=0.2)
    amp = 0.03 * bank.l0_m

    def u_fn(t):
        return np.full(2, 0.5 + 0.3 * np.sin(2 * np.pi * 2 * t))

    def lp_fn(t):
        return lp0 + amp * np.sin(2 * np.pi * t)

    def vp_fn(t):
        return amp * 2 * np.pi * np.cos(2 * np.pi * t)

    bank.reset(lp_fn(0.0), excitation=u_fn(0.0))
    steps = 500
    ref = solve_reference(bank, np.array([steps * DT]), u_fn, lp_fn)
    summed = np.zeros(2)
    for k in range(steps):
        out = bank.step(DT, u_fn(k * DT), lp_fn(k * DT), vp_fn(k * DT))
        summed += DT * out.energy_rate.total
    e = out.energy
    assert e.total == pytest.approx(e.activation + e.cross_bridge + e.recovery, rel=1e-12)
    assert e.total == pytest.approx(summed, rel=1e-12)
    assert out.energy_by_fibre.total.sum(axis=1) == pytest.approx(e.total, rel=1e-12)
    assert out.total_energy == pytest.approx(e.total.sum(), rel=1e-12)
    reference = ref.states[-1].energy_j.sum(axis=1)  # (n, 3) per component
    assert e.activation == pytest.approx(reference[:, 0], rel=0.01)
    assert e.cross_bridge == pytest.approx(reference[:, 1], rel=0.01)
    assert e.recovery == pytest.approx(reference[:, 2], rel=0.01)
