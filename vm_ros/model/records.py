"""What a step reports: the raw record both executors fill, and the records a caller reads.

| record | holds |
| :class:`StepRecord` | one step's outputs as the step computes them (fields: layout.OUTPUTS) |
| :class:`StepOutput` | what ``MuscleBank.step`` returns: the record plus fields derived on access |
| :class:`Trajectory` | every step of ``MuscleBank.run`` |
| :class:`EnergyRates` | an energy partition (activation, cross-bridge, recovery, total) |
"""

from __future__ import annotations

import dataclasses
import warnings
from dataclasses import dataclass
from functools import cached_property
from typing import NamedTuple

import numpy as np

from vm_ros.model import layout

ENERGY_COMPONENTS = ("activation", "cross_bridge", "recovery", "total")


def _deprecated(old: str, new: str) -> None:
    warnings.warn(f"{old} is deprecated; use {new} (the old name goes in the next release)",
                  DeprecationWarning, stacklevel=3)


@dataclass(frozen=True)
class EnergyRates:
    """Energy partition. Rates in W (or, for cumulative records, energies in J).

    | field | shape | meaning |
    | activation | (n,) or (n, 2) | ion pumping (Ca2+, Na+/K+), depends on stimulation only |
    | cross_bridge | same | cross-bridge cycling |
    | recovery | same | ATP/PCr resynthesis |
    | total | same | sum of the three |
    """

    activation: np.ndarray
    cross_bridge: np.ndarray
    recovery: np.ndarray
    total: np.ndarray

    @classmethod
    def from_components(cls, components: np.ndarray) -> EnergyRates:
        """From an array whose last axis is (activation, cross_bridge, recovery); the total is
        their sum in that order, the same numbers as ``sum(axis=-1)`` and faster than NumPy's
        reduction over an axis of 3 (docs/performance.md)."""
        activation, cross_bridge, recovery = (components[..., 0], components[..., 1],
                                              components[..., 2])
        return cls(activation, cross_bridge, recovery, activation + cross_bridge + recovery)

    def as_array(self) -> np.ndarray:
        """Stack as (..., 4) in the order of ENERGY_COMPONENTS."""
        return np.stack([self.activation, self.cross_bridge, self.recovery, self.total], axis=-1)

    def summed_over_fibres(self) -> EnergyRates:
        return EnergyRates(*(getattr(self, f.name).sum(axis=-1) for f in dataclasses.fields(self)))


class StepRecord(NamedTuple(
        "_StepRecordFields", [(a.name, np.ndarray) for a in layout.OUTPUTS])):  # type: ignore[misc]
    __doc__ = (
        "One step's outputs as the step computes them, in the kernel's argument order (fields\n"
        "from vm_ros.model.layout.OUTPUTS; a series record has a leading step axis k).\n\n"
        "    | field | shape | unit | meaning |\n" + layout.table_rows(layout.OUTPUTS) + "\n"
    )
    __slots__ = ()

    @classmethod
    def empty(cls, n: int, leading: tuple = ()) -> StepRecord:
        """Uninitialised arrays of every output for n muscles (with ``leading`` axes)."""
        return cls(*(a.empty({"n": n}, leading) for a in layout.OUTPUTS))

    def row(self, index: int) -> StepRecord:
        """The record of step ``index`` of a series (copies)."""
        return StepRecord(*(array[index].copy() for array in self))

    @classmethod
    def stack(cls, records) -> StepRecord:
        """One series record (k, ...) from k step records."""
        return cls(*(np.array(arrays) for arrays in zip(*records, strict=True)))


