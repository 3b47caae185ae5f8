"""Stage 1 of the coordination (docs/coordination.md): the distribution of the target moments
over the muscles as one linear programme over the frames, solved in overlapping time windows.

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
whose cost can lie above the hull. Solved by HiGHS (scipy.optimize.linprog) window by window
(``windows``; config/coordination.yaml distribution.window and overlap): the frames within
the window's length of its first, the force of the frame before the window fixed at the
previous window's solution (its smoothness term a constant plus |F*_a - F_fixed|), the
normalisers (C_ref, the means' counts) those of all frames; all but the window's last overlap
are kept and the next window starts there. The frames are coupled only through the smoothness
term, and HiGHS's time grows about as the cube of the frames in one LP, so windows make the
time linear in the frames; the result is a feasible point of the whole LP, equal to its
optimum without the smoothness term (docs/coordination.md).

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


@dataclass(frozen=True)
class _Terms:
    """The LP's normalisers over all frames (so that a window's LP is the whole LP's objective
    restricted to its frames): trapezoid weights dt (T,) s, C_ref, the counts the reserve and
    smoothness means divide by, and each muscle's largest table force F_max (n,) N."""

    dt: np.ndarray
    c_ref: float
    n_res: int
    n_s: int
    f_max: np.ndarray


def _terms(problem: CoordinationProblem, table: StaticTable, weights: np.ndarray) -> _Terms:
    frames, n, _ = table.force.shape
    dt = _frame_weights(problem.frame_times_s)
    reference = np.array([[np.interp(REFERENCE_DRIVE, table.levels[f, i], table.rate[f, i])
                           for i in range(n)] for f in range(frames)])
    c_ref = max(float(np.einsum("f,i,fi->", dt, weights, reference)), 1e-12)
    return _Terms(dt, c_ref, frames * problem.target.shape[1], max(frames - 1, 1) * n,
                  table.force.max(axis=(0, 2)).clip(min=1e-9))


def windows(times_s: np.ndarray, length_s: float, overlap_s: float) -> list:
    """(a, b, end) per window: the LP is solved on frames [a, b) (times within ``length_s`` of
    frame a's) and frames [a, end) are kept (within ``length_s - overlap_s``, at least one);
    the next window starts at end, the last keeps its every frame. ``length_s`` 0: one window
    over all frames."""
    frames = len(times_s)
    if length_s <= 0:
        return [(0, frames, frames)]
    out, a = [], 0
    while a < frames:
        b = max(a + 1, int(np.searchsorted(times_s, times_s[a] + length_s - 1e-9)))
        end = (frames if b >= frames else
               max(a + 1, int(np.searchsorted(times_s, times_s[a] + length_s - overlap_s
                                              - 1e-9))))
        out.append((a, min(b, frames), end))
        a = end
    return out


