"""Figures for ``vm-ros validate``: one PNG per check, the paper's claim in the title (matplotlib,
Agg backend; imported only when plotting)."""

from __future__ import annotations

import textwrap
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from vm_ros.validation import JOINT_TORQUE_BANDS, CheckResult, published_ratio  # noqa: E402
from vm_ros.validation.knee_extension_plot import plot_fig7  # noqa: E402
from vm_ros.validation.plot_style import finish  # noqa: E402
from vm_ros.validation.walk_plot import plot_walk  # noqa: E402


def plot_fig2(result: CheckResult, path: Path) -> None:
    fig, ax = plt.subplots(figsize=(7, 4.5))
    for name, colour in (("slow", "tab:blue"), ("fast", "tab:red")):
        d = result.data[name]
        v = np.asarray(d["velocity"])
        short = v <= 0
        ax.plot(v[short], d["barclay"][short], color=colour, lw=3, alpha=0.4,
                label=f"Barclay 1996 fit (V <= 0), {name}")
        ax.plot(v[short], d["model"][short], "o", color=colour, ms=4,
                label=f"model, 100 % {name}")
        ax.plot(v[~short], d["model"][~short], "^", color=colour, ms=5, mfc="none",
                label=f"model, lengthening (STEP 3 extension), {name}")
        ax.plot(v, d["e_a_per_kg_dry"], ":", color=colour, lw=1.5,
                label=f"model activation part E_a, {name}")
    ax.set(xlabel="fascicle velocity (L0/s, negative = shortening)",
           ylabel="tetanic initial energy rate (W/kg dry)")
    ax.axvline(0, color="grey", lw=0.5)
    ax.legend(fontsize=8)
    finish(fig, result, path)


def plot_fig3(result: CheckResult, path: Path) -> None:
    curves = result.data["curves"]
    fig, axes = plt.subplots(1, 3, figsize=(13, 4.2))
    for name, colour in (("slow", "tab:blue"), ("fast", "tab:red")):
        c = curves[name]
        per_kg = 1.0 / c["mass_kg"]
        axes[0].plot(c["drive"], np.array(c["e_a_drive"]) * per_kg, "--", color=colour,
                     label=f"{name}: activation")
        axes[0].plot(c["drive"], np.array(c["e_xb_drive"]) * per_kg, color=colour,
                     label=f"{name}: cross-bridge")
        axes[1].plot(c["velocity"], np.array(c["total_velocity"]) * per_kg, "o-", color=colour,
                     label=f"{name}: total (with recovery)")
        axes[1].plot(c["velocity"], np.array(c["initial_velocity"]) * per_kg, "s-.", ms=3,
                     color=colour, label=f"{name}: initial (E_a + E_xb)")
        axes[1].plot(c["velocity"], np.array(c["e_a_velocity"]) * per_kg, "--", color=colour,
                     label=f"{name}: activation")
        axes[2].plot(c["length"], np.array(c["total_length"]) * per_kg, "o-", color=colour,
                     label=f"{name}: total")
        axes[2].plot(c["length"], np.array(c["initial_length"]) * per_kg, "s-.", ms=3,
                     color=colour, label=f"{name}: initial")
        axes[2].plot(c["length"], np.array(c["e_a_length"]) * per_kg, "--", color=colour,
                     label=f"{name}: activation")
        xb = np.asarray(c["e_xb_length"]) * per_kg
        axes[2].plot(c["length"], xb, "-", lw=0.8, color=colour, label=f"{name}: cross-bridge")
        axes[2].plot(c["length"], np.asarray(c["fl_length"]) * xb[np.argmin(np.abs(
            c["length"] - 1.0))], ":", color=colour, label=f"{name}: FL x cross-bridge at L0")
    axes[0].set(xlabel="drive U (isometric, L0)", ylabel="energy rate (W/kg wet)")
    axes[1].set(xlabel="fascicle velocity (L0/s), U = 1", ylabel="energy rate (W/kg wet)")
    axes[2].set(xlabel="fascicle length (L0), isometric, U = 1", ylabel="energy rate (W/kg wet)")
    axes[2].set_title("cross-bridge part follows FL x Af(L) (Af falls at short L)", fontsize=9)
    d = result.data
    ratio = d["per_newton"]["fast"] / d["per_newton"]["slow"]
    ratio_total = d["per_newton_total"]["fast"] / d["per_newton_total"]["slow"]
    axes[0].set_title(f"fast/slow energy per newton: initial {ratio.min():.1f}-{ratio.max():.1f}"
                      f" (claim > 5);\ntotal with recovery {ratio_total.min():.1f}-"
                      f"{ratio_total.max():.1f} (reported)", fontsize=9)
    for ax in axes[:2]:
        ax.legend(fontsize=7)
    axes[2].set_ylim(0, 1.7 * axes[2].get_ylim()[1])  # room for the legend above the curves
    axes[2].legend(fontsize=6, ncol=2, loc="upper center")
    finish(fig, result, path)