class StepOutput:
    """What one step reports (SI unless the name says otherwise).

    Every field is a fresh array (changing it does not touch the bank); the derived ones are
    computed on first access, so a step costs only what the caller reads.

    | field | shape | unit | meaning |
    | time_s | () | s | model time at the end of the step |
    | force | (n,) | N | tendon force F_SE (VM's output force) |
    | contractile_force | (n,) | N | F_CE |
    | fascicle_length | (n,) | m | |
    | fascicle_velocity | (n,) | m/s | negative when shortening |
    | length_l0 | (n,) | L0 | normalised fascicle length |
    | velocity_l0_per_s | (n,) | L0/s | normalised fascicle velocity |
    | excitation | (n,) | 1 | drive U as used (clipped to [0, 1]) |
    | effective_drive | (n,) | 1 | filtered drive Ueff of the slow type (U for natural units) |
    | effective_drive_by_fibre | (n, 2) | 1 | filtered drive Ueff per fibre type (slow, fast) |
    | firing_rate_f05 | (n, 2) | f0.5 | f_eff per fibre type (PCSA-weighted mean over units) |
    | recruited_fraction | (n, 2) | 1 | recruited PCSA fraction per fibre type |
    | effective_activation | (n, 2) | 1 | Acteff per fibre type (recruitment x weighting x Af) |
    | energy_rate | EnergyRates (n,) | W | per muscle |
    | energy_rate_by_fibre | EnergyRates (n, 2) | W | per muscle and fibre type |
    | energy | EnergyRates (n,) | J | cumulative since reset |
    | energy_by_fibre | EnergyRates (n, 2) | J | cumulative since reset |
    | mechanical_power | (n,) | W | -F_CE * fascicle velocity (positive when shortening) |
    | mechanical_work | (n,) | J | cumulative |
    | total_energy_rate | () | W | whole bank |
    | total_energy | () | J | whole bank, cumulative |
    | energy_rate_models | (n, M, C) or None | W | with ``energetics_models``: each published
      model's rate per muscle x model (bank order) x component (activation_maintenance,
      shortening_lengthening, basal, mechanical_work, total; NaN where a model has none) |
    | energy_models | (n, M) or None | J | each model's total, integrated since reset |
    | record | StepRecord | | the step's raw outputs |

    ``energy_rate_by_fiber`` and ``energy_by_fiber`` are deprecated aliases (DeprecationWarning).
    """

    FIELDS = (
        "time_s", "force", "contractile_force", "fascicle_length", "fascicle_velocity",
        "length_l0", "velocity_l0_per_s", "excitation", "effective_drive",
        "effective_drive_by_fibre", "firing_rate_f05", "recruited_fraction",
        "effective_activation", "energy_rate", "energy_rate_by_fibre", "energy", "energy_by_fibre",
        "mechanical_power", "mechanical_work", "total_energy_rate", "total_energy",
    )

    def __init__(self, equations, state, record):
        # equations: the NumpyStep whose methods compute the fields read on demand
        self._equations = equations
        self._state = state  # never modified once published (every step works on a copy)
        self.record = record
        self.time_s = float(state.time_s)
        self.force = record.force
        self.contractile_force = record.contractile_force
        self.effective_activation = record.effective_activation
        self.mechanical_power = record.mechanical_power
        self.excitation = record.excitation
        self._model_rates: np.ndarray | None = None
        self._model_energies: np.ndarray | None = None
        self._models_due = None  # computes them on first read (the bank's pending steps)

    def set_models(self, rates: np.ndarray, energies: np.ndarray) -> None:
        """Attach the published models' rates (n, M, C) W and energies (n, M) J (the bank)."""
        self._model_rates, self._model_energies, self._models_due = rates, energies, None

    def defer_models(self, compute) -> None:
        """``compute()`` attaches the models' values (set_models) when they are first read:
        the bank computes the models of its pending steps in one batch."""
        self._models_due = compute

    @property
    def energy_rate_models(self) -> np.ndarray | None:
        if self._models_due is not None:
            self._models_due()
        return self._model_rates

    @property
    def energy_models(self) -> np.ndarray | None:
        if self._models_due is not None:
            self._models_due()
        return self._model_energies

    def __repr__(self) -> str:
        return f"StepOutput(time_s={self.time_s}, force={self.force!r})"

    @cached_property
    def fascicle_length(self) -> np.ndarray:
        return self._state.fascicle_length_m.copy()

    @cached_property
    def fascicle_velocity(self) -> np.ndarray:
        return self._state.fascicle_velocity_m_per_s.copy()

    @cached_property
    def length_l0(self) -> np.ndarray:
        return self._state.fascicle_length_m / self._equations.geometry.l0

    @cached_property
    def velocity_l0_per_s(self) -> np.ndarray:
        return self._state.fascicle_velocity_m_per_s / self._equations.geometry.l0

    @cached_property
    def effective_drive(self) -> np.ndarray:
        return self._state.effective_drive[:, 0].copy()

    @cached_property
    def effective_drive_by_fibre(self) -> np.ndarray:
        return self._state.effective_drive.copy()

    @cached_property
    def firing_rate_f05(self) -> np.ndarray:
        return self._equations.per_type_mean(self._state.firing_rate_effective)

    @cached_property
    def recruited_fraction(self) -> np.ndarray:
        eq = self._equations
        recruited = eq.recruitment.recruited_fraction(self.excitation, self._state.effective_drive)
        return recruited @ eq.membership

    @cached_property
    def energy_rate_by_fibre(self) -> EnergyRates:
        return EnergyRates.from_components(self.record.energy_components)

    @cached_property
    def energy_rate(self) -> EnergyRates:
        rates = self.record.energy_rates
        return EnergyRates(rates[:, 0], rates[:, 1], rates[:, 2], rates[:, 3])

    @cached_property
    def energy_by_fibre(self) -> EnergyRates:
        return EnergyRates.from_components(self._state.energy_j.copy())

    @cached_property
    def energy(self) -> EnergyRates:
        return EnergyRates.from_components(self._state.energy_j.sum(axis=1))

    @cached_property
    def mechanical_work(self) -> np.ndarray:
        return self._state.mechanical_work_j.copy()

    @cached_property
    def total_energy_rate(self) -> float:
        return float(self.record.energy_rates[:, 3].sum())

    @cached_property
    def total_energy(self) -> float:
        return float(self._state.energy_j.sum())

    @property
    def energy_rate_by_fiber(self) -> EnergyRates:
        """Deprecated alias of :attr:`energy_rate_by_fibre`."""
        _deprecated("StepOutput.energy_rate_by_fiber", "energy_rate_by_fibre")
        return self.energy_rate_by_fibre

    @property
    def energy_by_fiber(self) -> EnergyRates:
        """Deprecated alias of :attr:`energy_by_fibre`."""
        _deprecated("StepOutput.energy_by_fiber", "energy_by_fibre")
        return self.energy_by_fibre


