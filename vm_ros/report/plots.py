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

Figures. Per-muscle quantities get one panel per muscle (up to LANES_AFTER muscles) or, with
more, one lane per muscle in a shared plot, each lane scaled to that muscle's range (given under
its name), so that no muscle hides another and 80 muscles draw about as fast as 4: force.png,
kinematics.png (length and velocity), drive.png, energy_muscles.png (energy rate components
stacked, slow and fast fibres; a fibre type without energy says "not recruited"); runs longer
than ``DETAIL_AFTER_S`` get the last ``DETAIL_S`` as published beside. These hold at most
PAGE_MUSCLES muscles a file: more go to force-2.png, force-3.png, .... energy_rate.png (Tsianos
2012 Fig. 7 style: the whole body's activation, cross-bridge, recovery and total energy rate in
bins over time), energy_partition.png (bars wrapped into rows, paged like the above), totals.png,
joint_torque.png (joint-space runs) and summary.png (one page: the run, its numbers and the main
plots; with more than TOP_MUSCLES + 1 muscles the TOP_MUSCLES with the most energy by name and
colour, the others grey or summed as "others"). Logs with the published energetics models
(energy_rate_models): energy_models.png (each model's total energy rate beside Tsianos 2012's,
one panel or lane per muscle and one for all muscles, binned like the other energy plots) and
energy_models_totals.png (each model's energy over the run relative to Tsianos 2012, per muscle
and for all muscles, bars wrapped into rows). Legends sit outside the plots; no figure is larger
than MAX_FIGURE_PX.
"""

from __future__ import annotations

import gc
import math
import re
import textwrap
from pathlib import Path

import numpy as np

from vm_ros import telemetry as tm
from vm_ros.errors import VmRosError
from vm_ros.recording.run_log import RunLog
from vm_ros.report.summary import EFFORT_UNITS, run_totals
from vm_ros.report.tables import (
    FIBRE_TYPES,
    JOINT_UNITS,
    TSIANOS,
    Table,
    energy_models_axes,
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


_NUMBER_UNIT = re.compile(r"(\d) (?=[a-zA-Z%(])")


def wrap_text(text: str, width: int) -> str:
    """textwrap.fill that never separates a number from the word after it (its unit: '2.500 s'):
    a no-break space there, which textwrap does not break at and matplotlib draws as a space."""
    return textwrap.fill(_NUMBER_UNIT.sub("\\1\u00a0", text), width)

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
    from vm_ros.offline.scenarios import load_scenario

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

DPI = 110
MAX_FIGURE_PX = (2400, 3400)  # (width, height): no report figure is larger
PAGE_MUSCLES = 40  # per-muscle figures: muscles per file, more go to <name>-2.png, <name>-3.png
TOP_MUSCLES = 8  # summary page: the muscles with the most energy by name, the rest as "others"
BARS_PER_ROW = 40  # bar charts: wrapped into rows of at most this many bars
LANES_AFTER = 4  # per-muscle figures of more muscles: one lane per muscle in shared axes
LANE_IN = 0.42  # height of a lane (in)
OTHERS_COLOR = "0.6"
NAMED_COLORS = [f"C{k}" for k in (0, 1, 2, 3, 4, 5, 6, 8, 9)]  # C7 is grey, as the others
LEGEND = {"fontsize": 7, "frameon": False}
OUTSIDE_RIGHT = {"loc": "upper left", "bbox_to_anchor": (1.01, 1.0), **LEGEND}


PNG_COMPRESS_LEVEL = 3  # zlib; 6 (the default): files 5 % smaller, twice the encoding time


def _save(plt, fig, path: Path, written: list) -> None:
    """fig as an opaque RGB PNG at DPI, drawn by its Agg canvas (what savefig does, without its
    alpha channel, which is 255 everywhere on the report's white figures, and with a faster
    zlib level: the encoder is a fifth of the plotting time); then closed."""
    from PIL import Image

    fig.set_dpi(DPI)
    fig.canvas.draw()
    rgba = fig.canvas.buffer_rgba()
    Image.fromarray(np.asarray(rgba)[..., :3]).save(
        path, format="png", compress_level=PNG_COMPRESS_LEVEL, dpi=(DPI, DPI))
    plt.close(fig)
    written.append(path)


def _capped(width_in: float, height_in: float) -> tuple[float, float]:
    """A figure size (in) within MAX_FIGURE_PX at DPI."""
    return min(width_in, MAX_FIGURE_PX[0] / DPI), min(height_in, MAX_FIGURE_PX[1] / DPI)


def pages(items, per_page: int = PAGE_MUSCLES) -> list[list]:
    """items in consecutive pages of at most per_page, as even as possible (one empty page for
    no items)."""
    items = list(items)
    count = max(1, math.ceil(len(items) / per_page))
    size = max(1, math.ceil(len(items) / count))
    return [items[k:k + size] for k in range(0, len(items), size)] or [[]]


def page_path(out: Path, stem: str, page: int) -> Path:
    """<stem>.png for the first page, <stem>-2.png, <stem>-3.png, ... for the next."""
    return out / (f"{stem}.png" if page == 0 else f"{stem}-{page + 1}.png")


def _detail(time_s: np.ndarray) -> np.ndarray | None:
    """Mask of the last DETAIL_S seconds for runs longer than DETAIL_AFTER_S, else None."""
    if len(time_s) == 0 or time_s[-1] - time_s[0] <= DETAIL_AFTER_S:
        return None
    return time_s >= time_s[-1] - DETAIL_S


def _thinned(t, y, columns: int):
    """(t, y) with at most two samples per one of ``columns`` runs of consecutive samples: each
    run's lowest and highest, in time order (with its first and last), so that a line drawn
    ``columns`` pixels wide looks the same, peaks included; as given when not denser."""
    t, y = np.asarray(t), np.asarray(y)
    per = -(-len(y) // max(columns, 1))  # samples per run
    if per < 3:
        return t, y
    whole = len(y) // per * per
    runs = y[:whole].reshape(-1, per)
    first = np.arange(0, whole, per)
    keep = np.concatenate([first, first + runs.argmin(axis=1), first + runs.argmax(axis=1),
                           first + per - 1, np.arange(whole, len(y))])
    keep = np.unique(keep)  # sorted: time order
    return t[keep], y[keep]


def _plot(ax, t, y, *args, **style):
    """ax.plot of (t, y) thinned to the axes' width in pixels (see _thinned)."""
    columns = math.ceil(ax.get_position().width * ax.figure.get_figwidth() * DPI)
    return ax.plot(*_thinned(t, y, columns), *args, **style)


