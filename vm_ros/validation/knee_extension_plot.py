"""Figure of item 9, the 180 s knee extension (Fig. 7), for ``vm-ros validate``."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from vm_ros.validation.plot_style import finish, plt
from vm_ros.validation.results import CheckResult


def fig7_paper_comparison(total_j: float, run_s: float, paper_total_j: float,
                          paper_s: float) -> str:
    """The model's total against the paper's, like with like: the ratio only for a run as long as
    the paper's (the rate rises by about 40 % over it, so a shorter run's total, scaled or not,
    is not comparable)."""
    if abs(run_s - paper_s) > 1e-9 * paper_s:
        return (f"a shorter run: not comparable with the paper's {paper_total_j / 1e3:.0f} kJ "
                f"over {paper_s:g} s")
    return f"{total_j / paper_total_j:.2f} x the paper's {paper_total_j / 1e3:.0f} kJ"


def plot_fig7_table(ax, d: dict) -> None:
    """Cumulative total energy (kJ) against time for each row of the Fig. 7 table: colour the
    recruitment scheme and drive law, line style the recovery kernel; the paper's 35 kJ and the
    experiment's band at the paper's duration."""
    rows = d["table"]
    kernels = list(dict.fromkeys(r["recovery_kernel"] for r in rows))
    schemes = list(dict.fromkeys((r["recruitment"], r["drive_law"]) for r in rows))
    styles = {k: ("-", "--", ":", "-.")[i % 4] for i, k in enumerate(kernels)}
    colours = {s: f"C{i % 10}" for i, s in enumerate(schemes)}
    for r in rows:
        scheme = r["recruitment"] + ("" if r["drive_law"] == "-" else f" {r['drive_law']}")
        width_s = 2.0 * r["bin_time_s"][0]  # bins are centred: the first starts at 0
        ax.plot(r["bin_time_s"] + 0.5 * width_s, np.cumsum(r["total_rate_w"]) * width_s / 1e3,
                ls=styles[r["recovery_kernel"]],
                color=colours[r["recruitment"], r["drive_law"]],
                label=f"{scheme}, {r['recovery_kernel']}: {r['total_energy_j'] / 1e3:.1f} kJ, "
                      f"rise {r['total_rate_rise']:+.0%}")
    low, high = (e / 1e3 for e in d["experiment_band_j"])
    ax.errorbar([d["paper_duration_s"]], [d["paper_total_j"] / 1e3],
                yerr=[[d["paper_total_j"] / 1e3 - low], [high - d["paper_total_j"] / 1e3]],
                fmt="ks", ms=5, capsize=3, label="paper 35 kJ (experiment 30-40 kJ)")
    ax.set(xlabel="time (s)", ylabel="total energy, both muscles (kJ)", ylim=(0, None))
    ax.set_title("recruitment scheme x drive law x recovery kernel", fontsize=9)
    ax.legend(fontsize=6, loc="upper left")


def plot_fig7(result: CheckResult, path: Path) -> None:
    d = result.data
    with_table = bool(d.get("table"))
    fig, axes = plt.subplots(1, 3 + with_table, figsize=(15 + 5 * with_table, 5.8),
                             gridspec_kw={"width_ratios": [1.4, 1, 1] + [1.3] * with_table})
    ax, ax_act, ax_v = axes[:3]
    if with_table:
        plot_fig7_table(axes[3], d)
    labels = ("activation", "cross-bridge", "recovery", "total")
    for k, label in enumerate(labels):
        ax.plot(d["time"], d["bins"][:, k], label=label)
    ax.plot(d["time"], d["bins"][:, 0] + d["bins"][:, 1], "k--", lw=1, label="initial")
    duration = d["paper_duration_s"]
    paper_w = d["paper_total_j"] / duration
    low, high = (e / duration for e in d["experiment_band_j"])
    ax.axhspan(low, high, color="grey", alpha=0.15,
               label=f"mean rate of the experiment's 30-40 kJ over {duration:g} s "
                     f"({low:.0f}-{high:.0f} W)")
    ax.axhline(paper_w, color="grey", ls=":", label=f"mean rate of the paper's 35 kJ over "
               f"{duration:g} s ({paper_w:.0f} W)")
    ax.set(xlabel="time (s)", ylabel="energy rate, 1 s bins (W), rectus femoris + vasti",
           ylim=(0, None))
    work = float(np.sum(d["work_j"]))
    run_s = d["duration_s"]
    versus = fig7_paper_comparison(d["total_energy_j"], run_s, d["paper_total_j"], duration)
    ax.set_title(f"model, {run_s:g} s: total {d['total_energy_j'] / 1e3:.1f} kJ\n{versus}\n"
                 f"net fascicle work {work / 1e3:.2f} kJ ({work / run_s:.0f} W); "
                 f"quadriceps {np.sum(d['mass_kg']):.2f} kg", fontsize=9)
    # below the panel: inside, it covered the total energy rate
    ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.14), ncol=2)
    c = d["cycle"]
    t = c["time_s"] - c["time_s"][0]
    colours = ("tab:purple", "tab:green")
    for i, name in enumerate(d["names"]):
        ax_act.plot(t, c["activation"][:, i], color=colours[i],
                    label=f"{name}: Acteff / steady at U = 0.8")
        ax_act.plot(t, c["force_f0"][:, i], "--", color=colours[i],
                    label=f"{name}: tendon force (F0)")
        ax_v.plot(t, c["velocity_l0_per_s"][:, i], color=colours[i], label=f"{name}: velocity")
    ax_act.plot(t, c["drive"][:, 0], "k", lw=1, label="drive U")
    ax_act.plot(t, c["effective_drive"][:, 1], "k:", lw=1, label="Ueff (lumped filter, vasti)")
    ax_act.set(xlabel="time in the last cycle (s)", ylabel="fraction",
               ylim=(0, 1.05))
    ax_act.set_title("one cycle: drive on for 0.25 s; activation and force", fontsize=9)
    ax_act.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.17), ncol=2)
    ax_v.axhline(0, color="grey", lw=0.5)
    ax_v.set(xlabel="time in the last cycle (s)", ylabel="fascicle velocity (L0/s, < 0 shortening)")
    ax_e = ax_v.twinx()
    ax_e.plot(t, c["energy_rate_w"].sum(axis=1), color="tab:red", lw=1, label="total energy rate")
    ax_e.set_ylabel("total energy rate, both muscles (W)", color="tab:red")
    ax_v.set_title("one cycle: fascicle velocity and energy rate", fontsize=9)
    # one legend for both axes, below the panel (inside, the legends covered the curves)
    lines = ax_v.get_legend_handles_labels()
    rate = ax_e.get_legend_handles_labels()
    ax_v.legend(lines[0] + rate[0], lines[1] + rate[1], fontsize=7, loc="upper center",
                bbox_to_anchor=(0.5, -0.17), ncol=3)
    finish(fig, result, path)
