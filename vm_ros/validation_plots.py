"""Figures for ``vm-ros validate``: one PNG per check, the paper's claim in the title (matplotlib,
Agg backend; imported only when plotting)."""

from __future__ import annotations

import textwrap
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from vm_ros.validation import CheckResult  # noqa: E402


def _finish(fig, result: CheckResult, path: Path) -> None:
    status = "PASS" if result.passed else "FAIL"
    claim = textwrap.fill(f"Paper: {result.claim}", 150)
    fig.suptitle(f"{result.title}  [{status}]\n{claim}", fontsize=9)
    fig.tight_layout(rect=(0, 0, 1, 0.9))
    fig.savefig(path, dpi=100)
    plt.close(fig)


def plot_fig2(result: CheckResult, path: Path) -> None:
    fig, ax = plt.subplots(figsize=(7, 4.5))
    for name, colour in (("slow", "tab:blue"), ("fast", "tab:red")):
        d = result.data[name]
        ax.plot(d["velocity"], d["barclay"], color=colour, lw=3, alpha=0.4,
                label=f"Barclay 1996 fit, {name}")
        ax.plot(d["velocity"], d["model"], "o", color=colour, ms=4, label=f"model, 100 % {name}")
    ax.set(xlabel="fascicle velocity (L0/s, negative = shortening)",
           ylabel="tetanic initial energy rate (W/kg dry)")
    ax.axvline(0, color="grey", lw=0.5)
    ax.legend(fontsize=8)
    _finish(fig, result, path)


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
                     label=f"{name}: total")
        axes[1].plot(c["velocity"], np.array(c["e_a_velocity"]) * per_kg, "--", color=colour,
                     label=f"{name}: activation")
        axes[2].plot(c["length"], np.array(c["total_length"]) * per_kg, "o-", color=colour,
                     label=f"{name}: total")
        axes[2].plot(c["length"], np.array(c["e_a_length"]) * per_kg, "--", color=colour,
                     label=f"{name}: activation")
    axes[0].set(xlabel="drive U (isometric, L0)", ylabel="energy rate (W/kg wet)")
    axes[1].set(xlabel="fascicle velocity (L0/s), U = 1", ylabel="energy rate (W/kg wet)")
    axes[2].set(xlabel="fascicle length (L0), isometric, U = 1", ylabel="energy rate (W/kg wet)")
    ratio = result.data["per_newton"]["fast"] / result.data["per_newton"]["slow"]
    axes[0].set_title(f"fast/slow energy per newton: {ratio.min():.1f}-{ratio.max():.1f}",
                      fontsize=9)
    for ax in axes:
        ax.legend(fontsize=7)
    _finish(fig, result, path)


def plot_fig4(result: CheckResult, path: Path) -> None:
    d = result.data
    fig, (ax_f, ax_e) = plt.subplots(1, 2, figsize=(12, 4.5))
    colours = plt.cm.viridis(np.linspace(0, 0.9, len(d["drive"])))
    for i, u in enumerate(d["drive"]):
        ax_f.plot(d["velocity"], 100 * d["force_f0"][i], "o-", ms=3, color=colours[i],
                  label=f"drive {u:.0%}")
        ax_e.plot(d["velocity"], d["energy_w"][i], "o-", ms=3, color=colours[i],
                  label=f"drive {u:.0%}; {d['w_per_n'][i]:.3f} W/N isometric")
    ax_f.set(xlabel="fascicle velocity (L0/s, negative = shortening)", ylabel="force (% F0)")
    ax_e.set(xlabel="fascicle velocity (L0/s, negative = shortening)",
             ylabel="total energy rate (W)")
    ax_f.set_title(f"biceps long head analogue: F0 {d['f0_n']:.0f} N, L0 {d['l0_m']:.4f} m, "
                   "40 % slow", fontsize=9)
    for ax in (ax_f, ax_e):
        ax.axvline(0, color="grey", lw=0.5)
        ax.legend(fontsize=7)
    _finish(fig, result, path)


def plot_fig5(result: CheckResult, path: Path) -> None:
    d = result.data
    fig, ax = plt.subplots(figsize=(7.5, 4.8))
    for u, marker in ((1.0, "o"), (0.8, "s")):
        ax.plot(d["fast_percent"], 1e3 * d["rates_k_per_s"][u], marker, label=f"U = {u} at MVC")
    for x, y, name in zip(d["fast_percent"], 1e3 * d["rates_k_per_s"][1.0], d["names"],
                          strict=True):
        ax.annotate(name, (x, y), fontsize=6, xytext=(3, 3), textcoords="offset points")
    ax.set(xlabel="fast fibres (% PCSA)", ylabel="temperature rate at MVC (mK/s)")
    ax.legend(fontsize=8)
    _finish(fig, result, path)


