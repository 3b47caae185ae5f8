"""Coordination from motion (vm_ros.coordination): exactness checks against independent numbers.

One coordinate q (rad) crossed by muscles whose path lengths are L = 0.318 - r q (moment arm r,
inside the soleus' valid lengths); drives solved so that r^T F of the forward run follows a
target moment. Independent references: the static equilibrium of MuscleBank.reset (no forward
run, no solver), and a scalar static optimisation solved with SciPy on it.
"""

from __future__ import annotations

import numpy as np
import pytest
import yaml
from scipy import optimize

from vm_ros.coordination.costs import cost_named
from vm_ros.coordination.distribution import (
    COARSE_LEVELS,
    FINE_LEVELS,
    STRIDE,
    TABLE_LENGTHS,
    distribute,
    static_table,
    window,
    windows,
)
from vm_ros.coordination.problem import build_problem
from vm_ros.coordination.solver import SolverOptions, solve, solver_settings
from vm_ros.coordination.targets import JointMomentTargets
from vm_ros.errors import ConfigError, VmRosError
from vm_ros.geometry import Coordinate, MusclePath, PolynomialGeometry
from vm_ros.model import MuscleBank
from vm_ros.model.params import load_muscle_library
from vm_ros.node.motion_inputs import JointMotion
from vm_ros.resources import config_dir

LENGTH_AT_ZERO_M = 0.318   # inside the soleus' path lengths (0.305-0.332 m)


def library(tmp_path, **muscles) -> str:
    """A library of soleus copies, ``name={field: value}`` overriding fields of each."""
    soleus = load_muscle_library()["soleus"]
    entries = {name: {**soleus, **fields} for name, fields in muscles.items()}
    path = tmp_path / "muscles.yaml"
    path.write_text(yaml.safe_dump({"muscles": entries}))
    return str(path)


def geometry(arms: dict) -> PolynomialGeometry:
    """One coordinate q in [-0.6, 0.6] rad; muscle name -> moment arm r (m): L = 0.318 - r q."""
    return PolynomialGeometry(
        [Coordinate("q", "rad", -0.6, 0.6)],
        [MusclePath(name, ("q",), (0.0,), (1.0,), [[0], [1]], [LENGTH_AT_ZERO_M, -r])
         for name, r in arms.items()], backend="numpy")


def motion(duration_s: float, amplitude_rad: float = 0.0) -> JointMotion:
    """q = amplitude sin(pi t / duration): one slow half swing (rest when amplitude 0)."""
    t = np.linspace(0.0, duration_s, int(round(duration_s * 100)) + 1)
    w = np.pi / duration_s
    return JointMotion("analytic", ("q",), t, amplitude_rad * np.sin(w * t)[:, None],
                       amplitude_rad * w * np.cos(w * t)[:, None], 0.0)


def solved(tmp_path, fields: dict, arms: dict, moment, duration_s=1.0, amplitude_rad=0.0,
           **options):
    """The solution of the muscles ``fields`` (library overrides) with moment arms ``arms``
    following ``moment(t)`` (N m) at 50 frames per second."""
    names = list(arms)
    bank = MuscleBank.from_config(names, library=library(tmp_path, **fields))
    move = motion(duration_s, amplitude_rad)
    times = np.linspace(0.0, duration_s, int(round(duration_s * 50)) + 1)
    targets = JointMomentTargets(times, ("q",), np.asarray(moment(times), float)[:, None],
                                 "analytic")
    problem = build_problem(geometry(arms), move, targets, names)
    return bank, solve(bank, problem, SolverOptions(**options))


def steady_force(tmp_path, fields: dict, name: str, drive: float) -> float:
    """Tendon force (N) at static equilibrium at L = 0.318 m for a constant drive: the bank's
    reset, no forward run."""
    bank = MuscleBank.from_config([name], library=library(tmp_path, **{name: fields}))
    return float(bank.reset(path_length=[LENGTH_AT_ZERO_M], excitation=[drive]).force[0])