def _band(ax, x, low, high, **style) -> None:
    """ax.fill_between(x, low, high, step="mid", **style), built directly: one PolyCollection
    of the band's finite stretches (fill_between's general checks cost about 1 ms a call, and
    the 18-muscle walk's report makes 169)."""
    from matplotlib.cbook import contiguous_regions, pts_to_midstep
    from matplotlib.collections import PolyCollection

    x, low, high = pts_to_midstep(np.asarray(x, dtype=float), low, high)
    polygons = [np.concatenate([np.column_stack([x[a:b], high[a:b]]),
                                np.column_stack([x[a:b], low[a:b]])[::-1]])
                for a, b in contiguous_regions(np.isfinite(low) & np.isfinite(high))]
    ax.add_collection(PolyCollection(polygons, **style))


def _binned_line(ax, t, y, bin_s, label=None, color=None, band=True, scale=None, **style):
    """The bin mean as a line and the bin's range as a band (the raw line without binning);
    scale: values -> plotted y (lanes)."""
    centres, mean, low, high = bin_stats(t, y, bin_s)
    scale = scale or (lambda v: v)
    (line,) = _plot(ax, centres, scale(mean), color=color, label=label,
                    lw=style.pop("lw", 1.2), **style)
    if bin_s > 0 and band:
        _band(ax, centres, scale(low), scale(high), color=line.get_color(), alpha=0.2, lw=0)
    return line


def _bin_words(bin_reason: str) -> str:
    return ("bin mean (line) and range (band), bins of " + bin_reason
            if not bin_reason.startswith(("no binning", "--bin 0")) else "every sample")


def _series_style(label: str, n: int, styles: dict | None) -> dict:
    """Colour, width and line style of series n (C0-C9, then dashed), or styles[label]."""
    return (styles or {}).get(label, {"color": f"C{n % 10}", "lw": 1.2,
                                      "ls": "-" if n < 10 else "--"})


def _lane_range(series, quantity: str, stacked: bool) -> tuple[float, float]:
    """(low, high) of a lane: the raw values' range (stacked: 0 to the largest sum), from 0 for
    positive values whose low is under a quarter of their high; a drive (unit (1)) within 0-1
    keeps 0-1; a flat or empty series gets a range of 1 around it."""
    if stacked:
        low, high = 0.0, float(np.max(sum(np.nan_to_num(y) for _, y in series), initial=0.0))
    else:
        finite = np.concatenate([np.asarray(y)[np.isfinite(y)] for _, y in series])
        low, high = (float(finite.min()), float(finite.max())) if finite.size else (0.0, 0.0)
    if quantity.endswith("(1)") and low >= 0.0 and high <= 1.0:
        return 0.0, 1.0
    if 0.0 < low <= 0.25 * high:  # a lane of positive values near zero starts at zero
        low = 0.0
    return (low, high) if high > low else (low - 0.5, low + 0.5) if low else (0.0, 1.0)


def _draw_series(ax, detail_ax, t, series, bin_s, detail, stacked, styles, scale, note_y):
    """One muscle's series in its panel or lane (scale: values -> plotted y); stacked parts as
    stacked bands of bin means, "not recruited" where they are all zero."""
    several = len(series) > 1
    if not stacked:
        for n, (label, y) in enumerate(series):
            style = _series_style(label, n, styles)
            _binned_line(ax, t, y, bin_s, label=label, band=not several, scale=scale, **style)
            if detail is not None:
                _plot(detail_ax, t[detail], scale(y[detail]), **{**style, "lw": 1.0})
        return
    parts = np.nan_to_num(np.column_stack([y for _, y in series]))
    if not np.any(parts > 0):
        ax.text(0.5, note_y, "not recruited", transform=ax.get_yaxis_transform(), ha="center",
                va="center", fontsize=8, color="0.35")
    for target, mask, step in ((ax, slice(None), bin_s), (detail_ax, detail, 0.0)):
        if target is None or mask is None:
            continue
        centres, means, _, _ = bin_stats(t[mask], parts[mask], step)
        tops = np.cumsum(means, axis=1)
        for k in range(parts.shape[1]):
            below = tops[:, k - 1] if k else np.zeros(len(centres))
            _band(target, centres, scale(below), scale(tops[:, k]), lw=0, alpha=0.8,
                  color=_series_style(series[k][0], k, styles)["color"])


