"""Whole-trajectory coordination against the forward run of the full model (docs/coordination.md).

Unknowns: drive nodes u (N nodes x n muscles, every ``node_step_s``). Objective:

    J(u) = sum_i w_i C_i(u) / C_ref                       cost (costs.py), C_ref: the cost with
                                                          every drive held at REFERENCE_DRIVE
         + w_res mean_{f,c} (rho_fc / peak_c)^2           reserves rho = target - r^T F(u)
         + w_smooth mean_{i,j} ((u_i,j+1 - u_i,j) / h)^2  smoothness (weight in s^2)

with F(u) the tendon forces of a forward run (forward.py) at the target frames. Each iteration:
one forward run gives J and the reserves; ``groups`` perturbed runs give the banded sensitivity
of every muscle's force at the frames, and of every muscle's cost, to its drive nodes (every
``refresh`` kept steps, and after two rejected ones; in between one run with every node
perturbed rescales its rows by the change of each muscle's local gain and gives the cost's
gradient without the lag: forward.ForwardModel.gains); the model of J around u (reserves linear
in the change, drive2 exact, energy costs linear plus a diagonal curvature from the change of
their gradient between iterates, a secant estimate kept >= 0) plus a damping lambda J(u)
mean(du^2) (lambda >= MIN_DAMPING) is minimised over 0 <= u + du <= 1 as one sparse bounded
linear least-squares problem (bounded_least_squares: a primal active set over SciPy's sparse
LU); the step is kept when the forward run's J falls (lambda / 3), else lambda x 4 and the step
is solved again (Levenberg-Marquardt), after one correction step from the rejected trial with
the same sensitivity (the reserves' second-order error along the cost's descent would otherwise
stall it at heavy reserve weights). Stops after ``max_iterations`` kept steps, or when a kept
step lowers J by less than ``tolerance`` of it.
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
from scipy import sparse
from scipy.sparse import linalg

from vm_ros.coordination.costs import DEFAULT_COST, cost_named
from vm_ros.coordination.forward import ForwardModel, ForwardOutput
from vm_ros.coordination.problem import CoordinationProblem
from vm_ros.coordination.reserves import (
    InfeasibleFrame,
    ReserveSummary,
    infeasible_frames,
    summarize_reserves,
)
from vm_ros.errors import VmRosError

REFERENCE_DRIVE = 0.5   # C_ref: the cost of every drive held at this value over the motion
DAMPING_UP, DAMPING_DOWN = 4.0, 3.0
# lambda never falls below this: in directions the reserves do not see at first order (two
# muscles trading force) only the damping and the cost's curvature bound the step
MIN_DAMPING = 0.01
MAX_REJECTED = 10
RESCALE_LIMITS = (0.2, 5.0)        # consecutive rejected steps before the iteration stops


@dataclass(frozen=True)
class SolverOptions:
    """How to solve: ``cost`` (costs.COSTS name), ``muscle_weights`` (name -> w_i, default 1),
    ``node_step_s`` (s between drive nodes), ``reserve_weight`` (w_res), ``smoothness``
    (w_smooth, s^2), ``max_iterations``, ``tolerance`` (relative fall of J that stops),
    ``initial_drive`` (every node's start), ``memory_s`` (forward.py), ``damping`` (initial
    lambda), ``delta`` (perturbation of the drive nodes), ``refresh`` (kept steps between full
    sensitivities; in between one run rescales it)."""

    cost: str = DEFAULT_COST
    muscle_weights: Mapping = field(default_factory=dict)
    node_step_s: float = 0.04
    reserve_weight: float = 1e5
    smoothness: float = 1e-4
    max_iterations: int = 12
    tolerance: float = 1e-4
    initial_drive: float = 0.1
    memory_s: float = 0.8
    damping: float = 1.0
    delta: float = 0.02
    refresh: int = 4

    def check(self, muscles) -> None:
        cost_named(self.cost)
        unknown = [m for m in self.muscle_weights if m not in muscles]
        if unknown:
            raise VmRosError(f"muscle weight for {unknown[0]!r}: not a muscle of the problem")
        for name in ("node_step_s", "reserve_weight", "delta"):
            if not getattr(self, name) > 0:
                raise VmRosError(f"{name} must be > 0 (got {getattr(self, name)})")
        if not (self.smoothness >= 0 and 0 <= self.initial_drive <= 1
                and self.max_iterations >= 0 and all(w >= 0 for w in
                                                     self.muscle_weights.values())):
            raise VmRosError("smoothness and muscle weights must be >= 0, initial_drive in "
                             "[0, 1], max_iterations >= 0")


@dataclass
class Iteration:
    """One kept step: objective parts, RMS reserve per coordinate (% of peak), damping, runs."""

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
    | history | list of Iteration | one per kept step (the first: the start) |
    | forward_runs, seconds | | forward runs made, wall time of the solve |
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


class _Objective:
    """J and its parts for a forward run (module docstring)."""

    def __init__(self, problem: CoordinationProblem, options: SolverOptions, weights, c_ref,
                 node_step_s):
        self.p, self.o, self.w, self.c_ref, self.h = problem, options, weights, c_ref, node_step_s

    def scaled_reserves(self, out: ForwardOutput) -> np.ndarray:
        """(T, C) reserves / peak."""
        return (self.p.target - self.p.moments(out.force_frames)) / self.p.peak

    def muscle_cost(self, out: ForwardOutput) -> np.ndarray:
        return out.rates[self.o.cost].sum(axis=0) * self.p.dt_s

    def parts(self, nodes, out: ForwardOutput) -> tuple[float, float, float]:
        cost = float(self.w @ self.muscle_cost(out)) / self.c_ref
        rho = self.scaled_reserves(out)
        tracking = self.o.reserve_weight * float(np.mean(rho ** 2))
        smooth = (self.o.smoothness * float(np.mean((np.diff(nodes, axis=0) / self.h) ** 2))
                  if len(nodes) > 1 else 0.0)
        return cost, tracking, smooth


def _subproblem(problem, options, objective, nodes, base, jac, grad, damping):
    """The step du (N, n) minimising the model of J (module docstring)."""
    p, o = problem, options
    n_nodes, n = nodes.shape
    size = n_nodes * n
    frames, coords = p.target.shape
    blocks, rhs = [], []
    # reserves: a_c (sum_i r_fic J_i du_i) = a_c (target - tau)
    a = np.sqrt(o.reserve_weight / (frames * coords)) / p.peak
    rows, cols, vals = [], [], []
    for i in range(n):
        coo = jac[i].tocoo()
        for c in range(coords):
            rows.append(coo.row * coords + c)
            cols.append(coo.col * n + i)
            vals.append(coo.data * p.moment_arm[coo.row, i, c] * a[c])
    blocks.append(sparse.csr_matrix((np.concatenate(vals), (np.concatenate(rows),
                                                            np.concatenate(cols))),
                                    shape=(frames * coords, size)))
    rhs.append(((p.target - p.moments(base.force_frames)) * a).ravel())
    # smoothness: s D (u + du) with D the node differences of each muscle
    if o.smoothness > 0 and n_nodes > 1:
        s = np.sqrt(o.smoothness / (n * (n_nodes - 1))) / objective.h
        diff = sparse.diags([-np.ones(n_nodes - 1), np.ones(n_nodes - 1)], [0, 1],
                            shape=(n_nodes - 1, n_nodes))
        d = sparse.kron(diff, sparse.identity(n)) * s
        blocks.append(d)
        rhs.append(-(d @ nodes.ravel()))
    g = np.zeros(size)
    if cost_named(o.cost).quadratic:
        # int U_i^2 dt = dt |W u_i|^2, W the step interpolation
        scale = np.sqrt(p.dt_s * objective.w / objective.c_ref)
        q = sparse.kron(objective.forward.steps, sparse.diags(scale))
        blocks.append(q)
        rhs.append(-(q @ nodes.ravel()))
    else:
        g = (grad[o.cost] * objective.w / objective.c_ref).ravel()
    # g du + 1/2 H du^2 + lambda mean(du^2) = |k du + g / (2 k)|^2 + const, k^2 = H / 2 + l
    k = np.sqrt(objective.curvature.ravel() / 2 + damping * objective.scale / size)
    blocks.append(sparse.diags(k))
    rhs.append(-g / (2 * k))
    matrix = sparse.vstack(blocks).tocsr()
    flat = nodes.ravel()
    return bounded_least_squares(matrix, np.concatenate(rhs), -flat, 1.0 - flat).reshape(
        n_nodes, n)


def bounded_least_squares(matrix, rhs, lower, upper, passes: int = 30) -> np.ndarray:
    """min |A x - b|^2 over lower <= x <= upper by a primal active set: the free variables
    from the sparse normal equations (SuperLU), variables beyond a bound fixed at it, fixed
    ones whose gradient points inside released; at most ``passes`` passes, then clipped."""
    normal = (matrix.T @ matrix).tocsc()
    target = matrix.T @ rhs
    x = np.clip(np.zeros(len(lower)), lower, upper)
    fixed = np.zeros(len(lower), bool)
    for _ in range(passes):
        free = np.flatnonzero(~fixed)
        if len(free):
            reduced = normal[free][:, free]
            x[free] = linalg.spsolve(reduced, target[free] - normal[free] @ np.where(fixed, x, 0))
        beyond = ~fixed & ((x < lower) | (x > upper))
        gradient = normal @ x - target
        release = fixed & (((x <= lower) & (gradient < 0)) | ((x >= upper) & (gradient > 0)))
        if not beyond.any() and not release.any():
            break
        x = np.clip(x, lower, upper)
        fixed = (fixed | beyond) & ~release
    return np.clip(x, lower, upper)


def solve(bank, problem: CoordinationProblem, options: SolverOptions | None = None,
          progress=None) -> CoordinationResult:
    """The drives of ``bank``'s muscles (the problem's, in order) that reproduce the problem's
    targets at least cost (module docstring). ``bank`` must run the cost's published model when
    the cost is one (costs.Cost.bank_models). ``progress``: called with each Iteration."""
    options = options or SolverOptions()
    options.check(problem.muscles)
    if tuple(bank.names) != tuple(problem.muscles):
        raise VmRosError("the bank's muscles are not the problem's (same names, same order)")
    cost = cost_named(options.cost)
    missing = [m for m in cost.bank_models if m not in bank.energetics_models]
    if missing:
        raise VmRosError(f"cost {cost.name}: the bank must run energetics model {missing[0]}")
    started = time.perf_counter()
    forward = ForwardModel(bank, problem, options.node_step_s,
                           {options.cost: cost.rate_function(bank.energetics_models)},
                           options.memory_s)
    weights = np.array([float(options.muscle_weights.get(m, 1.0)) for m in problem.muscles])
    n = len(problem.muscles)
    reference = forward.run(np.full((forward.n_nodes, n), REFERENCE_DRIVE))
    c_ref = max(float(weights @ reference.rates[options.cost].sum(axis=0)) * problem.dt_s,
                1e-12)
    objective = _Objective(problem, options, weights, c_ref, options.node_step_s)
    objective.forward = forward
    nodes = np.full((forward.n_nodes, n), float(options.initial_drive))
    base = forward.run(nodes)
    value = objective.scale = sum(objective.parts(nodes, base))
    history = [_iteration(objective, nodes, base, options.damping, forward, started)]
    damping = options.damping
    kept = rejected = 0
    jac = grad = full = None
    objective.curvature = np.zeros_like(nodes)
    secant = None  # (nodes, gradient) of the last sensitivity, for the cost's curvature
    while kept < options.max_iterations and rejected < MAX_REJECTED:
        fresh = full is None or kept % options.refresh == 0 or rejected >= 2
        if jac is None and fresh:
            full, grad = forward.sensitivity(nodes, base, options.delta)
            reference, _ = forward.gains(nodes, base, options.delta)
            jac, rejected = full, min(rejected, 1)
        elif jac is None:
            gain, grad = forward.gains(nodes, base, options.delta)
            jac = _rescaled(full, gain, reference)
        if not cost.quadratic and secant is not None and secant[0] is not nodes:
            objective.curvature = _secant_curvature(objective, secant, nodes, grad,
                                                    options.cost)
        secant = (nodes, grad)
        step = _subproblem(problem, options, objective, nodes, base, jac, grad, damping)
        trial = np.clip(nodes + step, 0.0, 1.0)
        out = forward.run(trial)
        trial_value = sum(objective.parts(trial, out))
        if trial_value >= value:  # one correction from the trial with the same sensitivity
            step = _subproblem(problem, options, objective, trial, out, jac, grad, damping)
            trial = np.clip(trial + step, 0.0, 1.0)
            out = forward.run(trial)
            trial_value = sum(objective.parts(trial, out))
        if trial_value < value:
            fall = (value - trial_value) / objective.scale
            nodes, base = trial, out
            value = objective.scale = trial_value
            damping = max(damping / DAMPING_DOWN, MIN_DAMPING)
            kept += 1
            rejected = 0
            jac = None
            history.append(_iteration(objective, nodes, base, damping, forward, started))
            if progress is not None:
                progress(history[-1])
            if fall < options.tolerance:
                break
        else:
            damping *= DAMPING_UP
            rejected += 1
            if rejected >= 2 and jac is not full:
                jac = None
    return _result(bank, problem, options, forward, objective, nodes, base, history, started)


def _secant_curvature(objective, secant, nodes, grad, name) -> np.ndarray:
    """Diagonal curvature (N, n) of the normalised cost from the change of its gradient per
    node since the last iterate (>= 0; kept where the drive moved less than 1e-3)."""
    old_nodes, old_grad = secant
    moved = nodes - old_nodes
    change = (grad[name] - old_grad[name]) * objective.w / objective.c_ref
    ratio = np.divide(change, moved, out=np.zeros_like(moved), where=np.abs(moved) > 1e-3)
    return np.where(np.abs(moved) > 1e-3, np.clip(ratio, 0.0, None), objective.curvature)


def _rescaled(full, gain, reference) -> list:
    """Each muscle's banded sensitivity with its rows scaled by the change of the local gain
    since it was computed (the ratio kept within RESCALE_LIMITS)."""
    ratio = np.clip(np.divide(gain, reference, out=np.ones_like(gain),
                              where=np.abs(reference) > 1e-9), *RESCALE_LIMITS)
    ratio = np.where(np.isfinite(ratio), ratio, 1.0)
    return [sparse.diags(ratio[:, i]) @ full[i] for i in range(len(full))]


def _iteration(objective, nodes, out, damping, forward, started) -> Iteration:
    cost, tracking, smooth = objective.parts(nodes, out)
    p = objective.p
    rms = summarize_reserves(p.coordinates, p.target - p.moments(out.force_frames),
                             p.target).rms_percent
    return Iteration(cost + tracking + smooth, cost, tracking, smooth, rms, damping,
                     forward.runs, time.perf_counter() - started)


def _result(bank, problem, options, forward, objective, nodes, base, history, started):
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