def plot_fig4(result: CheckResult, path: Path) -> None:
    d = result.data
    fig, (ax_f, ax_e) = plt.subplots(1, 2, figsize=(12, 4.5))
    colours = plt.cm.viridis(np.linspace(0, 0.9, len(d["drive"])))
    iso_full = d["isometric_force_f0"][-1]  # the paper's "maximal isometric force"
    for i, u in enumerate(d["drive"]):
        ax_f.plot(d["velocity"], 100 * d["force_f0"][i] / iso_full, "o-", ms=3,
                  color=colours[i], label=f"drive {u:.0%}")
        ax_e.plot(d["velocity"], d["energy_w"][i], "o-", ms=3, color=colours[i],
                  label=f"drive {u:.0%}; {d['w_per_n'][i]:.3f} W/N isometric")
    ax_f.plot(d["velocity"], 100 * d["force_f0_no_yield"] / d["isometric_force_f0_no_yield"],
              "k:", lw=1.5, label="drive 100 %, yield off (cy = 0)")
    ax_f.axhline(140, color="grey", lw=3, alpha=0.3, label="paper: ~140 % when stretched")
    ax_f.axvspan(1.0, d["velocity"].max(), color="grey", alpha=0.08)
    ax_f.set(xlabel="fascicle velocity (L0/s, negative = shortening)",
             ylabel="force (% of the U = 1 isometric force)")
    peak = d["peak_over_isometric"]
    ax_f.set_title(f"biceps long head analogue: F0 {d['f0_n']:.0f} N, L0 {d['l0_m']:.4f} m, "
                   f"40 % slow; U = 1 isometric {iso_full:.3f} F0\npeak stretched > 1 L0/s: "
                   f"{100 * peak['yield on']:.0f} % (yield on), {100 * peak['yield off']:.0f} % "
                   "(yield off) of isometric", fontsize=9)
    ax_e.set(xlabel="fascicle velocity (L0/s, negative = shortening)",
             ylabel="total energy rate (W)")
    for ax in (ax_f, ax_e):
        ax.axvline(0, color="grey", lw=0.5)
        ax.legend(fontsize=7)
    finish(fig, result, path)


def plot_fig5(result: CheckResult, path: Path) -> None:
    d = result.data
    rates = d["rates_mk_per_s"]
    fig, ax = plt.subplots(figsize=(7.5, 4.8))
    for u, marker, colour in ((1.0, "o", "tab:blue"), (0.8, "s", "tab:orange")):
        ax.plot(d["fast_percent"], rates["initial"][u], marker, color=colour,
                label=f"U = {u} at MVC, initial (E_a + E_xb): compared")
        ax.plot(d["fast_percent"], rates["total"][u], marker, color=colour, mfc="none",
                label=f"U = {u} at MVC, total with recovery: reported")
    order = np.argsort(d["fast_percent"])
    for rank, i in enumerate(order):
        x, y = d["fast_percent"][i], rates["initial"][1.0][i]
        above = rank % 2 == 1  # neighbours alternate: left-above, right-below
        ax.annotate(d["names"][i], (x, y), fontsize=6, textcoords="offset points",
                    xytext=(-4, 4) if above else (4, -9), ha="right" if above else "left")
    ax.set_xlim(0, max(d["fast_percent"]) + 12)
    ax.set(xlabel="fast fibres (% PCSA)", ylabel="temperature rate at MVC (mK/s)")
    ax.set_title("isometric at L0; dT/dt = energy rate / (wet mass x 3.75 kJ/(kg K))",
                 fontsize=9)
    ax.legend(fontsize=7)
    finish(fig, result, path)


