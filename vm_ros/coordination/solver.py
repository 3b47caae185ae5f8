"""Whole-trajectory coordination against the forward run of the full model (docs/coordination.md).

solve() works in three stages: stage 1 (distribution.py) tabulates each muscle's quasi-static
force and cost per frame and drive and distributes the target moments over the muscles by one
linear programme (HiGHS), giving each muscle a target force; stage 2 (tracking.py) finds the
drives whose forward run meets those forces by iterative learning control, one forward run per
iteration; stage 3 takes ``refine`` Gauss-Newton steps on J below over the whole trajectory.

Unknowns: drive nodes u (N nodes x n muscles, every ``node_step_s`` = h). Objective:

    J(u) = sum_i w_i C_i(u) / C_ref                  cost (costs.py), C_ref: the cost with
                                                     every drive held at REFERENCE_DRIVE
         + w_res mean_{f,c} (rho_fc / peak_c)^2      reserves rho = target - r^T F(u)
         + w_smooth mean_{i,j} (tau^2 (u_i,j+1 - 2 u_i,j + u_i,j-1) / h^2)^2
                                                     smoothness, tau = 1 / (2 pi f_c)

with F(u) the tendon forces of a forward run (forward.py) at the target frames. A drive's
content at frequency f weighs (f / f_c)^4 of its size in the smoothness term (f_c =
``smoothness_cutoff_hz``). Each Gauss-Newton step: ``groups`` perturbed runs give the banded
sensitivity of every muscle's force at the frames, and of every muscle's cost, to its own drive
nodes (forward.ForwardModel.sensitivity: with the motion prescribed a muscle's force depends
only on its own drive); the model of J around u (reserves linear in the step, drive2 exactly
quadratic, the energy costs linear) plus a damping ``damping`` mean(du^2) is minimised over
0 <= u + du <= 1 as one sparse convex QP, solved by OSQP (StepQP: set up once, its matrices'
values, bounds and linear term updated each step, warm started). The step is kept when the
forward run's J falls, else the damping is multiplied by DAMPING_UP and the QP solved again with
the same sensitivity (Levenberg-Marquardt). Stops after ``refine`` kept steps, after
MAX_REJECTED rejected ones in a row, or when a kept step lowers J by less than ``tolerance``
of it.
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
import osqp
from scipy import sparse

from vm_ros.coordination.costs import DEFAULT_COST, cost_named
from vm_ros.coordination.distribution import FINE_LEVELS, TABLE_LENGTHS, refined, static_table
from vm_ros.coordination.forward import ForwardModel, ForwardOutput
from vm_ros.coordination.problem import CoordinationProblem
from vm_ros.coordination.reserves import (
    InfeasibleFrame,
    ReserveSummary,
    infeasible_frames,
    summarize_reserves,
)
from vm_ros.coordination.settings import solver_settings
from vm_ros.coordination.tracking import track
from vm_ros.errors import VmRosError

REFERENCE_DRIVE = 0.5   # C_ref: the cost of every drive held at this value over the motion
DAMPING_UP = 4.0
MAX_REJECTED = 4        # rejected steps in a row before the iteration stops
METHODS = ("auto", "trajectory", "receding")   # SolverOptions.method (methods.py solves by it)




def _setting(section: str, name: str, kind=float):
    """A SolverOptions field whose default is config/coordination.yaml's entry."""
    return field(default_factory=lambda: kind(getattr(solver_settings()[section], name)))


