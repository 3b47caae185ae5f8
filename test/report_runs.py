"""Run inputs with many muscles for the report tests: a muscle library of N muscles (copies of
the shipped library's, renamed) and a CSV of drive and path length for `vm-ros simulate
--inputs`, gait-like (one 1.1 s cycle per muscle, each at its own phase and amplitude, some too
weak to recruit fast fibres)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import yaml

from vm_ros.model.params import load_muscle_library

# the right and left leg muscles of a planar 18-muscle gait model
GAIT_18 = tuple(f"{m}_{side}" for side in "rl" for m in (
    "hamstrings", "bifemsh", "glut_max", "iliopsoas", "rect_fem", "vasti", "gastroc", "soleus",
    "tib_ant"))
CYCLE_S = 1.1


def muscle_run_names(n: int) -> list[str]:
    """n muscle names: the gait model's 18 when n == 18, else numbered copies of them."""
    if n == len(GAIT_18):
        return list(GAIT_18)
    return [f"{GAIT_18[k % len(GAIT_18)]}_{k // len(GAIT_18)}" for k in range(n)]


def write_muscle_run(folder: Path, n: int, duration_s: float, rate_hz: float = 200.0):
    """(library path, inputs CSV path) for an n-muscle run of duration_s."""
    shipped = load_muscle_library()
    bases = list(shipped)
    names = muscle_run_names(n)
    library = {name: dict(shipped[bases[k % len(bases)]]) for k, name in enumerate(names)}
    library_path = folder / f"muscles{n}.yaml"
    library_path.write_text(yaml.safe_dump({"muscles": library}, sort_keys=False))
    t = np.arange(0.0, duration_s + 0.5 / rate_hz, 1.0 / rate_hz)
    columns, blocks = ["time_s"], [t]
    for k, name in enumerate(names):
        spec = library[name]
        phase = 2 * np.pi * k / n
        wave = np.sin(2 * np.pi * t / CYCLE_S + phase)
        amplitude = 0.15 if k % 3 == 2 else 0.9  # every third muscle: slow fibres only
        low, high = spec["path_length_min_m"], spec["path_length_max_m"]
        columns += [f"{name}.excitation", f"{name}.path_length"]
        blocks += [0.02 + amplitude * np.maximum(wave, 0.0),
                   0.5 * (low + high) + 0.3 * (high - low) * np.cos(2 * np.pi * t / CYCLE_S
                                                                    + phase)]
    csv_path = folder / f"inputs{n}.csv"
    np.savetxt(csv_path, np.column_stack(blocks), delimiter=",", header=",".join(columns),
               comments="", fmt="%.9g")
    return library_path, csv_path
