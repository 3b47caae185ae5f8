"""Item 12: lumped against natural units on held-out drives, generated from fixed seeds.

Items 4, 5 and 11 compare the two schemes on the paper's steady states and sinusoids and on nine
steps; the drive filter was fitted (vm_ros.model.lumped_fit.fit_drive_filter) on a fixed training
drive of steps, slow sinusoids, ramps of other lengths and pulse trains from other seeds
(lumped_fit.TRAINING_SEEDS), at L0. This item draws drives the fit never sees, from the seeds in
HELD_OUT_SEEDS (numpy's default_rng):

| family | drive | fascicle |
| pulses_l0 | random levels 0-1 (one in five at rest), each held 50-400 ms | L0 |
| pulses_length | the same | held at 0.8-1.25 L0 |
| moving | the same | path moving at +-0.5 L0/s between 0.8 and 1.2 L0 |
| ramps | a -> b over 0.5 s or 3 s, held, then to c | L0 |
| sines | mean 0.2-0.6, amplitude 0.1-0.3, 0.5-20 Hz | L0 |
| library | pulse trains as pulses_l0, soleus, rectus femoris, first dorsal interosseous | L0 |

Synthetic muscles draw Fpcsa_S in 0.05-0.95 and Ur in 0.5-0.8. Every case runs for CASE_S with
the full model (mechanics, energetics), natural units with NATURAL_UNITS_PER_TYPE units per fibre
type against lumped units with the default drive law and, beside them, the paper's law
(tsianos2012). The measures:

- force RMS: RMS over the case of lumped - natural tendon force, % of the natural force at U = 1
  (isometric, at the case's fascicle length; L0 for moving paths);
- per jump: lumped / natural initial energy (E_a + E_xb) from a drive jump of a pulse train to
  the next; a jump counts when the natural units' mean initial rate over it is at least
  MIN_RATE_FRACTION of their isometric rate at U = 1 (a window near rest has no energy to compare);
- per window: lumped / natural total energy (with recovery) over each WINDOW_S window of every
  case, counted by the same rule on the total rate.

The criteria and their bounds (the targets of this item, written before it was first run):
pulse trains at L0 median force RMS <= 1.5 % and worst <= 3 %; at other lengths and on moving
paths worst <= 4 %; >= 97 % of jumps within 0.8-1.25 on initial energy; every window within
0.9-1.1 on total energy; for each library muscle the worst force RMS no larger than the paper's
law's; on the sines below and above 5 Hz the worst force RMS and the worst |steady mean error|
no larger than the paper's law's. Everything else is reported without a bound.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from vm_ros.model import MuscleBank, load_model_params
from vm_ros.model.curves import tendon_length_at_force
from vm_ros.model.lumped_fit import pulse_train, with_drive_law
from vm_ros.model.params import MuscleSpec, resolve_muscles
from vm_ros.validation.results import CheckResult, Criterion

HELD_OUT_SEEDS = (3101, 3102, 3103, 3104, 3105, 3106, 3107, 3108)
DT = 1e-3
CASE_S = 4.0
NATURAL_UNITS_PER_TYPE = 20
PULSE_HOLD_S = (0.05, 0.4)
REST_PROBABILITY = 0.2
LENGTH_RANGE_L0 = (0.8, 1.25)
MOVING_RANGE_L0 = (0.8, 1.2)
MOVING_SPEED_L0_PER_S = 0.5
RAMP_S = (0.5, 3.0)
SINE_HZ = (0.5, 1.0, 2.0, 5.0, 10.0, 20.0)
FPCSA_SLOW_RANGE = (0.05, 0.95)
UR_RANGE = (0.5, 0.8)
LIBRARY_MUSCLES = ("soleus", "rectus_femoris", "first_dorsal_interosseous")
MIN_RATE_FRACTION = 0.05
WINDOW_S = 1.0
PAPER_LAW = "tsianos2012"

# the targets (percent of F(U=1), fractions, ratios)
PULSES_L0_MEDIAN_RMS = 1.5
PULSES_L0_WORST_RMS = 3.0
OFF_L0_WORST_RMS = 4.0
JUMP_BAND = (0.8, 1.25)
JUMPS_WITHIN_FRACTION = 0.97
WINDOW_BAND = (0.9, 1.1)
SINE_SPLIT_HZ = 5.0

HELD_OUT_GAP = ("known gap (test/validation/REPORT.md item 12): the drive filter holds W while "
                "natural units derecruit and lets rises on top of active units through faster "
                "than recruitment (measured on held-out drives before this item existed)")


@dataclass(frozen=True)
class HeldOutCase:
    """One generated case: a muscle and its inputs.

    | field | shape | unit | meaning |
    | family | | | one of the families of the module docstring |
    | seed | | | the seed it was drawn from |
    | muscle | | | the library muscle's name, or "synthetic" |
    | spec | | | the muscle (named after the case) |
    | drive | (k,) | 1 | U per step |
    | length_l0 | (k,) | L0 | fascicle length the path is placed for (at half F0) |
    | velocity_l0_per_s | (k,) | L0/s | its rate |
    | jumps | (j,) | step | steps at which a pulse train's drive changes (empty otherwise) |
    | frequency_hz | | Hz | a sine's frequency (0 otherwise) |
    """

    family: str
    seed: int
    muscle: str
    spec: MuscleSpec
    drive: np.ndarray
    length_l0: np.ndarray
    velocity_l0_per_s: np.ndarray
    jumps: np.ndarray
    frequency_hz: float = 0.0


def _pulses(rng, steps: int, dt: float) -> np.ndarray:
    """A pulse train (lumped_fit.pulse_train) held PULSE_HOLD_S, at rest with REST_PROBABILITY."""
    return pulse_train(rng, steps, dt, PULSE_HOLD_S, REST_PROBABILITY)


def ramps(rng, steps: int, ramp_s: float, dt: float = DT) -> np.ndarray:
    """a -> b linearly over ``ramp_s``, held, then b -> c over ``ramp_s`` (or what is left),
    held to the end (a, b, c uniform 0-1)."""
    a, b, c = rng.uniform(0.0, 1.0, 3)
    n = int(round(ramp_s / dt))
    hold = max((steps - 2 * n) // 2, 0)
    first = np.linspace(a, b, n)
    second = np.linspace(b, c, n)
    drive = np.concatenate([first, np.full(hold, b), second, np.full(steps, c)])
    return drive[:steps]


def triangle_path(rng, steps: int, dt: float = DT) -> tuple[np.ndarray, np.ndarray]:
    """Fascicle length target (L0) moving at MOVING_SPEED_L0_PER_S between MOVING_RANGE_L0, from
    a random phase, and its rate (L0/s)."""
    low, high = MOVING_RANGE_L0
    period = 2.0 * (high - low) / MOVING_SPEED_L0_PER_S
    phase = (rng.uniform(0.0, period) + np.arange(steps) * dt) % period
    up = phase < period / 2
    length = np.where(up, low + MOVING_SPEED_L0_PER_S * phase,
                      high - MOVING_SPEED_L0_PER_S * (phase - period / 2))
    return length, np.where(up, MOVING_SPEED_L0_PER_S, -MOVING_SPEED_L0_PER_S)


def _jumps(drive: np.ndarray) -> np.ndarray:
    return np.flatnonzero(np.diff(drive) != 0.0) + 1


def _synthetic(rng) -> MuscleSpec:
    return MuscleSpec(name="synthetic", mass_kg=0.1, l0_m=0.1, l0t_m=0.1,
                      fpcsa_slow=float(rng.uniform(*FPCSA_SLOW_RANGE)),
                      ur=float(rng.uniform(*UR_RANGE)), lmax=1.3)


def held_out_cases(seeds=HELD_OUT_SEEDS, case_s: float = CASE_S, dt: float = DT,
                   library=LIBRARY_MUSCLES) -> list[HeldOutCase]:
    """Every case drawn from ``seeds``: per seed one case of pulses_l0, pulses_length and
    moving, a ramp of each RAMP_S, a sine below 5 Hz and one at 5-20 Hz, and a pulse train for
    each muscle of ``library``."""
    steps = int(round(case_s / dt))
    fixed = np.ones(steps), np.zeros(steps)
    library_specs = resolve_muscles(list(library), None, None, 0.8) if library else []
    cases = []
    for seed in seeds:
        rng = np.random.default_rng(seed)

        def case(family, spec, drive, path=fixed, frequency=0.0, jumps=True, seed=seed):
            muscle = spec.name if family == "library" else "synthetic"
            cases.append(HeldOutCase(
                family, seed, muscle,
                dataclasses.replace(spec, name=f"{family}_{seed}_{len(cases)}"),
                drive, *path, _jumps(drive) if jumps else np.zeros(0, dtype=int), frequency))

        case("pulses_l0", _synthetic(rng), _pulses(rng, steps, dt))
        length = rng.uniform(*LENGTH_RANGE_L0)
        case("pulses_length", _synthetic(rng), _pulses(rng, steps, dt),
             (np.full(steps, length), np.zeros(steps)))
        case("moving", _synthetic(rng), _pulses(rng, steps, dt),
             triangle_path(rng, steps, dt))
        for ramp_s in RAMP_S:
            case("ramps", _synthetic(rng), ramps(rng, steps, ramp_s, dt), jumps=False)
        t = np.arange(steps) * dt
        for band in (SINE_HZ[:3], SINE_HZ[3:]):  # one sine below 5 Hz, one at 5-20 Hz
            frequency = band[int(rng.integers(len(band)))]
            mean = rng.uniform(0.2, 0.6)
            amplitude = rng.uniform(0.1, min(0.3, mean))
            case("sines", _synthetic(rng), mean + amplitude * np.sin(2 * np.pi * frequency * t),
                 frequency=frequency, jumps=False)
        for spec in library_specs:
            case("library", spec, _pulses(rng, steps, dt))
    return cases


@dataclass(frozen=True)
class HeldOutRun:
    """Both schemes through every case.

    | field | shape | unit | meaning |
    | force_rms_percent | (c,) | % F(U=1) | RMS of lumped - natural force |
    | steady_mean_error_percent | (c,) | % F(U=1) | error of the mean force over the last half |
    | jump_energy_ratio | (j,) | 1 | lumped / natural initial energy per counted jump |
    | jump_case | (j,) | | the case of each counted jump |
    | window_energy_ratio | (w,) | 1 | lumped / natural total energy per counted window |
    | jump_step | (j,) | step | the step at which each counted jump starts (None: not kept) |
    """

    force_rms_percent: np.ndarray
    steady_mean_error_percent: np.ndarray
    jump_energy_ratio: np.ndarray
    jump_case: np.ndarray
    window_energy_ratio: np.ndarray
    jump_step: np.ndarray | None = None


def _path(bank: MuscleBank, length_l0, velocity_l0_per_s):
    g = bank.params.generic
    tendon = bank.l0t_m * tendon_length_at_force(0.5, g.ct, g.kt, g.lrt)
    return bank.l0_m * length_l0 + tendon, bank.l0_m * velocity_l0_per_s


def _simulate(bank: MuscleBank, cases, dt):
    """Force (N), initial and total energy rates (W), each (k, c), and the isometric force and
    rates at U = 1 at each case's reference length (c,)."""
    drive = np.stack([c.drive for c in cases], axis=1)
    length = np.stack([c.length_l0 for c in cases], axis=1)
    velocity = np.stack([c.velocity_l0_per_s for c in cases], axis=1)
    reference = np.where(velocity.any(axis=0), 1.0, length[0])
    full = bank.reset(_path(bank, reference, 0.0)[0], excitation=np.ones(bank.n))
    full_rates = full.energy_rate
    lp, vp = _path(bank, length, velocity)
    bank.reset(lp[0], excitation=drive[0])
    run = bank.run(dt, drive, lp, vp)
    rate = run.energy_rate
    return (run.force, rate.activation + rate.cross_bridge, rate.total, full.force,
            full_rates.activation + full_rates.cross_bridge, full_rates.total)


