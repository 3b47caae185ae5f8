"""Stage 1 of the coordination (docs/coordination.md): the distribution of the target moments
over the muscles, every frame at once, as one linear programme.

Table: for every target frame f, muscle i and drive level u_k (k = 1 .. K, evenly spaced in
[0, 1]), the muscle's quasi-static tendon force F_fik and cost rate c_fik: a bank of copies of
the muscles (MuscleBank.replicated) is reset to static equilibrium at the frame's path length
with its activation at the steady state of u_k, then stepped once (one model step, drive u_k,
same length, no path velocity); F and c are that step's tendon force and the cost's rate
(costs.Cost.rate: the same registry as the forward runs). The path velocity is ignored here
(isometric table); stage 2 (tracking.py) meets the forces on the moving muscles.

Linear programme, unknowns lambda_fik >= 0 (convex-combination weights), reserves
rho+_fc, rho-_fc >= 0 and, with smoothing, s_fi >= |u_fi - u_(f-1)i|:

    min  sum_f dt_f sum_i w_i sum_k lambda_fik c_fik / C_ref
         + w_res mean_fc (rho+_fc + rho-_fc) / peak_c
         + w_smooth mean_fi s_fi / (t_f - t_(f-1))
    s.t. sum_k lambda_fik = 1,
         sum_i r_fic sum_k lambda_fik F_fik + rho+_fc - rho-_fc = target_fc

with u_fi = sum_k lambda_fik u_k and C_ref = sum_f dt_f sum_i w_i c_fi(0.5) (the cost of every
drive at 0.5). The LP works on the lower convex hull of each muscle's (F, c) points: for a
cost convex in the force this is the static optimum (up to the table's resolution); where
c(F) is not convex the LP returns a mix of two table points, i.e. the convexified cost, and
the muscle's target force F*_fi = sum_k lambda_fik F_fik is then met in stage 2 with one drive,
whose cost can lie above the hull. Solved by HiGHS (scipy.optimize.linprog).

Muscles whose tables, moment arms and weights are identical are given the mean of their
weights lambda: the problem is symmetric in them, so the mean is also optimal, and it splits
their load equally (a vertex solution would split it arbitrarily).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import optimize, sparse

from vm_ros.coordination.problem import CoordinationProblem
from vm_ros.errors import VmRosError

COARSE_LEVELS, STRIDE = 21, 5   # the coarse LP: every 5th fine level, drives 0, 0.05, ..., 1
FINE_LEVELS = (COARSE_LEVELS - 1) * STRIDE + 1    # 101: drive resolution 0.01
TABLE_LENGTHS = 16              # path lengths per muscle the table is computed at
REFERENCE_DRIVE = 0.5


@dataclass(frozen=True)
class StaticTable:
    """Quasi-static force and cost rate per frame, muscle and drive level.

    | field | shape | unit |
    | --- | --- | --- |
    | levels | (T, n, K) | drive levels u_fik, increasing in k |
    | force | (T, n, K) | N, tendon force |
    | rate | (T, n, K) | the cost's rate (unit of the cost per s) |
    """

    levels: np.ndarray
    force: np.ndarray
    rate: np.ndarray

    def _segment(self, drive: np.ndarray) -> np.ndarray:
        """(T, n) index k of the table segment [u_k, u_k+1] holding ``drive``."""
        below = (self.levels <= drive[..., None]).sum(axis=2) - 1
        return np.clip(below, 0, self.levels.shape[2] - 2)

    def slope(self, drive: np.ndarray) -> np.ndarray:
        """(T, n) dF/du of each frame's table at drive (T, n) (piecewise linear)."""
        k = self._segment(drive)[..., None]
        pick = np.take_along_axis
        return ((pick(self.force, k + 1, 2) - pick(self.force, k, 2))
                / (pick(self.levels, k + 1, 2) - pick(self.levels, k, 2)))[..., 0]

    def drive_for(self, force: np.ndarray) -> np.ndarray:
        """(T, n) the drive whose table force is ``force`` (T, n), linear between levels,
        held at the ends (the table made non-decreasing in u first)."""
        table = np.maximum.accumulate(self.force, axis=2)
        out = np.empty(force.shape)
        for f, i in np.ndindex(force.shape):
            out[f, i] = np.interp(force[f, i], table[f, i], self.levels[f, i])
        return out


def frame_lengths(problem: CoordinationProblem) -> np.ndarray:
    """(T, n) path length at each frame (the model step nearest the frame)."""
    step = np.clip(np.round(problem.frame_times_s / problem.dt_s).astype(int), 0,
                   problem.n_steps - 1)
    return problem.path_length[step]


