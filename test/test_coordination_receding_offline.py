"""The receding-horizon method over a whole motion (vm_ros.coordination.receding_offline) and
the choice of method (vm_ros.coordination.methods), against independent numbers: the static
optimisation solved with SciPy (test_coordination.static_optimum), a symmetric split, and the
bank's own forward run of the returned drives."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import optimize
from test_coordination import geometry, library, motion, static_optimum, steady_force

from vm_ros.coordination import methods, receding_offline
from vm_ros.coordination.problem import build_problem
from vm_ros.coordination.solver import METHODS, SolverOptions
from vm_ros.coordination.targets import JointMomentTargets
from vm_ros.errors import VmRosError
from vm_ros.model import MuscleBank


def problem_of(tmp_path, arms: dict, moment, duration_s=1.0, amplitude_rad=0.0):
    """(bank, problem): soleus copies with moment arms ``arms`` on one coordinate following
    ``moment(t)`` (N m) at 50 frames per second (test_coordination's set-up)."""
    names = list(arms)
    bank = MuscleBank.from_config(names, library=library(tmp_path, **{n: {} for n in names}))
    times = np.linspace(0.0, duration_s, int(round(duration_s * 50)) + 1)
    targets = JointMomentTargets(times, ("q",), np.asarray(moment(times), float)[:, None],
                                 "analytic")
    return bank, build_problem(geometry(arms), motion(duration_s, amplitude_rad), targets,
                               names)


def test_frame_interpolation_is_linear_and_held_outside():
    from vm_ros.coordination.receding import at_times

    frames = np.array([0.0, 0.1, 0.3])
    values = np.array([[1.0], [3.0], [7.0]])
    got = at_times(values, frames, np.array([-0.2, 0.0, 0.05, 0.2, 0.3, 0.9]))
    assert got[:, 0] == pytest.approx([1.0, 1.0, 2.0, 5.0, 7.0, 7.0])


def test_one_muscle_holds_a_static_moment_at_the_drive_of_its_static_force(tmp_path):
    """One muscle, constant pose and moment 20 N m at 0.04 m: the closed form is the drive
    whose static-equilibrium force (MuscleBank.reset, no forward run) is 500 N, found with
    SciPy's brentq; the receding horizon's drives over the motion against it, and the forward
    run's moment within 1 % of the target. The coordinator's probe steps 5 ms (receding.py:
    its force within 1.5 % of the 1 ms step's), and the drive alternates period to period:
    measured 0.618-0.632 against 0.6075, so within 0.025."""
    bank, problem = problem_of(tmp_path, {"a": 0.04}, lambda t: np.full_like(t, 20.0),
                               duration_s=0.6)
    result = receding_offline.solve(bank, problem, SolverOptions(cost="drive2"))
    expected = optimize.brentq(lambda u: steady_force(tmp_path, {}, "a", u) - 500.0, 0.0, 1.0,
                               xtol=1e-8)
    motion_nodes = result.node_times_s >= 0.0
    assert result.drives[motion_nodes, 0] == pytest.approx(expected, abs=0.025)
    assert np.max(np.abs(result.reserves)) < 0.01 * 20.0


@pytest.mark.xfail(strict=True, reason="the coordinator's cost pulls the drives to zero and "
                   "weighs them against the force each moves within its 0.15 s horizon, not "
                   "the steady force: measured 0.41-0.43 / 0.705 over the second half (means "
                   "0.43 / 0.70), still moving at 3 s (0.26 / 0.715), against the optimum "
                   "0.109 / 0.739 (docs/coordination.md, Receding horizon over a whole motion)")
def test_drive_squared_static_case_is_the_static_optimisation_solution(tmp_path):
    """Constant pose and moment 30 N m, arms 0.02 and 0.04 m, cost drive2: the receding
    horizon's drives over the second half against min Ua^2 + Ub^2 subject to the moment (SciPy
    on the static-equilibrium forces, test_coordination.static_optimum)."""
    bank, problem = problem_of(tmp_path, {"a": 0.02, "b": 0.04}, lambda t: np.full_like(t, 30.0),
                               duration_s=0.6)
    result = receding_offline.solve(bank, problem, SolverOptions(cost="drive2"))
    expected = static_optimum(tmp_path, ({}, {}), (0.02, 0.04), 30.0)
    late = result.node_times_s >= 0.3
    assert np.mean(result.drives[late], axis=0) == pytest.approx(expected, abs=0.01)


@pytest.mark.parametrize("cost", ["tsianos2012", "drive2"])
def test_two_identical_muscles_share_the_moment_equally(tmp_path, cost):
    bank, problem = problem_of(tmp_path, {"a": 0.02, "b": 0.02},
                               lambda t: 12.0 - 4.0 * np.cos(2 * np.pi * t), amplitude_rad=0.1)
    result = receding_offline.solve(bank, problem, SolverOptions(cost=cost))
    force = result.forward.force
    assert np.max(np.abs(force[:, 0] - force[:, 1])) <= 1e-3 * np.max(force)
    assert np.allclose(result.drives[:, 0], result.drives[:, 1], atol=1e-6)


def test_slow_swing_is_tracked_and_the_result_is_its_own_forward_run(tmp_path):
    """An agonist pair and an antagonist over a slow swing (test_coordination's case: target
    10 - 5 cos(2 pi t / 1.5) N m, peak 15), default cost: the forward run's moment within 1 %
    of peak at every frame (the lead-in sets the state the motion starts in); the reported
    forces are those of a fresh bank run with the returned drives from the steady state of the
    first (the lead-in's steps first), to rounding."""
    arms = {"a": 0.02, "b": 0.03, "c": -0.02}
    names = list(arms)
    bank = MuscleBank.from_config(names, library=library(
        tmp_path, a={}, b={"fpcsa_slow": 0.4}, c={}))
    times = np.linspace(0.0, 1.5, 76)
    targets = JointMomentTargets(times, ("q",), (10.0 - 5.0 * np.cos(2 * np.pi * times / 1.5))
                                 [:, None], "analytic")
    problem = build_problem(geometry(arms), motion(1.5, 0.1), targets, names)
    result = receding_offline.solve(bank, problem)
    assert np.max(np.abs(result.reserves)) <= 0.01 * 15.0
    assert result.node_times_s[0] == pytest.approx(-SolverOptions().receding_lead_in_s)
    fresh = MuscleBank.from_config(names, library=library(
        tmp_path, a={}, b={"fpcsa_slow": 0.4}, c={}))
    lead = result.forward.lead_in
    fresh.reset(path_length=lead.path_length[0], excitation=lead.drive[0])
    fresh.run(problem.dt_s, lead.drive, lead.path_length, lead.path_velocity)
    run = fresh.run(problem.dt_s, result.forward.drive_steps, problem.path_length,
                    problem.path_velocity)
    # the forward run's force is at model times 0, dt, ..., k dt; the bank's at each step's end
    assert run.force == pytest.approx(result.forward.force[1:], rel=1e-9, abs=1e-9)
    assert result.unsolved_qps == 0


def test_method_auto_picks_by_size_and_names_are_checked(tmp_path):
    _, problem = problem_of(tmp_path, {"a": 0.02, "b": 0.04}, lambda t: np.full_like(t, 10.0))
    size = len(problem.muscles) * len(problem.frame_times_s)   # 2 x 51
    assert methods.chosen_method(problem, SolverOptions(receding_above=size)) == "trajectory"
    assert methods.chosen_method(problem, SolverOptions(receding_above=size - 1)) == "receding"
    assert methods.chosen_method(problem, SolverOptions(method="receding")) == "receding"
    assert methods.chosen_method(problem, SolverOptions(method="trajectory",
                                                        receding_above=0)) == "trajectory"
    with pytest.raises(VmRosError, match="method"):
        SolverOptions(method="fast").check(problem.muscles)
    with pytest.raises(VmRosError, match="'fast'"):   # not taken for "auto"
        methods.chosen_method(problem, SolverOptions(method="fast"))
    assert set(METHODS) == {"auto", *methods.SOLVERS}   # the names SolverOptions.check knows
    with pytest.raises(VmRosError, match="whole number"):
        SolverOptions(receding_start_iterations=2.7).check(problem.muscles)
    bank, problem = problem_of(tmp_path, {"a": 0.02, "b": 0.04}, lambda t: np.full_like(t, 10.0))
    with pytest.raises(VmRosError, match="alike"):
        receding_offline.solve(bank, problem, SolverOptions(muscle_weights={"a": 2.0}))