def compare_held_out(params, cases, lumped=None, dt: float = DT,
                     units_per_type: int = NATURAL_UNITS_PER_TYPE) -> list[HeldOutRun]:
    """Lumped against natural units (``params``) through ``cases``, one HeldOutRun per parameter
    set of ``lumped`` (default: ``params`` alone); the natural units run once."""
    specs = [c.spec for c in cases]
    natural_params = dataclasses.replace(params, natural=dataclasses.replace(
        params.natural, units_per_type=int(units_per_type)))
    nat_f, nat_e, nat_t, f1, e1, t1 = _simulate(MuscleBank(specs, natural_params, "natural"),
                                                cases, dt)
    w = int(round(WINDOW_S / dt))
    n_windows = len(nat_t) // w
    nat_w = nat_t[:n_windows * w].reshape(n_windows, w, len(cases)).sum(axis=1)
    counted = nat_w >= MIN_RATE_FRACTION * t1 * w
    runs = []
    for lumped_params in lumped or (params,):
        lum_f, lum_e, lum_t, *_ = _simulate(MuscleBank(specs, lumped_params, "lumped"), cases, dt)
        error = (lum_f - nat_f) / f1
        ratios, owners, starts = [], [], []
        for i, c in enumerate(cases):
            edges = np.append(c.jumps, len(c.drive))
            for start, stop in zip(edges[:-1], edges[1:], strict=True):
                if nat_e[start:stop, i].mean() >= MIN_RATE_FRACTION * e1[i]:
                    ratios.append(lum_e[start:stop, i].sum() / nat_e[start:stop, i].sum())
                    owners.append(i)
                    starts.append(start)
        lum_w = lum_t[:n_windows * w].reshape(n_windows, w, len(cases)).sum(axis=1)
        runs.append(HeldOutRun(100.0 * np.sqrt(np.mean(error**2, axis=0)),
                               100.0 * error[len(error) // 2:].mean(axis=0), np.array(ratios),
                               np.array(owners, dtype=int), lum_w[counted] / nat_w[counted],
                               np.array(starts, dtype=int)))
    return runs


def _families(cases) -> np.ndarray:
    return np.array([c.family for c in cases])


def held_out_criteria(cases, run: HeldOutRun, paper: HeldOutRun) -> list[Criterion]:
    """The item's criteria (bounds in the module docstring) and its reported numbers, the
    paper's law beside each."""
    family = _families(cases)
    criteria = []

    def add(description, value, low=None, high=None):
        bounded = low is not None or high is not None
        criteria.append(Criterion(description, float(value), low, high,
                                  HELD_OUT_GAP if bounded else ""))

    rms, paper_rms = run.force_rms_percent, paper.force_rms_percent
    at_l0 = family == "pulses_l0"
    add("pulse trains at L0: force RMS % F(U=1), median", np.median(rms[at_l0]), None,
        PULSES_L0_MEDIAN_RMS)
    add("pulse trains at L0: force RMS % F(U=1), worst", rms[at_l0].max(), None,
        PULSES_L0_WORST_RMS)
    for name in ("pulses_length", "moving"):
        add(f"{name}: force RMS % F(U=1), worst", rms[family == name].max(), None,
            OFF_L0_WORST_RMS)
    for name in ("pulses_l0", "pulses_length", "moving", "ramps", "sines", "library"):
        chosen = family == name
        if name != "pulses_l0":  # its median and worst are criteria above
            add(f"{name}: force RMS % F(U=1), median (reported)", np.median(rms[chosen]))
        if name not in ("pulses_l0", "pulses_length", "moving"):
            add(f"{name}: force RMS % F(U=1), worst (reported)", rms[chosen].max())
        add(f"{name}: {PAPER_LAW} law, force RMS median (reported)", np.median(paper_rms[chosen]))
        add(f"{name}: {PAPER_LAW} law, force RMS worst (reported)", paper_rms[chosen].max())
    for jumps, label in ((run.jump_energy_ratio, "lumped"),
                         (paper.jump_energy_ratio, f"{PAPER_LAW} law")):
        within = np.mean((jumps >= JUMP_BAND[0]) & (jumps <= JUMP_BAND[1]))
        if label == "lumped":
            add(f"jumps with initial energy ratio in 0.8-1.25 (fraction of {len(jumps)})",
                within, JUMPS_WITHIN_FRACTION, None)
        else:
            add(f"{label}: jumps with initial energy ratio in 0.8-1.25 (reported)", within)
        add(f"{label}: per-jump initial energy ratio, min (reported)", jumps.min())
        add(f"{label}: per-jump initial energy ratio, max (reported)", jumps.max())
    add(f"total energy ratio per {WINDOW_S:g} s window, min (of {len(run.window_energy_ratio)})",
        run.window_energy_ratio.min(), WINDOW_BAND[0], None)
    add(f"total energy ratio per {WINDOW_S:g} s window, max", run.window_energy_ratio.max(),
        None, WINDOW_BAND[1])
    add(f"{PAPER_LAW} law: total energy ratio per window, min (reported)",
        paper.window_energy_ratio.min())
    add(f"{PAPER_LAW} law: total energy ratio per window, max (reported)",
        paper.window_energy_ratio.max())
    library = np.array([c.muscle for c in cases])
    for name in dict.fromkeys(library[family == "library"]):
        chosen = (family == "library") & (library == name)
        add(f"library {name}: worst force RMS / the same with the {PAPER_LAW} law "
            f"({paper_rms[chosen].max():.2f} %)", rms[chosen].max() / paper_rms[chosen].max(),
            None, 1.0)
    frequency = np.array([c.frequency_hz for c in cases])
    mean_error = np.abs(run.steady_mean_error_percent)
    paper_mean_error = np.abs(paper.steady_mean_error_percent)
    for label, chosen in (("sines below 5 Hz", (family == "sines") & (frequency < SINE_SPLIT_HZ)),
                          ("sines 5-20 Hz", (family == "sines") & (frequency >= SINE_SPLIT_HZ))):
        if not chosen.any():
            continue
        for measure, mine, theirs in (("force RMS", rms, paper_rms),
                                      ("|steady mean error|", mean_error, paper_mean_error)):
            add(f"{label}: worst {measure} / the same with the {PAPER_LAW} law "
                f"({theirs[chosen].max():.2f} %)", mine[chosen].max() / theirs[chosen].max(),
                None, 1.0)
    return criteria


def held_out_summary(cases, run: HeldOutRun) -> str:
    """One line: pulse trains at L0 force RMS median / worst, off L0 and moving worst (% F(U=1)),
    jumps within 0.8-1.25, the range of the per-window energy ratio."""
    family = _families(cases)
    rms = run.force_rms_percent
    at_l0 = rms[family == "pulses_l0"]
    off = rms[(family == "pulses_length") | (family == "moving")]
    jumps = run.jump_energy_ratio
    within = np.mean((jumps >= JUMP_BAND[0]) & (jumps <= JUMP_BAND[1]))
    return (f"pulse trains at L0 force RMS {np.median(at_l0):.2f} / {at_l0.max():.2f} %, off L0 "
            f"and moving worst {off.max():.2f} %, jumps within 0.8-1.25 {within:.1%}, windows "
            f"{run.window_energy_ratio.min():.2f}-{run.window_energy_ratio.max():.2f}")


def check_held_out(params=None, seeds=HELD_OUT_SEEDS) -> CheckResult:
    """Item 12 (module docstring): the cases of ``seeds``, lumped with the default law and with
    the paper's, against natural units."""
    params = params or load_model_params()
    cases = held_out_cases(seeds)
    run, paper = compare_held_out(params, cases, (params, with_drive_law(params, PAPER_LAW)))
    result = CheckResult(
        "12", f"Held-out drives (seeds {seeds[0]}-{seeds[-1]}): lumped "
        f"({params.lumped.drive_law}) vs natural units",
        "lumped units give the force and energy of natural units (the paper: at steady state "
        "and for sinusoids); targets on drives the fit never sees: pulse trains at L0 force RMS "
        "median <= 1.5 %, worst <= 3 % of F(U=1), <= 4 % off L0 and moving; >= 97 % of jumps "
        "within 0.8-1.25 on initial energy; every window 0.9-1.1 on total energy; no worse than "
        "the paper's law per library muscle and on sines to 20 Hz")
    result.criteria = held_out_criteria(cases, run, paper)
    result.data = {"cases": cases, "run": run, "paper_law": paper, "seeds": tuple(seeds)}
    return result
