"""Lumped units against natural units: comparison and refit (Tsianos 2012 Appendix A, Figs. 9-10).

The lumped model replaces N discrete units per fibre type by one unit per type whose recruited
PCSA rF and weighting W make it behave like the ensemble. At steady state and L = L0 the ensemble's
effective activation per type is A_nat(U) = sum_j p_j Af(f_env_j(U)); the lumped unit gives
rF(U) W(U) Af(f_env(U)). W is therefore fixed by the natural-units model, which is how the paper
derived it. :func:`fit_weighting` refits W's coefficients (polynomials in U2, the fast threshold)
by least squares over a grid of fibre mixes, for any Ur; :func:`fit_drive_filter` refits the
constants of the drive filter's law against natural units through steps and sinusoids;
:func:`compare_steps` and :func:`compare_sinusoidal` compare the two schemes, with the full model,
on drives the fit did not see.

Errors are reported in % of the natural ensemble's force at U = 1 (the paper's Fig. 9 measure).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from vm_ros.model.bank import MuscleBank
from vm_ros.model.curves import tendon_length_at_force
from vm_ros.model.params import LumpedParams, ModelParams, MuscleSpec
from vm_ros.model.recruitment import LumpedRecruitment

W_FIELDS = ("w_slow_poly", "w_slow_a_poly", "w_slow_tau", "w_fast_b_poly", "w_fast_c_poly",
            "w_fast_offset", "w_fast_rise", "w_fast_tau_poly")
# the constants of each drive-filter law (params.DRIVE_LAWS) that fit_drive_filter refits
FILTER_FIELDS = {
    "tsianos2012": ("t_rise_poly", "t_fall_poly"),
    "relative_drive": ("relative_rise_poly", "relative_fall_poly", "relative_fall_power",
                       "relative_fall_floor"),
}
# Bounds of the fitted values (each coefficient of a polynomial), where the fit needs them: without
# them the relative_drive fit can trade a smaller error for a law that holds Ueff for minutes after
# a release (T_f ~ 1000 s with p ~ 150), where Ueff no longer means an effective drive. A time
# constant coefficient stays within 2 s, p in 1-4 (1: T_U linear in the firing mismatch; 4: only a
# large mismatch holds W), T_f0 within 0-0.5 s.
FILTER_BOUNDS = {
    "relative_rise_poly": (-2.0, 2.0),
    "relative_fall_poly": (-2.0, 2.0),
    "relative_fall_power": (1.0, 4.0), "relative_fall_floor": (0.0, 0.5),
}
# Where `vm-ros fit-w --drive-filter` starts each law's fit (None: the parameter file's values,
# the paper's for tsianos2012): fixed round values, so that the fitted constants do not depend on
# the ones shipped.
DRIVE_FILTER_START = {
    "tsianos2012": None,
    "relative_drive": {"relative_rise_poly": (0.0, 0.1), "relative_fall_poly": (0.0, 0.5),
                       "relative_fall_power": 2.0, "relative_fall_floor": 0.05},
}
DEFAULT_FPCSA_GRID = (0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8)
# The drive-filter fit's muscles: every (Fpcsa_S, Ur) of these
DRIVE_FILTER_FPCSA = (0.05, 0.2, 0.35, 0.5, 0.65, 0.8, 0.95)
DRIVE_FILTER_UR = (0.5, 0.65, 0.8)
DRIVE_FILTER_GRID = tuple((fs, ur) for ur in DRIVE_FILTER_UR for fs in DRIVE_FILTER_FPCSA)
DRIVE_FILTER_MAX_EVALUATIONS = 200


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


def pulse_train(rng, steps: int, dt: float, hold_s, rest_probability: float) -> np.ndarray:
    """Random levels (uniform 0-1; at rest with ``rest_probability``), each held a uniform
    ``hold_s`` (low, high), (steps,), from the numpy Generator ``rng``."""
    drive, k = np.empty(steps), 0
    while k < steps:
        hold = int(round(rng.uniform(*hold_s) / dt))
        level = 0.0 if rng.random() < rest_probability else rng.uniform(0.0, 1.0)
        drive[k:k + hold] = level
        k += hold
    return drive


def ramp_series(levels, ramp_s: float, hold_s: float, dt: float) -> np.ndarray:
    """From each of ``levels`` to the next linearly over ``ramp_s``, each level then held
    ``hold_s`` (k,)."""
    n, hold = int(round(ramp_s / dt)), int(round(hold_s / dt))
    pieces = [np.full(hold, levels[0])]
    for a, b in zip(levels[:-1], levels[1:], strict=True):
        pieces += [np.linspace(a, b, n + 1)[1:], np.full(hold, b)]
    return np.concatenate(pieces)


# Training drive of the drive-filter fit (isometric activation at L0): the staircase,
# TRAINING_RELEASES, sinusoids (mean, amplitude, Hz) of TRAINING_SINUSOID_S each, pulse trains
# (random levels each held TRAINING_PULSE_HOLD_S, one in five at rest) of TRAINING_PULSE_S from
# the seeds TRAINING_SEEDS, and ramps through TRAINING_RAMP_LEVELS at each of TRAINING_RAMP_S.
# Checked separately from the fit: compare_steps with the full model (7 of its 9 steps are not in
# the training drive; 0->0.2 and 0.5->0 are also steps of the staircase), compare_sinusoidal (the
# paper's Fig. 10 cases, none in training) and validation item 12 (other seeds, lengths, paths).
TRAINING_SINUSOIDS = ((0.4, 0.15, 3.0), (0.6, 0.25, 1.5), (0.25, 0.1, 6.0), (0.35, 0.2, 4.5))
TRAINING_SINUSOID_S = 2.0
# releases to rest and rises from it, from levels the validation steps do not use
TRAINING_RELEASES = (0.0, 0.6, 0.0, 0.3, 0.9, 0.0, 0.15, 0.4, 0.0)
TRAINING_SEEDS = (2901, 2902)
TRAINING_PULSE_S = 4.0
TRAINING_PULSE_HOLD_S = (0.05, 0.4)
TRAINING_PULSE_REST_PROBABILITY = 0.2
TRAINING_RAMP_LEVELS = (0.0, 0.85, 0.3, 0.0)
TRAINING_RAMP_S = (0.2, 0.6, 1.5)
TRAINING_RAMP_HOLD_S = 0.3


def training_drive_series(dt: float) -> np.ndarray:
    """The drive-filter fit's training drive (k,) (the constants above, in their order)."""
    t = np.arange(int(round(TRAINING_SINUSOID_S / dt))) * dt
    sines = [m + a * np.sin(2 * np.pi * f * t) for m, a, f in TRAINING_SINUSOIDS]
    pulses = [pulse_train(np.random.default_rng(seed), int(round(TRAINING_PULSE_S / dt)), dt,
                          TRAINING_PULSE_HOLD_S, TRAINING_PULSE_REST_PROBABILITY)
              for seed in TRAINING_SEEDS]
    ramps = [ramp_series(TRAINING_RAMP_LEVELS, r, TRAINING_RAMP_HOLD_S, dt)
             for r in TRAINING_RAMP_S]
    return np.concatenate([step_drive_series(dt), step_drive_series(dt, levels=TRAINING_RELEASES),
                           *sines, *pulses, *ramps])