@dataclass(frozen=True)
class Trajectory:
    """Every step of ``MuscleBank.run`` (k steps, n muscles; SI as in StepOutput).

    | field | shape | unit |
    | time_s | (k,) | s, model time at the end of each step |
    | excitation | (k, n) | 1, as used (clipped) |
    | force, contractile_force | (k, n) | N |
    | fascicle_length, fascicle_velocity | (k, n) | m, m/s |
    | effective_activation | (k, n, 2) | 1 |
    | energy_rate_by_fibre | EnergyRates (k, n, 2) | W |
    | mechanical_power | (k, n) | W |
    | last | StepOutput | the last step, with the cumulative energies and work |
    | snapshots | BankState (m, ...) or None | with ``run(..., snapshot_every=s)``: the state at
      the end of steps s, 2s, ... (rows s - 1, 2s - 1, ... of the arrays above), m = k // s |
    | record | StepRecord (k, ...) | every step's record, as the kernel wrote it |
    | energy_rate_models | (k, n, M, C) or None | W, with ``energetics_models`` (StepOutput) |
    | energy_models | (k, n, M) or None | J, cumulative since reset, at the end of each step |

    ``energy_rate_by_fiber`` is a deprecated alias (DeprecationWarning).
    """

    time_s: np.ndarray
    excitation: np.ndarray
    force: np.ndarray
    contractile_force: np.ndarray
    fascicle_length: np.ndarray
    fascicle_velocity: np.ndarray
    effective_activation: np.ndarray
    energy_rate_by_fibre: EnergyRates
    mechanical_power: np.ndarray
    last: StepOutput
    snapshots: object = None
    record: StepRecord | None = None
    energy_rate_models: np.ndarray | None = None
    energy_models: np.ndarray | None = None

    @classmethod
    def from_series(cls, time_s, series, fascicle_length, fascicle_velocity, last,
                    snapshots=None) -> Trajectory:
        """From a series StepRecord (k, ...), kept as ``record``, and the fascicle state of
        every step."""
        return cls(
            time_s=time_s,
            excitation=series.excitation,
            force=series.force,
            contractile_force=series.contractile_force,
            fascicle_length=fascicle_length,
            fascicle_velocity=fascicle_velocity,
            effective_activation=series.effective_activation,
            energy_rate_by_fibre=EnergyRates.from_components(series.energy_components),
            mechanical_power=series.mechanical_power,
            last=last,
            snapshots=snapshots,
            record=series,
        )

    @property
    def energy_rate(self) -> EnergyRates:
        """Per muscle (k, n), summed over the fibre types."""
        return self.energy_rate_by_fibre.summed_over_fibres()

    @property
    def energy_rate_by_fiber(self) -> EnergyRates:
        """Deprecated alias of :attr:`energy_rate_by_fibre`."""
        _deprecated("Trajectory.energy_rate_by_fiber", "energy_rate_by_fibre")
        return self.energy_rate_by_fibre


__all__ = ["ENERGY_COMPONENTS", "EnergyRates", "StepOutput", "StepRecord", "Trajectory"]