def static_optimum(tmp_path, fields, arms, target) -> np.ndarray:
    """Drives (Ua, Ub) minimising Ua^2 + Ub^2 subject to ra F_a(Ua) + rb F_b(Ub) = target,
    F the static-equilibrium force of each muscle (``fields``: library overrides) at constant
    drive (MuscleBank.reset), solved in one variable with SciPy."""
    cache = {}

    def f(which, u):
        if (which, u) not in cache:
            cache[which, u] = steady_force(tmp_path, fields[which], "ab"[which], u)
        return cache[which, u]

    def partner(ua):  # Ub meeting the moment for a given Ua
        return optimize.brentq(lambda ub: moment(ua, ub), 0.0, 1.0, xtol=1e-10)

    def moment(ua, ub):
        return arms[0] * f(0, ua) + arms[1] * f(1, ub) - target

    # the Ua for which some Ub in [0, 1] meets the moment
    low = 0.0 if moment(0.0, 1.0) >= 0 else optimize.brentq(moment, 0.0, 1.0, args=(1.0,))
    high = 1.0 if moment(1.0, 0.0) <= 0 else optimize.brentq(moment, 0.0, 1.0, args=(0.0,))
    best = optimize.minimize_scalar(lambda ua: ua ** 2 + partner(ua) ** 2,
                                    bounds=(low, high), method="bounded",
                                    options={"xatol": 1e-6})
    return np.array([best.x, partner(best.x)])


@pytest.mark.parametrize("cost", ["tsianos2012", "drive2"])
def test_two_identical_muscles_share_the_moment_equally(tmp_path, cost):
    _, result = solved(tmp_path, {"a": {}, "b": {}}, {"a": 0.02, "b": 0.02},
                       lambda t: 12.0 - 4.0 * np.cos(2 * np.pi * t), amplitude_rad=0.1,
                       cost=cost)
    force = result.forward.force
    assert np.max(np.abs(force[:, 0] - force[:, 1])) <= 1e-3 * np.max(force)
    assert np.allclose(result.drives[:, 0], result.drives[:, 1], atol=1e-6)


def test_drive_squared_split_of_identical_muscles_is_unequal_where_force_is_convex(tmp_path):
    """Why the equal split of identical muscles (test above) is a rule, not the drive^2 optimum:
    with VM's static-equilibrium force F(U) (MuscleBank.reset, 101 drives), two soleus copies
    carrying 600 N together, min Ua^2 + Ub^2 subject to F(Ua) + F(Ub) = 600 N over a grid of Ua
    (Ub from the interpolated inverse of F) has its minimum away from Ua = Ub, more than 1 %
    below the equal split's cost: F grows convexly with the drive. At 400 N the equal split is
    the minimum (within the grid's step)."""
    drives = np.linspace(0.0, 1.0, 101)
    force = np.array([steady_force(tmp_path, {}, "a", u) for u in drives])
    drives, force = drives[1:], force[1:]  # no unit below U1 = 0.01: F(0) = F(0.01)
    assert np.all(np.diff(force) > 0)

    def costs(total):
        ua = np.linspace(0.01, 1.0, 991)
        fa = np.interp(ua, drives, force)
        ok = (fa <= total) & (total - fa <= force[-1])
        ub = np.interp(total - fa[ok], force, drives)
        return ua[ok], ub, ua[ok] ** 2 + ub ** 2

    found = {}
    for total in (400.0, 600.0, 800.0):
        ua, ub, cost = costs(total)
        best = np.argmin(cost)
        equal = np.interp(total / 2, force, drives)
        found[total] = ua[best], ub[best], cost[best], 2 * equal ** 2
        print(f"\n{total:.0f} N: least drive^2 at {ua[best]:.3f} / {ub[best]:.3f} "
              f"({cost[best]:.4f}); split equally {equal:.3f} each ({2 * equal ** 2:.4f})")
    ua, ub, cost, equal = found[600.0]
    assert cost < 0.99 * equal and abs(ua - ub) > 0.2
    ua, ub, _, _ = found[400.0]
    assert abs(ua - ub) < 0.03


def test_drive_squared_static_case_is_the_static_optimisation_solution(tmp_path):
    """Constant pose and moment, arms 0.02 and 0.04 m: min Ua^2 + Ub^2 subject to
    0.02 F(Ua) + 0.04 F(Ub) = 30 N m, F the static-equilibrium force of the drive (reset),
    solved in one variable with SciPy."""
    arms = {"a": 0.02, "b": 0.04}
    target = 30.0
    _, result = solved(tmp_path, {"a": {}, "b": {}}, arms, lambda t: np.full_like(t, target),
                       duration_s=0.6, cost="drive2", smoothness=0.0)
    expected = static_optimum(tmp_path, ({}, {}), (0.02, 0.04), target)
    middle = len(result.drives) // 2
    assert result.drives[middle] == pytest.approx(expected, abs=0.01)
    assert expected[1] > 1.5 * expected[0]   # the longer arm carries more: not a trivial split