@dataclass(frozen=True)
class SolverOptions:
    """How to solve: ``cost`` (costs.COSTS name), ``muscle_weights`` (name -> w_i, default 1),
    ``node_step_s`` (s between drive nodes), ``lead_in_s`` (s the forward runs start before the
    motion's first frame, first pose held, drives free: forward.py). Defaults:
    config/coordination.yaml.

    Stage 1 (distribution.py): ``distribution_reserve_weight`` (w_res of the LP, on mean
    |reserve| / peak), ``distribution_smoothness`` (w_smooth of the LP, s, on mean
    |dF/dt| / F_max), ``distribution_window_s`` and ``distribution_overlap_s`` (the LP solved
    in windows of that length, each keeping all but its last overlap; 0: one LP). Stage 2
    (tracking.py): ``iterations`` (forward runs at most),
    ``patience``, ``lead_s``, ``gain``, ``tracking_tolerance`` (max RMS reserve / peak that
    stops).

    Stage 3 (Gauss-Newton, this module's docstring): ``refine`` kept steps (0: none),
    ``reserve_weight`` (w_res), ``smoothness`` (w_smooth), ``smoothness_cutoff_hz`` (f_c),
    ``damping`` (weight of mean du^2), ``delta`` (perturbation of the drive nodes),
    ``memory_s`` (forward.py), ``tolerance`` (relative fall of J that stops), ``qp_eps``
    (OSQP's tolerances).

    ``method``: "trajectory" (the three stages, solve()), "receding" (the receding horizon over
    the whole motion, receding_offline.py) or "auto" (receding above ``receding_above`` muscles x
    target frames); the receding horizon's ``receding_period_s``, ``receding_lead_in_s`` and
    ``receding_start_iterations`` (receding_offline.solve)."""

    cost: str = DEFAULT_COST
    method: str = "auto"
    muscle_weights: Mapping = field(default_factory=dict)
    node_step_s: float = _setting("drives", "node_step")
    lead_in_s: float = _setting("drives", "lead_in")
    distribution_reserve_weight: float = _setting("distribution", "reserve_weight")
    distribution_smoothness: float = _setting("distribution", "smoothness")
    distribution_window_s: float = _setting("distribution", "window")
    distribution_overlap_s: float = _setting("distribution", "overlap")
    iterations: int = _setting("tracking", "iterations", int)
    patience: int = _setting("tracking", "patience", int)
    lead_s: float = _setting("tracking", "lead")
    gain: float = _setting("tracking", "gain")
    tracking_tolerance: float = _setting("tracking", "tolerance")
    refine: int = _setting("gauss_newton", "steps", int)
    reserve_weight: float = _setting("gauss_newton", "reserve_weight")
    smoothness: float = _setting("gauss_newton", "smoothness")
    smoothness_cutoff_hz: float = _setting("gauss_newton", "smoothness_cutoff")
    damping: float = _setting("gauss_newton", "damping")
    delta: float = _setting("gauss_newton", "delta")
    memory_s: float = _setting("gauss_newton", "memory")
    tolerance: float = _setting("gauss_newton", "tolerance")
    qp_eps: float = _setting("gauss_newton", "eps")
    receding_above: float = _setting("receding", "above")
    receding_period_s: float = _setting("receding", "period")
    receding_lead_in_s: float = _setting("receding", "lead_in")
    receding_start_iterations: int = _setting("receding", "start_iterations", int)

    def check(self, muscles) -> None:
        cost_named(self.cost)
        unknown = [m for m in self.muscle_weights if m not in muscles]
        if unknown:
            raise VmRosError(f"muscle weight for {unknown[0]!r}: not a muscle of the problem")
        for name in ("node_step_s", "reserve_weight", "delta", "distribution_reserve_weight",
                     "gain", "iterations", "patience", "smoothness_cutoff_hz", "damping",
                     "qp_eps", "memory_s", "receding_period_s"):
            if not getattr(self, name) > 0:
                raise VmRosError(f"{name} must be > 0 (got {getattr(self, name)})")
        for name in ("smoothness", "distribution_smoothness", "distribution_window_s",
                     "distribution_overlap_s", "lead_s", "refine", "lead_in_s",
                     "tracking_tolerance", "tolerance", "receding_above",
                     "receding_lead_in_s", "receding_start_iterations"):
            if not getattr(self, name) >= 0:
                raise VmRosError(f"{name} must be >= 0 (got {getattr(self, name)})")
        if 0 < self.distribution_window_s <= self.distribution_overlap_s:
            raise VmRosError(f"distribution_overlap_s must be < distribution_window_s (got "
                             f"{self.distribution_overlap_s} >= {self.distribution_window_s})")
        if self.receding_start_iterations != int(self.receding_start_iterations):
            raise VmRosError(f"receding_start_iterations must be a whole number (got "
                             f"{self.receding_start_iterations})")
        if self.method not in METHODS:
            raise VmRosError(f"method {self.method!r}: not one of {', '.join(METHODS)}")
        if not all(w >= 0 for w in self.muscle_weights.values()):
            raise VmRosError("muscle weights must be >= 0")


@dataclass
class Iteration:
    """One kept iterate: objective parts, RMS reserve per coordinate (% of peak), damping,
    forward runs so far, seconds since the start."""

    objective: float
    cost: float
    tracking: float
    smooth: float
    rms_percent: np.ndarray
    damping: float
    runs: int
    seconds: float