def plot_fig6(result: CheckResult, path: Path) -> None:
    fig, ax = plt.subplots(figsize=(7, 4.5))
    for (u, s), colour in zip(result.data["series"].items(), ("tab:blue", "tab:orange"),
                              strict=True):
        ax.plot(s["force_pct"], s["initial"], "o-", color=colour,
                label=f"U = {u} at MVC, initial: compared ({s['initial_at_mvc']:.1f} mK/s "
                      "at MVC)")
        ax.plot(s["force_pct"], s["total"], "o--", color=colour, mfc="none",
                label=f"U = {u} at MVC, total with recovery: reported "
                      f"({s['total_at_mvc']:.1f} mK/s at MVC)")
    ax.set(xlabel="isometric force (% of the force at the 'MVC' drive)",
           ylabel="temperature rate (mK/s)")
    ax.set_title("drive at 10-90 % of the 'MVC' drive (U = 1 or U = 0.8), fascicle at L0",
                 fontsize=9)
    ax.legend(fontsize=7)
    finish(fig, result, path)


def plot_fig9(result: CheckResult, path: Path) -> None:
    c = result.data["comparison"]
    fig, (ax, ax_err) = plt.subplots(1, 2, figsize=(12, 4.5))
    colours = plt.cm.viridis(np.linspace(0, 0.9, len(c.fpcsa_slow)))
    error = c.error_percent
    for i, fs in enumerate(c.fpcsa_slow):
        nat = c.natural.sum(-1)[:, i]
        ax.plot(c.drive, nat / nat[-1], color=colours[i], lw=2.5, alpha=0.5,
                label=f"natural, {fs:.0%} slow")
        ax.plot(c.drive, c.lumped.sum(-1)[:, i] / nat[-1], "--", color=colours[i], lw=1,
                label=f"lumped, {fs:.0%} slow")
        ax_err.plot(c.drive, error[:, i], color=colours[i], label=f"{fs:.0%} slow")
    ax.set(xlabel="drive U", ylabel="steady isometric force at L0 / natural F(U=1)")
    ax.set_title("natural units (50/type, thick) vs lumped (dashed)", fontsize=9)
    ax.legend(fontsize=6, ncol=2)
    ax_err.axhspan(-2, 2, color="grey", alpha=0.15, label="target +-2 %")
    ax_err.axhline(0, color="grey", lw=0.5)
    ax_err.set(xlabel="drive U", ylabel="lumped - natural force (% of natural F(U=1))")
    ax_err.set_title(f"error: max {np.abs(error).max():.2f} %", fontsize=9)
    ax_err.legend(fontsize=7)
    finish(fig, result, path)


def plot_fig10(result: CheckResult, path: Path) -> None:
    table = result.data["table"]
    fig, (ax_t, ax_tab) = plt.subplots(1, 2, figsize=(13, 4.5),
                                       gridspec_kw={"width_ratios": [1.2, 1]})
    cols = list(table.columns)
    pick = int(np.argmax(np.abs(table.rows[:, cols.index("range_error")])))
    ax_t.plot(table.time_s, table.natural_force[:, pick], lw=2, alpha=0.6, label="natural")
    ax_t.plot(table.time_s, table.lumped_force[:, pick], "--", label="lumped")
    m, a, f = table.rows[pick, :3]
    ax_t.set(xlabel="time (s)", ylabel="tendon force (N)")
    ax_t.set_title(f"worst range error: U = {m} + {a} sin(2 pi {f} t), vastus lateralis",
                   fontsize=9)
    ax_t.legend(fontsize=8)
    ax_tab.axis("off")
    cell = [[f"{v:.2f}" for v in row] for row in table.rows]
    labels = ["mean U", "amplitude", "f (Hz)", "transient RMS", "mean", "range"]
    tab = ax_tab.table(cellText=cell, colLabels=labels, loc="center", fontsize=7)
    tab.scale(1, 0.9)
    ax_tab.set_title("lumped - natural, % of natural F(U=1): transient = RMS over the first "
                     "cycle;\nmean and range = steady state (last two cycles)", fontsize=9)
    finish(fig, result, path)


