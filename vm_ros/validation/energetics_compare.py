"""Every published energetics model against Tsianos 2012 on the same Virtual Muscle runs.

Each scenario is run once per fibre composition with ``MuscleBank.run`` (fixed step ``dt``); the
published models are computed from every step's state (vm_ros.model.energetics_models.vm_state), and
every model's rate, summed over the bank's muscles, is integrated on the step grid the bank
integrates its own energy on: E = sum_k rate_k dt, rate_k at the end of step k (the bank's
cumulative energy is exactly this sum for Tsianos 2012, which the tests check).

| scenario | muscles | what | recovery |
| isometric_u{U} | vasti | drive U from its steady state, fascicle held at L0 | static |
| isovelocity_{V} | vasti | drive 0.5, fascicle from 1 -/+ 0.15 L0 through L0 at V L0/s | static |
| knee_extension | rectus femoris, vasti | Tsianos 2012 Fig. 7 (offline.scenarios) | dynamic |
| gait_cycle | vasti | our gait-like cycle, below | static |

The gait-like cycle (ours, not from a paper; a stretch-shortening pattern like a knee extensor's
in walking): at 1 Hz, the drive is a sin^2 burst of peak 0.4 over the first 40 % of each cycle,
and the path length is the mid-range path length plus 0.08 L0 sin(2 pi t): the muscle is
stretched while the drive rises (phase 0-0.25) and shortens as it falls (0.25-0.4).

Compositions override every muscle's fpcsa_slow: slow 0.85 (like soleus, 0.88 in the library),
mixed 0.50, fast 0.15; ``library`` keeps the library's (vasti 0.47, rectus femoris 0.36).

Every constant of these scenarios (drives, speeds, travel, the cycle, the compositions, dt,
durations, recovery mode) is an entry {value, unit, tag, source} of config/energetics_compare.yaml,
read by :func:`load_comparison_settings` with model.yaml's reader (vm_ros.model.params); a bad
entry is a one-line ConfigError naming file and field. Numbers above are the shipped file's.
"""

from __future__ import annotations

import csv
import dataclasses
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from vm_ros.errors import ConfigError
from vm_ros.model import MuscleBank
from vm_ros.model.config_reader import holds, load_yaml, read_section, yaml_section
from vm_ros.model.curves import tendon_length_at_force
from vm_ros.model.energetics_models.vm_state import MODEL_NAMES, published_rates
from vm_ros.model.mechanics import contractile_force_normalised
from vm_ros.model.params import RECOVERY_MODES
from vm_ros.offline.scenarios import load_scenario
from vm_ros.report.tables import bin_means
from vm_ros.resources import config_dir

TSIANOS = "tsianos2012"
FILE_NAME = "energetics_compare.yaml"
LIBRARY = "library"  # the composition that keeps each muscle's own fpcsa_slow
COMPOSITION_NAMES = ("slow", "mixed", "fast", LIBRARY)
GROUPS = ("isometric", "isovelocity", "knee_extension", "gait_cycle")


# The file's sections, read field by field as model.yaml's are (unit checked against holds;
# values in the units the names give: s, 1/s, L0, L0/s).
@dataclass(frozen=True)
class RunSection:
    dt: float = holds("s")
    sweep_muscle: str = holds("-")
    sweep_recovery_mode: str = holds("-")
    rate_bin: float = holds("s")
    negligible_ratio: float = holds("1")


@dataclass(frozen=True)
class IsometricSection:
    drives: tuple = holds("1")
    duration: float = holds("s")
    fascicle_length: float = holds("L0")


@dataclass(frozen=True)
class IsovelocitySection:
    drive: float = holds("1")
    speeds: tuple = holds("L0/s")
    centre_length: float = holds("L0")
    half_travel: float = holds("L0")


@dataclass(frozen=True)
class KneeSection:
    duration: float = holds("s")


@dataclass(frozen=True)
class GaitSection:
    frequency: float = holds("1/s")
    cycles: float = holds("1")  # a whole number, held as an int once loaded
    peak_drive: float = holds("1")
    burst_fraction: float = holds("1")
    length_amplitude: float = holds("L0")
    mid_length: float = holds("L0")


@dataclass(frozen=True)
class CompositionsSection:
    slow: float = holds("1")
    mixed: float = holds("1")
    fast: float = holds("1")

    def slow_fraction(self, composition: str) -> float | None:
        """fpcsa_slow of ``composition``; None for LIBRARY (each muscle keeps its own)."""
        return None if composition == LIBRARY else getattr(self, composition)