def _dynamic_banks(params, specs, units_per_type):
    natural_params = dataclasses.replace(params, natural=dataclasses.replace(
        params.natural, units_per_type=int(units_per_type)))
    return MuscleBank(specs, natural_params, "natural"), MuscleBank(specs, params, "lumped")


def _trace(bank: MuscleBank, drive_series, dt):
    """Effective activation per fibre type, (k, n, 2), from rest, through the full model (the
    compiled run) at the fixed path length at which the fascicle is at L0 under half F0."""
    g = bank.params.generic
    path = bank.l0_m + bank.l0t_m * tendon_length_at_force(0.5, g.ct, g.kt, g.lrt)
    bank.reset(path, excitation=np.zeros(bank.n))
    k = len(drive_series)
    run = bank.run(dt, np.repeat(drive_series[:, None], bank.n, axis=1), np.tile(path, (k, 1)))
    return run.effective_activation


def with_drive_law(params: ModelParams, law: str) -> ModelParams:
    """``params`` with the lumped drive filter's law set to ``law`` (params.DRIVE_LAWS)."""
    return dataclasses.replace(params, lumped=dataclasses.replace(params.lumped, drive_law=law))


def with_lumped(params: ModelParams, **changes) -> ModelParams:
    """``params`` with the given recruitment.lumped fields replaced."""
    return dataclasses.replace(params, lumped=dataclasses.replace(params.lumped, **changes))


@dataclass(frozen=True)
class DriveFilterFit:
    """Result of :func:`fit_drive_filter` for one law: the refit params, the fitted fields, the
    RMS error of the isometric activation over the training drive (% of the reference at U = 1)
    per muscle of the grid, at the start and fitted, and least_squares' status and evaluations."""

    params: ModelParams
    fields: tuple
    rms_start_percent: np.ndarray
    rms_fitted_percent: np.ndarray
    status: int
    evaluations: int