def static_table(bank, problem: CoordinationProblem, rate_function, levels: int,
                 lengths: int) -> StaticTable:
    """The StaticTable of ``bank``'s muscles over ``problem``'s frames at ``levels`` evenly
    spaced drives (module docstring): computed at ``lengths`` path lengths per muscle evenly
    spanning its frames' lengths, then linear in the path length to each frame's;
    ``rate_function(trajectory, drive)`` -> (1, copies) rates."""
    at_frames = frame_lengths(problem)
    frames, n = at_frames.shape
    u = np.linspace(0.0, 1.0, int(levels))
    grid = np.linspace(at_frames.min(axis=0), at_frames.max(axis=0), int(lengths))  # (G, n)
    copies = bank.replicated(len(grid) * len(u))
    length = np.repeat(grid, len(u), axis=0).ravel()          # copy (g, k, i)
    excitation = np.tile(np.repeat(u, n), len(grid))
    copies.reset(path_length=length, excitation=excitation)
    trajectory = copies.run(problem.dt_s, excitation[None, :], length[None, :])
    shape = (len(grid), len(u), n)
    on_grid = [trajectory.force[0].reshape(shape),
               rate_function(trajectory, excitation[None, :])[0].reshape(shape)]
    force, rate = (np.empty((frames, n, len(u))) for _ in range(2))
    for i in range(n):
        span = grid[-1, i] - grid[0, i]
        where = (np.zeros(frames) if span <= 0 else
                 (at_frames[:, i] - grid[0, i]) / span * (len(grid) - 1))
        low = np.clip(np.floor(where).astype(int), 0, max(len(grid) - 2, 0))
        high = np.minimum(low + 1, len(grid) - 1)
        w = (where - low)[:, None]
        for out, table in zip((force, rate), on_grid, strict=True):
            out[:, i] = (1 - w) * table[low, :, i] + w * table[high, :, i]
    return StaticTable(np.array(np.broadcast_to(u, force.shape)), force, rate)


def window(table: StaticTable, first: np.ndarray, count: int, stride: int = 1) -> StaticTable:
    """The table restricted, per frame and muscle, to levels first, first + stride, ...
    (``count`` of them; ``first`` (T, n) of level indices)."""
    index = first[..., None] + stride * np.arange(count)
    return StaticTable(*(np.take_along_axis(a, index, axis=2)
                         for a in (table.levels, table.force, table.rate)))


@dataclass(frozen=True)
class Distribution:
    """Stage 1's solution: target forces (T, n) N, the LP's drives (T, n) (sum lambda u_k),
    reserves (T, C), the LP's objective and its weights lambda (T, n, K)."""

    force: np.ndarray
    drive: np.ndarray
    reserves: np.ndarray
    objective: float
    weights: np.ndarray


def _frame_weights(times: np.ndarray) -> np.ndarray:
    """Trapezoid weights (s) of the frame times."""
    if len(times) == 1:
        return np.ones(1)
    gaps = np.diff(times)
    return np.concatenate([[gaps[0] / 2], (gaps[:-1] + gaps[1:]) / 2, [gaps[-1] / 2]])