def _step_ratios(ax, comparison, paper_law=None) -> None:
    """Lumped / natural energy (o) and impulse (s) per case, coloured by fibre mix."""
    cases = comparison.cases
    mixes = np.unique(cases[:, 0])
    colours = plt.cm.viridis(np.linspace(0, 0.9, len(mixes)))
    steps = [f"{a:g}->{b:g}" for a, b in cases[cases[:, 0] == mixes[0], 1:]]
    x = np.arange(len(steps))
    for colour, fs in zip(colours, mixes, strict=True):
        rows = cases[:, 0] == fs
        ax.plot(x, comparison.energy_ratio[rows], "o", color=colour, label=f"energy, {fs:.0%} slow")
        ax.plot(x, comparison.impulse_ratio[rows], "s", mfc="none", color=colour,
                label=f"impulse, {fs:.0%} slow")
    if paper_law is not None:
        ax.plot(np.tile(x, len(mixes)), paper_law.energy_ratio, "x", color="grey",
                label="energy, the paper's law")
    ax.axhspan(0.8, 1.25, color="grey", alpha=0.12, label="target 0.8-1.25")
    ax.axhline(1, color="grey", lw=0.5)
    ax.set_xticks(x, steps, fontsize=7)
    ax.set(xlabel="drive step", ylabel="lumped / natural over the first 0.25 s")
    ax.legend(fontsize=6, ncol=3, framealpha=0.5, loc="lower left")


def plot_lumped_steps(result: CheckResult, path: Path) -> None:
    d = result.data
    fig, axes = plt.subplots(2, 2, figsize=(13, 8.5))
    c = d["at_l0"]
    shown = c.cases[:, 0] == 0.36
    t = 1e3 * c.time_s
    colours = plt.cm.tab10(np.arange(shown.sum()))
    for colour, i in zip(colours, np.flatnonzero(shown), strict=True):
        a, b = c.cases[i, 1:]
        axes[0, 0].plot(t, c.natural_force[:, i], color=colour, lw=2, alpha=0.5,
                        label=f"{a:g}->{b:g}")
        axes[0, 0].plot(t, c.lumped_force[:, i], "--", color=colour, lw=1)
        axes[0, 1].plot(t, c.natural_energy_rate[:, i], color=colour, lw=2, alpha=0.5)
        axes[0, 1].plot(t, c.lumped_energy_rate[:, i], "--", color=colour, lw=1)
    axes[0, 0].set(xlabel="time after the step (ms)", ylabel="tendon force / F0")
    axes[0, 0].set_title(f"36 % slow, L0: natural (thick) vs lumped, {d['law']} (dashed)",
                         fontsize=9)
    axes[0, 0].legend(fontsize=7, ncol=3)
    axes[0, 1].set(xlabel="time after the step (ms)", ylabel="initial energy rate E_a + E_xb (W)")
    axes[0, 1].set_title("the same steps: initial energy rate", fontsize=9)
    _step_ratios(axes[1, 0], c, d.get("paper_law"))
    axes[1, 0].set_title("at L0 (grey x: the paper's law, tsianos2012)", fontsize=9)
    _step_ratios(axes[1, 1], d["at_long"])
    axes[1, 1].set_title("at 1.3 L0 (reported; W was fitted at L0)", fontsize=9)
    finish(fig, result, path, top=0.93)