@dataclass
class CoordinationResult:
    """The solution.

    | field | shape | unit |
    | --- | --- | --- |
    | node_times_s | (N,) | s, model time of each drive node |
    | drives | (N, n) | drive U at the nodes (linear between them) |
    | forward | ForwardOutput | the forward run of ``drives`` |
    | moments | (T, C) | N m or N, r^T F at the target frames |
    | reserves | (T, C) | target - moments |
    | summary | ReserveSummary | per coordinate |
    | infeasible | list of InfeasibleFrame | frames beyond the muscles' capacity |
    | cost_value | () | the cost C (costs.Cost.unit), weighted |
    | muscle_cost | (n,) | each muscle's unweighted C_i |
    | history | list of Iteration | one per kept iterate (stage 2's runs, then the steps) |
    | forward_runs, seconds | | forward runs made, wall time of the solve |
    | unsolved_qps | | the receding method's periods whose QP OSQP did not report solved |
    """

    problem: CoordinationProblem
    options: SolverOptions
    node_times_s: np.ndarray
    drives: np.ndarray
    forward: ForwardOutput
    moments: np.ndarray
    reserves: np.ndarray
    summary: ReserveSummary
    infeasible: list[InfeasibleFrame]
    cost_value: float
    muscle_cost: np.ndarray
    history: list[Iteration]
    forward_runs: int
    seconds: float
    unsolved_qps: int = 0


def second_differences(n_nodes: int, n: int) -> sparse.csr_matrix:
    """((N - 2) n, N n): u_j+1 - 2 u_j + u_j-1 of every muscle, nodes flattened (j, i)."""
    if n_nodes < 3:
        return sparse.csr_matrix((0, n_nodes * n))
    d2 = sparse.diags([np.ones(n_nodes - 2), -2.0 * np.ones(n_nodes - 2),
                       np.ones(n_nodes - 2)], [0, 1, 2], shape=(n_nodes - 2, n_nodes))
    return sparse.kron(d2, sparse.identity(n)).tocsr()


class _Objective:
    """J and its parts for a forward run (module docstring)."""

    def __init__(self, problem: CoordinationProblem, options: SolverOptions, weights, c_ref,
                 forward: ForwardModel):
        self.p, self.o, self.w, self.c_ref, self.forward = (problem, options, weights, c_ref,
                                                            forward)
        n_nodes, n = forward.n_nodes, len(problem.muscles)
        tau = 1.0 / (2.0 * np.pi * options.smoothness_cutoff_hz)
        rows = max((n_nodes - 2) * n, 1)
        # smoothness = |S u|^2
        self.smooth_matrix = (second_differences(n_nodes, n)
                              * (np.sqrt(options.smoothness / rows) * tau ** 2
                                 / forward.node_step_s ** 2))

    def scaled_reserves(self, out: ForwardOutput) -> np.ndarray:
        """(T, C) reserves / peak."""
        return (self.p.target - self.p.moments(out.force_frames)) / self.p.peak

    def muscle_cost(self, out: ForwardOutput) -> np.ndarray:
        return out.rates[self.o.cost].sum(axis=0) * self.p.dt_s

    def parts(self, nodes, out: ForwardOutput) -> tuple[float, float, float]:
        cost = float(self.w @ self.muscle_cost(out)) / self.c_ref
        rho = self.scaled_reserves(out)
        tracking = self.o.reserve_weight * float(np.mean(rho ** 2))
        smooth = float(np.sum((self.smooth_matrix @ nodes.ravel()) ** 2))
        return cost, tracking, smooth