@pytest.mark.parametrize("refine", [0, 2])
@pytest.mark.parametrize("lead_in", [0.0, 0.2])
def test_forward_run_moments_follow_a_slow_target_within_one_percent_of_peak(tmp_path, refine,
                                                                              lead_in):
    """An agonist pair and an antagonist over a slow swing; default cost (VM's energy), the two
    stages alone and with two Gauss-Newton steps. Without a lead-in the first 0.1 s are held to
    the RMS only: the run starts at the steady state of the first drive node, which also drives
    the first 40 ms (measured: 1.9-2.1 % of peak at t = 0); with a lead-in of 0.2 s the drives
    before the first frame set the state the motion starts in, and every frame is held to 1 %
    (measured 0.2-0.3 % at t = 0)."""
    peak = 15.0
    _, result = solved(tmp_path, {"a": {}, "b": {"fpcsa_slow": 0.4}, "c": {}},
                       {"a": 0.02, "b": 0.03, "c": -0.02},
                       lambda t: 10.0 - 5.0 * np.cos(2 * np.pi * t / 1.5), duration_s=1.5,
                       amplitude_rad=0.1, refine=refine, lead_in_s=lead_in)
    held = result.problem.frame_times_s >= (0.0 if lead_in else 0.1)
    assert np.max(np.abs(result.reserves[held])) <= 0.01 * peak
    assert np.sqrt(np.mean(result.reserves ** 2)) <= 0.01 * peak
    assert result.infeasible == []


def test_targets_beyond_the_muscles_are_named_with_the_moment_they_lack(tmp_path):
    """Two soleus copies at 0.02 m give at most 2 x 0.02 x F(U = 1) isometric; a 0.2 s bump to
    110 N m exceeds that, and the frames inside it are named."""
    capacity = 2 * 0.02 * steady_force(tmp_path, {}, "a", 1.0)
    assert 40.0 < capacity < 100.0

    def moment(t):
        return np.where((t >= 0.5) & (t <= 0.7), 110.0, 10.0)

    _, result = solved(tmp_path, {"a": {}, "b": {}}, {"a": 0.02, "b": 0.02}, moment,
                       duration_s=1.2, iterations=4)
    named = {round(f.time_s, 3): f for f in result.infeasible}
    inside = [t for t in result.problem.frame_times_s if 0.5 <= t <= 0.7]
    assert sorted(named) == pytest.approx(inside)
    for frame in named.values():
        assert frame.coordinate == "q"
        assert frame.lacking == pytest.approx(110.0 - capacity, rel=0.05)
    assert result.summary.peak[0] >= 110.0 - capacity


