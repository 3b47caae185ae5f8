"""The plots of `vm-ros report` and the choice of their time bins.

    bin_s, reason = report_bin(run, span_s, sample_interval_s)
    written = plot_run(plt, run, tables, out, bin_s, reason)

Time bins. Long runs (a 180 s knee task has 180 pulses) are drawn as one value per bin: the bin
mean as a line, the bin's minimum to maximum as a shaded band. The bin is, in order:
  1. --bin S when given (0: no binning);
  2. the scenario's ``energy_bin`` (config/scenarios.yaml; 1 s for knee_extension, as in Tsianos
     2012 Fig. 7) when the run log's metadata names a scenario that has one and the run spans at
     least ``MIN_SCENARIO_BINS`` of them;
  3. otherwise from the run's length: the smallest 1-2-5 step (..., 0.1, 0.2, 0.5, 1, 2, 5, ...
     s) not shorter than span / ``MAX_BINS``, which gives 80-200 bins over the run (180 s: 1 s;
     4 s: 0.02 s);
and no binning when that bin would not be longer than the sample interval.

Figures (one panel per muscle where a quantity is per muscle, so that no muscle hides another):
force.png, kinematics.png, drive.png; runs longer than ``DETAIL_AFTER_S`` get a second column
with the last ``DETAIL_S`` as published. energy_<muscle>.png (stacked components per fibre
type), energy_rate.png (Tsianos 2012 Fig. 7 style: the whole body's activation, cross-bridge,
recovery and total energy rate in bins over time), energy_partition.png, totals.png,
joint_torque.png (joint-space runs) and summary.png (one page: the run, its numbers and the main
plots). Logs with the published energetics models (energy_rate_models): energy_models.png (each
model's total energy rate beside Tsianos 2012's, one panel per muscle and one for all muscles,
binned like the other energy plots) and energy_models_totals.png (each model's energy over the
run relative to Tsianos 2012, per muscle and for all muscles).
"""

from __future__ import annotations

import math
import textwrap
from pathlib import Path

import numpy as np

from vm_ros import telemetry as tm
from vm_ros.errors import VmRosError
from vm_ros.recording.run_log import RunLog
from vm_ros.recording.summary import EFFORT_UNITS, run_totals
from vm_ros.recording.tables import (
    FIBRE_TYPES,
    JOINT_UNITS,
    TSIANOS,
    Table,
    energy_models_axes,
    joint_units,
    model_totals,
    muscle_names,
    run_summary,
    time_origin_ns,
)

COMPONENTS = tm.COMPONENT_LABELS[:3]  # the parts of the total
MAX_BINS = 200  # a default bin gives at most this many bins over the run (80-200 with 1-2-5 steps)
MIN_SCENARIO_BINS = 10  # the scenario's bin is used when the run spans at least this many
DETAIL_AFTER_S = 20.0  # s; longer runs get a detail column of raw samples
DETAIL_S = 5.0  # s; the detail column shows the run's last DETAIL_S seconds as published
STEPS_125 = (1.0, 2.0, 5.0)


# --- time bins ------------------------------------------------------------------------------

def bin_from_length(span_s: float) -> float:
    """The smallest 1-2-5 step (s) not shorter than span_s / MAX_BINS; 0 for an empty span."""
    if not span_s > 0 or not math.isfinite(span_s):
        return 0.0
    target = span_s / MAX_BINS
    decade = 10.0 ** math.floor(math.log10(target))
    for factor in STEPS_125 + (10.0,):
        step = factor * decade
        if step >= target * (1 - 1e-9):
            return float(f"{step:.6g}")  # 0.1 * 2 -> 0.2, not 0.20000000000000004
    raise AssertionError("unreachable: 10 * decade >= target")


def scenario_bin(run: RunLog) -> tuple[str, float] | None:
    """(scenario name, its energy_bin in s) when the log's metadata names a built-in scenario
    (simulate writes it) that has one; None otherwise."""
    from vm_ros.errors import ConfigError
    from vm_ros.scenarios import load_scenario

    name = str(run.info.extra.get("scenario", "")) if run.info is not None else ""
    if not name:
        return None
    try:
        value = load_scenario(name).values.get("energy_bin")
    except (ConfigError, OSError):
        return None
    return (name, float(value)) if isinstance(value, (int, float)) and value > 0 else None


