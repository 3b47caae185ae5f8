"""What every system of ``vm-ros bench --compare`` shares: the stepper interface, the common
inputs and vm_ros's own stepper (the comparison itself: vm_ros_bench.peer_compare).
"""

from __future__ import annotations

import numpy as np

from vm_ros_bench.model_bench import DT, library_bank

PERIOD_STEPS = 2000  # input table: 2 s holds whole periods of the 1 Hz path and the 2 Hz drive
CYCLE_STEPS = 1000  # 1 s, the inputs' common period: a timed block is a whole number of these


class PeerStepper:
    """``n`` muscles of one system: ``advance(steps)`` runs steps from where the last call
    stopped; ``reading()`` the last step's total force (N) and total energy rate (W, or None)."""

    def advance(self, steps: int) -> None:
        raise NotImplementedError

    def reading(self) -> dict:
        raise NotImplementedError


def bench_inputs(n: int):
    """(u, lp, vp, bank): (PERIOD_STEPS, n) excitation, path length (m) and path velocity (m/s)
    (module docstring) for a bank of ``n`` library muscles (compiled back end when available);
    lp[:, 0] is the slider's coordinate."""
    from vm_ros.model import kernel

    bank = library_bank(n, backend="numba" if kernel.AVAILABLE else "numpy")
    t = DT * np.arange(PERIOD_STEPS)[:, None]
    u = 0.5 + 0.45 * np.sin(2 * np.pi * 2.0 * t + np.arange(n)[None, :])
    rest = bank.l0_m + bank.l0t_m
    swing = 0.02 * rest[0]
    lp = rest[None, :] + swing * np.sin(2 * np.pi * t)
    vp = np.broadcast_to(swing * 2 * np.pi * np.cos(2 * np.pi * t), lp.shape).copy()
    return u, lp, vp, bank


class VmRosMuscles(PeerStepper):
    def __init__(self, n: int):
        self.u, self.lp, self.vp, self.bank = bench_inputs(n)
        self.bank.reset(self.lp[0], excitation=self.u[0])
        self.k = 0
        self.force = self.rate = np.zeros(n)

    def advance(self, steps: int) -> None:
        bank, u, lp, vp, period = self.bank, self.u, self.lp, self.vp, len(self.u)
        k = self.k
        for _ in range(steps):
            j = k % period
            out = bank.step(DT, u[j], lp[j], vp[j])
            self.force, self.rate = out.force, out.energy_rate.total
            k += 1
        self.k = k

    def reading(self) -> dict:
        return {"total_force_n": float(np.sum(self.force)),
                "total_energy_rate_w": float(np.sum(self.rate))}