@dataclass(frozen=True)
class ComparisonSettings:
    """The comparison's scenario constants (module docstring): the sections of
    config/energetics_compare.yaml (:func:`load_comparison_settings`), and the selection of a
    run (compositions, groups, models: all by default)."""

    run: RunSection
    isometric: IsometricSection
    isovelocity: IsovelocitySection
    knee_extension: KneeSection
    gait_cycle: GaitSection
    slow_fractions: CompositionsSection  # the file's section "compositions"
    compositions: tuple = COMPOSITION_NAMES
    groups: tuple = GROUPS
    models: tuple = MODEL_NAMES


# file section -> (its dataclass, the ComparisonSettings field that holds it)
_SECTIONS = {"run": (RunSection, "run"), "isometric": (IsometricSection, "isometric"),
             "isovelocity": (IsovelocitySection, "isovelocity"),
             "knee_extension": (KneeSection, "knee_extension"),
             "gait_cycle": (GaitSection, "gait_cycle"),
             "compositions": (CompositionsSection, "slow_fractions")}


def comparison_config_path(path=None) -> Path:
    """``path``, or the shipped config/energetics_compare.yaml (vm_ros.resources.config_dir)."""
    return Path(path) if path is not None else config_dir() / FILE_NAME


def _check(path, where: str, values, ok, reason: str) -> None:
    for value in (values if isinstance(values, tuple) else (values,)):
        if not ok(value):
            raise ConfigError(path, where, values, reason)


def load_comparison_settings(path=None) -> ComparisonSettings:
    """The scenario constants of config/energetics_compare.yaml (or ``path``, same layout) as
    :class:`ComparisonSettings`; a bad entry (unit, missing tag or source, type, range) is a
    ConfigError naming file and field."""
    path = comparison_config_path(path)
    data = load_yaml(path)
    unknown = sorted(set(data) - set(_SECTIONS))
    if unknown:
        raise ConfigError(path, unknown[0], None,
                          f"unknown section; known: {', '.join(_SECTIONS)}")
    read = {name: cls(**read_section(cls, path, yaml_section(path, data, name), name, {}))
            for name, (cls, _) in _SECTIONS.items()}
    run, iso, vel = read["run"], read["isometric"], read["isovelocity"]
    knee, gait, comp = read["knee_extension"], read["gait_cycle"], read["compositions"]

    def positive(v):
        return v > 0.0

    def unit_interval(v):
        return 0.0 <= v <= 1.0

    for where, value, ok, reason in (
        ("run.dt.value", run.dt, positive, "must be > 0"),
        ("run.rate_bin.value", run.rate_bin, positive, "must be > 0"),
        ("run.negligible_ratio.value", run.negligible_ratio, positive, "must be > 0"),
        ("run.sweep_recovery_mode.value", run.sweep_recovery_mode,
         lambda v: v in RECOVERY_MODES, f"must be one of {', '.join(RECOVERY_MODES)}"),
        ("isometric.drives.value", iso.drives, unit_interval, "each must be in [0, 1]"),
        ("isometric.duration.value", iso.duration, positive, "must be > 0"),
        ("isometric.fascicle_length.value", iso.fascicle_length, positive, "must be > 0"),
        ("isovelocity.drive.value", vel.drive, unit_interval, "must be in [0, 1]"),
        ("isovelocity.speeds.value", vel.speeds, lambda v: v != 0.0,
         "each must be nonzero (shortening negative)"),
        ("isovelocity.half_travel.value", vel.half_travel,
         lambda v: 0.0 < v < vel.centre_length, "must be > 0 and below centre_length"),
        ("knee_extension.duration.value", knee.duration, positive, "must be > 0"),
        ("gait_cycle.frequency.value", gait.frequency, positive, "must be > 0"),
        ("gait_cycle.cycles.value", gait.cycles, lambda v: v >= 1 and float(v).is_integer(),
         "must be a whole number >= 1"),
        ("gait_cycle.peak_drive.value", gait.peak_drive, unit_interval, "must be in [0, 1]"),
        ("gait_cycle.burst_fraction.value", gait.burst_fraction, lambda v: 0.0 < v <= 1.0,
         "must be in (0, 1]"),
        ("gait_cycle.length_amplitude.value", gait.length_amplitude,
         lambda v: 0.0 <= v < gait.mid_length, "must be >= 0 and below mid_length"),
        *((f"compositions.{name}.value", getattr(comp, name), unit_interval,
           "must be in [0, 1]") for name in ("slow", "mixed", "fast")),
    ):
        _check(path, where, value, ok, reason)
    return ComparisonSettings(
        **{field: read[name] for name, (_, field) in _SECTIONS.items()
           if name != "gait_cycle"},
        gait_cycle=dataclasses.replace(gait, cycles=int(gait.cycles)))


