"""Receding-horizon coordination: the drives of the next period that make the muscles' joint
moments follow target joint moments over a horizon ahead (muscle_node's live coordination;
NumPy, SciPy and OSQP, no rclpy).

Each period of p model steps of dt, from the bank's state x0, with the coming path lengths
L(t) and moment arms r(t) of the m coordinated muscles and the targets tau(t) over the horizon
of k >= p steps, the drives are piecewise constant in B blocks (block 0 is the next period, the
rest of the horizon is split evenly), U of shape (B, m), each in [0, 1], and

    minimise  (1/S) sum_s sum_j (M_j(t_s; U) - tau_j(t_s))^2                  tracking, (N m)^2
              + cost(U)                   vm_ros.coordination.costs: tsianos2012 (default), ...
              + smoothness * (|U_0 - u_prev|^2 + sum_{b>0} |U_b - U_{b-1}|^2)

    M(t; U) = r(t)^T F(t; U), F the tendon forces of a forward run of the full model from x0
    (drive filter, activation, fascicle mass, tendon), t_s every ``eval_step_s`` of the horizon.

Solved by one Gauss-Newton step per period about the previous plan moved on by one period
(shifted_plan). The
path is prescribed, so muscle i's force depends on its own drive only: the derivatives of every
force with respect to block b of every drive come from one run with all of block b raised by
``probe_drive``. The B + 1 runs (nominal, one per block) run as banks of copies of the muscles,
block by block (RecedingHorizon). The linearised problem is a bounded QP, solved by OSQP (BoxQP: set
up once, updated and warm started each period); block 0 is applied, the rest seeds the next
period.

What is approximated: a secant linearisation per period (force is not linear in drive); the
horizon's motion is what the caller predicts (muscle_node: the latest joint sample moved on by its
velocity); moments beyond the horizon are not seen (a rise that needs more lead than the horizon
arrives late; the activation of VM rises 50 % in 77-132 ms, issue 30).
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import osqp
from scipy import sparse

from vm_ros.coordination import costs
from vm_ros.model import MuscleBank
from vm_ros.model.layout import STATE_NAMES, BankState

DRIVE_FLOOR_WEIGHT = 1e-3  # (N m)^2 per drive^2: keeps the energy cost's quadratic part > 0


def frame_interpolation(frame_times_s, times_s) -> tuple[np.ndarray, np.ndarray]:
    """(low, weight) of linear interpolation between the frames at ``times_s``, held before the
    first frame and after the last: value = (1 - w) v[low] + w v[low + 1]."""
    frames = np.asarray(frame_times_s, dtype=float)
    if len(frames) == 1:
        return np.zeros(len(times_s), dtype=int), np.zeros(len(times_s))
    t = np.clip(np.asarray(times_s, dtype=float), frames[0], frames[-1])
    low = np.clip(np.searchsorted(frames, t, side="right") - 1, 0, len(frames) - 2)
    weight = (t - frames[low]) / np.maximum(frames[low + 1] - frames[low], 1e-15)
    return low, weight


def at_times(values, frame_times_s, times_s) -> np.ndarray:
    """``values`` (T, ...) given at the frames, linearly interpolated to ``times_s``."""
    low, weight = frame_interpolation(frame_times_s, times_s)
    values = np.asarray(values, dtype=float)
    high = np.minimum(low + 1, len(values) - 1)
    shape = (-1,) + (1,) * (values.ndim - 1)
    return values[low] * (1.0 - weight).reshape(shape) + values[high] * weight.reshape(shape)


@dataclass(frozen=True)
class HorizonSettings:
    """The receding-horizon problem's constants (module docstring).

    | field | unit | meaning |
    | horizon_s | s | look-ahead H (>= one period) |
    | blocks | - | B drive blocks over the horizon (block 0 = the next period) |
    | cost | - | a name of vm_ros.coordination.costs.COSTS |
    | effort_weight | (N m)^2 per W, per drive^2 for drive2 | weight of the cost (None: RATE_WEIGHT
      or DRIVE2_WEIGHT) |
    | smoothness | (N m)^2 per drive^2 | weight of drive changes between blocks |
    | damping | (N m)^2 per drive^2 | weight of each drive's step away from the plan linearised
      about (a trust region: the linearisation holds near it) |
    | eval_step_s | s | spacing of the tracked samples t_s |
    | probe_drive | 1 | drive step of the derivative runs (a secant: from rest, force over
      150 ms grows much faster than linearly with drive) |
    """

    horizon_s: float = 0.15
    blocks: int = 3
    cost: str = "tsianos2012"
    effort_weight: float | None = None
    smoothness: float = 1.0
    damping: float = 0.0
    eval_step_s: float = 0.005
    probe_drive: float = 0.2


@dataclass(frozen=True)
class Probe:
    """What the cost terms see of one linearisation (B blocks, m muscles, S tracked samples).

    | field | shape | unit |
    | nominal | (B, m) | 1, the plan linearised about |
    | delta | (B, m) | 1, the drive step of each derivative run |
    | block_weight | (B,) | 1, each block's share of the horizon |
    | energy_rate | (m,) | W (drive2: 1), horizon mean of each muscle's cost rate, nominal plan |
    | energy_slope | (B, m) | its change per unit drive of block b |
    """

    nominal: np.ndarray
    delta: np.ndarray
    block_weight: np.ndarray
    energy_rate: np.ndarray
    energy_slope: np.ndarray


def _drive2(probe: Probe, weight: float) -> tuple[np.ndarray, np.ndarray]:
    """sum_b w_b sum_i u_bi^2 (OpenSim static optimisation's sum a^2, drive for activation):
    exact."""
    return 2.0 * weight * np.repeat(probe.block_weight[:, None], probe.nominal.shape[1], 1), \
        np.zeros_like(probe.nominal)


def _rate(probe: Probe, weight: float) -> tuple[np.ndarray, np.ndarray]:
    """The horizon mean of an energy rate summed over the muscles, linearised: dE_i/dU_bi from
    the derivative runs (a drive^2 floor of DRIVE_FLOOR_WEIGHT keeps the problem strictly
    convex)."""
    diag, _ = _drive2(probe, DRIVE_FLOOR_WEIGHT)
    return diag, weight * np.maximum(probe.energy_slope, 0.0)


# The costs are those of the offline coordination, by name (vm_ros.coordination.costs.COSTS:
# tsianos2012, the default, drive2 and the published energetics models on VM's state); the
# window's term: exact for the quadratic drive2, linearised for the rates. Default weights: on
# the slow elbow motion of test_coordination_live.py (peak 10 N m) tracking stays within 1.2 %
# RMS of peak with them; ten times larger weights gave 8 % (measured once).
RATE_WEIGHT, DRIVE2_WEIGHT = 1e-3, 0.1   # (N m)^2 per W, (N m)^2 per drive^2


def window_term(name: str) -> tuple[Callable[[Probe, float], tuple], float]:
    """(term(probe, weight) -> (D, g), default weight) of the cost ``name``: the cost is
    1/2 U D U + g U + const, D and g of shape (B, m); VmRosError for an unknown name."""
    cost = costs.cost_named(name)
    return (_drive2, DRIVE2_WEIGHT) if cost.quadratic else (_rate, RATE_WEIGHT)


@dataclass(frozen=True)
class WindowPlan:
    """One period's solution.

    | field | shape | unit |
    | drive | (m,) | 1, drives of the next period (block 0) |
    | plan | (B, m) | 1, every block |
    | predicted_moment | (S, c) | N m (N), M(t_s) of the linearised plan |
    """

    drive: np.ndarray
    plan: np.ndarray
    predicted_moment: np.ndarray


def block_edges(k: int, p: int, blocks: int) -> np.ndarray:
    """Step indices [0, p, ..., k] of the blocks: block 0 is the first p steps, the other
    blocks split the remaining k - p steps evenly (fewer blocks when there are fewer steps)."""
    rest = max(min(blocks - 1, k - p), 0)
    return np.concatenate(([0], p + np.round(np.linspace(0, k - p, rest + 1)).astype(int)))


def coupled_pairs(moment_arm, tracked) -> tuple[np.ndarray, np.ndarray]:
    """(i, j), every ordered pair of muscles that cross a common tracked joint (a nonzero moment
    arm at some sample), and every (i, i): where the tracking term couples muscle i's drives to
    muscle j's. 80 muscles over 27 joints: 320 pairs of the 6400."""
    crosses = np.any(moment_arm[:, :, tracked] != 0.0, axis=0).astype(float)   # (m, c)
    share = crosses @ crosses.T > 0.0
    np.fill_diagonal(share, True)
    return np.nonzero(share)


def tracking_hessian(moment_arm, sens, tracked) -> np.ndarray:
    """(B m, B m) sum_s J_s^T J_s of the tracking term, J_s[c, (b, i)] = r_sic dF_si/dU_bi,
    dense (window_hessian's entries, for tests and small problems)."""
    n_blocks, _, m = sens.shape
    rows, cols, values = window_entries(moment_arm, sens, tracked)
    hessian = np.zeros((n_blocks * m, n_blocks * m))
    hessian[rows, cols] = values
    return hessian


def window_entries(moment_arm, sens, tracked) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The nonzero entries (rows, cols, values) of the tracking Hessian sum_s J_s^T J_s, both
    triangles, unknown (b, i) at b m + i:

        H[(b, i), (d, j)] = sum_s (sum_c r_sic r_sjc) dF_bsi dF_dsj

    over the coupled_pairs (i, j) only: without the (S c, B m) Jacobian or a dense (B m)^2
    matrix, whose products cost 80 muscles most of a period."""
    n_blocks, _, m = sens.shape
    arms = moment_arm[:, :, tracked]
    if np.array_equal(arms, np.broadcast_to(arms[:1], arms.shape)):
        arms = arms[:1]  # held over the horizon (muscle_node): one sample stands for all
    i, j = coupled_pairs(arms, np.ones(arms.shape[2], dtype=bool))
    coupling = np.einsum("spc,spc->sp", arms[:, i], arms[:, j])                 # (S or 1, P)
    values = np.einsum("bsp,dsp->bdp", sens[:, :, i] * coupling, sens[:, :, j])  # (B, B, P)
    blocks = np.arange(n_blocks) * m
    rows = np.broadcast_to((blocks[:, None, None] + i), values.shape).ravel()
    cols = np.broadcast_to((blocks[None, :, None] + j), values.shape).ravel()
    return rows, cols, values.ravel()


def solve_window(forces, moment_arm, target, tracked, probe: Probe, settings: HorizonSettings,
                 previous_drive, qp: BoxQP | None = None) -> WindowPlan:
    """The linearised problem of one period, solved (the one function that poses and solves it:
    another solver replaces this one).

    forces: (B + 1, S, m) N at the tracked samples, run 0 nominal, run b + 1 with block b
    raised by probe.delta[b]; moment_arm (S, m, c) m; target (S, c) N m; tracked (c,) bool;
    previous_drive (m,) the drive applied last period; qp: the BoxQP to solve it with (kept
    from period to period for its set-up and warm start; None: a new one).
    """
    n_blocks, m = probe.nominal.shape
    n = n_blocks * m
    sens = (forces[1:] - forces[0]) / probe.delta[:, None, :]          # (B, S, m) N per drive
    moment0 = np.einsum("smc,sm->sc", moment_arm, forces[0])            # (S, c)
    x0 = probe.nominal.ravel()
    scale = 1.0 / max(len(moment0), 1)
    arms = moment_arm[:, :, tracked]
    residual = (target - moment0)[:, tracked]                           # (S, c)
    # 1/2 x H x - f x: f = J^T (residual + J x0) without J, J^T v = sum_s dF_bs o (r_s v_s)
    linear = scale * np.einsum("bsi,si->bi", sens,
                               np.einsum("sic,sc->si", arms, residual)).ravel()
    rows, cols, values = window_entries(moment_arm, sens, tracked)
    values = scale * values
    linear += np.bincount(rows, values * x0[cols], minlength=n)        # + H x0
    term, default = window_term(settings.cost)
    diag, lin = term(probe, default if settings.effort_weight is None else settings.effort_weight)
    linear -= lin.ravel()
    # the cost's diagonal and the smoothness D^T D (same muscle, blocks b and d) on the entries
    # (b, i), (d, i), which the pairs (i, i) hold
    same = rows % m == cols % m
    b, d = rows[same] // m, cols[same] // m
    values[same] += np.where(b == d, diag.ravel()[rows[same]], 0.0)
    if settings.smoothness > 0:
        values[same] += settings.smoothness * smoothness_matrix(n_blocks)[b, d]
        linear[:m] += settings.smoothness * np.asarray(previous_drive, dtype=float)
    if settings.damping > 0:  # 1/2 damping |x - x0|^2
        values[rows == cols] += settings.damping
        linear += settings.damping * x0
    upper = rows <= cols
    solution = (qp or BoxQP()).solve_entries(rows[upper], cols[upper], values[upper], linear, x0)
    plan = solution.reshape(n_blocks, m)
    change = np.einsum("bsm,bm->sm", sens, plan - probe.nominal)        # (S, m) N
    predicted = moment0 + np.einsum("smc,sm->sc", moment_arm, change)
    return WindowPlan(plan[0].copy(), plan, predicted)


def shifted_plan(plan, edges) -> np.ndarray:
    """(B, m) the previous period's ``plan`` (blocks over the step ``edges``, block_edges) one
    period on: each block takes the old plan's drive at its middle step, one period (the first
    block's steps) later, the last block held beyond the horizon."""
    per_step = np.repeat(plan, np.diff(edges), axis=0)                     # (k, m)
    middle = (edges[:-1] + edges[1:]) // 2 + edges[1]
    return per_step[np.minimum(middle, len(per_step) - 1)]


@functools.lru_cache(maxsize=4)
def smoothness_matrix(n_blocks: int) -> np.ndarray:
    """D^T D of one muscle's block-to-block changes U_b - U_{b-1} (U_{-1} fixed: the applied
    drive), (B, B); made once per size (read-only)."""
    change = np.eye(n_blocks) - np.eye(n_blocks, k=-1)
    product = change.T @ change
    product.flags.writeable = False
    return product


class BoxQP:
    """argmin 1/2 x H x - f x over 0 <= x <= 1, H symmetric positive definite, by OSQP (an
    operator-splitting QP solver), set up once for the entries of H's upper triangle and, while
    a later H has the same entries (rows and columns), updated in place (values of H, f) and
    warm started from ``start`` (the caller's previous plan) instead of set up again. Muscles
    that share no tracked joint are separate blocks of H; OSQP's sparse factorisation keeps them
    apart without splitting the problem here.

    Tolerances: OSQP_EPS absolute and relative, without OSQP's solution polishing (OSQP 1.1.3's
    C code prints a line on stdout whenever polishing finds no active bound, whatever
    ``verbose``: every period of a node); on random problems of 8 unknowns the answer equals a
    tight L-BFGS-B reference within 1e-6 (test_coordination_live.py). A solve that OSQP does not
    report solved (SOLVED) is counted in ``unsolved`` and its iterate, clipped into the box, is
    used (the start when the iterate is not finite).
    """

    def __init__(self):
        self._solver = None
        self._entries: tuple | None = None   # (n, rows, cols) of the set-up
        self._order = None                   # the entries in P's CSC order
        self.unsolved = 0

    def _setup(self, rows, cols, values, linear) -> None:
        n = len(linear)
        self._entries = (n, rows.copy(), cols.copy())
        self._order = np.lexsort((rows, cols))  # by column, then row: CSC
        indptr = np.concatenate(([0], np.cumsum(np.bincount(cols, minlength=n))))
        upper = sparse.csc_matrix((values[self._order], rows[self._order], indptr),
                                  shape=(n, n))
        self._solver = osqp.OSQP()
        self._solver.setup(P=upper, q=-linear, A=sparse.identity(n, format="csc"),
                           l=np.zeros(n), u=np.ones(n), verbose=False, warm_starting=True,
                           polishing=False, eps_abs=OSQP_EPS, eps_rel=OSQP_EPS,
                           max_iter=OSQP_MAX_ITER)

    def solve_entries(self, rows, cols, values, linear, start) -> np.ndarray:
        """H given by its upper triangle's entries (rows <= cols, each once, every diagonal
        entry among them)."""
        known = self._entries
        if known is None or known[0] != len(linear) or not (
                np.array_equal(known[1], rows) and np.array_equal(known[2], cols)):
            self._setup(rows, cols, values, linear)
        else:
            self._solver.update(q=-linear, Px=values[self._order])
        self._solver.warm_start(x=np.clip(np.asarray(start, dtype=float), 0.0, 1.0))
        result = self._solver.solve(raise_error=False)
        if result.info.status_val not in SOLVED:
            self.unsolved += 1
        x = result.x
        if x is None or not np.all(np.isfinite(x)):
            return np.clip(np.asarray(start, dtype=float), 0.0, 1.0)
        return np.clip(x, 0.0, 1.0)

    def solve(self, hessian, linear, start) -> np.ndarray:
        """H dense (n, n): its upper triangle's nonzeros and the diagonal are the entries."""
        upper = np.triu(hessian) != 0.0
        upper[np.diag_indices_from(upper)] = True
        rows, cols = np.nonzero(upper)
        return self.solve_entries(rows, cols, hessian[rows, cols], linear, start)


OSQP_EPS, OSQP_MAX_ITER = 1e-7, 4000
SOLVED = (1, 2)  # OSQP_SOLVED, OSQP_SOLVED_INACCURATE


def box_qp(hessian, linear, start) -> np.ndarray:
    """argmin 1/2 x H x - f x over 0 <= x <= 1 (a one-off BoxQP)."""
    return BoxQP().solve(hessian, linear, start)


def _replicated(state, index, copies: int):
    """The bank state of muscles ``index``, ``copies`` times along the muscle axis."""
    return BankState(time_s=float(state.time_s), **{
        name: np.concatenate([getattr(state, name)[index]] * copies) for name in STATE_NAMES})


def _with_first_again(state, m: int):
    """``state`` with its first ``m`` muscles appended once more."""
    return BankState(time_s=float(state.time_s), **{
        name: np.concatenate([getattr(state, name), getattr(state, name)[:m]])
        for name in STATE_NAMES})


class RecedingHorizon:
    """The live coordinator of the muscles ``index`` of ``bank`` (module docstring). It owns
    its probe banks (2, ..., B + 1 copies of those muscles, no published energetics models) and
    the plan carried from one period to the next; the caller's bank is never stepped here.

    The probe runs block by block: over block s the nominal plan and the copies that raise
    blocks 0..s; the copy that raises block s starts at the block's start from the nominal's
    state there (before it, its drives are the nominal's, and every muscle's arithmetic is its
    own, so that is the state it would have reached). 3 blocks over 30 steps: 102 copy-steps
    instead of 120.

    The forward runs step ``probe_dt_s``: ``settings.eval_step_s`` rounded so that a whole
    number of them make the period (``period_s``); the tracked samples are the ends of those
    steps. The fixed step's force at 5 ms steps (the default) is within 1.5 % of its force at
    1 ms, at 10 ms steps within 4 % (a 150 ms run at drive 0.5 on a moving path, five library
    muscles; test_coordination_live.py): the probe needs the derivatives, and each period starts
    again from the caller's state. 10 ms would halve the probe run, most of an 80-muscle
    period's work, but with it the drives of two identical muscles on one joint (8 N m held)
    oscillated over the first periods and split apart by up to 0.25 (at 5 ms: 4e-13; the same
    with the active-set QP solver this replaced: a property of the coarser probe, not of OSQP;
    measured once)."""

    def __init__(self, bank: MuscleBank, index, period_s: float,
                 settings: HorizonSettings = HorizonSettings()):
        self.cost = costs.cost_named(settings.cost)  # VmRosError for an unknown name
        self.index = np.asarray(index, dtype=int)
        self.settings = settings
        self.period_steps = max(int(round(period_s / settings.eval_step_s)), 1)
        self.probe_dt_s = period_s / self.period_steps
        self.steps = max(int(round(settings.horizon_s / self.probe_dt_s)), self.period_steps)
        self.edges = block_edges(self.steps, self.period_steps, settings.blocks)
        self.n_blocks = len(self.edges) - 1
        self.m = len(self.index)
        specs = [bank.specs[i] for i in self.index]
        self.probe_banks = [MuscleBank(specs * (s + 2), bank.params,
                                       recruitment=bank.recruitment.name,
                                       recovery_mode=bank.recovery_mode, backend=bank.backend,
                                       energetics_models=self.cost.bank_models)
                            for s in range(self.n_blocks)]
        self.plan = np.zeros((self.n_blocks, self.m))
        self.drive = np.zeros(self.m)  # applied last period
        self.qp = BoxQP()  # set up at the first period, updated after

    @property
    def start_offsets_s(self) -> np.ndarray:
        """(k,) s after the window start at which each probe step starts (path lengths)."""
        return self.probe_dt_s * np.arange(self.steps)

    @property
    def end_offsets_s(self) -> np.ndarray:
        """(k,) s after the window start at which each probe step ends (targets, moment arms)."""
        return self.probe_dt_s * np.arange(1, self.steps + 1)

    def _probe(self, state, plans, path_length, path_velocity) -> tuple:
        """(forces N, cost rates) (B + 1, k, m) of the nominal plan (copy 0) and of the plans
        raising block b (copy b + 1), block by block (class docstring)."""
        m, edges = self.m, self.edges
        per_step = np.repeat(plans, np.diff(edges), axis=1)               # (B + 1, k, m)
        forces, rates = np.empty_like(per_step), np.empty_like(per_step)
        current = _replicated(state, self.index, 2)
        for s, bank in enumerate(self.probe_banks):
            a, b, copies = edges[s], edges[s + 1], s + 2
            if s > 0:  # block s's copy starts from the nominal's state
                current = _with_first_again(current, m)
            drives = np.ascontiguousarray(
                per_step[:copies, a:b].transpose(1, 0, 2).reshape(b - a, copies * m))
            bank.set_state(current)
            run = bank.run(self.probe_dt_s, drives, np.tile(path_length[a:b], (1, copies)),
                           np.tile(path_velocity[a:b], (1, copies)))
            current = bank.restore_point()
            forces[:copies, a:b] = run.force.reshape(b - a, copies, m).transpose(1, 0, 2)
            rates[:copies, a:b] = self.cost.rate(run, drives, self.cost.bank_models).reshape(
                b - a, copies, m).transpose(1, 0, 2)
        for block in range(1, self.n_blocks):  # before its block, a copy is the nominal
            forces[block + 1, :edges[block]] = forces[0, :edges[block]]
            rates[block + 1, :edges[block]] = rates[0, :edges[block]]
        return forces, rates

    def solve(self, state, path_length, path_velocity, moment_arm, target,
              tracked=None) -> WindowPlan:
        """The drives of the next period.

        state: the caller's BankState at the window start; path_length, path_velocity: (k, m)
        m and m/s of the coordinated muscles at ``start_offsets_s``; moment_arm (k, m, c) m and
        target (k, c) N m at ``end_offsets_s``; tracked (c,) bool (None: all).
        """
        target = np.asarray(target, dtype=float)
        tracked = (np.ones(target.shape[1], dtype=bool) if tracked is None
                   else np.asarray(tracked, dtype=bool))
        nominal = shifted_plan(self.plan, self.edges)  # one period on
        step = self.settings.probe_drive
        delta = np.where(nominal + step <= 1.0, step, -step)
        copies = self.n_blocks + 1
        plans = np.repeat(nominal[None], copies, axis=0)
        for b in range(self.n_blocks):
            plans[b + 1, b] += delta[b]
        forces, rates = self._probe(state, plans, path_length, path_velocity)
        rates = rates.mean(axis=1)
        probe = Probe(nominal, delta, np.diff(self.edges) / self.steps, rates[0],
                      (rates[1:] - rates[0]) / delta)
        plan = solve_window(forces, moment_arm, target, tracked, probe, self.settings,
                            self.drive, self.qp)
        self.plan, self.drive = plan.plan, plan.drive
        return plan


def tracking_lag(times_s, target, achieved, max_lag_s: float) -> tuple[float, float]:
    """(lag s, RMS error at that lag) of ``achieved`` (n, c) behind ``target`` (n, c), both at
    ``times_s`` (n,) increasing: the shift in [0, max_lag_s] (on the samples' own spacing) that
    minimises the RMS of achieved(t) - target(t - lag) over all coordinates. (nan, nan) with
    fewer than two samples."""
    times_s = np.asarray(times_s, dtype=float)
    target, achieved = np.asarray(target, float), np.asarray(achieved, float)
    if len(times_s) < 2:
        return float("nan"), float("nan")
    step = float(np.median(np.diff(times_s)))
    best = (float("nan"), float("inf"))
    for shift in range(int(max_lag_s / step + 1e-9) + 1):
        if len(times_s) - shift < 2:
            break
        error = achieved[shift:] - target[:len(target) - shift]
        rms = float(np.sqrt(np.mean(error ** 2)))
        if rms < best[1]:
            best = (shift * step, rms)
    return best


__all__ = ["DRIVE2_WEIGHT", "RATE_WEIGHT", "HorizonSettings", "Probe", "RecedingHorizon",
           "at_times", "frame_interpolation",
           "BoxQP", "WindowPlan", "block_edges", "box_qp", "coupled_pairs", "solve_window",
           "tracking_hessian", "tracking_lag", "window_entries",
           "window_term"]
