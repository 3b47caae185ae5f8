"""Lumped units against natural units: comparison and refit (Tsianos 2012 Appendix A, Figs. 9-10).

The lumped model replaces N discrete units per fibre type by one unit per type whose recruited
PCSA rF and weighting W make it behave like the ensemble. At steady state and L = L0 the ensemble's
effective activation per type is A_nat(U) = sum_j p_j Af(f_env_j(U)); the lumped unit gives
rF(U) W(U) Af(f_env(U)). W is therefore fixed by the natural-units model, which is how the paper
derived it. :func:`fit_weighting` refits W's coefficients (polynomials in U2, the fast threshold)
by least squares over a grid of fibre mixes, for any Ur; :func:`fit_drive_filter` refits the
drive filter's T_rise and T_fall polynomials against step responses.

Errors are reported in % of the natural ensemble's force at U = 1 (the paper's Fig. 9 measure).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from vm_ros.model.bank import MuscleBank
from vm_ros.model.params import LumpedParams, ModelParams, MuscleSpec
from vm_ros.model.recruitment import LumpedRecruitment

W_FIELDS = ("w_slow_poly", "w_slow_a_poly", "w_slow_tau", "w_fast_b_poly", "w_fast_c_poly",
            "w_fast_offset", "w_fast_rise", "w_fast_tau_poly")
FILTER_FIELDS = ("t_rise_poly", "t_fall_poly")
DEFAULT_FPCSA_GRID = (0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8)


def synthetic_muscles(fpcsa_slow_grid, ur: float) -> list[MuscleSpec]:
    """One muscle per fibre mix; geometry is irrelevant to isometric activation at L0."""
    return [MuscleSpec(name=f"fpcsa_slow_{fs:.3f}", mass_kg=0.1, l0_m=0.1, l0t_m=0.1,
                       fpcsa_slow=float(fs), ur=float(ur), lmax=1.3) for fs in fpcsa_slow_grid]


def _pack(lumped: LumpedParams, fields) -> np.ndarray:
    return np.concatenate([np.atleast_1d(np.asarray(getattr(lumped, f), dtype=float))
                           for f in fields])


def _unpack(vector, lumped: LumpedParams, fields) -> LumpedParams:
    changes, offset = {}, 0
    for f in fields:
        old = getattr(lumped, f)
        size = len(old) if isinstance(old, tuple) else 1
        chunk = vector[offset:offset + size]
        changes[f] = tuple(float(c) for c in chunk) if isinstance(old, tuple) else float(chunk[0])
        offset += size
    return dataclasses.replace(lumped, **changes)


@dataclass(frozen=True)
class SteadyComparison:
    """Steady-state isometric activation at L0 (F_CE/F0 = total activation at L0 plus PE1(L0)).

    | field | shape | meaning |
    | drive | (k,) | U grid |
    | fpcsa_slow | (m,) | fibre mixes |
    | natural, lumped | (k, m, 2) | effective activation per fibre type |
    | error_percent | (k, m) | (lumped - natural) total / natural total at U = 1, in % |
    """

    drive: np.ndarray
    fpcsa_slow: np.ndarray
    natural: np.ndarray
    lumped: np.ndarray

    @property
    def error_percent(self) -> np.ndarray:
        nat, lum = self.natural.sum(-1), self.lumped.sum(-1)
        return 100.0 * (lum - nat) / nat[-1]

    @property
    def max_error_percent(self) -> np.ndarray:
        """Largest |error| over the drive grid, per fibre mix (m,)."""
        return np.abs(self.error_percent).max(axis=0)


def _steady(bank: MuscleBank, drive) -> np.ndarray:
    return np.array([bank.steady_effective_activation(np.full(bank.n, u)) for u in drive])


def compare_steady(params: ModelParams, ur: float = 0.8, fpcsa_slow_grid=DEFAULT_FPCSA_GRID,
                   units_per_type: int = 50, drive=None) -> SteadyComparison:
    """Steady-state isometric activation of lumped vs natural units (the paper's Fig. 9)."""
    drive = np.linspace(0.0, 1.0, 101) if drive is None else np.asarray(drive, dtype=float)
    specs = synthetic_muscles(fpcsa_slow_grid, ur)
    natural_params = dataclasses.replace(params, natural=dataclasses.replace(
        params.natural, units_per_type=int(units_per_type)))
    natural = _steady(MuscleBank(specs, natural_params, "natural"), drive)
    lumped = _steady(MuscleBank(specs, params, "lumped"), drive)
    return SteadyComparison(drive, np.asarray(fpcsa_slow_grid, dtype=float), natural, lumped)


@dataclass(frozen=True)
class WeightingFit:
    """Result of :func:`fit_weighting`: refit params and the comparisons before and after."""

    params: ModelParams
    published: SteadyComparison
    fitted: SteadyComparison
    cost_reduction: float


def fit_weighting(params: ModelParams, ur: float = 0.8, fpcsa_slow_grid=DEFAULT_FPCSA_GRID,
                  units_per_type: int = 50, drive=None) -> WeightingFit:
    """Refit the lumped weighting W (all its coefficients, as polynomials in U2) to the natural
    units' steady-state isometric activation at L0, per fibre type, with scipy's least_squares
    started from the published coefficients."""
    base = compare_steady(params, ur, fpcsa_slow_grid, units_per_type, drive)
    specs = synthetic_muscles(fpcsa_slow_grid, ur)
    lumped_bank = MuscleBank(specs, params, "lumped")
    fpcsa, urs = lumped_bank.fpcsa, lumped_bank.ur
    # Af of the lumped units at steady state does not depend on W: take it once.
    with_unit_weights = np.array([
        lumped_bank.recruitment.pool_weights(np.full(len(specs), u)) for u in base.drive])
    af = np.divide(base.lumped, with_unit_weights, out=np.zeros_like(base.lumped),
                   where=with_unit_weights > 0)
    scale = base.natural.sum(-1)[-1]  # natural force at U = 1, per mix

    def residual(vector):
        trial = LumpedRecruitment(fpcsa, urs, _unpack(vector, params.lumped, W_FIELDS))
        weights = np.array([trial.pool_weights(np.full(len(specs), u)) for u in base.drive])
        return ((weights * af - base.natural) / scale[None, :, None]).ravel()

    x0 = _pack(params.lumped, W_FIELDS)
    result = least_squares(residual, x0, method="lm", x_scale="jac")
    fitted_params = dataclasses.replace(params, lumped=_unpack(result.x, params.lumped, W_FIELDS))
    fitted = compare_steady(fitted_params, ur, fpcsa_slow_grid, units_per_type, base.drive)
    cost0 = 0.5 * float(np.sum(residual(x0) ** 2))
    return WeightingFit(fitted_params, base, fitted, cost0 / max(result.cost, 1e-300))


def step_drive_series(dt: float, hold_s: float = 0.5,
                      levels=(0.0, 0.2, 0.45, 0.1, 0.7, 0.35, 1.0, 0.5, 0.0)) -> np.ndarray:
    """A staircase of drive steps up and down (k,), each level held ``hold_s``."""
    return np.repeat(np.asarray(levels, dtype=float), int(round(hold_s / dt)))


def _dynamic_banks(params, specs, units_per_type):
    natural_params = dataclasses.replace(params, natural=dataclasses.replace(
        params.natural, units_per_type=int(units_per_type)))
    return MuscleBank(specs, natural_params, "natural"), MuscleBank(specs, params, "lumped")


def _trace(bank: MuscleBank, drive_series, dt):
    bank.reset(np.full(bank.n, 1.0) * (bank.l0_m + bank.l0t_m), excitation=np.zeros(bank.n))
    series = np.repeat(drive_series[:, None], bank.n, axis=1)
    return bank.activation_trace(dt, series).sum(-1)


@dataclass(frozen=True)
class DriveFilterFit:
    """Result of :func:`fit_drive_filter`: RMS errors (% of natural force at U = 1) per mix."""

    params: ModelParams
    rms_published_percent: np.ndarray
    rms_fitted_percent: np.ndarray


def fit_drive_filter(params: ModelParams, ur: float = 0.8, fpcsa_slow_grid=DEFAULT_FPCSA_GRID,
                     units_per_type: int = 20, dt: float = 0.002, hold_s: float = 0.5,
                     max_nfev: int = 60) -> DriveFilterFit:
    """Refit T_rise(U2) and T_fall(U2) so the lumped units' isometric activation follows the
    natural units' through a staircase of drive steps (least squares over all mixes)."""
    specs = synthetic_muscles(fpcsa_slow_grid, ur)
    natural_bank, lumped_bank = _dynamic_banks(params, specs, units_per_type)
    drive = step_drive_series(dt, hold_s)
    target = _trace(natural_bank, drive, dt)
    scale = natural_bank.steady_effective_activation(np.ones(len(specs))).sum(-1)

    def simulate(vector):
        trial = dataclasses.replace(params, lumped=_unpack(vector, params.lumped, FILTER_FIELDS))
        return _trace(MuscleBank(specs, trial, "lumped"), drive, dt)

    def residual(vector):
        return ((simulate(vector) - target) / scale).ravel()

    x0 = _pack(params.lumped, FILTER_FIELDS)
    result = least_squares(residual, x0, max_nfev=max_nfev, x_scale="jac")

    def rms(vector):
        return 100.0 * np.sqrt(np.mean(((simulate(vector) - target) / scale) ** 2, axis=0))

    fitted = dataclasses.replace(params, lumped=_unpack(result.x, params.lumped, FILTER_FIELDS))
    return DriveFilterFit(fitted, rms(x0), rms(result.x))


@dataclass(frozen=True)
class SinusoidComparison:
    """Force response to sinusoidal drive, lumped vs natural (the paper's Fig. 10).

    Every case is one row; errors in % of the natural muscle's force at U = 1.

    | column | meaning |
    | mean_drive, amplitude, frequency_hz | the drive U = mean + amplitude sin(2 pi f t) |
    | transient_rms_error | RMS force error over the first cycle |
    | mean_error | steady state: error of the mean force over the last two cycles |
    | range_error | steady state: error of the modulation range (max - min force) |
    """

    columns: tuple
    rows: np.ndarray
    time_s: np.ndarray
    natural_force: np.ndarray
    lumped_force: np.ndarray


def compare_sinusoidal(params: ModelParams, muscle: MuscleSpec, mean_drive=(0.3, 0.5),
                       amplitudes=(0.1, 0.2), frequencies_hz=(0.5, 1.0, 2.0, 4.0),
                       units_per_type: int = 20, dt: float = 0.001, cycles: int = 4,
                       progress=None) -> SinusoidComparison:
    """Run every (mean, amplitude, frequency) case as one muscle of a bank, natural and lumped,
    at a fixed path length (fascicle near L0 at half force), through the full model."""
    from vm_ros.model.curves import tendon_length_at_force

    cases = [(m, a, f) for m in mean_drive for a in amplitudes for f in frequencies_hz]
    specs = [dataclasses.replace(muscle, name=f"case{i}") for i in range(len(cases))]
    mean_u = np.array([c[0] for c in cases])
    amp = np.array([c[1] for c in cases])
    freq = np.array([c[2] for c in cases])
    duration = cycles / freq.min()
    steps = int(round(duration / dt))
    time_s = np.arange(1, steps + 1) * dt
    forces, f_max = [], []
    natural, lumped = _dynamic_banks(params, specs, units_per_type)
    g = params.generic
    for bank in (natural, lumped):
        lp = bank.l0_m + bank.l0t_m * tendon_length_at_force(0.5, g.ct, g.kt, g.lrt)
        f_max.append(bank.reset(lp, excitation=np.ones(bank.n)).force)
        bank.reset(lp, excitation=mean_u)
        trace = np.empty((steps, bank.n))
        for k in range(steps):
            u = mean_u + amp * np.sin(2 * np.pi * freq * k * dt)
            trace[k] = bank.step(dt, u, lp).force
            if progress is not None and k % 500 == 0:
                progress(bank.recruitment.name, k, steps)
        forces.append(trace)
    nat, lum = forces
    scale = f_max[0]
    rows = []
    for i, (m, a, f) in enumerate(cases):
        first = time_s <= 1.0 / f
        # each case's own last two cycles (its series is longer than it needs when f > f_min)
        last = (time_s > (cycles - 2) / f) & (time_s <= cycles / f)
        transient = np.sqrt(np.mean((lum[first, i] - nat[first, i]) ** 2)) / scale[i]
        mean_err = (lum[last, i].mean() - nat[last, i].mean()) / scale[i]
        range_err = (np.ptp(lum[last, i]) - np.ptp(nat[last, i])) / scale[i]
        rows.append([m, a, f, 100 * transient, 100 * mean_err, 100 * range_err])
    columns = ("mean_drive", "amplitude", "frequency_hz", "transient_rms_error",
               "mean_error", "range_error")
    return SinusoidComparison(columns, np.array(rows), time_s, nat, lum)
