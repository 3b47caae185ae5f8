"""Glue between a bank and the compiled step (vm_ros.model.kernel): the constants packed once into
the tables the kernel reads, and the calls with the flat argument list vm_ros.model.layout declares.

The kernel takes every array as its own argument (grouping them costs 1.4-3x per call, and a Numba
jitclass is compiled anew in every process), so the lists here are built from the declaration:
constants in ``layout.CONSTANTS`` order, state in ``layout.STATE`` order, outputs as StepRecord.
"""

from __future__ import annotations

import dataclasses
import operator

import numpy as np

from vm_ros.model import kernel, layout
from vm_ros.model.layout import LUMPED_ONLY, BankState, M, P, S, T
from vm_ros.model.records import StepRecord


def _from_bank(cls, bank):
    """Pack the constants of a MuscleBank (its equations, geometry and recruitment scheme)."""
    eq, p, geo, rec = bank.equations, bank.params, bank.geometry, bank.recruitment
    scheme = kernel.SCHEME_CODES[rec.name]
    per_muscle = {
        "dry_mass": eq.dry_mass[:, 0],
        "ur": bank.ur,
        "fpcsa_s": bank.fpcsa[:, 0],
        "fpcsa_f": bank.fpcsa[:, 1],
    }
    if scheme == kernel.LUMPED:
        lower, upper = rec.recruitment_range
        per_muscle.update(
            u2=rec.u2, rec_lower_s=lower[:, 0], rec_lower_f=lower[:, 1],
            rec_upper_s=upper[:, 0], rec_upper_f=upper[:, 1],
        )
        lumped_sources = [rec.coefficients]
    else:
        lumped_sources = [dict.fromkeys(LUMPED_ONLY, np.nan)]  # read by the lumped scheme only
    continuous = {
        "continuous_tau_rise": p.continuous.tau_rise,
        "continuous_tau_fall": p.continuous.tau_fall,
        "drive_law_code": kernel.DRIVE_LAW_CODES[p.lumped.drive_law],
    }
    return cls(
        scheme=scheme,
        dynamic_recovery=bank.recovery_mode == "dynamic",
        muscle=layout.table("muscle", M, bank.n, [geo, per_muscle, *lumped_sources]),
        pool=layout.table("pool", P, bank.n_pools, [eq.pool_fibre, {"l_max": eq.pool_l_max}]),
        pool_type=np.ascontiguousarray(rec.fibre_index, dtype=np.int64),
        thresholds=np.ascontiguousarray(rec.thresholds, dtype=float),
        pool_pcsa=np.ascontiguousarray(rec.pool_pcsa, dtype=float),
        fibre_type=layout.table("fibre_type", T, 2, [p.energetics, p.fibre]),
        shared=layout.table("shared", S, 1, [p.generic, p.energetics, p.lumped, continuous]),
        w_slow_poly=np.asarray(p.lumped.w_slow_poly, dtype=float),
    )


def _arguments(self) -> tuple:
    """The constants in the kernel's argument order."""
    return tuple(getattr(self, a.name) for a in layout.CONSTANTS)


KernelConstants = dataclasses.make_dataclass(
    "KernelConstants",
    [(a.name, a.dtype if a.shape == () else np.ndarray) for a in layout.CONSTANTS],
    namespace={"from_bank": classmethod(_from_bank), "arguments": _arguments},
    frozen=True,
)
KernelConstants.__module__ = __name__
KernelConstants.__doc__ = (
    "Everything constant that the compiled step reads (fields from layout.CONSTANTS).\n\n"
    "    | field | shape | unit | meaning |\n" + layout.table_rows(layout.CONSTANTS) + "\n"
)

_state_arrays = operator.attrgetter(*layout.STATE_NAMES)


class CompiledStep:
    """Steps a bank's state with the kernel; holds the packed constants and the kernel's cache.

    ``advance`` and ``advance_series`` default to the compiled kernel; the uncompiled Python
    functions (``kernel._advance``...) run the same step as plain Python.
    """

    def __init__(self, constants, n: int, advance=None, advance_series=None):
        self.constants = constants
        self.n = n
        self._constants = constants.arguments()
        self._advance = advance or kernel.advance
        self._advance_series = advance_series or kernel.advance_series
        # the (L, V) terms of F_CE at the (x, xdot) of the last step's end (NaN: none)
        self._terms_end = np.zeros((n, layout.N_TERMS))
        self._xv_end = np.full((n, 2), np.nan)
        self._zeros = np.zeros(n)
        self._shapes = tuple(a.shape_for({"n": n}) for a in layout.OUTPUTS)

    def _vector(self, value):
        """``value`` as a float (n,) array without checks (a scalar is broadcast); None if the
        shape is wrong."""
        array = np.asarray(value, dtype=float)
        if array.shape == ():
            return np.full(self.n, float(array))
        if array.shape != (self.n,):
            return None
        # the kernel is compiled for writable C-ordered arrays: anything else would recompile it
        return array if array.flags.c_contiguous and array.flags.writeable else array.copy()

    def step(self, old: BankState, dt: float, excitation, path_length, path_velocity):
        """(new state, StepRecord), or None on a bad input (the caller then raises the
        InputError; the kernel checks finiteness and path length > 0 itself). ``old`` is not
        modified."""
        u = self._vector(excitation)
        lp = self._vector(path_length)
        vp = self._zeros if path_velocity is None else self._vector(path_velocity)
        if u is None or lp is None or vp is None:
            return None
        new = old.copy()
        record = StepRecord(*[np.empty(shape) for shape in self._shapes])
        status = self._advance(dt, u, lp, vp, *self._constants, *_state_arrays(new),
                               self._terms_end, self._xv_end, *record)
        if status != 0:
            return None
        new.time_s = old.time_s + dt
        return new, record

    def series(self, old: BankState, dt: float, u, lp, vp, snapshot_every: int = 0):
        """k steps in one kernel call, inputs (k, n) checked for shape: (status, new state,
        series StepRecord, fascicle length (k, n), fascicle velocity (k, n), snapshots). Status
        0, or 1 + step * n + muscle of the first bad input; ``old`` is not modified. The new
        state's time is left at ``old``'s. ``snapshots``: the state arrays (layout.STATE order)
        at the end of every ``snapshot_every``-th step, (k // snapshot_every, ...) each."""
        k = u.shape[0]
        new = old.copy()
        record = StepRecord.empty(self.n, (k,))
        length, velocity = (a.empty({"n": self.n}, (k,))
                            for a in layout.SERIES_OUTPUTS[len(layout.OUTPUTS):])
        sizes = layout.state_sizes(self.n, old.firing_rate_intermediate.shape[1])
        count = k // snapshot_every if snapshot_every > 0 else 0
        snapshots = [a.empty(sizes, (count,)) for a in layout.SNAPSHOTS]
        status = self._advance_series(dt, u, lp, vp, *self._constants, *_state_arrays(new),
                                      self._terms_end, self._xv_end, *record, length, velocity,
                                      int(max(snapshot_every, 0)), *snapshots)
        return status, new, record, length, velocity, snapshots


__all__ = ["CompiledStep", "KernelConstants"]
