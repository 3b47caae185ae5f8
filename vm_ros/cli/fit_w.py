"""Refit the lumped units' weighting W (and optionally the constants of the drive filter's law)
from the natural-units model, for a recruitment range Ur and a grid of fibre mixes, and report how
well the starting coefficients (W: Tsianos 2012's, fitted for Ur = 0.8) and the refit match natural
units.

Writes, in --out: fit_w.csv (max error per fibre mix, published vs refit), fit_w.png (lumped vs
natural isometric force-drive curves), and model_fit_w.yaml: a copy of the model parameter file
with the refit W, usable as `--params` / `params=` elsewhere. With --drive-filter also
model_drive_filter.yaml: the parameter file with the drive filter's constants refit (with the
file's own W, over lumped_fit.DRIVE_FILTER_GRID, from lumped_fit.DRIVE_FILTER_START, rounded to
the printed digits: the shipped config/model.yaml holds this fit's output), and
drive_filter_steps.csv: the refit law on drive steps the fit did not see (lumped / natural
initial energy and force impulse over 0.25 s, full model, at L0), and the paper's Fig. 10
sinusoids; it also prints the held-out drives' summary (validation item 12).
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import yaml

from vm_ros.model import load_model_params
from vm_ros.model.lumped_fit import (
    DEFAULT_FPCSA_GRID,
    DRIVE_FILTER_FPCSA,
    DRIVE_FILTER_GRID,
    DRIVE_FILTER_START,
    DRIVE_FILTER_UR,
    W_FIELDS,
    compare_sinusoidal,
    compare_steps,
    fit_drive_filter,
    fit_weighting,
    with_drive_law,
    with_lumped,
)
from vm_ros.model.params import DRIVE_LAWS, resolve_muscles
from vm_ros.resources import config_dir
from vm_ros.validation.held_out import (
    HELD_OUT_SEEDS,
    compare_held_out,
    held_out_cases,
    held_out_summary,
)


def add_arguments(parser) -> None:
    parser.add_argument("--ur", type=float, default=0.8,
                        help="drive at which all units are recruited (default 0.8)")
    parser.add_argument("--fpcsa-slow", type=float, nargs="+", default=list(DEFAULT_FPCSA_GRID),
                        metavar="F", help="slow PCSA fractions to fit W over (default 0.2 ... "
                        "0.8; the drive filter has its own grid, lumped_fit.DRIVE_FILTER_GRID)")
    parser.add_argument("--units", type=int, default=50,
                        help="natural units per fibre type in the reference ensemble (default 50)")
    parser.add_argument("--drive-filter", action="store_true",
                        help="also refit the drive filter's law against natural units through "
                             "steps, sinusoids, pulse trains and ramps (with the parameter file's "
                             "W, Fpcsa_S x Ur of lumped_fit.DRIVE_FILTER_GRID), and check it on "
                             "the validation drives (~10-20 min)")
    parser.add_argument("--drive-law", choices=DRIVE_LAWS, default=None,
                        help="the drive filter's law to fit and write (default: the parameter "
                             "file's recruitment.lumped.drive_law)")
    parser.add_argument("--params", type=Path, default=None,
                        help="model parameter YAML to start from (default: the shipped one)")
    parser.add_argument("--out", type=Path, default=Path("out/fit-w"),
                        help="output folder (default out/fit-w)")
    parser.add_argument("--no-plot", action="store_true", help="skip the PNG")


# significant digits of the drive filter's constants as printed and written (and shipped)
FILTER_DIGITS = 4


def _rounded(value, rounding):
    if isinstance(value, tuple):
        return tuple(rounding(float(v)) for v in value)
    return rounding(float(value))


def _significant(value):
    return _rounded(value, lambda v: float(f"{v:.{FILTER_DIGITS}g}"))


def _write_params_yaml(source: Path, lumped, fields, rounding, how: str, path: Path) -> None:
    data = yaml.safe_load(source.read_text(encoding="utf-8"))
    section = data["recruitment"]["lumped"]
    section["drive_law"]["value"] = lumped.drive_law
    for name in fields:
        value = rounding(getattr(lumped, name))
        section[name] = {
            "value": list(value) if isinstance(value, tuple) else value,
            "unit": section[name]["unit"], "tag": "R",
            "source": f"{how}; value before the fit {section[name]['value']}",
        }
    path.write_text(yaml.safe_dump(data, sort_keys=False, width=100), encoding="utf-8")


def _held_out(params, start_params, ur: float, path: Path) -> None:
    """The refit law against natural units on drives the fit did not see, before and after."""
    muscle = resolve_muscles(["vastus_lateralis"], None, None, ur)[0]
    rows, summary = [], []
    for label, p in (("before", start_params), ("refit", params)):
        steps = compare_steps(p, ur=ur)
        sines = compare_sinusoidal(p, muscle, cycles=3)
        rows += [[label, *case, e, f] for case, e, f in
                 zip(steps.cases, steps.energy_ratio, steps.impulse_ratio, strict=True)]
        worst = np.abs(sines.rows[:, 3:]).max(axis=0)
        summary.append((label, steps, worst))
    with open(path, "w", newline="", encoding="utf-8") as handle:
        writer = csv.writer(handle)
        writer.writerow(["law_constants", "fpcsa_slow", "drive_before", "drive_after",
                         "energy_ratio", "impulse_ratio"])
        writer.writerows([[r[0]] + [f"{v:.4f}" for v in r[1:]] for r in rows])
    cases = held_out_cases()
    held_out = compare_held_out(start_params, cases, (start_params, params))
    print("\nvalidation drives, lumped / natural over the first 0.25 s after a step (full model, "
          "L0) and the paper's Fig. 10 sinusoids (worst |error|, % F(U=1))")
    for label, steps, worst in summary:
        e, f = steps.energy_ratio, steps.impulse_ratio
        print(f"  {label:6}  initial energy {e.min():.2f}-{e.max():.2f} (median "
              f"{np.median(e):.3f}), force impulse {f.min():.2f}-{f.max():.2f} (median "
              f"{np.median(f):.3f}); Fig. 10 transient {worst[0]:.2f}, mean {worst[1]:.2f}, "
              f"range {worst[2]:.2f}")
    print(f"held-out drives (vm-ros validate --only held_out, seeds {HELD_OUT_SEEDS[0]}-"
          f"{HELD_OUT_SEEDS[-1]}), % of F(U=1)")
    for (label, *_), run in zip(summary, held_out, strict=True):
        print(f"  {label:6}  {held_out_summary(cases, run)}")


def _fit_drive_filter(params, source, args) -> list[Path]:
    """The drive filter's fit (the parameter file's W), its constants printed and written to
    model_drive_filter.yaml to FILTER_DIGITS significant digits, and its checks."""
    law = params.lumped.drive_law
    print(f"\nfitting the drive filter ({law}) against 20 natural units per type through steps, "
          f"sinusoids, pulse trains and ramps, Fpcsa_S {DRIVE_FILTER_FPCSA} x Ur "
          f"{DRIVE_FILTER_UR} ...")
    dyn = fit_drive_filter(params, start=DRIVE_FILTER_START[law])
    fitted = with_lumped(params, **{name: _significant(getattr(dyn.params.lumped, name))
                                    for name in dyn.fields})
    print(f"  least_squares status {dyn.status} after {dyn.evaluations} evaluations; training "
          f"RMS % of natural F(U=1) per muscle: start {dyn.rms_start_percent.max():.3f} worst, "
          f"fitted {np.median(dyn.rms_fitted_percent):.3f} median, "
          f"{dyn.rms_fitted_percent.max():.3f} worst")
    for name in dyn.fields:
        print(f"  {name}: {getattr(fitted.lumped, name)} (the parameter file's: "
              f"{getattr(params.lumped, name)})")
    path = args.out / "model_drive_filter.yaml"
    how = ("vm-ros fit-w --drive-filter: least squares against 20 natural units per type, "
           f"Fpcsa_S {min(DRIVE_FILTER_FPCSA)}-{max(DRIVE_FILTER_FPCSA)} x Ur "
           f"{min(DRIVE_FILTER_UR)}-{max(DRIVE_FILTER_UR)} ({len(DRIVE_FILTER_GRID)} muscles), "
           "lumped_fit.training_drive_series; docs/model.md section 5d")
    _write_params_yaml(Path(source), fitted.lumped, dyn.fields, _significant, how, path)
    _held_out(fitted, params, 0.8, args.out / "drive_filter_steps.csv")
    return [path, args.out / "drive_filter_steps.csv"]


def _plot(fit, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax_force, ax_err) = plt.subplots(1, 2, figsize=(12, 4.8))
    colours = plt.cm.viridis(np.linspace(0, 0.9, len(fit.published.fpcsa_slow)))
    for i, fs in enumerate(fit.published.fpcsa_slow):
        nat = fit.published.natural.sum(-1)[:, i]
        ax_force.plot(fit.published.drive, nat / nat[-1], color=colours[i], lw=2,
                      label=f"natural, slow {fs:.0%}")
        ax_force.plot(fit.published.drive, fit.published.lumped.sum(-1)[:, i] / nat[-1], "--",
                      color=colours[i], lw=1)
        ax_err.plot(fit.published.drive, fit.published.error_percent[:, i], "--", color=colours[i])
        ax_err.plot(fit.fitted.drive, fit.fitted.error_percent[:, i], color=colours[i])
    ax_force.set(xlabel="drive U", ylabel="isometric force at L0 / natural F(U=1)",
                 title="Lumped (dashed, published W) vs natural units")
    ax_force.legend(fontsize=7)
    ax_err.axhline(2, color="grey", lw=0.5)
    ax_err.axhline(-2, color="grey", lw=0.5)
    ax_err.set(xlabel="drive U", ylabel="lumped - natural (% of natural F(U=1))",
               title="lumped - natural: published W (dashed), refit W (solid)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def run(args) -> int:
    source = args.params or config_dir() / "model.yaml"
    params = load_model_params(source)
    args.out.mkdir(parents=True, exist_ok=True)
    print(f"fitting W for Ur = {args.ur} against {args.units} natural units per fibre type ...")
    fit = fit_weighting(params, ur=args.ur, fpcsa_slow_grid=args.fpcsa_slow,
                        units_per_type=args.units)
    header = ["fpcsa_slow", "published_max_error_percent", "refit_max_error_percent"]
    published, refit = fit.published.max_error_percent, fit.fitted.max_error_percent
    rows = [[fs, p, f] for fs, p, f in zip(fit.published.fpcsa_slow, published, refit,
                                           strict=True)]
    with open(args.out / "fit_w.csv", "w", newline="", encoding="utf-8") as handle:
        writer = csv.writer(handle)
        writer.writerow(header)
        writer.writerows([[f"{v:.4f}" for v in row] for row in rows])
    print(f"\nsteady-state isometric force at L0, max |lumped - natural| in % of natural F(U=1), "
          f"Ur = {args.ur}")
    print("  " + "  ".join(f"{h:>28}" for h in header))
    for row in rows:
        print("  " + "  ".join(f"{v:28.3f}" for v in row))
    _write_params_yaml(Path(source), fit.params.lumped, W_FIELDS,
                       lambda v: _rounded(v, lambda c: round(c, 6)),
                       f"vm-ros fit-w: least squares against {args.units} natural units per "
                       f"type, Ur = {args.ur}", args.out / "model_fit_w.yaml")
    written = [args.out / "fit_w.csv", args.out / "model_fit_w.yaml"]
    if args.drive_filter:
        written += _fit_drive_filter(params if args.drive_law is None
                                     else with_drive_law(params, args.drive_law), source, args)
    if not args.no_plot:
        try:
            _plot(fit, args.out / "fit_w.png")
            written.append(args.out / "fit_w.png")
        except ImportError:
            print("matplotlib is not installed: no plot (pip install 'vm_ros[plot]')")
    print("\nwrote " + ", ".join(str(p) for p in written))
    return 0