def with_duration(settings: ComparisonSettings, duration_s: float) -> ComparisonSettings:
    """``settings`` with the knee extension lasting ``duration_s`` and the gait-like cycle cut
    to as many whole cycles (at least 1) as fit in it, never more than the file's."""
    gait = settings.gait_cycle
    fit = max(1, math.floor(duration_s * gait.frequency + 1e-9))
    return dataclasses.replace(
        settings, knee_extension=dataclasses.replace(settings.knee_extension, duration=duration_s),
        gait_cycle=dataclasses.replace(gait, cycles=min(gait.cycles, fit)))


@dataclass(frozen=True)
class ScenarioRun:
    """One scenario: its muscles, recovery mode and a builder of the run's inputs for a bank:
    (excitation (k, n), path length (k, n), path velocity (k, n), reset drive or None)."""

    name: str
    group: str
    muscles: tuple
    recovery_mode: str
    inputs: Callable = field(repr=False)


@dataclass
class ScenarioResult:
    """Energies (J) per model of one scenario and composition, with the traces for figures."""

    scenario: str
    group: str
    composition: str
    fpcsa_slow: tuple
    duration_s: float
    energy_j: dict
    bank_total_energy_j: float
    time_s: np.ndarray | None = None
    rates_w: dict | None = None  # model -> (k,) bank-summed rate, kept for knee_extension


def path_length_at(bank: MuscleBank, drive: float, length_l0: float) -> np.ndarray:
    """Path length (m) at which the fascicles sit at ``length_l0`` (L0) in the isometric steady
    state for constant ``drive``: L0 L + L0T L_SE(F_CE(L, V = 0))."""
    activity = bank.steady_effective_activation(np.full(bank.n, drive), length_l0)
    l = np.full(bank.n, float(length_l0))
    g = bank.params.generic
    f_ce, _, _ = contractile_force_normalised(l, np.zeros(bank.n), activity, bank.lmax,
                                              bank.params.fibre, g)
    force = np.maximum(f_ce, 1e-6)  # a slack tendon: the length where it carries a trace
    return bank.l0_m * l + bank.l0t_m * tendon_length_at_force(force, g.ct, g.kt, g.lrt)


def _steps(duration_s: float, dt: float) -> int:
    return max(1, int(round(duration_s / dt)))


def _isometric(drive: float, s: ComparisonSettings) -> ScenarioRun:
    def inputs(bank):
        k = _steps(s.isometric.duration, s.run.dt)
        lp = path_length_at(bank, drive, s.isometric.fascicle_length)
        return (np.full((k, bank.n), drive), np.tile(lp, (k, 1)), np.zeros((k, bank.n)),
                np.full(bank.n, drive))
    return ScenarioRun(f"isometric_u{drive:.2f}", "isometric", (s.run.sweep_muscle,),
                       s.run.sweep_recovery_mode, inputs)


def _isovelocity(speed: float, s: ComparisonSettings) -> ScenarioRun:
    c = s.isovelocity

    def inputs(bank):
        k = _steps(2.0 * c.half_travel / abs(speed), s.run.dt)
        lp0 = path_length_at(bank, c.drive, c.centre_length - np.sign(speed) * c.half_travel)
        t = np.arange(k)[:, None] * s.run.dt
        velocity = speed * bank.l0_m
        return (np.full((k, bank.n), c.drive), lp0 + velocity * t, np.tile(velocity, (k, 1)),
                np.full(bank.n, c.drive))
    return ScenarioRun(f"isovelocity_{speed:+.2f}", "isovelocity", (s.run.sweep_muscle,),
                       s.run.sweep_recovery_mode, inputs)


def _knee(s: ComparisonSettings) -> ScenarioRun:
    scenario = load_scenario("knee_extension")

    def inputs(bank):
        k = _steps(s.knee_extension.duration, s.run.dt)
        u, lp, vp = scenario.inputs(bank).sample(np.arange(k) * s.run.dt)
        return u, lp, vp, None
    return ScenarioRun("knee_extension", "knee_extension", scenario.muscles,
                       scenario.recovery_mode, inputs)


