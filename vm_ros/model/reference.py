"""Reference integration of a bank's equations with ``scipy.integrate.solve_ivp``.

The bank's :meth:`~vm_ros.model.bank.MuscleBank.derivatives` is the continuous right-hand side of
the same equations the fixed step uses; here it is integrated by an implicit solver (Radau by
default) with tight tolerances, to judge the fixed-step integrator's accuracy. Slow: for tests,
validation and benchmarks, not for control loops.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import numpy as np
from scipy.integrate import solve_ivp

from vm_ros.model.bank import MuscleBank
from vm_ros.model.layout import OUTPUT_INTEGRALS, STATE, STATE_NAMES, BankState


def pack_state(state: BankState) -> np.ndarray:
    """Flatten the integrated fields of a state into one vector (order: layout.STATE)."""
    return np.concatenate([np.ravel(getattr(state, name)) for name in STATE_NAMES])


def unpack_state(vector: np.ndarray, template: BankState, time_s: float) -> BankState:
    """Inverse of :func:`pack_state`, shapes taken from ``template``."""
    fields, offset = {"time_s": time_s}, 0
    for name in STATE_NAMES:
        shape = np.shape(getattr(template, name))
        size = int(np.prod(shape))
        fields[name] = vector[offset : offset + size].reshape(shape)
        offset += size
    return dataclasses.replace(template, **fields)


@dataclasses.dataclass(frozen=True)
class ReferenceRun:
    """Forces and states of a reference run at the requested times.

    | field | shape | unit |
    | time_s | (k,) | s |
    | force | (k, n) | N (tendon force) |
    | states | list of BankState | |
    """

    time_s: np.ndarray
    force: np.ndarray
    states: list


def jacobian_sparsity(template: BankState) -> np.ndarray:
    """Which state can influence which: muscles are independent of each other, and the energy
    integrals feed nothing back, so their columns are empty but for the diagonal (the recovery
    filters do feed the recovery energy). Lets the solver's finite-difference Jacobian use a few
    grouped evaluations instead of one per state."""
    owners, feeds_back = [], []
    for name in STATE_NAMES:
        value = np.asarray(getattr(template, name))
        n = value.shape[0]
        per_muscle = int(np.prod(value.shape[1:]))
        owners.append(np.repeat(np.arange(n), per_muscle))
        feeds_back.append(np.full(n * per_muscle, name not in OUTPUT_INTEGRALS))
    owner, feeds = np.concatenate(owners), np.concatenate(feeds_back)
    sparsity = (owner[:, None] == owner[None, :]) & feeds[None, :]
    np.fill_diagonal(sparsity, True)
    return sparsity


def absolute_scale(bank: MuscleBank, template: BankState) -> np.ndarray:
    """A physical magnitude per state for the absolute tolerance, by the state's unit
    (layout.STATE): L0 for m, L0 per second for m/s, the energy a muscle spends in 1 s at 1 kW/kg
    for J, and 1 for the normalised activation states (units 1 and f0.5)."""
    energy = 1e3 * bank.mass_kg
    by_unit = {"m": bank.l0_m, "m/s": bank.l0_m, "J": energy, "1": 1.0, "f0.5": 1.0}
    parts = []
    for declared in STATE:
        if declared.unit not in by_unit:
            raise ValueError(f"no tolerance scale for state {declared.name} in {declared.unit}")
        value = np.asarray(getattr(template, declared.name))
        per_muscle = np.broadcast_to(by_unit[declared.unit], (bank.n,))
        parts.append(np.broadcast_to(per_muscle.reshape((-1,) + (1,) * (value.ndim - 1)),
                                     value.shape).ravel())
    return np.concatenate(parts)


def solve_reference(
    bank: MuscleBank,
    t_eval: np.ndarray,
    excitation: Callable[[float], np.ndarray],
    path_length: Callable[[float], np.ndarray],
    breakpoints=(),
    method: str = "Radau",
    rtol: float = 1e-8,
    atol: float = 1e-9,
) -> ReferenceRun:
    """Integrate from the bank's current state over ``t_eval`` (absolute times, s).

    ``excitation(t)`` and ``path_length(t)`` give the inputs as functions of time; integration is
    restarted at each of ``breakpoints`` (discontinuities of the inputs) so the solver never steps
    across one. The bank's state is left unchanged.
    """
    start = bank.state
    t0 = start.time_s
    t_eval = np.asarray(t_eval, dtype=float)
    edges = [t0] + sorted(b for b in breakpoints if t0 < b < t_eval[-1]) + [t_eval[-1]]
    y = pack_state(start)
    atol_vector = atol * absolute_scale(bank, start)
    sparsity = jacobian_sparsity(start)

    def rhs(t, vec):
        state = unpack_state(vec, start, t)
        d = bank.derivatives(state, excitation(t), path_length(t))
        return pack_state(d)

    times, states = [], []
    for a, b in zip(edges[:-1], edges[1:], strict=True):
        # scipy's finite-difference Jacobian probes step sizes that overflow on the way
        # (RuntimeWarnings from num_jac); the solve itself is unaffected.
        with np.errstate(over="ignore", invalid="ignore"):
            sol = solve_ivp(rhs, (a, b), y, method=method, rtol=rtol, atol=atol_vector,
                            dense_output=True, jac_sparsity=sparsity)
        if not sol.success:
            raise RuntimeError(f"reference solve failed on [{a}, {b}]: {sol.message}")
        # a time on a breakpoint belongs to the segment that starts there (the new inputs)
        inside = t_eval[(t_eval >= a) & (t_eval < b)] if b < t_eval[-1] else t_eval[t_eval >= a]
        for t in inside:
            times.append(t)
            states.append(unpack_state(sol.sol(t), start, t))
        y = sol.y[:, -1]
    forces = np.array([bank.forces_at(s, path_length(s.time_s))[0] for s in states])
    return ReferenceRun(np.array(times), forces, states)