def plot_held_out(result: CheckResult, path: Path) -> None:
    """Item 12: force RMS per case by family, and the per-jump and per-window energy ratios, for
    the default drive law and the paper's."""
    d = result.data
    families = list(dict.fromkeys(c.family for c in d["cases"]))
    family = np.array([c.family for c in d["cases"]])
    fig, axes = plt.subplots(1, 3, figsize=(14, 4.5))
    for offset, run, colour, label in ((-0.15, d["run"], "tab:blue", "default law"),
                                       (0.15, d["paper_law"], "grey", "tsianos2012 law")):
        for j, name in enumerate(families):
            values = run.force_rms_percent[family == name]
            axes[0].plot(np.full(len(values), j + offset), values, "o", color=colour, ms=4,
                         label=label if j == 0 else None)
        axes[1].hist(run.jump_energy_ratio, bins=50, range=(0.0, 2.0), histtype="step",
                     color=colour, label=label)
        axes[2].hist(run.window_energy_ratio, bins=50, range=(0.0, 2.0), histtype="step",
                     color=colour, label=label)
    axes[0].set_xticks(range(len(families)), families, rotation=30, fontsize=8)
    axes[0].set(ylabel="force RMS, % of F(U=1)")
    axes[0].legend(fontsize=8)
    for ax, what, band in ((axes[1], "per-jump initial energy, lumped / natural", (0.8, 1.25)),
                           (axes[2], "per-window total energy, lumped / natural", (0.9, 1.1))):
        for edge in band:
            ax.axvline(edge, color="k", lw=0.8, ls=":")
        ax.set(xlabel=what, ylabel="count")
        ax.legend(fontsize=8)
    finish(fig, result, path, top=0.8)


def plot_cost(result: CheckResult, path: Path) -> None:
    s, sizes = result.data["seconds_per_step"], result.data["sizes"]
    fig, ax = plt.subplots(figsize=(6, 4))
    for scheme, label in (("lumped", "lumped units"), ("natural", "natural, 20 units/type")):
        ax.loglog(sizes, [1e6 * s[(scheme, n)] for n in sizes], "o-", label=label)
    for n in sizes:
        ax.annotate(f"x{s[('natural', n)] / s[('lumped', n)]:.1f}",
                    (n, 1e6 * s[("natural", n)]), fontsize=8, xytext=(-8, 6),
                    textcoords="offset points")
    ax.set(xlabel="muscles in the bank", ylabel="median step time (us)")
    load = result.data.get("load_average")
    title = "labels: natural / lumped step time"
    if load is not None:
        title += "\n" + textwrap.fill(
            f"measured under load {load:.1f} (1-minute load average, "
            f"{result.data.get('cpus', '?')} CPUs): other work slows both and skews the ratio", 75)
    ax.set_title(title, fontsize=8)
    ax.legend(fontsize=8)
    finish(fig, result, path)


