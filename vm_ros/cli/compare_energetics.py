"""Every published energetics model (vm_ros.model.energetics_models) against Tsianos 2012 on the
same Virtual Muscle runs: an isometric drive sweep (fascicle held at L0), an isovelocity sweep
(shortening and lengthening at a fixed drive), the paper's 180 s knee extension and a gait-like
cycle (ours), each for slow, mixed, fast and library fibre compositions
(docs/energetics_models.md section 8).

Writes into --out (default ./compare-energetics/): energetics_comparison.csv (one row per model x
scenario x composition: energy in J, its ratio to Tsianos 2012, mean rate in W) and, unless
--no-plots (or without matplotlib, pip install 'vm_ros[plot]'), knee_extension_rates.png (1 s
bins, every model against Tsianos 2012, one panel per composition) and one bar chart per scenario
group (ratio_<group>.png, log y axis). The table is printed; the wall time of the whole run is
reported. The scenario constants come from config/energetics_compare.yaml (--config FILE: another
file of that layout); --duration, --scenarios, --compositions and --models override them.
"""

from __future__ import annotations

import dataclasses
import sys
import time
from pathlib import Path

import numpy as np

from vm_ros.errors import VmRosError
from vm_ros.model.energetics_models.vm_state import MODEL_NAMES
from vm_ros.validation.energetics_compare import (
    COMPOSITION_NAMES,
    FILE_NAME,
    GROUPS,
    TSIANOS,
    ComparisonSettings,
    format_table,
    load_comparison_settings,
    table_rows,
    timed_comparison,
    with_duration,
    write_figures,
    write_table,
)

TABLE_NAME = "energetics_comparison.csv"


def add_arguments(parser) -> None:
    parser.add_argument("--out", type=Path, default=Path("compare-energetics"),
                        help="output folder (default ./compare-energetics)")
    parser.add_argument("--config", type=Path, default=None, metavar="FILE",
                        help=f"scenario constants (default the shipped config/{FILE_NAME})")
    parser.add_argument("--duration", default=None,
                        help="knee-extension duration in s (default the config's: 180, the "
                             "paper's); the gait-like cycle is cut to it too")
    parser.add_argument("--scenarios", nargs="+", default=list(GROUPS), metavar="GROUP",
                        help=f"scenario groups (default all: {', '.join(GROUPS)})")
    parser.add_argument("--compositions", nargs="+", default=list(COMPOSITION_NAMES),
                        metavar="NAME",
                        help=f"fibre compositions (default all: {', '.join(COMPOSITION_NAMES)}; "
                             f"slow fractions in the config, library the muscles' own)")
    parser.add_argument("--models", nargs="+", default=list(MODEL_NAMES), metavar="MODEL",
                        help=f"published models (default all: {', '.join(MODEL_NAMES)})")
    parser.add_argument("--no-plots", action="store_true", help="skip the figures")


def _positive(name: str, text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise VmRosError(f"--{name} must be a number of seconds (got {text!r})") from None
    if not np.isfinite(value) or value <= 0.0:
        raise VmRosError(f"--{name} must be > 0 s (got {text})")
    return value


def _subset(name: str, given, known) -> tuple:
    unknown = [g for g in given if g not in known]
    if unknown:
        raise VmRosError(f"--{name}: unknown {unknown[0]!r}; known: {', '.join(known)}")
    return tuple(dict.fromkeys(given))


def settings_from_args(args) -> ComparisonSettings:
    """The config file's settings (--config or the shipped one) with the options applied."""
    settings = load_comparison_settings(args.config)
    if args.duration is not None:
        settings = with_duration(settings, _positive("duration", args.duration))
    return dataclasses.replace(
        settings,
        groups=_subset("scenarios", args.scenarios, GROUPS),
        compositions=_subset("compositions", args.compositions, COMPOSITION_NAMES),
        models=_subset("models", args.models, MODEL_NAMES))


def _progress(done: int, total: int, label: str) -> None:
    print(f"[{done}/{total}] {label}", file=sys.stderr, flush=True)


def run(args) -> int:
    started = time.monotonic()
    settings = settings_from_args(args)
    try:
        args.out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise VmRosError(f"--out {args.out}: cannot create ({exc.strerror or exc})") from None
    results, wall_s = timed_comparison(settings, _progress)
    path = args.out / TABLE_NAME
    write_table(table_rows(results), path)
    print("energy relative to Tsianos 2012 (Tsianos 2012 in J)")
    print(format_table(results, settings.models))
    print(f"table: {path}")
    if not args.no_plots:
        try:
            figures = write_figures(results, settings, args.out)
        except ImportError:
            print("matplotlib is not installed: no figures (pip install 'vm_ros[plot]')",
                  file=sys.stderr)
        else:
            for figure in figures:
                print(f"figure: {figure}")
    print(f"wall time: {time.monotonic() - started:.1f} s in all, of which the model runs "
          f"{wall_s:.1f} s (the rest: the table and the figures)")
    return 0


__all__ = ["TABLE_NAME", "TSIANOS", "add_arguments", "run", "settings_from_args"]
