"""Figure of the ``walk`` item: per solution, target against muscle moments of hip, knee and
ankle (right), the right-leg drives over the gait cycle with the EMG windows of
config/walk_validation.yaml, and the metabolic power beside the calorimetric references and
OpenSim's Umberger probe."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from vm_ros.validation.plot_style import finish, plt
from vm_ros.validation.results import CheckResult
from vm_ros.validation.walk import TRACKED, load_walk_config
from vm_ros.validation.walk_reference import cycle_percent

RIGHT = [c for c in TRACKED if c.endswith("_r")]


def plot_walk(result: CheckResult, path: Path) -> None:
    config, _ = load_walk_config()
    labels = [k for k, v in result.data.items() if isinstance(v, dict) and "solution" in v]
    context = result.data["context"]
    fig, axes = plt.subplots(len(labels), 5, figsize=(22, 4.2 * len(labels)), squeeze=False)
    for row, label in zip(axes, labels, strict=True):
        entry = result.data[label]
        s = entry["solution"]
        inside, percent = cycle_percent(s.times_s, context["strikes"])
        for ax, name in zip(row[:3], RIGHT, strict=True):
            j = s.coordinates.index(name)
            ax.plot(percent[inside], s.targets_nm[inside, j], "k-", label="inverse dynamics")
            ax.plot(percent[inside], s.moments_nm[inside, j], "C0--", label="muscles (forward)")
            t = entry["tracking"][name]
            ax.set_title(f"{label}: {name}\nRMS {100 * t['rms_of_peak']:.1f} % of peak, "
                         f"{t['spikes']} spike frames", fontsize=8)
            ax.set_xlabel("% gait cycle (right)")
            ax.set_ylabel("N m")
        row[0].legend(fontsize=7)
        ax = row[3]
        for k, key in enumerate(config["emg_timing"]):
            name = f"{key}_r"
            if name not in s.muscles:
                continue
            u = s.drives[inside, s.muscles.index(name)]
            span = max(float(np.ptp(u)), 1e-12)
            ax.plot(percent[inside], k + (u - u.min()) / span * 0.8, f"C{k}")
            windows = config["emg_timing"][key]
            ax.axvspan(*windows["active"], ymin=(k + 0.05) / 6, ymax=(k + 0.85) / 6,
                       color=f"C{k}", alpha=0.15)
            ax.text(101, k + 0.3, name, fontsize=7)
        ax.set_ylim(0, 6)
        ax.set_xlim(0, 115)
        ax.set_title("drives over the cycle (normalised); shaded: EMG active windows",
                     fontsize=8)
        ax.set_xlabel("% gait cycle (right)")
        ax = row[4]
        bars = {f"{label}": entry["metabolic_w_per_kg"], **entry["metabolic_references"],
                "OpenSim Umberger (CMC)": context["umberger"]["per_kg"]}
        ax.barh(list(bars), list(bars.values()), color=["C0"] + ["0.6"] * (len(bars) - 1))
        ax.set_xlabel("net metabolic power (W/kg)")
        ax.tick_params(axis="y", labelsize=7)
    finish(fig, result, path, top=0.93)