def _gait(s: ComparisonSettings) -> ScenarioRun:
    g = s.gait_cycle

    def inputs(bank):
        k = _steps(g.cycles / g.frequency, s.run.dt)
        t = np.arange(k) * s.run.dt
        phase = (t * g.frequency) % 1.0
        burst = np.where(phase < g.burst_fraction,
                         np.sin(np.pi * phase / g.burst_fraction) ** 2, 0.0)
        w = 2.0 * np.pi * g.frequency
        mid = path_length_at(bank, 0.0, g.mid_length)
        amplitude = g.length_amplitude * bank.l0_m
        u = np.tile((g.peak_drive * burst)[:, None], (1, bank.n))
        return (u, mid + amplitude * np.sin(w * t)[:, None],
                amplitude * w * np.cos(w * t)[:, None] * np.ones(bank.n), None)
    return ScenarioRun("gait_cycle", "gait_cycle", (s.run.sweep_muscle,),
                       s.run.sweep_recovery_mode, inputs)


def scenario_set(settings: ComparisonSettings) -> list:
    """The scenarios of ``settings.groups``, in the order of GROUPS."""
    s = settings
    runs = []
    if "isometric" in s.groups:
        runs += [_isometric(d, s) for d in s.isometric.drives]
    if "isovelocity" in s.groups:
        runs += [_isovelocity(v, s) for v in s.isovelocity.speeds]
    if "knee_extension" in s.groups:
        runs.append(_knee(s))
    if "gait_cycle" in s.groups:
        runs.append(_gait(s))
    return runs


def make_bank(run: ScenarioRun, composition: str, settings: ComparisonSettings) -> MuscleBank:
    """The scenario's bank with every muscle's fpcsa_slow set by ``composition`` (its fraction
    in ``settings``; ``library`` keeps the library's)."""
    slow = settings.slow_fractions.slow_fraction(composition)
    overrides = None if slow is None else {m: {"fpcsa_slow": slow} for m in run.muscles}
    return MuscleBank.from_config(list(run.muscles), overrides=overrides,
                                  recovery_mode=run.recovery_mode)


def run_scenario(run: ScenarioRun, composition: str, settings: ComparisonSettings,
                 keep_traces: bool = False) -> ScenarioResult:
    """Run one scenario for one composition; energies of Tsianos 2012 and every model."""
    bank = make_bank(run, composition, settings)
    u, lp, vp, reset_drive = run.inputs(bank)
    bank.reset(lp[0], excitation=reset_drive)
    dt = settings.run.dt
    trajectory = bank.run(dt, u, lp, vp)
    rates = {TSIANOS: trajectory.record.energy_rates[..., 3].sum(axis=-1)}
    for name, heat in published_rates(bank, trajectory, settings.models).items():
        rates[name] = heat.total.sum(axis=-1)
    energy = {name: float(rate.sum() * dt) for name, rate in rates.items()}
    return ScenarioResult(
        scenario=run.name, group=run.group, composition=composition,
        fpcsa_slow=tuple(float(f) for f in bank.fpcsa[:, 0]),
        duration_s=float(len(u) * dt),
        energy_j=energy, bank_total_energy_j=trajectory.last.total_energy,
        time_s=trajectory.time_s if keep_traces else None,
        rates_w=rates if keep_traces else None,
    )


def run_comparison(settings: ComparisonSettings, progress=None) -> list:
    """Every scenario x composition of ``settings``; ``progress(done, total, label)`` is called
    before each run."""
    runs = scenario_set(settings)
    jobs = [(run, c) for c in settings.compositions for run in runs]
    results = []
    for i, (run, composition) in enumerate(jobs):
        if progress is not None:
            progress(i, len(jobs), f"{run.name} ({composition})")
        results.append(run_scenario(run, composition, settings,
                                    keep_traces=run.group == "knee_extension"))
    if progress is not None:
        progress(len(jobs), len(jobs), "done")
    return results


TABLE_COLUMNS = ("scenario", "group", "composition", "fpcsa_slow", "model", "energy_j",
                 "ratio_to_tsianos2012", "mean_rate_w", "duration_s")