class _DriveFilterProblem:
    """The drive-filter fit's target (the ``reference`` scheme through the training drive) and
    residual. The reference is natural units; "lumped" (the lumped units with ``params``' own
    constants) gives a target whose constants are known, to check that the fit recovers them."""

    def __init__(self, params, grid, units_per_type, dt, reference="natural"):
        self.params, self.dt = params, dt
        self.specs = grid_muscles(grid)
        natural_bank, lumped_bank = _dynamic_banks(params, self.specs, units_per_type)
        reference_bank = {"natural": natural_bank, "lumped": lumped_bank}[reference]
        self.drive = training_drive_series(dt)
        self.target = _trace(reference_bank, self.drive, dt)
        full = reference_bank.steady_effective_activation(np.ones(len(self.specs)))
        # isometric tetanic initial energy per unit activation and dry mass (Barclay's fit at
        # V = 0, e3/e4; the activation share scales both types alike): fast ~6x slow
        e = params.energetics
        self.energy_weight = np.asarray(e.e3, dtype=float) / np.asarray(e.e4, dtype=float)
        self.scale = np.stack([full.sum(-1), full @ self.energy_weight], axis=-1)  # (mixes, 2)

    def _measures(self, activation) -> np.ndarray:
        """Force-like (activation summed over types) and energy-like (weighted by energy per
        unit activation) measures, (k, mixes, 2), each / its reference value at U = 1."""
        return np.stack([activation.sum(-1), activation @ self.energy_weight], axis=-1) / self.scale

    def error(self, params) -> np.ndarray:
        """(lumped - reference), force and energy measures, (k, mixes, 2): what the lumped units
        stand in for, so that a fast-fibre error (six times the energy of a slow one for the same
        force) counts as much as it costs."""
        lumped = _trace(MuscleBank(self.specs, params, "lumped"), self.drive, self.dt)
        return self._measures(lumped) - self._measures(self.target)

    def rms_percent(self, params) -> np.ndarray:
        """RMS over time and both measures, per muscle (% of the reference at U = 1)."""
        return 100.0 * np.sqrt(np.mean(self.error(params) ** 2, axis=(0, 2)))


def grid_muscles(grid) -> list[MuscleSpec]:
    """One synthetic muscle per (Fpcsa_S, Ur) pair of ``grid``."""
    return [dataclasses.replace(spec, name=f"{spec.name}_ur_{ur:.3f}")
            for fs, ur in grid for spec in synthetic_muscles((fs,), ur)]


def drive_filter_rms_percent(params: ModelParams, grid=DRIVE_FILTER_GRID,
                             units_per_type: int = 20, dt: float = 0.002) -> np.ndarray:
    """RMS error (% of natural at U = 1) of the lumped isometric activation against natural units
    over the training drive, per muscle of ``grid``: what :func:`fit_drive_filter` minimises."""
    return _DriveFilterProblem(params, grid, units_per_type, dt).rms_percent(params)


def fit_drive_filter(params: ModelParams, grid=DRIVE_FILTER_GRID, units_per_type: int = 20,
                     dt: float = 0.002, max_nfev: int = DRIVE_FILTER_MAX_EVALUATIONS,
                     start: dict | None = None, reference: str = "natural") -> DriveFilterFit:
    """Refit the constants of the drive filter's law (``params.lumped.drive_law``, fields in
    FILTER_FIELDS) so that the lumped units' isometric activation at L0 follows the reference's
    (natural units) through :func:`training_drive_series`, least squares over every muscle of
    ``grid`` (Fpcsa_S, Ur) at once (the polynomials in U2 make the constants depend on the mix, as
    W's do). Started from ``start`` (field: value; None: ``params``' own values), bounded by
    FILTER_BOUNDS; scipy's least_squares (trf, 2-point differences) is deterministic: the same
    inputs give the same constants."""
    fields = FILTER_FIELDS[params.lumped.drive_law]
    problem = _DriveFilterProblem(params, grid, units_per_type, dt, reference)
    begin = with_lumped(params, **(start or {}))

    def trial(vector):
        return dataclasses.replace(params, lumped=_unpack(vector, params.lumped, fields))

    x0 = _pack(begin.lumped, fields)
    sizes = [np.size(getattr(params.lumped, f)) for f in fields]
    low, high = (np.repeat([FILTER_BOUNDS.get(f, (-np.inf, np.inf))[side] for f in fields], sizes)
                 for side in (0, 1))
    result = least_squares(lambda x: problem.error(trial(x)).ravel(), np.clip(x0, low, high),
                           bounds=(low, high), max_nfev=max_nfev, x_scale="jac")
    fitted = trial(result.x)
    return DriveFilterFit(fitted, fields, problem.rms_percent(begin), problem.rms_percent(fitted),
                          int(result.status), int(result.nfev))