def report_bin(run: RunLog, span_s: float, sample_interval_s: float,
               requested_s: float | None = None) -> tuple[float, str]:
    """(bin in s, 0 for none; the reason, one line) by the rules in the module docstring."""
    if requested_s is not None:
        if requested_s < 0 or not math.isfinite(requested_s):
            raise VmRosError(f"--bin {requested_s}: give a bin length in seconds >= 0")
        return requested_s, ("--bin 0: no binning" if requested_s == 0
                             else f"{requested_s:g} s (--bin)")
    found = scenario_bin(run)
    note = ""
    if found is not None:
        name, value = found
        if span_s >= MIN_SCENARIO_BINS * value:
            return value, f"{value:g} s (scenario {name}'s energy_bin)"
        note = (f"; scenario {name}'s energy_bin of {value:g} s not used: the run "
                f"({span_s:.3g} s) spans fewer than {MIN_SCENARIO_BINS} of them")
    value = bin_from_length(span_s)
    if value <= sample_interval_s:
        return 0.0, (f"no binning: the run is short ({span_s:.3g} s), every sample is "
                     f"shown{note}")
    return value, (f"{value:g} s (from the run's length, {span_s:.3g} s: 1-2-5 step giving "
                   f"<= {MAX_BINS} bins){note}")


def bin_stats(time_s: np.ndarray, values: np.ndarray, bin_s: float):
    """Per consecutive ``bin_s`` window: (bin centres, means, minima, maxima) of ``values``
    (k, ...) over sorted ``time_s``; unbinned (each sample its own bin) when bin_s <= 0."""
    values = np.asarray(values, dtype=float)
    if bin_s <= 0 or len(time_s) == 0:
        return time_s, values, values, values
    index = np.floor((time_s - time_s[0]) / bin_s).astype(np.int64)
    starts = np.flatnonzero(np.r_[True, np.diff(index) != 0])
    counts = np.diff(np.r_[starts, len(time_s)]).reshape((-1,) + (1,) * (values.ndim - 1))
    means = np.add.reduceat(values, starts, axis=0) / counts
    low = np.fmin.reduceat(values, starts, axis=0)
    high = np.fmax.reduceat(values, starts, axis=0)
    return time_s[0] + (index[starts] + 0.5) * bin_s, means, low, high


# --- figure helpers -------------------------------------------------------------------------

def _save(plt, fig, path: Path, written: list) -> None:
    fig.savefig(path, dpi=110)
    plt.close(fig)
    written.append(path)


def _detail(time_s: np.ndarray) -> np.ndarray | None:
    """Mask of the last DETAIL_S seconds for runs longer than DETAIL_AFTER_S, else None."""
    if len(time_s) == 0 or time_s[-1] - time_s[0] <= DETAIL_AFTER_S:
        return None
    return time_s >= time_s[-1] - DETAIL_S


def _binned_line(ax, t, y, bin_s, label=None, color=None, band=True):
    """The bin mean as a line and the bin's range as a band (the raw line without binning)."""
    centres, mean, low, high = bin_stats(t, y, bin_s)
    (line,) = ax.plot(centres, mean, color=color, label=label, lw=1.2)
    if bin_s > 0 and band:
        ax.fill_between(centres, low, high, color=line.get_color(), alpha=0.2, lw=0, step="mid")
    return line


def _panel_grid(plt, rows: int, detail: bool, title: str, bin_reason: str):
    """rows x (1 or 2) axes sharing x per column; (fig, axes (rows, columns))."""
    columns = 2 if detail else 1
    fig, axes = plt.subplots(rows, columns, figsize=(11 if detail else 9, 1.4 + 2.2 * rows),
                             sharex="col", squeeze=False,
                             gridspec_kw={"width_ratios": [3, 1]} if detail else None,
                             layout="constrained")
    for ax in axes.flat:
        ax.grid(alpha=0.3)
    for ax in axes[-1]:
        ax.set_xlabel("time (s)")
    axes[0, 0].set_title(textwrap.fill(f"whole run: {_bin_words(bin_reason)}",
                                       90 if detail else 110), fontsize=9)
    # (panels with several series show the bin means only: overlapping bands hide each other)
    if detail:
        axes[0, 1].set_title(f"last {DETAIL_S:g} s, as published", fontsize=9)
    fig.suptitle(title)
    return fig, axes