def _joint_row(axes, key, run) -> None:
    """One joint: normalised torque against the published data, torque in N m, operating point."""
    ax_n, ax_a, ax_l = axes
    s, settings = run["sweep"], run["settings"]
    angles, net = s.angles_deg, s.total()
    bands = JOINT_TORQUE_BANDS[key]
    what = settings["torque_name"]
    ax_n.axvspan(*bands["peak_deg"], color="tab:green", alpha=0.12,
                 label=f"criterion: peak in {bands['peak_deg'][0]:g}-{bands['peak_deg'][1]:g} deg")
    for angle, (low, high) in bands["ratio_at_deg"].items():
        ax_n.plot([angle, angle], [low, high], color="tab:green", lw=6, alpha=0.35,
                  solid_capstyle="butt")
    ax_n.plot([], [], color="tab:green", lw=6, alpha=0.35, label="criterion: ratio windows")
    markers = iter("osD^vP")
    for entry in settings["published"]:
        if entry["kind"] == "anderson_cosine":
            ax_n.plot(angles, published_ratio(entry, angles), lw=1.5, alpha=0.8,
                      label=entry["label"])
        else:
            ax_n.plot(entry["angles_deg"], published_ratio(entry, None), next(markers), ms=6,
                      mfc="none", mew=1.5, label=entry["label"])
    ax_n.plot(angles, net / net.max(), "k", lw=2.5, label="model (net: agonists U=1, others U=0)")
    ag = s.total("agonist")
    ax_n.plot(angles, ag / ag.max(), "k--", lw=1, label="model, agonists only")
    for label, v in run["variants"].items():
        ax_n.plot(angles, v.total() / v.total().max(), "k:", lw=1.2, label=f"model, {label}")
    ratios = ", ".join(f"{r:.2f} at {a:g}" for a, r in run["ratios"].items())
    ax_n.set_title(f"{settings['title']}\nmodel: peak at {run['peak_deg']:.0f} deg; {ratios} deg",
                   fontsize=9)
    ax_n.set(xlabel="joint angle (deg flexion, 0 = full extension)",
             ylabel=f"{what} / its peak", ylim=(-0.05, 1.15))
    ax_n.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.14), ncol=2)

    colours = plt.cm.tab10(np.arange(len(s.names)) % 10)
    ax_a.plot(angles, net, "k", lw=2.5, label="model, net")
    for i, name in enumerate(s.names):
        if s.roles[i] == "agonist":
            ax_a.plot(angles, s.torque_n_m[:, i], color=colours[i], lw=1.2,
                      label=f"{name} (F0 {run['f0_n'][i]:.0f} N)")
    ax_a.plot(angles, s.total("other"), color="tab:red", lw=1.5, ls="--",
              label="others, passive (U = 0), sum")
    ref = settings.get("absolute_reference")
    if ref and ref.get("kind") == "anderson_cosine":
        scale = ref["c1"] * ref["mass_kg"] * 9.81 * ref["height_m"]
        ax_a.plot(angles, scale * published_ratio(ref, angles), color="grey", lw=3,
                  alpha=0.5, label=ref["label"])
    elif ref:
        ax_a.plot(ref["angles_deg"], ref["torque_n_m"], "o", color="grey", ms=8, mfc="none",
                  mew=2, label=ref["label"])
    ax_a.axhline(0, color="grey", lw=0.5)
    ax_a.set(xlabel="joint angle (deg)", ylabel=f"{what} (N m)")
    ax_a.set_title(f"model peak {run['peak_n_m']:.1f} N m "
                   f"({run['peak_n_m'] / run['published_peak_n_m']:.2f} of the published peak); "
                   "others' passive torque down to "
                   f"{s.total('other').min():.1f} N m", fontsize=9)
    ax_a.set_ylim(min(0.0, 1.1 * s.total("other").min()), None)
    ax_a.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.14), ncol=2)

    ax_r = ax_l.twinx()
    for i, name in enumerate(s.names):
        if s.roles[i] == "agonist":
            ax_l.plot(angles, s.length_l0[:, i], color=colours[i], lw=1.5, label=f"{name}: L/L0")
            ax_r.plot(angles, 1e3 * np.abs(s.moment_arm_m[:, i]), color=colours[i], lw=1,
                      ls="--")
    ax_l.axhline(1.0, color="grey", lw=0.5)
    ax_l.set(xlabel="joint angle (deg)", ylabel="steady fascicle length at U = 1 (L0), solid")
    ax_r.set_ylabel("|moment arm| (mm), dashed (MuJoCo, exact)")
    worst = max(run["mismatch_l0"].items(), key=lambda kv: kv[1])
    ax_l.set_title(f"operating point; paths vs OpenSim source model within {worst[1]:.3f} L0 "
                   f"({worst[0]})", fontsize=9)
    ax_l.plot([], [], "k--", lw=1, label="|moment arm| (right axis)")
    ax_l.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.14), ncol=2)


def plot_joint_torque(result: CheckResult, path: Path) -> None:
    keys = list(result.data)
    fig, axes = plt.subplots(len(keys), 3, figsize=(16, 6.4 * len(keys)), squeeze=False)
    for row, key in zip(axes, keys, strict=True):
        _joint_row(row, key, result.data[key])
    finish(fig, result, path, top=0.965)


PLOTS = {"fig2": plot_fig2, "fig3": plot_fig3, "fig4": plot_fig4, "fig5": plot_fig5,
         "fig6": plot_fig6, "fig7": plot_fig7, "fig9": plot_fig9, "fig10": plot_fig10,
         "cost": plot_cost, "joint_torque": plot_joint_torque, "steps": plot_lumped_steps,
         "held_out": plot_held_out, "walk": plot_walk}