def plot_fig6(result: CheckResult, path: Path) -> None:
    fig, ax = plt.subplots(figsize=(7, 4.5))
    for u, (_levels, force_pct, rate) in result.data["series"].items():
        ax.plot(force_pct, 1e3 * rate, "o-", label=f"U = {u} at MVC")
    ax.set(xlabel="isometric force (% MVC)", ylabel="temperature rate (mK/s)")
    ax.legend(fontsize=8)
    _finish(fig, result, path)


def plot_fig7(result: CheckResult, path: Path) -> None:
    d = result.data
    fig, ax = plt.subplots(figsize=(8, 4.5))
    labels = ("activation", "cross-bridge", "recovery", "total")
    for k, label in enumerate(labels):
        ax.plot(d["time"], d["bins"][:, k], label=label)
    ax.plot(d["time"], d["bins"][:, 0] + d["bins"][:, 1], "k--", lw=1, label="initial")
    ax.set(xlabel="time (s)", ylabel="energy rate, 1 s bins (W), rectus femoris + vasti")
    ax.set_title(f"total energy {d['total_energy_j']:.0f} J", fontsize=9)
    ax.legend(fontsize=8)
    _finish(fig, result, path)


def plot_fig9(result: CheckResult, path: Path) -> None:
    c = result.data["comparison"]
    fig, ax = plt.subplots(figsize=(7, 4.5))
    colours = plt.cm.viridis(np.linspace(0, 0.9, len(c.fpcsa_slow)))
    for i, fs in enumerate(c.fpcsa_slow):
        nat = c.natural.sum(-1)[:, i]
        ax.plot(c.drive, nat / nat[-1], color=colours[i], lw=2.5, alpha=0.5,
                label=f"natural, {fs:.0%} slow")
        ax.plot(c.drive, c.lumped.sum(-1)[:, i] / nat[-1], "--", color=colours[i], lw=1)
    ax.set(xlabel="drive U", ylabel="steady isometric force at L0 / natural F(U=1)")
    ax.set_title("natural units (50/type, thick) vs lumped (dashed)", fontsize=9)
    ax.legend(fontsize=7)
    _finish(fig, result, path)


def plot_fig10(result: CheckResult, path: Path) -> None:
    table = result.data["table"]
    fig, (ax_t, ax_tab) = plt.subplots(1, 2, figsize=(13, 4.5),
                                       gridspec_kw={"width_ratios": [1.2, 1]})
    cols = list(table.columns)
    pick = int(np.argmax(np.abs(table.rows[:, cols.index("range_error")])))
    ax_t.plot(table.time_s, table.natural_force[:, pick], lw=2, alpha=0.6, label="natural")
    ax_t.plot(table.time_s, table.lumped_force[:, pick], "--", label="lumped")
    m, a, f = table.rows[pick, :3]
    ax_t.set(xlabel="time (s)", ylabel="tendon force (N)",
             title=f"worst case: U = {m} + {a} sin(2 pi {f} t), vastus lateralis")
    ax_t.legend(fontsize=8)
    ax_tab.axis("off")
    cell = [[f"{v:.2f}" for v in row] for row in table.rows]
    tab = ax_tab.table(cellText=cell, colLabels=["mean U", "amp", "Hz", "transient", "mean",
                                                  "range"], loc="center", fontsize=7)
    tab.scale(1, 0.9)
    ax_tab.set_title("errors, % of natural F(U=1)", fontsize=9)
    _finish(fig, result, path)


def plot_cost(result: CheckResult, path: Path) -> None:
    s, sizes = result.data["seconds_per_step"], result.data["sizes"]
    fig, ax = plt.subplots(figsize=(6, 4))
    for scheme in ("lumped", "natural"):
        ax.loglog(sizes, [1e6 * s[(scheme, n)] for n in sizes], "o-", label=scheme)
    ax.set(xlabel="muscles in the bank", ylabel="median step time (us)")
    ax.legend(fontsize=8)
    _finish(fig, result, path)


PLOTS = {"fig2": plot_fig2, "fig3": plot_fig3, "fig4": plot_fig4, "fig5": plot_fig5,
         "fig6": plot_fig6, "fig7": plot_fig7, "fig9": plot_fig9, "fig10": plot_fig10,
         "cost": plot_cost}