def table_rows(results) -> list:
    """One row per model (Tsianos 2012 first) x scenario x composition (TABLE_COLUMNS)."""
    rows = []
    for r in results:
        reference = r.energy_j[TSIANOS]
        for model, energy in r.energy_j.items():
            ratio = energy / reference if reference != 0.0 else float("nan")
            rows.append({
                "scenario": r.scenario, "group": r.group, "composition": r.composition,
                "fpcsa_slow": " ".join(f"{f:.2f}" for f in r.fpcsa_slow), "model": model,
                "energy_j": energy, "ratio_to_tsianos2012": ratio,
                "mean_rate_w": energy / r.duration_s, "duration_s": r.duration_s,
            })
    return rows


def write_table(rows, path: Path) -> None:
    with open(path, "w", newline="", encoding="utf-8") as handle:
        writer = csv.DictWriter(handle, fieldnames=TABLE_COLUMNS)
        writer.writeheader()
        for row in rows:
            writer.writerow({k: (f"{v:.6g}" if isinstance(v, float) else v)
                             for k, v in row.items()})


def column_label(model: str) -> str:
    """A model's short, unique column label: its first three letters and its year, or its first
    three letters of each author name (umb2003, lic_wil)."""
    head, _, tail = model.partition("_")
    year = "".join(ch for ch in model if ch.isdigit())
    return f"{head[:3]}{year}" if year else f"{head[:3]}_{tail[:3]}"


def format_table(results, models) -> str:
    """A printed table: per scenario and composition, Tsianos 2012's energy (J) and each model's
    energy relative to it (columns :func:`column_label`, named in a last line)."""
    header = (f"{'scenario':<20}{'comp.':<8}{'tsianos J':>11}"
              + "".join(f"{column_label(m):>9}" for m in models))
    lines = [header, "-" * len(header)]
    for r in results:
        reference = r.energy_j[TSIANOS]
        cells = "".join(f"{r.energy_j[m] / reference:>9.3f}" if reference else f"{'nan':>9}"
                        for m in models)
        lines.append(f"{r.scenario:<20}{r.composition:<8}{reference:>11.1f}{cells}")
    lines.append("columns: " + ", ".join(f"{column_label(m)} = {m}" for m in models))
    return "\n".join(lines)


def timed_comparison(settings: ComparisonSettings, progress=None):
    """:func:`run_comparison` and its wall time (s)."""
    start = time.monotonic()
    results = run_comparison(settings, progress)
    return results, time.monotonic() - start


MODEL_STYLE = {TSIANOS: ("black", "-", 2.2)}


def _style(model: str, index: int):
    """(colour, line style, width) of a model in every figure; Tsianos 2012 black and thick."""
    if model in MODEL_STYLE:
        return MODEL_STYLE[model]
    return (f"C{index % 10}", "-" if index < 10 else "--", 1.2)


def ratio_row(results, scenarios, composition: str, model: str) -> np.ndarray:
    """``model``'s energy / Tsianos 2012's per scenario of ``scenarios`` (NaN where a scenario
    is missing for ``composition`` or Tsianos 2012's energy is 0)."""
    by_scenario = {r.scenario: r for r in results if r.composition == composition}
    return np.array([by_scenario[s].energy_j[model] / by_scenario[s].energy_j[TSIANOS]
                     if s in by_scenario and by_scenario[s].energy_j[TSIANOS] else np.nan
                     for s in scenarios], dtype=float)


def ratio_axis(ratios, negligible: float) -> tuple:
    """The y axis of a ratio bar chart, so that ratios a thousand times apart are all readable:
    ("log", bottom) when no ratio is below -``negligible``, ("symlog", linthresh) otherwise (a
    negative ratio: a model that counts absorbed work as negative energy); bottom and linthresh
    are the decade below the smallest |ratio| of at least ``negligible`` (1 when there is none).
    Ratios smaller than ``negligible`` in size (Margaria 1968's round-off work in an isometric
    run) get no bar: the chart marks them "~0"."""
    values = np.asarray(ratios, dtype=float)
    values = values[np.isfinite(values) & (np.abs(values) >= negligible)]
    floor = 10.0 ** math.floor(math.log10(np.abs(values).min())) if values.size else 1.0
    return ("symlog" if np.any(values < 0.0) else "log"), floor