def test_energy_loads_the_slow_muscle_at_low_moment_and_recruits_the_fast_one_as_it_rises(
        tmp_path):
    """Tsianos 2012, Discussion B: a slow and a fast muscle of equal strength (same mass and
    L0, so the same F0) and moment arm, held isometric at a constant moment. Under VM's energy
    cost the slow muscle carries more of a low moment than under drive^2, and the fast muscle's
    share grows as the moment rises. Under drive^2 the drives are the static optimum (SciPy,
    static_optimum), checked on its cost Us^2 + Uf^2 within 1 %: VM's force grows convexly
    with the drive, so that cost is nearly flat along the moment constraint and the optimum is
    not an equal split (measured: 0.20 / 0.27 at 10 % of capacity, 0.39 / 0.81 at 50 %)."""
    fields = {"slow": {"fpcsa_slow": 1.0}, "fast": {"fpcsa_slow": 0.0}}
    arms = {"slow": 0.02, "fast": 0.02}
    capacity = 0.02 * sum(steady_force(tmp_path, fields[m], m, 1.0) for m in fields)
    shares = {}
    for level in (0.1, 0.5):
        for cost in ("tsianos2012", "drive2"):
            result = solved(tmp_path, fields, arms, lambda t, m=level * capacity:
                            np.full_like(t, m), duration_s=0.6, cost=cost)[1]
            force = result.forward.force[len(result.forward.force) // 2]
            shares[level, cost] = force[0] / force.sum()
            if cost == "drive2":
                middle = result.drives[len(result.drives) // 2]
                best = static_optimum(tmp_path, (fields["slow"], fields["fast"]), (0.02, 0.02),
                                      level * capacity)
                assert np.sum(middle ** 2) == pytest.approx(np.sum(best ** 2), rel=0.01)
    assert shares[0.1, "tsianos2012"] > shares[0.1, "drive2"]
    assert shares[0.5, "tsianos2012"] < shares[0.1, "tsianos2012"]


@pytest.mark.parametrize(("old", "new", "field"), [
    ("node_step: {value: 0.04, unit: s,", "node_step: {value: 0.04, unit: kg,",
     "drives.node_step.unit"),
    ("damping: {value: 10000.0, unit: \"1\", tag: R,", "damping: {value: 10000.0, unit: \"1\",",
     "gauss_newton.damping.tag"),
])
def test_a_bad_solver_setting_is_named(tmp_path, old, new, field):
    """config/coordination.yaml with one entry broken (a unit of another quantity, no tag):
    a ConfigError naming that field."""
    text = (config_dir() / "coordination.yaml").read_text()
    assert old in text
    path = tmp_path / "coordination.yaml"
    path.write_text(text.replace(old, new))
    with pytest.raises(ConfigError) as caught:
        solver_settings(path)
    assert caught.value.field == field


def test_lp_windows_cover_every_frame_once_and_solve_the_overlap_twice():
    """distribution.windows on frames every 10 ms: windows of 0.05 s (frames within 0.05 s of
    the window's first) keeping all but their last 0.02 s, counted by hand; length 0 is one
    window."""
    times = np.arange(10) * 0.01
    assert windows(times, 0.05, 0.02) == [(0, 5, 3), (3, 8, 6), (6, 10, 10)]
    assert windows(times, 0.0, 0.0) == [(0, 10, 10)]
    assert windows(times, 0.005, 0.0) == [(a, a + 1, a + 1) for a in range(10)]


def lp_case(tmp_path, smoothness):
    """Stage 1's LP (drive2, 21 levels) of two muscles (arms 0.02 and 0.04 m) under a moment
    rising and falling over 1 s at 50 frames per second, solved as one LP and in windows of
    0.1 s overlapping by 0.04 s: (one, windowed) Distributions."""
    arms = {"a": 0.02, "b": 0.04}
    bank = MuscleBank.from_config(list(arms), library=library(tmp_path, a={}, b={}))
    times = np.linspace(0.0, 1.0, 51)
    targets = JointMomentTargets(times, ("q",), (30.0 + 20.0 * np.sin(6.0 * times))[:, None],
                                 "analytic")
    problem = build_problem(geometry(arms), motion(1.0, 0.3), targets, list(arms))
    rate = cost_named("drive2").rate_function(bank.energetics_models)
    table = window(static_table(bank, problem, rate, FINE_LEVELS, TABLE_LENGTHS),
                   np.zeros((51, 2), int), COARSE_LEVELS, STRIDE)
    return [distribute(problem, table, np.ones(2), 1e3, smoothness, *span)
            for span in ((0.0, 0.0), (0.1, 0.04))]


def test_without_smoothness_the_windowed_lp_is_the_single_lp(tmp_path):
    """Without the smoothness term the LP falls apart frame by frame, so solving it in windows
    must give the single LP's optimum: objective within 1e-6 relative, reserves within
    1e-6 N m."""
    one, windowed = lp_case(tmp_path, 0.0)
    assert windowed.objective == pytest.approx(one.objective, rel=1e-6)
    np.testing.assert_allclose(windowed.reserves, one.reserves, atol=1e-6)


def test_the_windowed_lp_is_feasible_and_not_below_the_single_lp(tmp_path):
    """With the smoothness term, windows (each fixing the force before it) give a feasible
    point of the whole LP, so its objective is at least the single LP's optimum; and it stays
    within 1 % of it on a smooth target."""
    one, windowed = lp_case(tmp_path, 0.1)
    assert one.objective <= windowed.objective * (1 + 1e-9)
    assert windowed.objective == pytest.approx(one.objective, rel=0.01)


def test_an_lp_overlap_not_below_its_window_is_an_error():
    """distribution_overlap_s >= distribution_window_s (> 0) would never advance: VmRosError
    naming it."""
    with pytest.raises(VmRosError, match="distribution_overlap_s"):
        SolverOptions(distribution_window_s=0.1, distribution_overlap_s=0.1).check(())