def _window_lp(problem: CoordinationProblem, table: StaticTable, weights: np.ndarray,
               reserve_weight: float, smoothness: float, terms: _Terms, a: int, b: int,
               before: np.ndarray | None):
    """The LP of the module docstring on frames [a, b), with the target force of frame a - 1
    fixed at ``before`` (n,) N (None: none, frame a is the first). Each target force is a
    variable of its own, x_fi = F*_fi / F_max,i, tied to the weights by one row
    sum_k lambda_fik F_fik / F_max,i - x_fi = 0: the moment and smoothness rows then hold one
    entry per muscle instead of one per level (the same LP, a third of the nonzeros).
    Returns (lambda (b - a, n, K), reserves (b - a, C) N m); VmRosError when HiGHS fails."""
    force, rate = table.force[a:b], table.rate[a:b]
    frames, n, levels = force.shape
    coords = problem.target.shape[1]
    times = problem.frame_times_s[max(a - 1, 0):b] if before is not None else \
        problem.frame_times_s[a:b]
    n_lambda, n_x, n_res = frames * n * levels, frames * n, frames * coords
    pairs = len(times) - 1 if smoothness > 0 else 0          # smoothness terms in the window
    lam = np.arange(n_lambda).reshape(frames, n, levels)
    x = n_lambda + np.arange(n_x).reshape(frames, n)
    res = n_lambda + n_x + np.arange(n_res)
    s = n_lambda + n_x + 2 * n_res + np.arange(pairs * n).reshape(pairs, n)
    n_var = n_lambda + n_x + 2 * n_res + pairs * n
    cost = np.zeros(n_var)
    cost[:n_lambda] = (rate * weights[None, :, None]
                       * terms.dt[a:b, None, None]).ravel() / terms.c_ref
    cost[res[0]:] = np.concatenate([np.tile(reserve_weight / (terms.n_res * problem.peak),
                                            2 * frames),
                                    np.repeat(smoothness / (terms.n_s * np.diff(times)[:pairs].clip(
                                        min=1e-9)), n)])
    # rows: sum_k lambda = 1 (fi), sum_k lambda F / F_max - x = 0 (fi), moments (fc)
    fi = np.arange(n_x)
    f_c = np.arange(n_res).reshape(frames, coords)
    arm = problem.moment_arm[a:b] * terms.f_max[None, :, None]              # (T, n, C)
    f_idx, i_idx, c_idx = np.nonzero(arm)
    eq = sparse.csr_matrix(
        (np.concatenate([np.ones(n_lambda), (force / terms.f_max[None, :, None]).ravel(),
                         -np.ones(n_x), arm[f_idx, i_idx, c_idx], np.ones(n_res),
                         -np.ones(n_res)]),
         (np.concatenate([np.repeat(fi, levels), n_x + np.repeat(fi, levels), n_x + fi,
                          2 * n_x + f_c[f_idx, c_idx], 2 * n_x + np.arange(n_res),
                          2 * n_x + np.arange(n_res)]),
          np.concatenate([lam.ravel(), lam.ravel(), x.ravel(), x[f_idx, i_idx], res,
                          res + n_res]))), shape=(2 * n_x + n_res, n_var))
    b_eq = np.concatenate([np.ones(n_x), np.zeros(n_x), problem.target[a:b].ravel()])
    a_ub = b_ub = None
    if pairs:
        # +-(x_f - x_(f-1)) - s <= 0, x_(a-1) = before / F_max a constant
        now = x[1:].ravel() if before is None else x.ravel()
        earlier = x[:-1].ravel() if before is None else \
            np.concatenate([np.full(n, -1), x[:-1].ravel()])
        rows = np.arange(pairs * n)
        known = earlier >= 0
        one = np.ones(pairs * n)
        a_ub = sparse.csr_matrix(
            (np.concatenate([one, -one[known], -one, -one, one[known], -one]),
             (np.concatenate([rows, rows[known], rows, pairs * n + rows,
                              pairs * n + rows[known], pairs * n + rows]),
              np.concatenate([now, earlier[known], s.ravel(), now, earlier[known],
                              s.ravel()]))), shape=(2 * pairs * n, n_var))
        fixed = np.zeros(pairs * n)
        if before is not None:
            fixed[:n] = before / terms.f_max
        b_ub = np.concatenate([fixed, -fixed])
    out = optimize.linprog(cost, A_ub=a_ub, b_ub=b_ub, A_eq=eq, b_eq=b_eq, bounds=(0, None),
                           method="highs")
    if out.status != 0:
        raise VmRosError(f"coordination: the distribution LP failed ({out.message})")
    rho = out.x[res] - out.x[res + n_res]
    return out.x[:n_lambda].reshape(frames, n, levels), rho.reshape(frames, coords)


def distribute(problem: CoordinationProblem, table: StaticTable, weights: np.ndarray,
               reserve_weight: float, smoothness: float, window_s: float = 0.0,
               overlap_s: float = 0.0) -> Distribution:
    """The LP of the module docstring, solved by HiGHS window by window (``windows``: each
    window's LP with the previous window's last kept force fixed before it; ``window_s`` 0:
    one LP over all frames); VmRosError when HiGHS fails. The objective is the LP's at the
    assembled solution."""
    terms = _terms(problem, table, weights)
    frames, n, levels = table.force.shape
    lam = np.empty((frames, n, levels))
    rho = np.empty(problem.target.shape)
    before = None
    for a, b, end in windows(problem.frame_times_s, window_s, overlap_s):
        lam_w, rho_w = _window_lp(problem, table, weights, reserve_weight, smoothness, terms,
                                  a, b, before)
        lam[a:end], rho[a:end] = lam_w[:end - a], rho_w[:end - a]
        before = np.einsum("ik,ik->i", lam[end - 1], table.force[end - 1])
    weights_lk = _symmetric(lam, table, problem, weights)
    force = np.einsum("fik,fik->fi", weights_lk, table.force)
    drive = np.einsum("fik,fik->fi", weights_lk, table.levels)
    objective = (np.einsum("fik,fik,i,f->", lam, table.rate, weights, terms.dt) / terms.c_ref
                 + reserve_weight * float(np.sum(np.abs(rho) / problem.peak)) / terms.n_res)
    if smoothness > 0 and frames > 1:
        change = np.abs(np.diff(np.einsum("fik,fik->fi", lam, table.force), axis=0))
        gap = np.diff(problem.frame_times_s).clip(min=1e-9)
        objective += smoothness * float(np.sum(change / terms.f_max / gap[:, None])) / terms.n_s
    return Distribution(force, drive, rho, float(objective), weights_lk)


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
            reserve_weight: float, smoothness: float, window_s: float = 0.0,
            overlap_s: float = 0.0):
    """The LP on every STRIDE-th level of the ``fine`` table (COARSE_LEVELS), then again, per
    frame and muscle, on COARSE_LEVELS consecutive fine levels around the coarse solution where
    that solution uses one level or two neighbours (a cost convex there), on the coarse levels
    elsewhere; returns (that table, its Distribution)."""
    shape = fine.force.shape[:2]
    wide = window(fine, np.zeros(shape, int), COARSE_LEVELS, STRIDE)
    coarse = distribute(problem, wide, weights, reserve_weight, smoothness, window_s,
                        overlap_s)
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
    return table, distribute(problem, table, weights, reserve_weight, smoothness, window_s,
                            overlap_s)
