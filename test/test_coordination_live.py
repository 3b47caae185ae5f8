"""The receding-horizon coordinator (vm_ros.coordination.receding) without ROS: an elbow with two
flexors and an extensor on constant moment arms, driven along a slow analytic motion. The joint
moments are those of an independent forward run of a second MuscleBank stepped at 1 ms with the
coordinator's drives, r . F by hand, against analytic targets."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from vm_ros.coordination.receding import (
    DRIVE2_WEIGHT,
    BoxQP,
    HorizonSettings,
    Probe,
    RecedingHorizon,
    block_edges,
    box_qp,
    shifted_plan,
    solve_window,
    tracking_hessian,
    tracking_lag,
)
from vm_ros.model import MuscleBank

MUSCLES = ["biceps_long_head", "brachialis", "triceps_long_head"]
ARM_M = np.array([0.03, 0.03, -0.025])  # flexion positive: two flexors, one extensor
DT_S, PERIOD_STEPS = 1e-3, 10           # 1 kHz model, 100 Hz periods
CYCLE_HZ = 0.5


def mid_lengths(bank) -> np.ndarray:
    return np.array([(s.path_length_min_m + s.path_length_max_m) / 2 for s in bank.specs])


def motion(bank, arm=ARM_M):
    """Path length and velocity (m, m/s) as functions of time: the elbow swings 1 +- 0.3 rad at
    0.5 Hz, L = L_mid - r (q - 1)."""
    mid = mid_lengths(bank)

    def length(t):
        return mid - arm * (0.3 * np.sin(2 * np.pi * CYCLE_HZ * np.asarray(t)))[..., None]

    def velocity(t):
        qdot = 0.3 * 2 * np.pi * CYCLE_HZ * np.cos(2 * np.pi * CYCLE_HZ * np.asarray(t))
        return -arm * qdot[..., None]

    return length, velocity


def track(bank, target, duration_s, settings=None, arm=ARM_M):
    """Run the coordinator period by period on the motion; returns (times s, achieved N m,
    target N m, drives (periods, m)) at every 1 ms step."""
    length, velocity = motion(bank, arm)
    coordinator = RecedingHorizon(bank, np.arange(bank.n), PERIOD_STEPS * DT_S,
                                  settings or HorizonSettings())
    bank.reset(path_length=length(0.0))
    arms = np.repeat(arm[None, :, None], coordinator.steps, axis=0)
    achieved, drives, t0 = [], [], 0.0
    periods = int(round(duration_s / (PERIOD_STEPS * DT_S)))
    for _ in range(periods):
        start, end = t0 + coordinator.start_offsets_s, t0 + coordinator.end_offsets_s
        plan = coordinator.solve(bank.state, length(start), velocity(start), arms,
                                 target(end)[:, None])
        t = t0 + DT_S * np.arange(PERIOD_STEPS)
        run = bank.run(DT_S, np.repeat(plan.drive[None], PERIOD_STEPS, axis=0), length(t),
                       velocity(t))
        achieved.append(run.force @ arm)
        drives.append(plan.drive)
        t0 += PERIOD_STEPS * DT_S
    times = DT_S * np.arange(1, periods * PERIOD_STEPS + 1)
    return times, np.concatenate(achieved), target(times), np.array(drives)


def sine_target(t):
    """4 + 6 sin(2 pi 0.5 t) N m: -2 to 10 N m, both muscle groups needed."""
    return 4.0 + 6.0 * np.sin(2 * np.pi * CYCLE_HZ * np.asarray(t))


@pytest.mark.parametrize("cost", ["tsianos2012", "drive2"])
def test_slow_motion_targets_are_reproduced(cost):
    """After the first second (the start from rest), the forward run's moment follows the
    targets within 2.5 % RMS and 6 % at worst of the target's peak, with either cost (pytest -s
    prints them)."""
    bank = MuscleBank.from_config(MUSCLES)
    times, achieved, target, _ = track(bank, sine_target, 4.0, HorizonSettings(cost=cost))
    after = times > 1.0
    error = achieved[after] - target[after]
    peak = np.abs(target).max()
    print(f"{cost}: RMS {100 * np.sqrt(np.mean(error ** 2)) / peak:.2f} % of peak, worst "
          f"{100 * np.abs(error).max() / peak:.2f} %")
    assert np.sqrt(np.mean(error ** 2)) < 0.025 * peak
    assert np.abs(error).max() < 0.06 * peak


def test_infeasible_targets_leave_a_reserve_of_what_the_muscles_lack():
    """A flexion moment of 40 N m (about twice what the flexors give at full drive on these arms):
    the flexors go to full drive, the extensor stays off, and the muscles' moment equals that of
    an independent run at full flexor drive, so the reserve (target - muscles) is 40 N m minus
    that capacity."""
    bank = MuscleBank.from_config(MUSCLES)
    times, achieved, target, drives = track(bank, lambda t: np.full(np.shape(t), 40.0), 2.0)
    assert np.all(drives[-50:, :2] > 0.99) and np.all(drives[-50:, 2] < 0.01)
    length, velocity = motion(MuscleBank.from_config(MUSCLES))
    reference = MuscleBank.from_config(MUSCLES)
    reference.reset(path_length=length(0.0))
    run = reference.run(DT_S, np.tile([1.0, 1.0, 0.0], (len(times), 1)), length(times - DT_S),
                        velocity(times - DT_S))
    capacity = run.force @ ARM_M
    late = times > 1.0
    assert capacity[late].min() > 10.0 and capacity[late].max() < 30.0
    reserve = target - achieved
    np.testing.assert_allclose(reserve[late], 40.0 - capacity[late], atol=0.02 * 40.0)


def test_two_identical_muscles_share_equally():
    """Two copies of one muscle on one arm (as in issue 30's exactness tests): equal drives."""
    spec = MuscleBank.from_config(["brachialis"]).specs[0]
    bank = MuscleBank([spec, dataclasses.replace(spec, name="brachialis_copy")],
                      MuscleBank.from_config(["brachialis"]).params)
    arm = np.array([0.03, 0.03])
    *_, drives = track(bank, lambda t: np.full(np.shape(t), 8.0), 1.0, arm=arm)
    assert drives[-1, 0] > 0.05
    np.testing.assert_allclose(drives[:, 0], drives[:, 1], rtol=1e-6, atol=1e-9)


def test_blocks_cover_the_horizon():
    assert block_edges(30, 2, 3).tolist() == [0, 2, 16, 30]
    assert block_edges(2, 2, 3).tolist() == [0, 2]
    assert block_edges(4, 2, 5).tolist() == [0, 2, 3, 4]


def test_the_plan_moves_on_by_one_period_not_one_block():
    """Blocks over steps [0, 2, 7, 12] (a period of 2 steps): the next period's block 0 covers
    the old steps 2-3 (old block 1), block 1 the old steps 4-8 (middle 6: old block 1), block 2
    the old steps 9-13 (old block 2, held beyond the horizon); per muscle."""
    plan = np.array([[0.1, 1.0], [0.2, 2.0], [0.3, 3.0]])
    np.testing.assert_array_equal(shifted_plan(plan, np.array([0, 2, 7, 12])),
                                  [[0.2, 2.0], [0.2, 2.0], [0.3, 3.0]])


def test_tracking_lag_finds_a_known_delay():
    """A 0.5 Hz sine and the same sine 30 ms later, sampled at 100 Hz: lag 0.03 s, error 0."""
    t = np.arange(0.0, 4.0, 0.01)
    target = np.stack([np.sin(np.pi * t), 2 * np.cos(np.pi * t)], axis=1)
    achieved = np.stack([np.sin(np.pi * (t - 0.03)), 2 * np.cos(np.pi * (t - 0.03))], axis=1)
    lag, rms = tracking_lag(t, target, achieved, max_lag_s=0.2)
    assert lag == pytest.approx(0.03)
    assert rms < 1e-12
    lag0, rms0 = tracking_lag(t, target, target + 0.5, max_lag_s=0.2)
    assert lag0 == 0.0 and rms0 == pytest.approx(0.5)
    assert np.isnan(tracking_lag(t[:1], target[:1], target[:1], 0.2)[0])


def test_box_qp_matches_an_independent_bounded_solver():
    """Random strictly convex problems with some bounds active, in one BoxQP updated from problem
    to problem (OSQP set up once, warm started) and on other nonzero entries (set up again):
    its minimiser equals scipy's L-BFGS-B's (a quasi-Newton method, not OSQP's splitting) to
    1e-6; a one-off box_qp too."""
    from scipy.optimize import minimize

    rng = np.random.default_rng(3)
    qp, active = BoxQP(), 0
    for k in range(20):
        a = rng.normal(size=(12, 8))
        hessian = a.T @ a + 0.1 * np.eye(8)
        if k >= 10:  # two uncoupled groups: other entries, set up again, then updated
            hessian[:4, 4:] = hessian[4:, :4] = 0.0
        linear = rng.normal(scale=4.0, size=8)
        start = rng.uniform(size=8)
        reference = minimize(lambda y, h=hessian, f=linear: 0.5 * y @ h @ y - f @ y,
                             np.full(8, 0.5), jac=lambda y, h=hessian, f=linear: h @ y - f,
                             method="L-BFGS-B",
                             bounds=[(0.0, 1.0)] * 8, options={"ftol": 1e-15, "gtol": 1e-12})
        active += int(np.sum((reference.x < 1e-9) | (reference.x > 1 - 1e-9)))
        solver = qp._solver
        for x in (qp.solve(hessian, linear, start), box_qp(hessian, linear, start)):
            np.testing.assert_allclose(x, reference.x, atol=1e-6)
            assert np.all((x >= 0) & (x <= 1))
        # same entries as the problem before: OSQP updated, not set up again
        assert (qp._solver is solver) == (k not in (0, 10))
    assert active >= 20  # bounds active in the references
    qp.solve(np.eye(3), np.ones(3), np.zeros(3))  # another size: set up again
    assert qp.unsolved == 0


def test_damping_holds_the_plan_near_the_linearisation_point():
    """solve_window with ``damping`` D (drive2, no smoothness) minimises over the box the
    linearised tracking term (mean over the samples of 1/2 |target - moment|^2), drive2's
    weight x block share x drive^2 and D/2 |plan - nominal|^2: its plan equals scipy's
    L-BFGS-B minimiser of that objective written out here, for D = 0 and D = 50; with D = 1e6
    the plan stays at the nominal one."""
    from scipy.optimize import minimize

    rng = np.random.default_rng(7)
    n_blocks, samples, m, c = 2, 6, 3, 2
    forces0 = rng.uniform(50.0, 200.0, size=(samples, m))                 # N, nominal plan
    slope = rng.uniform(100.0, 400.0, size=(n_blocks, samples, m))        # N per drive
    nominal = rng.uniform(0.2, 0.6, size=(n_blocks, m))
    delta = np.full((n_blocks, m), 0.2)
    forces = np.concatenate([forces0[None], forces0 + slope * delta[:, None, :]])
    arm = rng.normal(scale=0.03, size=(samples, m, c))
    target = rng.normal(scale=5.0, size=(samples, c))
    share = np.full(n_blocks, 1.0 / n_blocks)
    probe = Probe(nominal, delta, share, np.zeros(m), np.zeros((n_blocks, m)))

    def objective(x, damping):
        plan = x.reshape(n_blocks, m)
        force = forces0 + np.einsum("bsm,bm->sm", slope, plan - nominal)
        moment = np.einsum("smc,sm->sc", arm, force)
        return (0.5 * np.sum((target - moment) ** 2) / samples
                + DRIVE2_WEIGHT * np.sum(share[:, None] * plan ** 2)
                + 0.5 * damping * np.sum((plan - nominal) ** 2))

    for damping in (0.0, 50.0):
        settings = HorizonSettings(cost="drive2", smoothness=0.0, damping=damping)
        plan = solve_window(forces, arm, target, np.ones(c, dtype=bool), probe, settings,
                            np.zeros(m)).plan
        reference = minimize(objective, nominal.ravel(), args=(damping,), method="L-BFGS-B",
                             bounds=[(0.0, 1.0)] * plan.size,
                             options={"ftol": 1e-15, "gtol": 1e-10})
        np.testing.assert_allclose(plan.ravel(), reference.x, atol=1e-5)
    held = solve_window(forces, arm, target, np.ones(c, dtype=bool), probe,
                        HorizonSettings(cost="drive2", smoothness=0.0, damping=1e6),
                        np.zeros(m)).plan
    np.testing.assert_allclose(held, nominal, atol=1e-3)


def test_the_tracking_hessian_equals_the_jacobians_product():
    """tracking_hessian against J^T J of the explicit Jacobian, for arms held and varying."""
    rng = np.random.default_rng(5)
    n_blocks, samples, m, c = 3, 7, 5, 4
    sens = rng.normal(size=(n_blocks, samples, m))
    tracked = np.array([True, False, True, True])
    for arm in (np.broadcast_to(rng.normal(size=(m, c)), (samples, m, c)),
                rng.normal(size=(samples, m, c))):
        jac = np.zeros((samples, c, n_blocks, m))
        for s in range(samples):
            for j in range(c):
                for b in range(n_blocks):
                    jac[s, j, b] = arm[s, :, j] * sens[b, s]
        jac = jac[:, tracked].reshape(-1, n_blocks * m)
        np.testing.assert_allclose(tracking_hessian(arm, sens, tracked), jac.T @ jac,
                                   rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize(("probe_dt", "rtol"), [(5e-3, 0.015), (1e-2, 0.04)])
def test_the_probe_step_gives_the_forces_of_1_ms_steps(probe_dt, rtol):
    """The coordinator's forward runs step coordination.sample_period_s (5 ms by default): on a
    150 ms run at drive 0.5 from drive 0.2's steady state, on a path moving 1 cm at 1 Hz, five
    library muscles' forces at 50, 100 and 150 ms are within 1.5 % (5 ms steps) and 4 % (10 ms
    steps) of those of 1 ms steps (measured 1.3 % and 3.5 %)."""
    names = ["biceps_long_head", "brachialis", "triceps_long_head", "soleus", "vasti"]
    forces = {}
    for dt in (1e-3, probe_dt):
        bank = MuscleBank.from_config(names)
        mid = mid_lengths(bank)
        k = int(round(0.15 / dt))
        t = dt * np.arange(k)
        bank.reset(path_length=mid, excitation=np.full(5, 0.2))
        run = bank.run(dt, np.full((k, 5), 0.5), mid + 0.01 * np.sin(2 * np.pi * t)[:, None],
                       np.repeat((0.01 * 2 * np.pi * np.cos(2 * np.pi * t))[:, None], 5, 1))
        forces[dt] = run.force[[int(round(x / dt)) - 1 for x in (0.05, 0.1, 0.15)]]
    np.testing.assert_allclose(forces[probe_dt], forces[1e-3], rtol=rtol)