STEP_CASES = ((0.0, 0.2), (0.0, 0.5), (0.0, 0.8), (0.0, 1.0), (0.3, 0.6), (0.5, 0.8), (0.8, 0.0),
              (0.5, 0.0), (0.6, 0.3))
STEP_FPCSA_SLOW = (0.2, 0.36, 0.5, 0.8)


@dataclass(frozen=True)
class StepComparison:
    """Lumped against natural units after drive steps, through the full model.

    Every (fibre mix, step) is a muscle of one bank, held at a fixed path length at which the
    fascicle is at ``length_l0`` under half F0, started at steady state for the first drive and
    stepped to the second at t = 0.

    | field | shape | meaning |
    | cases | (c, 3) | fpcsa_slow, drive before, drive after |
    | energy_ratio | (c,) | lumped / natural initial energy (E_a + E_xb) over the window |
    | impulse_ratio | (c,) | lumped / natural tendon-force impulse over the window |
    | time_s | (k,) | time after the step |
    | natural_force, lumped_force | (k, c) | tendon force / F0 |
    | natural_energy_rate, lumped_energy_rate | (k, c) | initial energy rate (W) |
    | steady_energy_ratio, steady_force_ratio | (c,) | lumped / natural at steady state for the |
    |  |  | drive after the step, same path (NaN for a step to rest) |
    """

    length_l0: float
    window_s: float
    cases: np.ndarray
    energy_ratio: np.ndarray
    impulse_ratio: np.ndarray
    time_s: np.ndarray
    natural_force: np.ndarray
    lumped_force: np.ndarray
    natural_energy_rate: np.ndarray
    lumped_energy_rate: np.ndarray
    steady_energy_ratio: np.ndarray
    steady_force_ratio: np.ndarray


def compare_steps(params: ModelParams, length_l0: float = 1.0, fpcsa_slow_grid=STEP_FPCSA_SLOW,
                  steps=STEP_CASES, ur: float = 0.8, units_per_type: int = 20,
                  window_s: float = 0.25, dt: float = 1e-3) -> StepComparison:
    """Lumped against natural units after drive steps (see :class:`StepComparison`)."""
    cases = np.array([(fs, a, b) for fs in fpcsa_slow_grid for a, b in steps], dtype=float)
    specs = [dataclasses.replace(spec, name=f"case{i}")
             for i, spec in enumerate(synthetic_muscles(cases[:, 0], ur))]
    k = int(round(window_s / dt))
    traces, steady = [], []
    for bank in _dynamic_banks(params, specs, units_per_type):
        g = bank.params.generic
        lp = bank.l0_m * length_l0 + bank.l0t_m * tendon_length_at_force(0.5, g.ct, g.kt, g.lrt)
        after = bank.reset(lp, excitation=cases[:, 2])
        rate = after.energy_rate
        steady.append((after.force, rate.activation + rate.cross_bridge))
        bank.reset(lp, excitation=cases[:, 1])
        run = bank.run(dt, np.tile(cases[:, 2], (k, 1)), np.tile(lp, (k, 1)))
        rate = run.energy_rate
        traces.append((run.force / bank.f0, rate.activation + rate.cross_bridge))
    (nat_f, nat_e), (lum_f, lum_e) = traces
    to_rest = cases[:, 2] == 0.0
    (nat_sf, nat_se), (lum_sf, lum_se) = steady
    return StepComparison(
        length_l0=float(length_l0), window_s=float(window_s), cases=cases,
        energy_ratio=lum_e.sum(0) / nat_e.sum(0), impulse_ratio=lum_f.sum(0) / nat_f.sum(0),
        time_s=np.arange(1, k + 1) * dt, natural_force=nat_f, lumped_force=lum_f,
        natural_energy_rate=nat_e, lumped_energy_rate=lum_e,
        steady_energy_ratio=np.where(to_rest, np.nan, lum_se / np.where(to_rest, 1.0, nat_se)),
        steady_force_ratio=np.where(to_rest, np.nan, lum_sf / np.where(to_rest, 1.0, nat_sf)),
    )


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