def write_figures(results, settings: ComparisonSettings, out: Path) -> list:
    """The knee-extension rate traces (bins of ``settings.run.rate_bin`` s, one panel per
    composition) and a bar chart of every model's energy relative to Tsianos 2012 per scenario
    group (one panel per composition, log y axis: :func:`ratio_axis`). Returns the PNG paths.
    Needs matplotlib (ImportError otherwise)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    models = (TSIANOS, *settings.models)
    compositions = list(dict.fromkeys(r.composition for r in results))
    written = []
    knee = [r for r in results if r.group == "knee_extension" and r.rates_w is not None]
    if knee:
        fig, axes = plt.subplots(len(knee), 1, figsize=(10, 2.6 * len(knee) + 0.8),
                                 sharex=True, squeeze=False)
        for ax, r in zip(axes[:, 0], knee, strict=True):
            for i, model in enumerate(models):
                colour, style, width = _style(model, i - 1)
                centres, rates = bin_means(r.time_s, r.rates_w[model], settings.run.rate_bin)
                ax.plot(centres, rates, color=colour, linestyle=style, linewidth=width,
                        label=model)
            ax.set_ylabel("rate (W)")
            ax.set_title(f"knee extension, {r.composition} (fpcsa_slow "
                         f"{', '.join(f'{f:.2f}' for f in r.fpcsa_slow)}), "
                         f"{settings.run.rate_bin:g} s bins",
                         fontsize=9)
            ax.grid(alpha=0.3)
        axes[-1, 0].set_xlabel("time (s)")
        axes[0, 0].legend(fontsize=7, ncol=3, loc="upper right")
        fig.tight_layout()
        path = out / "knee_extension_rates.png"
        fig.savefig(path, dpi=110)
        plt.close(fig)
        written.append(path)
    for group in GROUPS:
        chosen = [r for r in results if r.group == group]
        if not chosen:
            continue
        scenarios = list(dict.fromkeys(r.scenario for r in chosen))
        fig, axes = plt.subplots(len(compositions), 1,
                                 figsize=(max(6.0, 1.3 * len(scenarios) + 3), 2.8
                                          * len(compositions) + 0.6), squeeze=False)
        width = 0.8 / len(settings.models)
        ratios = {(c, m): ratio_row(chosen, scenarios, c, m)
                  for c in compositions for m in settings.models}
        scale, floor = ratio_axis(np.concatenate(list(ratios.values())),
                                  settings.run.negligible_ratio)
        for ax, composition in zip(axes[:, 0], compositions, strict=True):
            x = np.arange(len(scenarios))
            ax.set_yscale(scale, **({"linthresh": floor} if scale == "symlog" else {}))
            for i, model in enumerate(settings.models):
                values = ratios[(composition, model)]
                negligible = np.abs(values) < settings.run.negligible_ratio
                centres = x - 0.4 + (i + 0.5) * width
                colour = _style(model, i)[0]
                ax.bar(centres, np.where(negligible, np.nan, values), width, color=colour,
                       label=model)
                for centre in centres[negligible]:  # no bar: say so
                    ax.text(centre, floor if scale == "log" else 0.0, "~0", color=colour,
                            fontsize=6, ha="center", va="bottom", rotation=90)
            if scale == "log":  # from the floor to the largest bar, a third of a decade above
                ax.set_ylim(floor, np.nanmax([floor, *np.concatenate(list(ratios.values()))])
                            * 10.0 ** (1.0 / 3.0))
            ax.axhline(1.0, color="black", linewidth=1.5, label=f"{TSIANOS} (= 1)")
            ax.set_xticks(x, [s.replace(f"{group}_", "") for s in scenarios], fontsize=8)
            ax.set_ylabel("energy / Tsianos 2012" + (" (log)" if scale == "log"
                                                     else " (symlog)"))
            ax.set_title(f"{group}, {composition}", fontsize=9)
            ax.grid(alpha=0.3, axis="y")
        axes[0, 0].legend(fontsize=7, ncol=3)
        fig.tight_layout()
        path = out / f"ratio_{group}.png"
        fig.savefig(path, dpi=110)
        plt.close(fig)
        written.append(path)
    return written


__all__ = [
    "ratio_axis",
    "ratio_row",
    "column_label",
    "write_figures",
    "COMPOSITION_NAMES",
    "FILE_NAME",
    "LIBRARY",
    "GROUPS",
    "TABLE_COLUMNS",
    "TSIANOS",
    "ComparisonSettings",
    "CompositionsSection",
    "GaitSection",
    "IsometricSection",
    "IsovelocitySection",
    "KneeSection",
    "RunSection",
    "ScenarioResult",
    "ScenarioRun",
    "comparison_config_path",
    "load_comparison_settings",
    "with_duration",
    "format_table",
    "make_bank",
    "path_length_at",
    "run_comparison",
    "run_scenario",
    "scenario_set",
    "table_rows",
    "timed_comparison",
    "write_table",
]