def _bin_words(bin_reason: str) -> str:
    return ("bin mean (line) and range (band), bins of " + bin_reason
            if not bin_reason.startswith(("no binning", "--bin 0")) else "every sample")


def _series_panels(plt, t, rows: list, bin_s: float, bin_reason: str, title: str):
    """rows: [(row label, [(series label, values), ...]), ...]: one panel per row."""
    detail = _detail(t)
    fig, axes = _panel_grid(plt, len(rows), detail is not None, title, bin_reason)
    for k, (ylabel, series) in enumerate(rows):
        axes[k, 0].set_ylabel(ylabel, fontsize=9)
        for n, (label, y) in enumerate(series):
            _binned_line(axes[k, 0], t, y, bin_s, label=label, color=f"C{n}",
                         band=len(series) == 1)
            if detail is not None:
                axes[k, 1].plot(t[detail], y[detail], color=f"C{n}", lw=1.0)
        if len(series) > 1:
            axes[k, 0].legend(fontsize=7, loc="upper right")
    return fig, axes


# --- the figures ----------------------------------------------------------------------------

def force_figure(plt, force: Table, names, bin_s: float, bin_reason: str):
    """One panel per muscle: tendon force (N)."""
    t = force.column("time_s")
    rows = [(f"{m}\ntendon force (N)", [(m, force.column(f"{m}.force_N"))]) for m in names]
    return _series_panels(plt, t, rows, bin_s, bin_reason, "tendon force")[0]


def kinematics_figure(plt, force: Table, names, bin_s: float, bin_reason: str):
    """Two panels per muscle: fascicle length (m) and velocity (m/s)."""
    t = force.column("time_s")
    rows = []
    for m in names:
        rows.append((f"{m}\nfascicle length (m)", [(m, force.column(f"{m}.fascicle_length_m"))]))
        rows.append((f"{m}\nvelocity (m/s)",
                     [(m, force.column(f"{m}.fascicle_velocity_m_per_s"))]))
    return _series_panels(plt, t, rows, bin_s, bin_reason,
                          "fascicle kinematics (velocity < 0: shortening)")[0]


def drive_figure(plt, run: RunLog, telemetry: Table | None, names, bin_s: float,
                 bin_reason: str):
    """One panel per muscle: drive U, filtered drive Ueff and Acteff per fibre type (telemetry),
    or U alone (the excitation topic); None when the log has neither."""
    excitation = run.get(tm.TOPIC_EXCITATION)
    if telemetry is not None:
        t = telemetry.column("time_s")
        rows = [(f"{m}\n(1)", [("U", telemetry.column(f"{m}.excitation_1")),
                               ("Ueff", telemetry.column(f"{m}.effective_drive_1"))]
                 + [(f"Acteff {f}", telemetry.column(f"{m}.{f}.effective_activation_1"))
                    for f in FIBRE_TYPES]) for m in names]
        title = "drive U, filtered drive Ueff and effective activation Acteff per fibre type"
    elif excitation is not None and len(excitation):
        t = (excitation.time_ns - time_origin_ns(run)) * 1e-9
        rows = [(f"{m}\n(1)", [("U", excitation.fields["position"][:, i])])
                for i, m in enumerate(names)]
        title = "drive U"
    else:
        return None
    return _series_panels(plt, t, rows, bin_s, bin_reason, title)[0]


def muscle_energy_figure(plt, rates: Table, muscle: str, bin_s: float, bin_reason: str):
    """Stacked energy rate components (W) per fibre type of one muscle, bin means."""
    fig, axes = plt.subplots(2, 1, figsize=(9, 5.8), sharex=True, layout="constrained")
    t_all = rates.column("time_s")
    for ax, f in zip(axes, FIBRE_TYPES, strict=True):
        parts = np.column_stack([rates.column(f"{muscle}.{f}.{c}_W") for c in COMPONENTS])
        t, parts, _, _ = bin_stats(t_all, parts, bin_s)
        ax.stackplot(t, np.nan_to_num(parts).T, labels=COMPONENTS, alpha=0.8, step="mid")
        ax.set_ylabel(f"{f} fibres (W)")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="upper left")
    axes[-1].set_xlabel("time (s)")
    axes[0].set_title(textwrap.fill(_bin_words(bin_reason).replace(
        "bin mean (line) and range (band)", "bin means"), 110), fontsize=9)
    fig.suptitle(f"{muscle}: energy rate by component")
    return fig


