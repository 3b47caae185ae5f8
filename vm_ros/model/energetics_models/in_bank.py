"""The published energetics models run by a MuscleBank (``energetics_models=(...)``), after each
step or run, on the outputs the step reported.

    models = BankModels(("umberger2010", "bhargava2004"), VmMuscleConstants.from_bank(bank))
    rates, energies = models.advance(dt, times, excitation, effective_activation, length,
                                     velocity)        # (k, n, M, C) W and (k, n, M) J

One code path for both back ends and for step and run: the step's (n,) or the run's (k, n)
arrays go through the mapping once (vm_state.vm_model_inputs: the curves shared by every model)
and then through each model, in NumPy. The state the models need is kept here, per muscle:

- ``onset_s`` (n,): model time (s) at the end of the first step of the current stretch of
  drive U > 0 (NaN while U = 0), so that Lichtwark & Wilson's stimulation duration is the same
  whether the steps come one by one or in runs (vm_state.time_since_onset counts it the same
  way over one series); kept only where a selected model takes the stimulation duration (the
  registry's extras), NaN otherwise;
- ``energy_j`` (n, M): each model's total integrated step by step, E += rate(end of step) dt,
  the rate at the state at the end of the step as the bank's own energetics are.

Both restart with ``reset``. The layout of the rates: muscle x model (``names``) x component
(COMPONENTS); NaN where a model has no such component.
"""

from __future__ import annotations

import numpy as np

from vm_ros.errors import InputError
from vm_ros.model.energetics_models import compiled
from vm_ros.model.energetics_models.vm_state import (
    MODEL_NAMES,
    VmMuscleConstants,
    current_model_name,
    published_model,
    vm_model_inputs,
)

COMPONENTS = ("activation_maintenance", "shortening_lengthening", "basal", "mechanical_work",
              "total")
TOTAL = COMPONENTS.index("total")
# muscle-steps per chunk of a series: (k, n, 2) temporaries of about 160 kB, which stay in the
# cache (cheaper per step than whole batches: docs/performance.md)
CHUNK_MUSCLE_STEPS = 10_000


def model_names(selection) -> tuple:
    """The models of ``selection``: names (a sequence, or one string of names separated by
    commas), ``"all"`` for every published model, empty or None for none; a former name
    (vm_state.RENAMED) gives the current one. InputError naming the known models for an unknown
    or repeated name."""
    if selection is None:
        return ()
    if isinstance(selection, str):
        selection = [part.strip() for part in selection.split(",") if part.strip()]
    names = tuple(current_model_name(str(name)) for name in selection)
    if names == ("all",):
        return MODEL_NAMES
    for name in names:
        if name not in MODEL_NAMES:
            raise InputError("energetics model", name,
                             f"unknown; known: {', '.join(MODEL_NAMES)} (or all)")
    if len(set(names)) != len(names):
        raise InputError("energetics models", ",".join(names), "a model is named twice")
    return names