def distribute(problem: CoordinationProblem, table: StaticTable, weights: np.ndarray,
               reserve_weight: float, smoothness: float) -> Distribution:
    """The LP of the module docstring, solved by HiGHS; VmRosError when HiGHS fails."""
    frames, n, levels = table.force.shape
    coords = problem.target.shape[1]
    dt = _frame_weights(problem.frame_times_s)
    reference = np.array([[np.interp(REFERENCE_DRIVE, table.levels[f, i], table.rate[f, i])
                           for i in range(n)] for f in range(frames)])
    c_ref = max(float(np.einsum("f,i,fi->", dt, weights, reference)), 1e-12)
    n_lambda = frames * n * levels
    n_res = frames * coords
    smooth = smoothness > 0 and frames > 1
    n_s = (frames - 1) * n if smooth else 0
    cost = np.concatenate([
        (table.rate * weights[None, :, None] * dt[:, None, None]).ravel() / c_ref,
        np.tile(reserve_weight / (n_res * problem.peak), 2 * frames)])
    lam = np.arange(n_lambda).reshape(frames, n, levels)
    # sum_k lambda = 1
    rows_a = np.repeat(np.arange(frames * n), levels)
    cols_a = lam.ravel()
    vals_a = np.ones(n_lambda)
    # moments: row T n + f C + c
    f_idx, i_idx, k_idx, c_idx = np.meshgrid(np.arange(frames), np.arange(n), np.arange(levels),
                                             np.arange(coords), indexing="ij")
    arm = problem.moment_arm[f_idx, i_idx, c_idx]
    nonzero = arm != 0
    rows_m = frames * n + (f_idx * coords + c_idx)[nonzero]
    cols_m = lam[f_idx, i_idx, k_idx][nonzero]
    vals_m = (arm * table.force[f_idx, i_idx, k_idx])[nonzero]
    res = n_lambda + np.arange(n_res)
    rows_r = frames * n + np.arange(n_res)
    eq = sparse.csr_matrix((np.concatenate([vals_a, vals_m, np.ones(n_res), -np.ones(n_res)]),
                            (np.concatenate([rows_a, rows_m, rows_r, rows_r]),
                             np.concatenate([cols_a, cols_m, res, res + n_res]))),
                           shape=(frames * n + n_res, n_lambda + 2 * n_res + n_s))
    b_eq = np.concatenate([np.ones(frames * n), problem.target.ravel()])
    a_ub = b_ub = None
    if smooth:
        gap = np.diff(problem.frame_times_s).clip(min=1e-9)
        cost = np.concatenate([cost, np.repeat(smoothness / (n_s * gap), n)])
        # +-(F_f - F_(f-1)) / F_max - s <= 0, F_f = sum_k lambda F_fk; row (f - 1) n + i
        f1, i1, k1 = np.meshgrid(np.arange(1, frames), np.arange(n), np.arange(levels),
                                 indexing="ij")
        row = ((f1 - 1) * n + i1).ravel()
        scale = table.force.max(axis=(0, 2)).clip(min=1e-9)[i1]
        now = (table.force[f1, i1, k1] / scale).ravel()
        before = (table.force[f1 - 1, i1, k1] / scale).ravel()
        rows = np.concatenate([row, row, np.arange(n_s)])
        cols = np.concatenate([lam[f1, i1, k1].ravel(), lam[f1 - 1, i1, k1].ravel(),
                               n_lambda + 2 * n_res + np.arange(n_s)])
        diff = sparse.csr_matrix((np.concatenate([now, -before, -np.ones(n_s)]), (rows, cols)),
                                 shape=(n_s, eq.shape[1]))
        mirror = sparse.csr_matrix((np.concatenate([-now, before, -np.ones(n_s)]),
                                    (rows, cols)), shape=(n_s, eq.shape[1]))
        a_ub = sparse.vstack([diff, mirror]).tocsr()
        b_ub = np.zeros(2 * n_s)
    out = optimize.linprog(cost, A_ub=a_ub, b_ub=b_ub, A_eq=eq, b_eq=b_eq, bounds=(0, None),
                           method="highs")
    if out.status != 0:
        raise VmRosError(f"coordination: the distribution LP failed ({out.message})")
    weights_lk = _symmetric(out.x[:n_lambda].reshape(frames, n, levels), table, problem,
                            weights)
    force = np.einsum("fik,fik->fi", weights_lk, table.force)
    drive = np.einsum("fik,fik->fi", weights_lk, table.levels)
    rho = out.x[n_lambda:n_lambda + n_res] - out.x[n_lambda + n_res:n_lambda + 2 * n_res]
    return Distribution(force, drive, rho.reshape(frames, coords), float(out.fun), weights_lk)


def _symmetric(lam: np.ndarray, table: StaticTable, problem: CoordinationProblem,
               weights: np.ndarray) -> np.ndarray:
    """``lam`` with the weights of identical muscles (same table, arms, weight) averaged."""
    groups: dict = {}
    for i in range(lam.shape[1]):
        key = (table.force[:, i].tobytes(), table.rate[:, i].tobytes(),
               problem.moment_arm[:, i].tobytes(), float(weights[i]))
        groups.setdefault(key, []).append(i)
    out = lam.copy()
    for members in groups.values():
        if len(members) > 1:
            out[:, members] = lam[:, members].mean(axis=1, keepdims=True)
    return out


def refined(problem: CoordinationProblem, fine: StaticTable, weights: np.ndarray,
            reserve_weight: float, smoothness: float):
    """The LP on every STRIDE-th level of the ``fine`` table (COARSE_LEVELS), then again, per
    frame and muscle, on COARSE_LEVELS consecutive fine levels around the coarse solution where
    that solution uses one level or two neighbours (a cost convex there), on the coarse levels
    elsewhere; returns (that table, its Distribution)."""
    shape = fine.force.shape[:2]
    wide = window(fine, np.zeros(shape, int), COARSE_LEVELS, STRIDE)
    coarse = distribute(problem, wide, weights, reserve_weight, smoothness)
    used = coarse.weights > 1e-9
    first = np.argmax(used, axis=2)
    last = COARSE_LEVELS - 1 - np.argmax(used[..., ::-1], axis=2)
    local = (last - first <= 1)[..., None]
    start = np.clip(first * STRIDE - (COARSE_LEVELS - STRIDE) // 2, 0,
                    FINE_LEVELS - COARSE_LEVELS)
    near = window(fine, start, COARSE_LEVELS, 1)
    table = StaticTable(*(np.where(local, a, b) for a, b in
                          zip((near.levels, near.force, near.rate),
                              (wide.levels, wide.force, wide.rate), strict=True)))
    return table, distribute(problem, table, weights, reserve_weight, smoothness)
