"""Item 9: the 180 s dynamic knee extension of Tsianos, Rustin & Loeb 2012 (Fig. 7).

The task is config/scenarios.yaml ``knee_extension``; :func:`run_knee_extension` simulates it and
:func:`check_fig7_knee_extension` compares it with the paper's claims.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from vm_ros.model import MuscleBank, load_model_params
from vm_ros.model.params import DRIVE_LAWS, RECOVERY_KERNELS
from vm_ros.offline.scenarios import load_scenario
from vm_ros.validation.paper import DT, isometric_at
from vm_ros.validation.results import CheckResult, Criterion

# The paper's total energy for the 180 s task, and the experiment's band (Tsianos 2012 Fig. 7).
FIG7_PAPER_TOTAL_J = 35_000.0
FIG7_EXPERIMENT_BAND_J = (30_000.0, 40_000.0)
# Natural units per fibre type in the Fig. 7 table (the paper's Fig. 10 comparison uses 20 too).
FIG7_NATURAL_UNITS_PER_TYPE = 20
FIG7_ENERGY_GAP = ("known gap (test/validation/REPORT.md item 9): the task as specified gives "
                   "about half of the paper's total energy")


@dataclass(frozen=True)
class KneeExtensionRun:
    """The Fig. 7 task as simulated.

    | field | shape | unit | meaning |
    | bin_time_s | (k,) | s | centres of the energy bins |
    | bins_w | (k, 4) | W | mean rate per bin, both muscles: activation, cross-bridge, |
    |  |  |  | recovery, total |
    | cycle | dict | SI | traces of the last full cycle (see :func:`run_knee_extension`) |
    | out | StepOutput | | the last step (cumulative energies and work) |
    | bank | MuscleBank | | the bank, for names, masses and F0 |
    """

    bin_time_s: np.ndarray
    bins_w: np.ndarray
    cycle: dict
    out: object
    bank: MuscleBank


def run_knee_extension(duration_s=None, dt=DT, progress=None, params=None, recruitment="lumped",
                       units_per_type=None, trace=True) -> KneeExtensionRun:
    """The Fig. 7 task (config/scenarios.yaml ``knee_extension``), 1 s energy bins.

    ``recruitment`` and ``units_per_type`` choose the scheme (MuscleBank.from_config). With
    ``trace``, ``cycle`` holds the last full cycle: time_s (k,), drive U, Ueff, force (F0),
    velocity (L0/s), energy rate (W; all (k, n)) and activation (k, n): Acteff summed over fibre
    types relative to its isometric steady value at the scenario's drive; otherwise it is empty.
    """
    scenario = load_scenario("knee_extension")
    bank = scenario.make_bank(params=params or load_model_params(), recruitment=recruitment,
                              **({} if units_per_type is None
                                 else {"units_per_type": units_per_type}))
    inputs = scenario.inputs(bank)
    duration = duration_s or scenario.duration_s
    drive = np.full(bank.n, scenario.values["drive"])
    steady = isometric_at(bank, drive).effective_activation.sum(axis=-1) if trace else None
    bank.reset(inputs.path_length(0.0))
    steps = int(round(duration / dt))
    bin_steps = int(round(scenario.values["energy_bin"] / dt))
    cycle_steps = int(round(1.0 / (scenario.values["frequency"] * dt)))
    first_traced = max((steps // cycle_steps - 1) * cycle_steps, 0) if trace else steps
    rates = np.zeros((steps, 4))
    cycle = {key: [] for key in ("time_s", "drive", "effective_drive", "activation",
                                 "force_f0", "velocity_l0_per_s", "energy_rate_w")}
    out = None
    chunk = 2000
    for start in range(0, first_traced, chunk):  # whole chunks of steps in one call each
        stop = min(start + chunk, first_traced)
        run = bank.run(dt, *inputs.sample(dt * np.arange(start, stop)))
        rates[start:stop] = run.energy_rate.as_array().sum(axis=1)
        out = run.last
        if progress is not None:
            progress(stop, steps)
    for k in range(first_traced, steps):  # the traced cycles step by step
        t = k * dt
        out = bank.step(dt, inputs.excitation(t), inputs.path_length(t), inputs.path_velocity(t))
        rates[k] = out.energy_rate.as_array().sum(axis=0)
        if first_traced <= k < first_traced + cycle_steps:
            for key, value in (("time_s", out.time_s), ("drive", out.excitation),
                               ("effective_drive", out.effective_drive),
                               ("activation", out.effective_activation.sum(-1) / steady),
                               ("force_f0", out.force / bank.f0),
                               ("velocity_l0_per_s", out.velocity_l0_per_s),
                               ("energy_rate_w", out.energy_rate.total)):
                cycle[key].append(np.copy(value))
        if progress is not None and k % 2000 == 0:
            progress(k, steps)
    n_bins = steps // bin_steps
    bins = rates[: n_bins * bin_steps].reshape(n_bins, bin_steps, 4).mean(axis=1)
    times = (np.arange(n_bins) + 0.5) * scenario.values["energy_bin"]
    return KneeExtensionRun(times, bins, {k: np.array(v) for k, v in cycle.items()}, out, bank)


def _first_and_last_bins(n_bins: int) -> tuple[slice, slice]:
    """The 1 s bins compared for a rise: bins 1-5 (the first is the start-up transient) and the
    last 5."""
    return slice(1, 6), slice(max(n_bins - 5, 0), n_bins)


def total_rate_rise(bins_w: np.ndarray) -> float:
    """Total rate of the last 5 bins over that of bins 1-5, minus 1 (``bins_w`` (k, 4), W)."""
    first, last = _first_and_last_bins(len(bins_w))
    return float(bins_w[last, 3].mean() / bins_w[first, 3].mean() - 1.0)


def fig7_combinations(params) -> list[tuple[str, str, str]]:
    """(recruitment, drive law, recovery kernel) of each row of the Fig. 7 table: lumped under
    each drive law (the model file's first), natural and continuous (no drive law: "-"), each
    under each recovery kernel (the model file's first)."""
    laws = sorted(DRIVE_LAWS, key=lambda law: law != params.lumped.drive_law)
    kernels = sorted(RECOVERY_KERNELS, key=lambda k: k != params.energetics.recovery_kernel)
    schemes = [("lumped", law) for law in laws] + [("natural", "-"), ("continuous", "-")]
    return [(scheme, law, kernel) for kernel in kernels for scheme, law in schemes]


def params_for(params, drive_law: str, kernel: str):
    """``params`` with the lumped drive law (unless "-") and the recovery kernel replaced."""
    if drive_law != "-":
        params = dataclasses.replace(params, lumped=dataclasses.replace(params.lumped,
                                                                         drive_law=drive_law))
    return params.with_energetics(recovery_kernel=kernel)


def fig7_table_row(run: KneeExtensionRun, recruitment: str, drive_law: str,
                   kernel: str) -> dict:
    """One row of the Fig. 7 table from a run: energies in J over the run, the total-rate rise
    (as the check computes it) and the 1 s bins of the total rate (W) for the figure."""
    energy = run.out.energy
    return {"recruitment": recruitment, "drive_law": drive_law, "recovery_kernel": kernel,
            "total_energy_j": float(np.sum(energy.total)),
            "initial_energy_j": float(np.sum(energy.activation) + np.sum(energy.cross_bridge)),
            "recovery_energy_j": float(np.sum(energy.recovery)),
            "total_rate_rise": total_rate_rise(run.bins_w),
            "bin_time_s": run.bin_time_s, "total_rate_w": run.bins_w[:, 3]}


def fig7_table(params=None, duration_s=None, progress=None, done=None) -> list[dict]:
    """The Fig. 7 task for every row of :func:`fig7_combinations` (natural units with
    FIG7_NATURAL_UNITS_PER_TYPE units per fibre type), as :func:`fig7_table_row` dicts.

    ``done`` maps a (recruitment, drive law, kernel) already run to its KneeExtensionRun (the
    check's own run), which is not run again.
    """
    params = params or load_model_params()
    runs = dict(done or {})
    to_run = [c for c in fig7_combinations(params) if c not in runs]
    for i, (scheme, law, kernel) in enumerate(to_run):
        runs[scheme, law, kernel] = run_knee_extension(
            duration_s, progress=_share(progress, i, len(to_run)),
            params=params_for(params, law, kernel), recruitment=scheme, trace=False,
            units_per_type=FIG7_NATURAL_UNITS_PER_TYPE if scheme == "natural" else None)
    return [fig7_table_row(runs[c], *c) for c in fig7_combinations(params)]


def _share(progress, index: int, count: int):
    """A progress callback (k, n) for run ``index`` of ``count`` that reports the whole."""
    if progress is None:
        return None
    return lambda k, n: progress(index * n + k, count * n)


def _row(rows: list[dict], recruitment: str, drive_law: str, kernel: str) -> dict:
    return next(r for r in rows if (r["recruitment"], r["drive_law"], r["recovery_kernel"])
                == (recruitment, drive_law, kernel))


def check_fig7_knee_extension(params=None, duration_s=None, progress=None,
                              table=True) -> CheckResult:
    """Fig. 7. The model does NOT reach the paper's total energy: it gives less than half of the
    35 000 J (test/validation/REPORT.md explains the gap). The criteria hold what the paper's
    trace shows and the model reproduces (constant initial energy, rising recovery, a ~40 % rise),
    the cost per unit of work (a physiological efficiency), the experiment's energy band (a known
    gap: the model misses it, reported as GAP with its value), and lumped against natural units.
    ``vm-ros validate --quick`` keeps the first two criteria only.

    ``data["table"]`` (with ``table``): the task under each recruitment scheme, lumped drive law
    and recovery kernel (:func:`fig7_table`); the lumped/natural criterion needs it.
    """
    params = params or load_model_params()
    paper_duration_s = load_scenario("knee_extension").duration_s
    run_s = duration_s or paper_duration_s
    result = CheckResult("9", f"Fig. 7: {run_s:g} s dynamic knee extension",
                         "initial energy constant cycle to cycle, recovery energy rises, total "
                         "rate rises by about 40 % over the run; total energy about 35 000 J "
                         "(experiment 30 000-40 000 J)")
    n_runs = len(fig7_combinations(params)) if table else 1
    run = run_knee_extension(duration_s, progress=_share(progress, 0, n_runs), params=params)
    bins, out = run.bins_w, run.out
    initial = bins[:, 0] + bins[:, 1]
    first, last = _first_and_last_bins(len(bins))
    rise = total_rate_rise(bins)
    work = float(out.mechanical_work.sum())
    result.criteria += [
        # Nothing in the initial-energy path is slower than the 1 s cycle (drive filter < 0.5 s,
        # yield 0.2 s, sag 43 ms): it repeats to < 0.1 %; 1 % catches any drift or state leak.
        Criterion("initial energy rate: last 5 bins / first 5 bins (paper: constant)",
                  float(initial[last].mean() / initial[first].mean()), 0.99, 1.01),
        Criterion("recovery rate: last 5 bins / first 5 bins (paper: rises)",
                  float(bins[last, 2].mean() / bins[first, 2].mean()), 1.5, None),
        # "About 40 %" is read from the paper's figure of 1 s bins; the rise is set by the
        # recovery kernel [R, chosen for it] and the fibre mix (R 1.5 slow, 1.0 fast): +-0.10.
        # The measured PCr recovery kernel (pcr_slade2006) gives +0.91 instead (data["table"]).
        Criterion("total rate rise, first to last 5 bins (paper ~0.40)", float(rise), 0.30, 0.50),
        # Mechanical efficiency (work / (heat + work)) of human knee-extensor exercise measured
        # from muscle heat and work: 0.32-0.56 (Krustrup et al. 2003, J Physiol 549:255); widened
        # to 0.25-0.60 because the model's work is net fascicle work, not ergometer work.
        Criterion("net fascicle work / total energy (measured 0.32-0.56)",
                  work / float(out.total_energy), 0.25, 0.60),
        # The experiment's band, 30 000-40 000 J over the 180 s (0.857-1.143 of the paper's
        # 35 000 J). The model misses it: a known gap, reported with its measured value (with the
        # relative_drive law and the fitted_fig7 kernel 18.8 kJ, 0.538; test/validation/REPORT.md
        # item 9 says why). No band is set around the model's own value.
        Criterion("total energy / paper's 35 000 J (experiment 30-40 kJ)",
                  float(out.total_energy) / FIG7_PAPER_TOTAL_J,
                  FIG7_EXPERIMENT_BAND_J[0] / FIG7_PAPER_TOTAL_J,
                  FIG7_EXPERIMENT_BAND_J[1] / FIG7_PAPER_TOTAL_J, known_gap=FIG7_ENERGY_GAP),
    ]
    rows = []
    if table:
        key = ("lumped", params.lumped.drive_law, params.energetics.recovery_kernel)
        rest = None if progress is None else (
            lambda k, n: progress(n + k * (n_runs - 1), n * n_runs))
        rows = fig7_table(params, duration_s, progress=rest, done={key: run})
        natural = _row(rows, "natural", "-", key[2])["total_energy_j"]
        # Lumped units stand in for natural ones (Tsianos 2012 Appendix A): the task's energy
        # with the default drive law and kernel within 10 % of 20 natural units per type.
        result.criteria.append(Criterion(
            f"lumped ({key[1]}) / natural ({FIG7_NATURAL_UNITS_PER_TYPE} units per type) total "
            f"energy, {key[2]} kernel", float(out.total_energy) / natural, 0.90, 1.10))
    result.data = {"time": run.bin_time_s, "bins": bins, "total_energy_j": out.total_energy,
                   "energy_by_muscle_j": out.energy.total, "work_j": out.mechanical_work,
                   "names": run.bank.names, "mass_kg": run.bank.mass_kg, "cycle": run.cycle,
                   "paper_total_j": FIG7_PAPER_TOTAL_J,
                   "paper_duration_s": paper_duration_s, "duration_s": run_s,
                   "experiment_band_j": FIG7_EXPERIMENT_BAND_J, "table": rows}
    return result