def whole_body_components(rates: Table, names) -> np.ndarray:
    """(k, 4) W: activation, cross-bridge, recovery, total energy rate summed over muscles."""
    return np.column_stack([
        sum(np.nan_to_num(rates.column(f"{m}.all.{c}_W")) for m in names)
        for c in tm.COMPONENT_LABELS])


def _energy_rate_axes(ax, rates: Table, names, bin_s: float) -> None:
    t, means, _, _ = bin_stats(rates.column("time_s"), whole_body_components(rates, names), bin_s)
    for k, label in enumerate(tm.COMPONENT_LABELS):
        ax.plot(t, means[:, k], drawstyle="steps-mid", lw=2.0 if label == "total" else 1.3,
                color="k" if label == "total" else f"C{k}", label=label.replace("_", "-"))
    ax.set_ylabel("energy rate (W)")
    ax.set_ylim(bottom=0)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="center right")


def energy_rate_figure(plt, rates: Table, names, bin_s: float, bin_reason: str):
    """Tsianos 2012 Fig. 7 style: whole-body energy rate per component in bins over time."""
    fig, ax = plt.subplots(figsize=(9, 4.2), layout="constrained")
    _energy_rate_axes(ax, rates, names, bin_s)
    ax.set_xlabel("time (s)")
    what = "mean energy rate per bin" if bin_s > 0 else "energy rate"
    ax.set_title(textwrap.fill(f"all muscles ({', '.join(names)}): {what}; bins: {bin_reason}",
                               110), fontsize=9)
    fig.suptitle("energy rate by component (Tsianos 2012 Fig. 7 style)")
    return fig


