"""The fixed 1 ms step against a tight scipy reference (Radau, rtol 1e-8) of the same equations.

Target (issue 2): tendon-force RMS error within 1 % of F0 for steps, ramps and sinusoids of drive
and path length, for several library muscles, in every recruitment scheme. Measured with the
analytic Jacobian (2026-11-22): RMS 0.13-0.26 % F0 after a drive step, 0.06-0.16 % on drive
ramps, 0.01 % on path ramps, 0.01-0.04 % on sinusoids; at worst 0.45 % F0 (the drive step).
Earlier, with a difference Jacobian, the first dorsal interosseous reached 3.5 % F0 for one
sample at an instantaneous reversal of path velocity (FV's slope kink at V = 0 inside one step),
so the max limit is 5 %.
"""

from __future__ import annotations

import numpy as np
import pytest

from vm_ros.model import MuscleBank
from vm_ros.model.reference import solve_reference

DT = 1e-3
MUSCLES = ["soleus", "vasti", "biceps_long_head", "first_dorsal_interosseous"]
RMS_LIMIT_F0 = 0.01
MAX_LIMIT_F0 = 0.05  # one-sample transient where a path velocity jumps


def _scenario(name, bank):
    l0 = bank.l0_m
    from vm_ros.model.curves import tendon_length_at_force

    g = bank.params.generic
    lp0 = l0 * 1.0 + bank.l0t_m * tendon_length_at_force(0.2, g.ct, g.kt, g.lrt)
    n = bank.n
    zero = np.zeros(n)
    if name == "drive_step":
        return (lambda t: np.full(n, 0.8 if t >= 0.1 else 0.05), lambda t: lp0,
                lambda t: zero, [0.1], 0.5)
    if name == "drive_ramp_down_and_up":
        return (lambda t: np.full(n, np.interp(t, [0, 0.2, 0.35, 0.5], [0.1, 0.9, 0.9, 0.2])),
                lambda t: lp0, lambda t: zero, [0.2, 0.35], 0.5)
    if name == "path_ramp_stretch_hold_release":
        # 0.5 L0/s stretch by 0.05 L0, hold, release at the same speed
        knots, disp = [0.0, 0.1, 0.2, 0.3, 0.4, 0.5], [0.0, 0.0, 0.05, 0.05, 0.0, 0.0]
        rates = [0.0, 0.5, 0.0, -0.5, 0.0]

        def velocity(t):
            return rates[min(int(np.searchsorted(knots, t, side="right")) - 1, 4)] * l0

        return (lambda t: np.full(n, 0.4), lambda t: lp0 + np.interp(t, knots, disp) * l0,
                velocity, knots[1:-1], 0.5)
    if name == "sinusoids":
        w_u, w_l = 2 * np.pi * 3.0, 2 * np.pi * 1.5
        amp = 0.03 * l0
        return (lambda t: np.full(n, 0.45 + 0.35 * np.sin(w_u * t)),
                lambda t: lp0 + amp * np.sin(w_l * t), lambda t: amp * w_l * np.cos(w_l * t),
                [], 0.5)
    raise KeyError(name)


def _compare(bank, name):
    u_fn, lp_fn, vp_fn, breaks, duration = _scenario(name, bank)
    bank.reset(lp_fn(0.0), excitation=u_fn(0.0))
    steps = int(round(duration / DT))
    t_eval = np.arange(1, steps + 1) * DT
    ref = solve_reference(bank, t_eval, u_fn, lp_fn, breakpoints=breaks)
    force = np.array([bank.step(DT, u_fn(k * DT), lp_fn(k * DT), vp_fn(k * DT)).force
                      for k in range(steps)])
    err = (force - ref.force) / bank.f0
    return np.sqrt(np.mean(err**2, axis=0)), np.abs(err).max(axis=0), ref


@pytest.mark.parametrize("name", ["drive_step", "drive_ramp_down_and_up",
                                  "path_ramp_stretch_hold_release", "sinusoids"])
def test_lumped_step_matches_reference(name):
    # the path ramp's velocity jumps make the Radau reference slow (vasti's alone took 5x
    # soleus's CPU at rtol 1e-6, about 200 s of the suite): soleus only for that one
    bank = MuscleBank.from_config(MUSCLES[:1] if name.startswith("path") else MUSCLES)
    rms, worst, ref = _compare(bank, name)
    print(f"{name}: RMS error % F0 {np.round(100 * rms, 4)}, max {np.round(100 * worst, 4)}")
    assert np.all(rms < RMS_LIMIT_F0) and np.all(worst < MAX_LIMIT_F0)
    # the scenario exercises the muscle: force varies by more than 10 % F0
    assert np.all(np.ptp(ref.force, axis=0) / bank.f0 > 0.1)


@pytest.mark.parametrize("scheme", ["natural", "continuous"])
def test_other_schemes_match_reference(scheme):
    bank = MuscleBank.from_config(MUSCLES[:2], recruitment=scheme, units_per_type=3)
    rms, worst, _ = _compare(bank, "sinusoids")
    print(f"{scheme}: RMS error % F0 {np.round(100 * rms, 4)}, max {np.round(100 * worst, 4)}")
    assert np.all(rms < RMS_LIMIT_F0) and np.all(worst < MAX_LIMIT_F0)


def test_reference_detects_a_wrong_step():
    """The comparison can fail: a bank stepped at 20 ms misses the reference by far more."""
    bank = MuscleBank.from_config(["vasti"])
    u_fn, lp_fn, vp_fn, breaks, duration = _scenario("drive_step", bank)
    bank.reset(lp_fn(0.0), excitation=u_fn(0.0))
    coarse = 0.02
    t_eval = np.arange(1, int(duration / coarse) + 1) * coarse
    ref = solve_reference(bank, t_eval, u_fn, lp_fn, breakpoints=breaks)
    force = np.array([bank.step(coarse, u_fn(k * coarse), lp_fn(k * coarse)).force
                      for k in range(len(t_eval))])
    assert np.sqrt(np.mean(((force - ref.force) / bank.f0) ** 2)) > RMS_LIMIT_F0