class StepQP:
    """The Gauss-Newton step's QP (module docstring) in OSQP's form, over x = (du, r) with r
    the scaled reserves after the step:

        min  1/2 x^T P x + q^T x
        s.t. A_F du + r = rho / peak,    -u <= du <= 1 - u

    P = 2 (S^T S + damping / (N n) I [+ Q^T Q for drive2]) on du and 2 w_res / (T C) I on r;
    A_F holds r_fic dF_i(t_f)/du_ij / peak_c. Its sparsity is fixed by the problem (the
    sensitivity's windows, the crossed coordinates), so OSQP is set up once and later steps
    update values only."""

    def __init__(self, problem: CoordinationProblem, options: SolverOptions,
                 objective: _Objective, forward: ForwardModel):
        self.p, self.o, self.objective = problem, options, objective
        self.n_nodes, self.n = forward.n_nodes, len(problem.muscles)
        frames, coords = problem.target.shape
        self.size, self.residuals = self.n_nodes * self.n, frames * coords
        self.curvature = objective.smooth_matrix.T @ objective.smooth_matrix
        if cost_named(options.cost).quadratic:
            # int U_i^2 dt = dt |W u_i|^2, W the step interpolation
            scale = np.sqrt(problem.dt_s * objective.w / objective.c_ref)
            q = sparse.kron(forward.steps, sparse.diags(scale))
            self.curvature = self.curvature + q.T @ q
        self.curvature = sparse.csc_matrix(self.curvature)
        # each muscle's (frame, coordinate) pairs it crosses
        self.crossed = [np.flatnonzero(np.any(problem.moment_arm[:, i, :] != 0, axis=0))
                        for i in range(self.n)]
        self.solver = self.pattern = None

    def _hessian(self, damping: float) -> sparse.csc_matrix:
        du = self.curvature + sparse.identity(self.size) * (damping / self.size)
        r = sparse.identity(self.residuals) * (self.o.reserve_weight / self.residuals)
        return sparse.triu(sparse.block_diag([du, r]) * 2.0, format="csc")

    def _constraints(self, jac) -> sparse.csc_matrix:
        p, coords = self.p, self.p.target.shape[1]
        rows, cols, vals = [], [], []
        for i in range(self.n):
            coo = jac[i].tocoo()
            for c in self.crossed[i]:
                rows.append(coo.row * coords + c)
                cols.append(coo.col * self.n + i)
                vals.append(coo.data * p.moment_arm[coo.row, i, c] / p.peak[c])
        sensitivity = sparse.csc_matrix(
            (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
            shape=(self.residuals, self.size))
        return sparse.vstack([
            sparse.hstack([sensitivity, sparse.identity(self.residuals)]),
            sparse.hstack([sparse.identity(self.size),
                           sparse.csc_matrix((self.size, self.residuals))])], format="csc")

    def step(self, nodes, base: ForwardOutput, jac, grad, damping: float) -> np.ndarray:
        """The step du (N, n) from ``nodes`` with forward run ``base``, sensitivity ``jac`` (a
        (T, N) matrix per muscle) and the cost's gradient ``grad`` (N, n)."""
        u = nodes.ravel()
        linear = 2.0 * (self.curvature @ u)
        if not cost_named(self.o.cost).quadratic:
            linear = linear + (grad * self.objective.w / self.objective.c_ref).ravel()
        q = np.concatenate([linear, np.zeros(self.residuals)])
        rho = self.objective.scaled_reserves(base).ravel()
        low = np.concatenate([rho, -u])
        high = np.concatenate([rho, 1.0 - u])
        hessian, constraints = self._hessian(damping), self._constraints(jac)
        pattern = (hessian.nnz, constraints.nnz)
        if self.solver is None or pattern != self.pattern:   # set up once (same sparsity)
            self.solver, self.pattern = osqp.OSQP(), pattern
            self.solver.setup(P=hessian, q=q, A=constraints, l=low, u=high, verbose=False,
                              eps_abs=self.o.qp_eps, eps_rel=self.o.qp_eps, polishing=False,
                              warm_starting=True)
        else:
            self.solver.update(Px=hessian.data, Ax=constraints.data, q=q, l=low, u=high)
        out = self.solver.solve(raise_error=False)
        if out.x is None or not np.all(np.isfinite(out.x)):
            raise VmRosError(f"coordination: the Gauss-Newton step's QP failed "
                             f"({out.info.status})")
        return np.clip(out.x[:self.size], -u, 1.0 - u).reshape(self.n_nodes, self.n)


def checked_rate(bank, problem: CoordinationProblem, options: SolverOptions):
    """The cost's rate function (costs.Cost.rate_function) of ``bank``, after checking
    ``options`` and that ``bank`` holds the problem's muscles in order and runs the cost's
    published model when the cost is one (VmRosError otherwise)."""
    options.check(problem.muscles)
    if tuple(bank.names) != tuple(problem.muscles):
        raise VmRosError("the bank's muscles are not the problem's (same names, same order)")
    cost = cost_named(options.cost)
    missing = [m for m in cost.bank_models if m not in bank.energetics_models]
    if missing:
        raise VmRosError(f"cost {cost.name}: the bank must run energetics model {missing[0]}")
    return cost.rate_function(bank.energetics_models)


def reference_objective(problem: CoordinationProblem, options: SolverOptions,
                        forward: ForwardModel) -> _Objective:
    """J of the module docstring over ``forward``'s nodes, its C_ref from one forward run with
    every drive at REFERENCE_DRIVE."""
    weights = np.array([float(options.muscle_weights.get(m, 1.0)) for m in problem.muscles])
    reference = forward.run(np.full((forward.n_nodes, len(problem.muscles)), REFERENCE_DRIVE))
    c_ref = max(float(weights @ reference.rates[options.cost].sum(axis=0)) * problem.dt_s,
                1e-12)
    return _Objective(problem, options, weights, c_ref, forward)


def solve(bank, problem: CoordinationProblem, options: SolverOptions | None = None,
          progress=None) -> CoordinationResult:
    """The drives of ``bank``'s muscles (the problem's, in order) that reproduce the problem's
    targets at least cost (module docstring). ``bank`` must run the cost's published model when
    the cost is one (costs.Cost.bank_models). ``progress``: called with each Iteration."""
    options = options or SolverOptions()
    rate = checked_rate(bank, problem, options)
    started = time.perf_counter()
    forward = ForwardModel(bank, problem, options.node_step_s, {options.cost: rate},
                           options.memory_s, options.lead_in_s)
    objective = reference_objective(problem, options, forward)
    weights = objective.w
    # stage 1: the distribution; stage 2: drives whose forward run meets it
    fine = static_table(bank, problem, rate, FINE_LEVELS, TABLE_LENGTHS)
    table, shares = refined(problem, fine, weights, options.distribution_reserve_weight,
                            options.distribution_smoothness, options.distribution_window_s,
                            options.distribution_overlap_s)
    history = []

    def kept(nodes, out, damping):
        history.append(_iteration(objective, nodes, out, damping, forward, started))
        if progress is not None:
            progress(history[-1])

    best = track(forward, table, shares.force, options.lead_s, options.gain,
                 options.iterations, options.tracking_tolerance, options.patience,
                 progress=lambda nodes, out: kept(nodes, out, options.damping))
    nodes, base = _gauss_newton(problem, options, objective, forward, best.nodes, best.forward,
                                lambda nodes, out, damping: kept(nodes, out, damping))
    return _result(problem, options, forward, objective, nodes, base, history, started)


def _gauss_newton(problem, options, objective, forward, nodes, base, kept):
    """Stage 3 (module docstring) from ``nodes`` with forward run ``base``: (nodes, run)."""
    qp = StepQP(problem, options, objective, forward)
    value = sum(objective.parts(nodes, base))
    damping = options.damping
    steps = rejected = 0
    jac = None
    while steps < options.refine and rejected < MAX_REJECTED:
        if jac is None:
            jac, grad = forward.sensitivity(nodes, base, options.delta)
        trial = np.clip(nodes + qp.step(nodes, base, jac, grad[options.cost], damping),
                        0.0, 1.0)
        out = forward.run(trial)
        trial_value = sum(objective.parts(trial, out))
        if trial_value >= value:
            damping *= DAMPING_UP
            rejected += 1
            continue
        fall = (value - trial_value) / value
        nodes, base, value, jac = trial, out, trial_value, None
        steps, rejected = steps + 1, 0
        kept(nodes, base, damping)
        if fall < options.tolerance:
            break
    return nodes, base


def _iteration(objective, nodes, out, damping, forward, started) -> Iteration:
    cost, tracking, smooth = objective.parts(nodes, out)
    p = objective.p
    rms = summarize_reserves(p.coordinates, p.target - p.moments(out.force_frames),
                             p.target).rms_percent
    return Iteration(cost + tracking + smooth, cost, tracking, smooth, rms, damping,
                     forward.runs, time.perf_counter() - started)


def _result(problem, options, forward, objective, nodes, base, history, started):
    moments = problem.moments(base.force_frames)
    reserves = problem.target - moments
    full = forward.run(np.ones_like(nodes))
    passive = forward.run(np.zeros_like(nodes))
    infeasible = infeasible_frames(problem.frame_times_s, problem.coordinates, problem.target,
                                   problem.moment_arm, full.force_frames, passive.force_frames)
    muscle_cost = objective.muscle_cost(base)
    # the final forward run again, so that the bank's state is the solution's end
    final = forward.run(nodes)
    return CoordinationResult(
        problem, options, forward.node_times_s, nodes, final, moments, reserves,
        summarize_reserves(problem.coordinates, reserves, problem.target), infeasible,
        float(objective.w @ muscle_cost), muscle_cost, history, forward.runs,
        time.perf_counter() - started)