def energy_models_figure(plt, models: Table, rates: Table | None, axes, bin_s: float,
                         bin_reason: str):
    """One panel per muscle and one for all muscles: each published model's total energy rate
    (W) and Tsianos 2012's (black), bin means."""
    muscles, names, _ = axes
    t = models.column("time_s")
    detail = _detail(t)
    fig, grid = _panel_grid(plt, len(muscles) + 1, detail is not None,
                            "total energy rate: published models beside Tsianos 2012",
                            bin_reason)
    grid[0, 0].set_title(textwrap.fill(_bin_words(bin_reason).replace(
        "bin mean (line) and range (band)", "bin means"), 90 if detail is not None else 110),
        fontsize=9)
    total = {name: 0.0 for name in names}
    own_total = 0.0
    for row, muscle in enumerate([*muscles, None]):
        ax = grid[row, 0]
        series = []
        for name in names:
            if muscle is not None:
                y = models.column(f"{muscle}.{name}.total_W")
                total[name] = total[name] + y
            else:
                y = total[name]
            series.append((name, y))
        if rates is not None:
            if muscle is not None:
                own = np.interp(t, rates.column("time_s"), rates.column(f"{muscle}.all.total_W"))
                own_total = own_total + own
            else:
                own = own_total
            series.append((f"{TSIANOS} (vm_ros)", own))
        for k, (label, y) in enumerate(series):
            own_line = label.startswith(TSIANOS)
            color = "k" if own_line else f"C{k % 10}"
            centres, mean, _, _ = bin_stats(t, y, bin_s)
            ax.plot(centres, mean, color=color, lw=2.2 if own_line else 1.1,
                    ls="-" if k < 10 or own_line else "--", label=label, drawstyle="steps-mid")
            if detail is not None:
                grid[row, 1].plot(t[detail], y[detail], color=color, lw=1.6 if own_line else 0.9)
        ax.set_ylabel(f"{muscle or 'all muscles'}\n(W)", fontsize=9)
    handles, labels = grid[0, 0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside lower center", ncol=min(5, len(labels)), fontsize=8)
    return fig


def energy_models_totals_figure(plt, rows, muscles):
    """Grouped bars: each model's energy over the run relative to Tsianos 2012, per muscle and
    for all muscles (1 = Tsianos)."""
    groups = [*muscles, "all muscles"]
    fig, ax = plt.subplots(figsize=(max(7.0, 1.2 * len(groups) * len(rows) / 3), 4.4),
                           layout="constrained")
    width = 0.8 / max(1, len(rows))
    x = np.arange(len(groups))
    for k, row in enumerate(rows):
        with np.errstate(divide="ignore", invalid="ignore"):
            per_muscle = np.where(row.tsianos > 0, row.energy / row.tsianos, np.nan)
        values = np.append(per_muscle, row.relative)
        # the colours of energy_models.png: models in log order, Tsianos 2012 in black
        own = row.model == TSIANOS
        ax.bar(x + (k - (len(rows) - 1) / 2) * width, values, width, label=row.model,
               color="white" if own else f"C{(k - 1) % 10}", edgecolor="k" if own else None,
               hatch="//" if own else None)
    ax.axhline(1.0, color="k", lw=0.8)
    ax.set_xticks(x, groups)
    ax.set_ylabel("energy / Tsianos 2012 (1)")
    ax.grid(alpha=0.3, axis="y")
    fig.legend(loc="outside lower center", ncol=min(5, len(rows)), fontsize=8)
    ax.set_title("energy over the run per published model, relative to Tsianos 2012 "
                 "(trapezoidal integrals of the published rates)", fontsize=9)
    return fig


def _partition_axes(ax, summary, per_fibre: bool) -> None:
    fibres = range(2) if per_fibre else (2,)
    labels = [f"{row.name}\n{tm.FIBRE_LABELS[j]}" if per_fibre else row.name
              for row in summary for j in fibres]
    bottom = np.zeros(len(labels))
    for k, component in enumerate(COMPONENTS):
        values = np.array([row.energy[j, k] for row in summary for j in fibres])
        ax.bar(labels, values, bottom=bottom, label=component.replace("_", "-"))
        bottom += values
    ax.set_ylabel("energy (J)")
    ax.legend(fontsize=8)


def partition_figure(plt, summary):
    fig, ax = plt.subplots(figsize=(max(5, 3.2 * len(summary)), 4), layout="constrained")
    _partition_axes(ax, summary, per_fibre=True)
    ax.set_title("energy partition per muscle and fibre type")
    return fig


def totals_figure(plt, totals: Table, bin_s: float, bin_reason: str):
    t = totals.column("time_s")
    fig, axes = _panel_grid(plt, 2, False, "whole body", bin_reason)
    _binned_line(axes[0, 0], t, totals.column("energy_rate_total_W"), bin_s)
    axes[0, 0].set_ylabel("energy rate (W)")
    axes[1, 0].plot(t, totals.column("energy_total_J"))
    axes[1, 0].set_ylabel("energy (J)")
    return fig


def joint_figure(plt, run: RunLog, efforts: Table, states: Table | None):
    """One panel per joint: generalized force (N m or N), and on a twin axis the joint angle
    received (joint_states; deg for rotational joints) or, without them, the one used."""
    joints = [c.split(".effort_")[0] for c in efforts.columns if ".effort_" in c]
    units = joint_units(run, joints)
    fig, axes = plt.subplots(len(joints), 1, figsize=(9, 1.4 + 2.2 * len(joints)), sharex=True,
                             squeeze=False, layout="constrained")
    for ax, joint, unit in zip(axes[:, 0], joints, units, strict=True):
        _joint_axes(ax, joint, unit, efforts, states)
    axes[-1, 0].set_xlabel("time (s)")
    fig.suptitle("joint torques (robot convention) and joint angles")
    return fig


def _joint_axes(ax, joint: str, unit: str, efforts: Table, states: Table | None) -> None:
    position, _, effort = (f"{joint}.{q}_{s}" for q, s in zip(
        ("position", "velocity", "effort"), JOINT_UNITS[unit], strict=True))
    ax.plot(efforts.column("time_s"), efforts.column(effort), color="C0", label="torque")
    ax.set_ylabel(f"{joint} ({EFFORT_UNITS[unit]})", fontsize=9)
    ax.grid(alpha=0.3)
    source = states if states is not None and position in states.columns else efforts
    scale, angle_unit = (180.0 / np.pi, "deg") if unit == "rad" else (1.0, "m")
    twin = ax.twinx()
    twin.plot(source.column("time_s"), scale * source.column(position), color="C1", alpha=0.8)
    twin.set_ylabel(f"angle ({angle_unit})" if unit == "rad" else "position (m)", color="C1",
                    fontsize=9)


def summary_figure(plt, run: RunLog, tables: dict, bin_s: float, bin_reason: str):
    """One A4 page: the run (log, scenario, span, bins), the totals, force per muscle, the Fig. 7
    style energy rate, cumulative energy and the partition per muscle, and joint torques or
    drive (long runs: force in their last DETAIL_S as published)."""
    names = muscle_names(run)
    summary = run_summary(run)
    force, rates = tables.get("forces"), tables.get("energy_rate")
    telemetry, efforts = tables.get("telemetry"), tables.get("joint_efforts")
    fig = plt.figure(figsize=(8.27, 11.69), layout="constrained")
    grid = fig.add_gridspec(5, 2, height_ratios=[0.55, 1, 1.1, 1, 1])
    header = fig.add_subplot(grid[0, :])
    header.axis("off")
    lines = [wrapped for line in _header_lines(run, force, summary, bin_reason)
             for wrapped in textwrap.wrap(line, 96, subsequent_indent="    ")]
    header.text(0, 1, "\n".join(lines), va="top",
                ha="left", family="monospace", fontsize=8, transform=header.transAxes)
    ax = fig.add_subplot(grid[1, :])
    if force is not None:
        t = force.column("time_s")
        for n, m in enumerate(names):
            centres, mean, _, high = bin_stats(t, force.column(f"{m}.force_N"), bin_s)
            ax.plot(centres, mean, color=f"C{n}", label=f"{m} mean" if bin_s > 0 else m)
            if bin_s > 0:
                ax.plot(centres, high, "--", color=f"C{n}", label=f"{m} peak")
        ax.legend(fontsize=7, loc="upper right", ncol=2)
    ax.set_ylabel("tendon force (N)")
    ax.set_title("tendon force per muscle" + (": mean and peak per bin" if bin_s > 0 else ""),
                 fontsize=9)
    ax.grid(alpha=0.3)
    ax = fig.add_subplot(grid[2, :])
    if rates is not None:
        _energy_rate_axes(ax, rates, names, bin_s)
    ax.set_title("energy rate by component, all muscles (Tsianos 2012 Fig. 7 style)",
                 fontsize=9)
    ax = fig.add_subplot(grid[3, 0])
    if telemetry is not None:
        for n, m in enumerate(names):
            ax.plot(telemetry.column("time_s"), telemetry.column(f"{m}.all.total_energy_J"),
                    color=f"C{n}", label=m)
    elif rates is not None:
        t = rates.column("time_s")
        for n, m in enumerate(names):
            rate = np.nan_to_num(rates.column(f"{m}.all.total_W"))
            ax.plot(t, np.r_[0.0, np.cumsum(0.5 * (rate[1:] + rate[:-1]) * np.diff(t))],
                    color=f"C{n}", label=m)
    ax.set_ylabel("energy (J)")
    ax.set_xlabel("time (s)")
    ax.set_title("cumulative energy per muscle", fontsize=9)
    ax.grid(alpha=0.3)
    if ax.get_lines():
        ax.legend(fontsize=7)
    ax = fig.add_subplot(grid[3, 1])
    if summary:
        _partition_axes(ax, summary, per_fibre=False)
    ax.set_title("energy partition per muscle", fontsize=9)
    ax = fig.add_subplot(grid[4, :])
    if efforts is not None:
        joints = [c.split(".effort_")[0] for c in efforts.columns if ".effort_" in c]
        for n, (joint, unit) in enumerate(zip(joints, joint_units(run, joints), strict=True)):
            column = f"{joint}.effort_{JOINT_UNITS[unit][2]}"
            _binned_line(ax, efforts.column("time_s"), efforts.column(column), bin_s,
                         label=f"{joint} ({EFFORT_UNITS[unit]})", color=f"C{n}")
        ax.set_ylabel("generalized force")
        ax.set_title("joint torques (robot convention)", fontsize=9)
        ax.legend(fontsize=7)
    elif force is not None and _detail(force.column("time_s")) is not None:
        t = force.column("time_s")
        detail = _detail(t)
        for n, m in enumerate(names):
            ax.plot(t[detail], force.column(f"{m}.force_N")[detail], color=f"C{n}", label=m)
        ax.set_ylabel("tendon force (N)")
        ax.set_title(f"tendon force, last {DETAIL_S:g} s as published", fontsize=9)
        ax.legend(fontsize=7, loc="upper right")
    elif telemetry is not None:
        for n, m in enumerate(names):
            ax.plot(telemetry.column("time_s"), telemetry.column(f"{m}.excitation_1"),
                    color=f"C{n}", label=f"{m} U")
        ax.set_ylabel("drive (1)")
        ax.set_title("drive U per muscle", fontsize=9)
        ax.legend(fontsize=7)
    ax.set_xlabel("time (s)")
    ax.grid(alpha=0.3)
    fig.suptitle(f"vm-ros report: {Path(str(run.path)).name}")
    return fig


def _header_lines(run: RunLog, force: Table | None, summary, bin_reason: str) -> list:
    extra = run.info.extra if run.info is not None else {}
    span = force.column("time_s")[-1] if force is not None and len(force.data) else float("nan")
    source = next((f"{key} {extra[key]}" for key in ("scenario", "inputs_file", "motion_file")
                   if extra.get(key)), "not recorded")
    lines = [f"source: {source}"
             f"   model time: {span:.3f} s   muscles: {', '.join(muscle_names(run))}",
             f"bins: {bin_reason}"]
    if not run.complete:
        lines.append(f"log cut short ({run.stop_reason}): the report covers what it holds")
    if summary:
        energy, work, efficiency = run_totals(summary)
        lines.append("energy (J): " + "  ".join(
            f"{c.replace('_', '-')} {energy[k]:.4g}" for k, c in enumerate(tm.COMPONENT_LABELS)))
        eff = f"{100 * efficiency:.1f} %" if np.isfinite(efficiency) else "n/a"
        lines.append(f"mechanical work: {work:.4g} J   net efficiency: {eff}")
        for row in summary:
            lines.append(f"  {row.name:<20} peak {row.peak_force:8.1f} N  mean "
                         f"{row.mean_force:7.1f} N  energy {row.energy[-1, -1]:10.4g} J")
    return lines


def plot_run(plt, run: RunLog, tables: dict, out: Path, bin_s: float, bin_reason: str) -> list:
    """Write every figure the log allows into ``out``; the paths written."""
    names = muscle_names(run)
    written: list = []
    force, telemetry = tables.get("forces"), tables.get("telemetry")
    if force is not None:
        _save(plt, force_figure(plt, force, names, bin_s, bin_reason), out / "force.png",
              written)
        _save(plt, kinematics_figure(plt, force, names, bin_s, bin_reason),
              out / "kinematics.png", written)
    fig = drive_figure(plt, run, telemetry, names, bin_s, bin_reason)
    if fig is not None:
        _save(plt, fig, out / "drive.png", written)
    rates = tables.get("energy_rate")
    if rates is not None:
        for m in names:
            _save(plt, muscle_energy_figure(plt, rates, m, bin_s, bin_reason),
                  out / f"energy_{m}.png", written)
        _save(plt, energy_rate_figure(plt, rates, names, bin_s, bin_reason),
              out / "energy_rate.png", written)
    models, axes = tables.get("energy_rate_models"), energy_models_axes(run)
    if models is not None and axes is not None:
        _save(plt, energy_models_figure(plt, models, rates, axes, bin_s, bin_reason),
              out / "energy_models.png", written)
        _save(plt, energy_models_totals_figure(plt, model_totals(run), axes[0]),
              out / "energy_models_totals.png", written)
    summary = run_summary(run)
    if summary:
        _save(plt, partition_figure(plt, summary), out / "energy_partition.png", written)
    totals = tables.get("totals")
    if totals is not None:
        _save(plt, totals_figure(plt, totals, bin_s, bin_reason), out / "totals.png", written)
    efforts = tables.get("joint_efforts")
    if efforts is not None:
        _save(plt, joint_figure(plt, run, efforts, tables.get("joint_states")),
              out / "joint_torque.png", written)
    _save(plt, summary_figure(plt, run, tables, bin_s, bin_reason), out / "summary.png",
          written)
    return written