def _legend_handles(labels, stacked: bool, styles: dict | None) -> list:
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    return [Patch(color=_series_style(label, n, styles)["color"], alpha=0.8, label=label)
            if stacked else Line2D([], [], label=label, **_series_style(label, n, styles))
            for n, label in enumerate(labels)]


def _series_panels(plt, t, cells: list, bin_s: float, bin_reason: str, title: str,
                   stacked: bool = False, styles: dict | None = None):
    """cells: [(muscle, [(quantity, [(series label, values), ...]), ...]), ...].

    Up to LANES_AFTER muscles: one panel per muscle and quantity, each with its own y axis.
    More: one axes per quantity, one lane per muscle in it (top to bottom in the cells' order),
    each lane scaled to that muscle's range, given under its name (fast with many muscles, and
    no muscle hides another). Runs longer than DETAIL_AFTER_S add their last DETAIL_S as
    published beside each. stacked: the series are parts of a total, drawn stacked (bin means);
    all zero: "not recruited". Several series: bin means only (overlapping bands hide each other)
    and one legend above the plots."""
    detail = _detail(t)
    quantities = [q for q, _ in cells[0][1]]
    labels = [label for label, _ in cells[0][1][0][1]]
    lanes = len(cells) > LANES_AFTER
    per = 1 if detail is None else 2
    words = _bin_words(bin_reason)
    if stacked or len(labels) > 1:
        words = words.replace("bin mean (line) and range (band)", "bin means")
    subtitle = wrap_text(f"whole run: {words}" + (
        "" if detail is None else f"; right: the last {DETAIL_S:g} s as published"), 120)
    legend = len(labels) > 1 or stacked
    if lanes:  # margins in inches, no layout engine: one draw instead of two
        fig, axes = plt.subplots(1, len(quantities) * per, squeeze=False,
                                 figsize=_capped((2.5 + (7.5 if per == 1 else 10.0))
                                                 * len(quantities),
                                                 2.0 + 0.3 * legend + LANE_IN * len(cells)),
                                 width_ratios=[3, 1] * len(quantities) if per > 1 else None)
        _margins(fig, 1.5, 0.25, 0.5 + 0.17 * subtitle.count("\n") + 0.35,
                 0.6 + 0.3 * legend, wspace=1.1, columns=len(quantities) * per)
    else:
        fig, axes = plt.subplots(len(cells) * len(quantities), per, sharex="col", squeeze=False,
                                 figsize=_capped(11 if per > 1 else 9, 1.6 + 2.0 * len(cells)
                                                 * len(quantities)), layout="constrained",
                                 width_ratios=[3, 1] if per > 1 else None)
    ticks = [([], []) for _ in quantities]  # lanes: per quantity, y tick positions and labels
    for i, (muscle, rows) in enumerate(cells):
        base = len(cells) - 1 - i
        shared = _lane_range([s for _, series in rows for s in series], "", True) \
            if lanes and stacked else None
        for k, (quantity, series) in enumerate(rows):
            row = axes[0, k * per:(k + 1) * per] if lanes else axes[i * len(rows) + k]
            ax, detail_ax = row[0], (row[1] if per > 1 else None)
            if lanes:
                low, high = shared or _lane_range(series, quantity, stacked)
                scale = _lane_scale(base, low, high)
                ticks[k][0].append(base + 0.5)
                span = f"{_short(low)} to {_short(high)}"
                ticks[k][1].append(f"{muscle}\n{span}" if k == 0 else span)
            else:
                scale = _lane_scale(None, 0.0, 1.0)
                ax.set_ylabel(f"{muscle}\n{quantity}", fontsize=8)
            _draw_series(ax, detail_ax, t, series, bin_s, detail, stacked, styles, scale,
                         base + 0.5 if lanes else 0.5)
    for ax in axes.flat:
        ax.grid(alpha=0.3, axis="x" if lanes else "both")
        ax.tick_params(labelsize=7)
    for ax in axes[-1]:
        ax.set_xlabel("time (s)", fontsize=8)
    if lanes:
        for k, quantity in enumerate(quantities):
            axes[0, k * per].set_title(f"{quantity}; each lane from its low to its high "
                                       "value (under the name)", fontsize=8)
            if per > 1:
                axes[0, k * per + 1].set_title(f"last {DETAIL_S:g} s", fontsize=8)
        for c, ax in enumerate(axes[0]):
            ax.set_ylim(0, len(cells))
            ax.hlines(np.arange(1, len(cells)), 0, 1, transform=ax.get_yaxis_transform(),
                      color="0.75", lw=0.6)
            if c % per:
                ax.set_yticks([])
            else:
                ax.set_yticks(*ticks[c // per], fontsize=7)
    if legend:
        fig.legend(handles=_legend_handles(labels, stacked, styles),
                   loc="lower center" if lanes else "outside lower center",
                   ncol=min(6, len(labels)), **LEGEND)
    if lanes:  # placed in the top margin; constrained layout places it itself
        fig.suptitle(f"{title}\n{subtitle}", fontsize=10, y=1 - 0.08 / fig.get_figheight(),
                     va="top")
    else:
        fig.suptitle(f"{title}\n{subtitle}", fontsize=10)
    return fig


def _margins(fig, left: float, right: float, top: float, bottom: float, wspace: float = 0.0,
             hspace: float = 0.0, columns: int = 1, rows: int = 1) -> dict:
    """Subplot margins and gaps given in inches, as fractions (for subplots_adjust and
    gridspecs); applied to fig's subplots when it has axes."""
    width, height = fig.get_size_inches()
    axes_w = (width - left - right - (columns - 1) * wspace) / columns
    axes_h = (height - top - bottom - (rows - 1) * hspace) / rows
    fractions = {"left": left / width, "right": 1 - right / width, "top": 1 - top / height,
                 "bottom": bottom / height, "wspace": wspace / axes_w,
                 "hspace": hspace / axes_h}
    if fig.axes:
        fig.subplots_adjust(**fractions)
    return fractions


def _short(value: float) -> str:
    """Three significant digits, without an exponent up to 10^6."""
    return f"{value:.3g}" if abs(value) < 1e3 or abs(value) >= 1e6 else f"{value:.0f}"


def _lane_scale(base: int | None, low: float, high: float):
    """values -> plotted y: into lane ``base`` (0 at the bottom) from low to high; None: as
    they are (panels)."""
    if base is None:
        return lambda v: v
    return lambda v: base + 0.1 + 0.8 * (np.asarray(v) - low) / (high - low)


# --- the figures ----------------------------------------------------------------------------

def force_figure(plt, force: Table, names, bin_s: float, bin_reason: str):
    """One panel per muscle: tendon force (N)."""
    cells = [(m, [("force (N)", [(m, force.column(f"{m}.force_N"))])]) for m in names]
    return _series_panels(plt, force.column("time_s"), cells, bin_s, bin_reason,
                          "tendon force")


def kinematics_figure(plt, force: Table, names, bin_s: float, bin_reason: str):
    """Two panels per muscle: fascicle length (m) and velocity (m/s)."""
    cells = [(m, [("length (m)", [(m, force.column(f"{m}.fascicle_length_m"))]),
                  ("velocity (m/s)", [(m, force.column(f"{m}.fascicle_velocity_m_per_s"))])])
             for m in names]
    return _series_panels(plt, force.column("time_s"), cells, bin_s, bin_reason,
                          "fascicle kinematics (velocity < 0: shortening)")


def drive_figure(plt, run: RunLog, telemetry: Table | None, names, bin_s: float,
                 bin_reason: str):
    """One panel per muscle: drive U, filtered drive Ueff and Acteff per fibre type (telemetry),
    or U alone (the excitation topic); None when the log has neither."""
    excitation = run.get(tm.TOPIC_EXCITATION)
    if telemetry is not None:
        t = telemetry.column("time_s")
        cells = [(m, [("(1)", [("U", telemetry.column(f"{m}.excitation_1")),
                               ("Ueff", telemetry.column(f"{m}.effective_drive_1"))]
                       + [(f"Acteff {f}", telemetry.column(f"{m}.{f}.effective_activation_1"))
                          for f in FIBRE_TYPES])]) for m in names]
        title = "drive U, filtered drive Ueff and effective activation Acteff per fibre type"
    elif excitation is not None and len(excitation):
        t = (excitation.time_ns - time_origin_ns(run)) * 1e-9
        index = {m: i for i, m in enumerate(muscle_names(run))}
        cells = [(m, [("(1)", [("U", excitation.fields["position"][:, index[m]])])])
                 for m in names]
        title = "drive U"
    else:
        return None
    return _series_panels(plt, t, cells, bin_s, bin_reason, title)


def muscle_energy_figure(plt, rates: Table, names, bin_s: float, bin_reason: str):
    """Per muscle: the energy rate components (W) of its slow and of its fast fibres, stacked
    (bin means); a fibre type without energy says "not recruited"."""
    cells = [(m, [(f"{f} fibres (W)", [(c.replace("_", "-"), rates.column(f"{m}.{f}.{c}_W"))
                                       for c in COMPONENTS]) for f in FIBRE_TYPES])
             for m in names]
    return _series_panels(plt, rates.column("time_s"), cells, bin_s, bin_reason,
                          "energy rate by component", stacked=True)


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
    ax.legend(**OUTSIDE_RIGHT)


def _muscles_words(names) -> str:
    return (f"all muscles ({', '.join(names)})" if len(names) <= TOP_MUSCLES + 1
            else f"all {len(names)} muscles")


def energy_rate_figure(plt, rates: Table, names, bin_s: float, bin_reason: str):
    """Tsianos 2012 Fig. 7 style: whole-body energy rate per component in bins over time."""
    fig, ax = plt.subplots(figsize=(10, 4.2))
    _margins(fig, 0.8, 1.4, 1.0, 0.55)
    _energy_rate_axes(ax, rates, names, bin_s)
    ax.set_xlabel("time (s)")
    what = "mean energy rate per bin" if bin_s > 0 else "energy rate"
    ax.set_title(wrap_text(f"{_muscles_words(names)}: {what}; bins: {bin_reason}", 110),
                 fontsize=9)
    fig.suptitle("energy rate by component (Tsianos 2012 Fig. 7 style)")
    return fig


def energy_models_figure(plt, models: Table, rates: Table | None, axes, bin_s: float,
                         bin_reason: str, page=None, with_all: bool = True):
    """One panel (or lane) per muscle of ``page`` (default: all) and, with ``with_all``, one for
    all muscles first: each published model's total energy rate (W) and Tsianos 2012's (black),
    bin means."""
    muscles, names, _ = axes
    t = models.column("time_s")
    own_label = f"{TSIANOS} (vm_ros)"

    def series(group) -> list:
        """[(label, W)] of the muscles in group, summed."""
        out = [(name, sum(models.column(f"{m}.{name}.total_W") for m in group))
               for name in names]
        if rates is not None:
            own = sum(rates.column(f"{m}.all.total_W") for m in group)
            out.append((own_label, np.interp(t, rates.column("time_s"), own)))
        return out

    cells = ([("all muscles", [("total energy rate (W)", series(muscles))])] if with_all
             else []) + [(m, [("total energy rate (W)", series((m,)))])
                         for m in (muscles if page is None else page)]
    return _series_panels(plt, t, cells, bin_s, bin_reason,
                          "total energy rate: published models beside Tsianos 2012",
                          styles={own_label: {"color": "k", "lw": 2.2, "ls": "-"}})


def _wrapped_rows(plt, count: int, per_row: int, row_h: float, width: float = 11.0):
    """A figure of bar-chart rows (count groups, at most per_row a row; room below each for
    slanted labels, and for a legend at the bottom): (fig, [(axes, group indices)])."""
    chunks = pages(range(count), per_row)
    fig, axes = plt.subplots(len(chunks), 1, figsize=_capped(width, 1.6 + row_h * len(chunks)),
                             squeeze=False)
    _margins(fig, 0.9, 0.2, 0.75, 1.4, hspace=1.0, rows=len(chunks))
    return fig, list(zip(axes[:, 0], chunks, strict=True))


def energy_models_totals_figure(plt, rows, muscles):
    """Grouped bars: each model's energy over the run relative to Tsianos 2012, per muscle and
    for all muscles (1 = Tsianos); wrapped into rows of at most BARS_PER_ROW bars."""
    groups = [*muscles, "all muscles"]
    values = []
    for row in rows:
        with np.errstate(divide="ignore", invalid="ignore"):
            per_muscle = np.where(row.tsianos > 0, row.energy / row.tsianos, np.nan)
        values.append(np.append(per_muscle, row.relative))
    fig, chunks = _wrapped_rows(plt, len(groups), max(1, BARS_PER_ROW // max(1, len(rows))),
                                2.3)
    width = 0.8 / max(1, len(rows))
    for ax, chunk in chunks:
        x = np.arange(len(chunk))
        for k, row in enumerate(rows):
            # the colours of energy_models.png: models in log order, Tsianos 2012 in black
            own = row.model == TSIANOS
            ax.bar(x + (k - (len(rows) - 1) / 2) * width, values[k][chunk], width,
                   label=row.model, color="white" if own else f"C{(k - 1) % 10}",
                   edgecolor="k" if own else None, hatch="//" if own else None)
        ax.axhline(1.0, color="k", lw=0.8)
        ax.set_xticks(x, [groups[i] for i in chunk], fontsize=8, rotation=20, ha="right")
        ax.set_xlim(-0.6, max(len(chunk), 4) - 0.4)
        ax.set_ylabel("energy / Tsianos 2012 (1)", fontsize=8)
        ax.grid(alpha=0.3, axis="y")
    handles, labels = chunks[0][0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=min(5, len(rows)), **LEGEND)
    fig.suptitle(wrap_text("energy over the run per published model, relative to Tsianos "
                               "2012 (trapezoidal integrals of the published rates)", 100),
                 fontsize=10)
    return fig


def partition_figure(plt, summary):
    """Per muscle: the energy of its slow and fast (hatched) fibres, stacked by component;
    wrapped into rows of at most BARS_PER_ROW / 4 muscles."""
    fig, chunks = _wrapped_rows(plt, len(summary), BARS_PER_ROW // 4, 2.4)
    for ax, chunk in chunks:
        x = np.arange(len(chunk))
        for j, (fibre, hatch) in enumerate(zip(FIBRE_TYPES, ("", "///"), strict=True)):
            bottom = np.zeros(len(chunk))
            for k, component in enumerate(COMPONENTS):
                values = np.array([summary[i].energy[j, k] for i in chunk])
                ax.bar(x + (j - 0.5) * 0.4, values, 0.38, bottom=bottom, color=f"C{k}",
                       hatch=hatch, edgecolor="white", lw=0,
                       label=f"{component.replace('_', '-')}, {fibre}")
                bottom += values
        ax.set_xticks(x, [summary[i].name for i in chunk], fontsize=8, rotation=20, ha="right")
        ax.set_xlim(-0.6, max(len(chunk), 4) - 0.4)
        ax.set_ylabel("energy (J)", fontsize=8)
        ax.grid(alpha=0.3, axis="y")
    handles, labels = chunks[0][0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=3, **LEGEND)
    fig.suptitle("energy partition per muscle: slow fibres (left bar), fast fibres (right, "
                 "hatched)", fontsize=10)
    return fig


def totals_figure(plt, totals: Table, bin_s: float, bin_reason: str):
    t = totals.column("time_s")
    fig, axes = plt.subplots(2, 1, figsize=(9, 5.8), sharex=True)
    _margins(fig, 0.9, 0.3, 0.9, 0.55, hspace=0.3, rows=2)
    _binned_line(axes[0], t, totals.column("energy_rate_total_W"), bin_s)
    axes[0].set_ylabel("energy rate (W)")
    axes[0].set_title(wrap_text(f"whole run: {_bin_words(bin_reason)}", 110), fontsize=9)
    _plot(axes[1], t, totals.column("energy_total_J"))
    axes[1].set_ylabel("energy (J)")
    axes[1].set_xlabel("time (s)")
    for ax in axes:
        ax.grid(alpha=0.3)
    fig.suptitle("whole body")
    return fig


def effort_joints(efforts: Table) -> list[tuple[str, str]]:
    """(joint, "rad" or "m") per joint of the joint_efforts table, from its effort columns'
    unit suffixes (JOINT_UNITS: the table names them by the geometry's units)."""
    units = {suffixes[2]: unit for unit, suffixes in JOINT_UNITS.items()}
    return [(joint, units[suffix]) for joint, _, suffix in
            (c.partition(".effort_") for c in efforts.columns) if suffix]


def joint_figure(plt, efforts: Table, states: Table | None):
    """One panel per joint: generalized force (N m or N), and on a twin axis the joint angle
    received (joint_states; deg for rotational joints) or, without them, the one used."""
    joints = effort_joints(efforts)
    fig, axes = plt.subplots(len(joints), 1, figsize=_capped(9, 1.4 + 2.2 * len(joints)),
                             sharex=True, squeeze=False)
    # margins in inches (labels on both sides), no layout engine: one draw instead of two
    _margins(fig, 0.85, 0.8, 0.45, 0.5, hspace=0.2, rows=len(joints))
    for ax, (joint, unit) in zip(axes[:, 0], joints, strict=True):
        _joint_axes(ax, joint, unit, efforts, states)
    axes[-1, 0].set_xlabel("time (s)")
    fig.suptitle("joint torques (robot convention) and joint angles",
                 y=1 - 0.1 / fig.get_figheight(), va="top")
    return fig


def _joint_axes(ax, joint: str, unit: str, efforts: Table, states: Table | None) -> None:
    position, _, effort = (f"{joint}.{q}_{s}" for q, s in zip(
        ("position", "velocity", "effort"), JOINT_UNITS[unit], strict=True))
    _plot(ax, efforts.column("time_s"), efforts.column(effort), color="C0", label="torque")
    ax.set_ylabel(f"{joint} ({EFFORT_UNITS[unit]})", fontsize=9)
    ax.grid(alpha=0.3)
    source = states if states is not None and position in states.columns else efforts
    scale, angle_unit = (180.0 / np.pi, "deg") if unit == "rad" else (1.0, "m")
    twin = ax.twinx()
    _plot(twin, source.column("time_s"), scale * source.column(position), color="C1",
          alpha=0.8)
    twin.set_ylabel(f"angle ({angle_unit})" if unit == "rad" else "position (m)", color="C1",
                    fontsize=9)


def top_muscles(summary, names, count: int = TOP_MUSCLES) -> tuple[list, list]:
    """(named, others): the ``count`` muscles with the most total energy, most first, and the
    rest in log order; every muscle named when there are at most count + 1 (or no energy)."""
    energy = {row.name: float(np.nan_to_num(row.energy[-1, -1])) for row in summary}
    if len(names) <= count + 1 or not energy:
        return list(names), []
    named = sorted(names, key=lambda m: -energy.get(m, 0.0))[:count]
    return named, [m for m in names if m not in named]


def _muscle_lines(ax, t, columns: dict, named, others) -> None:
    """One line per named muscle (its colour) and thin grey lines for the others (one legend
    entry); columns: muscle -> values."""
    for n, m in enumerate(named):
        _plot(ax, t, columns[m], color=NAMED_COLORS[n % len(NAMED_COLORS)], label=m, lw=1.2)
    for k, m in enumerate(others):
        _plot(ax, t, columns[m], color=OTHERS_COLOR, lw=0.6, zorder=1,
                label=f"others ({len(others)})" if k == 0 else None)


def summary_figure(plt, run: RunLog, tables: dict, bin_s: float, bin_reason: str):
    """One A4 page: the run (log, scenario, span, bins), the totals, force per muscle, the Fig. 7
    style energy rate, cumulative energy and the partition per muscle, and joint torques or
    drive (long runs: force in their last DETAIL_S as published). Many muscles: the
    TOP_MUSCLES with the most energy by name and colour, the others grey (their sum where a
    sum means something). Legends right of the plots."""
    from matplotlib.lines import Line2D

    names = muscle_names(run)
    summary = run_summary(run)
    named, others = top_muscles(summary, names)
    force, rates, telemetry = (tables.get(k) for k in ("forces", "energy_rate", "telemetry"))
    lines = [wrapped for line in _header_lines(run, force, summary, bin_reason, named, others)
             for wrapped in textwrap.wrap(line, 100, subsequent_indent="    ")]
    bars = len(named) + bool(others)
    heights = [2.0, 1.6, 1.5, 0.5 + 0.17 * bars, 1.6]  # in: force, rate, energy, bars, last
    header_in = 0.4 + 0.12 * len(lines)  # the title and the header's lines
    gap, bottom = 0.75, 0.5
    fig = plt.figure(figsize=(8.27, header_in + sum(heights) + gap * len(heights) + bottom))
    grid = fig.add_gridspec(len(heights), 1, height_ratios=heights, **_margins(
        fig, 1.35, 1.75, header_in + gap - 0.1, bottom, hspace=gap, rows=len(heights)))
    fig.text(0.35 / 8.27, 1 - 0.45 / fig.get_figheight(), "\n".join(lines), va="top",
             ha="left", family="monospace", fontsize=7.5)
    ax = fig.add_subplot(grid[0])
    if force is not None:
        t = force.column("time_s")
        means, peaks = {}, {}
        for m in names:
            centres, means[m], _, peaks[m] = bin_stats(t, force.column(f"{m}.force_N"), bin_s)
        _muscle_lines(ax, centres, means, named, others)
        handles = ax.get_legend_handles_labels()[0]
        if bin_s > 0:
            for n, m in enumerate(named):
                ax.plot(centres, peaks[m], "--", color=NAMED_COLORS[n % len(NAMED_COLORS)],
                        lw=0.9)
            handles += [Line2D([], [], color="k", lw=1.2, label="bin mean"),
                        Line2D([], [], color="k", lw=0.9, ls="--", label="bin peak")]
        ax.legend(handles=handles, **OUTSIDE_RIGHT)
    ax.set_ylabel("tendon force (N)")
    ax.set_title("tendon force per muscle" + (": mean and peak per bin" if bin_s > 0 else ""),
                 fontsize=9)
    ax.grid(alpha=0.3)
    ax = fig.add_subplot(grid[1])
    if rates is not None:
        _energy_rate_axes(ax, rates, names, bin_s)
    ax.set_title("energy rate by component, all muscles (Tsianos 2012 Fig. 7 style)",
                 fontsize=9)
    ax = fig.add_subplot(grid[2])
    cumulative = _cumulative_energy(telemetry, rates, names)
    if cumulative is not None:
        t, energy = cumulative
        _muscle_lines(ax, t, energy, named, [])
        if others:
            _plot(ax, t, sum(energy[m] for m in others), color=OTHERS_COLOR, lw=1.5, ls="--",
                    label=f"others ({len(others)}), sum")
        ax.legend(**OUTSIDE_RIGHT)
    ax.set_ylabel("energy (J)")
    ax.set_title("cumulative energy per muscle", fontsize=9)
    ax.grid(alpha=0.3)
    ax = fig.add_subplot(grid[3])
    if summary:
        _partition_barh(ax, summary, named, others)
    ax.set_title("energy partition per muscle", fontsize=9)
    ax = fig.add_subplot(grid[4])
    _summary_bottom(ax, tables, bin_s, named, others)
    ax.set_xlabel("time (s)")
    ax.grid(alpha=0.3)
    fig.suptitle(f"vm-ros report: {Path(str(run.path)).name}", y=1 - 0.1 / fig.get_figheight(),
                 va="top")
    return fig


def _cumulative_energy(telemetry: Table | None, rates: Table | None, names):
    """(time s, {muscle: energy J}): the telemetry's counters, else the trapezoidal integral of
    the published rates; None without either."""
    if telemetry is not None:
        return telemetry.column("time_s"), {
            m: telemetry.column(f"{m}.all.total_energy_J") for m in names}
    if rates is None:
        return None
    t = rates.column("time_s")
    energy = {}
    for m in names:
        rate = np.nan_to_num(rates.column(f"{m}.all.total_W"))
        energy[m] = np.r_[0.0, np.cumsum(0.5 * (rate[1:] + rate[:-1]) * np.diff(t))]
    return t, energy


def _partition_barh(ax, summary, named, others) -> None:
    """Horizontal stacked bars: each named muscle's energy per component (all fibres), and the
    others' sum."""
    rows = {row.name: row.energy[-1, :3] for row in summary}
    labels = [m for m in named if m in rows]
    values = [rows[m] for m in labels]
    if others:
        labels.append(f"others ({len(others)})")
        values.append(sum(rows[m] for m in others if m in rows))
    values = np.array(values, dtype=float)
    y = np.arange(len(labels))[::-1]
    left = np.zeros(len(labels))
    for k, component in enumerate(COMPONENTS):
        ax.barh(y, values[:, k], 0.7, left=left, color=f"C{k}",
                label=component.replace("_", "-"))
        left += values[:, k]
    ax.set_yticks(y, labels, fontsize=7)
    ax.set_xlabel("energy (J)", fontsize=8)
    ax.grid(alpha=0.3, axis="x")
    ax.legend(**OUTSIDE_RIGHT)


def _summary_bottom(ax, tables: dict, bin_s: float, named, others) -> None:
    """The summary's last panel: joint torques, else long runs' force in their last DETAIL_S,
    else drive U per muscle."""
    force, telemetry = tables.get("forces"), tables.get("telemetry")
    efforts = tables.get("joint_efforts")
    detail = _detail(force.column("time_s")) if force is not None else None
    if efforts is not None:
        for n, (joint, unit) in enumerate(effort_joints(efforts)):
            column = f"{joint}.effort_{JOINT_UNITS[unit][2]}"
            _binned_line(ax, efforts.column("time_s"), efforts.column(column), bin_s,
                         label=f"{joint} ({EFFORT_UNITS[unit]})", color=f"C{n % 10}")
        ax.set_ylabel("generalized force")
        ax.set_title("joint torques (robot convention)", fontsize=9)
    elif detail is not None:
        t = force.column("time_s")
        _muscle_lines(ax, t[detail], {m: force.column(f"{m}.force_N")[detail]
                                      for m in [*named, *others]}, named, others)
        ax.set_ylabel("tendon force (N)")
        ax.set_title(f"tendon force, last {DETAIL_S:g} s as published", fontsize=9)
    elif telemetry is not None:
        _muscle_lines(ax, telemetry.column("time_s"), {
            m: telemetry.column(f"{m}.excitation_1") for m in [*named, *others]}, named, others)
        ax.set_ylabel("drive (1)")
        ax.set_title("drive U per muscle", fontsize=9)
    if ax.get_lines():
        ax.legend(**OUTSIDE_RIGHT)


def _header_lines(run: RunLog, force: Table | None, summary, bin_reason: str, named,
                  others) -> list:
    extra = run.info.extra if run.info is not None else {}
    span = force.column("time_s")[-1] if force is not None and len(force.data) else float("nan")
    source = next((f"{key} {extra[key]}" for key in ("scenario", "inputs_file", "motion_file")
                   if extra.get(key)), "not recorded")
    muscles = (", ".join(named) if not others else
               f"{len(named) + len(others)}: the {len(named)} with the most energy by name, "
               f"{len(others)} others (every muscle in summary.csv)")
    lines = [f"source: {source}   model time: {span:.3f} s   muscles: {muscles}",
             f"bins: {bin_reason}"]
    if not run.complete:
        lines.append(f"log cut short ({run.stop_reason}): the report covers what it holds")
    if summary:
        energy, work, efficiency = run_totals(summary)
        lines.append("energy (J): " + "  ".join(
            f"{c.replace('_', '-')} {energy[k]:.4g}" for k, c in enumerate(tm.COMPONENT_LABELS)))
        eff = f"{100 * efficiency:.1f} %" if np.isfinite(efficiency) else "n/a"
        lines.append(f"mechanical work: {work:.4g} J   net efficiency: {eff}")
        rows = {row.name: row for row in summary}
        for m in named:
            row = rows[m]
            lines.append(f"  {row.name:<20} peak {row.peak_force:8.1f} N  mean "
                         f"{row.mean_force:7.1f} N  energy {row.energy[-1, -1]:10.4g} J")
        if others:
            lines.append(f"  others ({len(others)} muscles): energy "
                         f"{sum(rows[m].energy[-1, -1] for m in others):.4g} J together")
    return lines


def report_figures(plt, run: RunLog, tables: dict, out: Path, bin_s: float, bin_reason: str):
    """(path, figure) of every figure the log allows, one at a time (the caller saves and closes
    each). Per-muscle figures hold at most PAGE_MUSCLES muscles a file (more: <name>-2.png,
    ...)."""
    names = muscle_names(run)
    force, telemetry = tables.get("forces"), tables.get("telemetry")
    rates = tables.get("energy_rate")
    models, axes = tables.get("energy_rate_models"), energy_models_axes(run)
    summary = run_summary(run)
    for page, chunk in enumerate(pages(names)):
        if force is not None:
            yield (page_path(out, "force", page),
                   force_figure(plt, force, chunk, bin_s, bin_reason))
            yield (page_path(out, "kinematics", page),
                   kinematics_figure(plt, force, chunk, bin_s, bin_reason))
        fig = drive_figure(plt, run, telemetry, chunk, bin_s, bin_reason)
        if fig is not None:
            yield page_path(out, "drive", page), fig
        if rates is not None:
            yield (page_path(out, "energy_muscles", page),
                   muscle_energy_figure(plt, rates, chunk, bin_s, bin_reason))
    if models is not None and axes is not None:
        for page, chunk in enumerate(pages(axes[0])):
            yield (page_path(out, "energy_models", page),
                   energy_models_figure(plt, models, rates, axes, bin_s, bin_reason, chunk,
                                        with_all=page == 0))
        yield (out / "energy_models_totals.png",
               energy_models_totals_figure(plt, model_totals(run), axes[0]))
    if rates is not None:
        yield out / "energy_rate.png", energy_rate_figure(plt, rates, names, bin_s, bin_reason)
    for page, chunk in enumerate(pages(summary) if summary else []):
        yield page_path(out, "energy_partition", page), partition_figure(plt, chunk)
    totals = tables.get("totals")
    if totals is not None:
        yield out / "totals.png", totals_figure(plt, totals, bin_s, bin_reason)
    efforts = tables.get("joint_efforts")
    if efforts is not None:
        yield (out / "joint_torque.png",
               joint_figure(plt, efforts, tables.get("joint_states")))
    yield out / "summary.png", summary_figure(plt, run, tables, bin_s, bin_reason)


def plot_run(plt, run: RunLog, tables: dict, out: Path, bin_s: float, bin_reason: str) -> list:
    """Write every figure of :func:`report_figures` into ``out``; the paths written."""
    written: list = []
    enabled = gc.isenabled()
    gc.disable()  # a figure makes ~10^5 objects; the automatic full collections they trigger
    try:  # would walk the whole log each time. Without them a figure's objects stay young:
        for path, fig in report_figures(plt, run, tables, out, bin_s, bin_reason):
            _save(plt, fig, path, written)
            gc.collect(0)  # its cycles, without walking the older objects
    finally:
        if enabled:
            gc.enable()
    return written
