"""Glue between a bank and the compiled step (vm_ros.model.kernel): the constants packed once into
the tables the kernel reads, and the calls with the flat argument list vm_ros.model.layout declares.

The kernel takes every array as its own argument (grouping them makes each call dearer,
docs/performance.md, and a Numba jitclass is compiled anew in every process), so the lists here are
built from the declaration: constants in ``layout.CONSTANTS`` order, state in ``layout.STATE``
order, outputs as StepRecord.
"""

from __future__ import annotations

import dataclasses
import operator
import sys

import numpy as np

from vm_ros.model import kernel, layout
from vm_ros.model import recruitment as rc
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
            t_rise_rate=rc.lumped_drive_rise_rate(rec.coefficients.t_rise,
                                                  p.lumped.t_rise_step_scale),
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
        w_slow_poly=layout.padded_polynomial(p.lumped.w_slow_poly),
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


def _references(arrays) -> int:
    """The most references any of ``arrays`` has (CPython's count, this call's own included)."""
    return max(sys.getrefcount(a) for a in arrays)


# what _references reports for arrays held by one tuple and nothing else
_UNSHARED = _references((np.empty(0),)) if hasattr(sys, "getrefcount") else None


class CompiledStep:
    """Steps a bank's state with the kernel; holds the packed constants and the kernel's cache.

    ``advance_series`` defaults to the compiled kernel (``kernel.advance_series``, which also
    runs each single step: a step is a series of one); the uncompiled Python function
    (``kernel._advance_series``) runs the same steps as plain Python.
    ``parallel`` (None: the VM_ROS_PARALLEL environment variable, kernel.parallel_wanted) steps
    blocks of muscles on Numba's threads, the same numbers to the bit, for banks of
    kernel.PARALLEL_MIN_MUSCLES or more (``parallel_chunk``: muscles per block, 0 when serial).

    :meth:`series` writes into output arrays kept from an earlier call when the caller no longer
    holds any of them (no page faults on fresh memory); arrays a caller still holds are never
    written again.
    """

    def __init__(self, constants, n: int, advance_series=None, parallel=None):
        self.constants = constants
        self.n = n
        self._constants = constants.arguments()
        compiled = advance_series is None
        self._advance_series = advance_series or kernel.advance_series
        self.parallel_chunk = (kernel.parallel_chunk(n)
                               if compiled and kernel.parallel_wanted(parallel) else 0)
        if self.parallel_chunk:
            kernel.warm_up(parallel=True)
            self._advance_series = kernel.advance_series_parallel
        # the (L, V) terms of F_CE at the (x, xdot) of the last step's end (NaN: none)
        self._terms_end = np.zeros((n, layout.N_TERMS))
        self._xv_end = np.full((n, 2), np.nan)
        self._zeros = np.zeros(n)
        self._shapes = tuple((1, *a.shape_for({"n": n})) for a in layout.OUTPUTS)
        self._series_sets = []  # [(key, arrays)]: the last two series' output arrays
        # a step is a series of one: its fascicle state outputs and (no) snapshots
        self._step_extra = None

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
        modified. The kernel runs it as a series of one step."""
        u = self._vector(excitation)
        lp = self._vector(path_length)
        vp = self._zeros if path_velocity is None else self._vector(path_velocity)
        if u is None or lp is None or vp is None:
            return None
        if self._step_extra is None:
            sizes = layout.state_sizes(self.n, old.firing_rate_intermediate.shape[1])
            self._step_extra = (
                *(a.empty(sizes, (1,)) for a in layout.SERIES_OUTPUTS[len(layout.OUTPUTS):]),
                0, *(a.empty(sizes, (0,)) for a in layout.SNAPSHOTS),
            )
        new = old.copy()
        outputs = [np.empty(shape) for shape in self._shapes]
        status = self._advance_series(dt, u[None], lp[None], vp[None], *self._constants,
                                      *_state_arrays(new), self._terms_end, self._xv_end,
                                      *outputs, *self._step_extra, self.parallel_chunk)
        if status != 0:
            return None
        new.time_s = old.time_s + dt
        return new, StepRecord(*(array[0] for array in outputs))

    def _series_arrays(self, k: int, pools: int, count: int) -> tuple:
        """Output arrays of a series (layout.SERIES_OUTPUTS, then layout.SNAPSHOTS): kept ones
        of the same shapes that no caller holds any more, else new ones."""
        key = (k, pools, count)
        for kept_key, arrays in self._series_sets:
            if kept_key == key and _UNSHARED is not None and _references(arrays) <= _UNSHARED:
                return arrays
        sizes = layout.state_sizes(self.n, pools)
        arrays = (*(a.empty(sizes, (k,)) for a in layout.SERIES_OUTPUTS),
                  *(a.empty(sizes, (count,)) for a in layout.SNAPSHOTS))
        self._series_sets = [*self._series_sets[-1:], (key, arrays)]
        return arrays

    def series(self, old: BankState, dt: float, u, lp, vp, snapshot_every: int = 0):
        """k steps in one kernel call, inputs (k, n) checked for shape: (status, new state,
        series StepRecord, fascicle length (k, n), fascicle velocity (k, n), snapshots). Status
        0, or 1 + step * n + muscle of the first bad input; ``old`` is not modified. The new
        state's time is left at ``old``'s. ``snapshots``: the state arrays (layout.STATE order)
        at the end of every ``snapshot_every``-th step, (k // snapshot_every, ...) each."""
        k = u.shape[0]
        new = old.copy()
        count = k // snapshot_every if snapshot_every > 0 else 0
        arrays = self._series_arrays(k, old.firing_rate_intermediate.shape[1], count)
        n_outputs = len(layout.OUTPUTS)
        record = StepRecord(*arrays[:n_outputs])
        length, velocity = arrays[n_outputs:len(layout.SERIES_OUTPUTS)]
        snapshots = list(arrays[len(layout.SERIES_OUTPUTS):])
        status = self._advance_series(dt, u, lp, vp, *self._constants, *_state_arrays(new),
                                      self._terms_end, self._xv_end, *record, length, velocity,
                                      int(max(snapshot_every, 0)), *snapshots,
                                      self.parallel_chunk)
        return status, new, record, length, velocity, snapshots


__all__ = ["CompiledStep", "KernelConstants"]