class BankModels:
    """The selected models of one bank, their constants (loaded once) and their state. With
    ``compile_models`` (and Numba) a series goes through compiled loops (compiled.CompiledModels:
    the NumPy path's values to the bit), compiled or loaded from Numba's cache here."""

    def __init__(self, names, muscle: VmMuscleConstants, compile_models: bool = True):
        self.names = model_names(names)
        self.muscle = muscle
        self._models = [published_model(name) for name in self.names]
        self._constants = [model.load_constants() for model in self._models]
        # the stimulation duration, counted only for a model that takes it (Lichtwark's)
        self._duration = any("stimulation_duration" in model.extras for model in self._models)
        self._compiled = None
        if compile_models and compiled.AVAILABLE and self.names:
            self._compiled = compiled.CompiledModels(self._models, self._constants, muscle)
            compiled.warm_up(self._compiled)
        self.n = len(np.atleast_1d(muscle.f0))
        self.reset()

    def reset(self) -> None:
        self.onset_s = np.full(self.n, np.nan)
        self.energy_j = np.zeros((self.n, len(self.names)))

    def stimulation_duration(self, time_s, excitation) -> np.ndarray:
        """Time (s) since the drive last rose above 0, (k, n), at the end times (k,) of k steps
        with drive (k, n), continuing from ``onset_s``, which it advances."""
        if self._compiled is not None:  # the same times, in one compiled pass
            duration, self.onset_s = compiled.stimulation_duration(time_s, excitation,
                                                                   self.onset_s)
            return duration
        t = np.asarray(time_s, dtype=float)
        on = np.asarray(excitation) > 0.0
        before = np.vstack([~np.isnan(self.onset_s)[None, :], on[:-1]])
        rows = np.arange(on.shape[0])[:, None]
        last = np.maximum.accumulate(np.where(on & ~before, rows, -1), axis=0)
        onset = np.where(last >= 0, t[np.maximum(last, 0)], self.onset_s[None, :])
        self.onset_s = np.where(on[-1], onset[-1], np.nan)
        return np.where(on, t[:, None] - onset, 0.0)

    def rates(self, excitation, effective_activation, length_m, velocity_m_per_s,
              stimulation_duration, each_chunk=None) -> np.ndarray:
        """Rates (W), (..., n, M, C), of every model at outputs of shape (..., n) (effective
        activation (..., n, 2)); no state is changed. A series (k, n) goes through in chunks
        of at most CHUNK_MUSCLE_STEPS muscle-steps, whose temporaries stay in the cache;
        ``each_chunk(out, rows)`` (optional) is called as each chunk's rows (a slice of the k)
        of out (M, C, k, n) are filled, while they are in the cache."""
        shape = np.shape(length_m)
        # filled model by model in contiguous (M, C, ...) rows, handed out as the (..., M, C)
        # view: no strided writes, no copy
        out = np.empty((len(self.names), len(COMPONENTS), *shape))
        if len(shape) == 1:
            self._fill(out, excitation, effective_activation, length_m, velocity_m_per_s,
                       stimulation_duration)
            return np.moveaxis(out, (0, 1), (-2, -1))
        k, n = shape
        rows = max(1, CHUNK_MUSCLE_STEPS // max(1, n))
        for start in range(0, k, rows):
            part = slice(start, min(k, start + rows))
            self._fill(out[:, :, part], excitation[part], effective_activation[part],
                       length_m[part], velocity_m_per_s[part],
                       None if stimulation_duration is None else stimulation_duration[part])
            if each_chunk is not None:
                each_chunk(out, part)
        return np.moveaxis(out, (0, 1), (-2, -1))

    def _fill(self, out, excitation, effective_activation, length_m, velocity_m_per_s,
              stimulation_duration) -> None:
        """out[m, c] = component c of model m; the mapping once for every model. A series
        block goes through the compiled loops where Numba is there (compiled.CompiledModels: the
        same bits)."""
        if self._compiled is not None and np.ndim(length_m) == 2:
            self._compiled.fill(out, excitation, effective_activation, length_m,
                                velocity_m_per_s, stimulation_duration)
            return
        inputs = vm_model_inputs(self.muscle, excitation, effective_activation, length_m,
                                 velocity_m_per_s, stimulation_duration)
        for m, (model, constants) in enumerate(zip(self._models, self._constants,
                                                   strict=True)):
            extras = {key: getattr(inputs, key) for key in model.extras}
            heat = model.function(inputs.state, constants, **extras)
            for c, component in enumerate(COMPONENTS):
                out[m, c] = getattr(heat, component)

    def advance(self, dt, time_s, excitation, effective_activation, length_m,
                velocity_m_per_s):
        """k steps of ``dt`` s (one for all, or (k,)) that ended at ``time_s`` (k,), outputs
        (k, n) (effective activation (k, n, 2)): (rates (k, n, M, C) W, cumulative energies
        (k, n, M) J), the state advanced past them."""
        dt = np.broadcast_to(np.asarray(dt, dtype=float), np.shape(time_s))
        duration = self.stimulation_duration(time_s, excitation) if self._duration else None
        if self._compiled is not None and np.shape(time_s)[0] > 1:
            # each chunk's energies summed while its rates are in the cache, in a compiled loop
            # (the same sums)
            energies = np.empty((len(self.names), *np.shape(length_m)))  # (M, k, n)
            before = np.ascontiguousarray(self.energy_j.T)
            steps = np.ascontiguousarray(dt)
            rates = self.rates(excitation, effective_activation, length_m, velocity_m_per_s,
                               duration, lambda out, part: compiled.integrate_energies(
                                   before, out[:, TOTAL], steps, part, energies))
            energies = np.moveaxis(energies, 0, -1)  # (k, n, M) view
            self.energy_j = energies[-1].copy()
            return rates, energies
        rates = self.rates(excitation, effective_activation, length_m, velocity_m_per_s,
                           duration)
        totals = rates.base[:, TOTAL] if rates.base is not None else rates[..., TOTAL]
        if totals.shape[-2] == 1:  # one step: E + rate dt, the same sum without the stacking
            self.energy_j = self.energy_j + totals[:, 0].T * dt[0]
            return rates, self.energy_j[None].copy()
        steps = np.empty((len(self.names), totals.shape[-2] + 1, self.n))  # (M, 1 + k, n)
        steps[:, 0] = self.energy_j.T
        np.multiply(totals, dt[None, :, None], out=steps[:, 1:])
        # sequential sums along the steps, as step-by-step integration adds them (a loop over
        # the steps: contiguous rows, several times faster than cumsum along axis 1)
        for j in range(totals.shape[-2]):
            np.add(steps[:, j], steps[:, j + 1], out=steps[:, j + 1])
        energies = np.moveaxis(steps[:, 1:], 0, -1)  # (k, n, M) view
        self.energy_j = energies[-1].copy()
        return rates, energies

    def at_rest(self, excitation, effective_activation, length_m, velocity_m_per_s):
        """Rates (n, M, C) at a state reported without a step (the reset): stimulation
        duration 0."""
        return self.rates(excitation, effective_activation, length_m, velocity_m_per_s, None)


__all__ = ["COMPONENTS", "BankModels", "model_names"]
