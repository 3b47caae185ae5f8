"""Lumped units against natural units (Tsianos 2012 Appendix A, Figs. 9-10) and the W refit.

Targets: Fig. 9 steady-state isometric force at L0, drive 0-1, Fpcsa_S 0.2-0.8: max error within
2 % of F(U=1) (issue 2; the paper: "nearly identical"). Measured when written, against 50 natural
units per type: 0.85-1.53 % with the published W, 0.41-0.92 % after `fit-w`.
Fig. 10 sinusoidal drive (vastus lateralis, 20 units per type, means 0.3/0.5, amplitudes 0.1/0.2,
0.5-4 Hz): measured worst transient RMS 2.4 %, mean-force 2.0 %, modulation-range 5.0 % of F(U=1);
the thresholds held below (3 %, 3 %, 6 %) leave a quarter of headroom for platform differences
while still failing if the lumped filter or W were off by a visible amount.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from vm_ros.cli import main as cli_main
from vm_ros.model import load_model_params
from vm_ros.model.lumped_fit import (
    FILTER_FIELDS,
    compare_sinusoidal,
    compare_steady,
    drive_filter_rms_percent,
    fit_drive_filter,
    fit_weighting,
)
from vm_ros.model.params import resolve_muscles

PARAMS = load_model_params()


def test_fig9_steady_isometric_force_lumped_matches_natural_within_2_percent():
    comparison = compare_steady(PARAMS, ur=0.8, units_per_type=50)
    errors = comparison.max_error_percent.round(2)
    print("max error % of F(U=1) per Fpcsa_S",
          dict(zip(comparison.fpcsa_slow, errors, strict=True)))
    assert np.all(comparison.max_error_percent < 2.0)
    # the comparison is not vacuous: both rise from 0 to full activation
    assert np.all(comparison.natural.sum(-1)[0] < 1e-3)
    assert np.all(comparison.natural.sum(-1)[-1] > 0.9)


def test_fig9_comparison_fails_for_uncapped_recruitment():
    """Reading rF literally (full recruitment only at U = 1) breaks the match
    (docs/model.md section 5b)."""
    import dataclasses

    literal = dataclasses.replace(PARAMS, lumped=dataclasses.replace(
        PARAMS.lumped, cap_recruitment_at_full=False))
    assert compare_steady(literal, units_per_type=50).max_error_percent.max() > 2.0


@pytest.mark.parametrize("ur", [0.6, 0.8])
def test_refit_w_improves_on_published_and_stays_within_target(ur):
    fit = fit_weighting(PARAMS, ur=ur, units_per_type=30)
    print(f"Ur {ur}: published {fit.published.max_error_percent.round(2)}, "
          f"refit {fit.fitted.max_error_percent.round(2)}")
    assert fit.fitted.max_error_percent.max() < 1.5
    assert fit.fitted.max_error_percent.max() < fit.published.max_error_percent.max()


def test_fig10_sinusoidal_drive_table():
    muscle = resolve_muscles(["vastus_lateralis"], None, None, 0.8)[0]
    table = compare_sinusoidal(PARAMS, muscle, cycles=3)
    col = {name: i for i, name in enumerate(table.columns)}
    print("\n" + " ".join(f"{c:>20}" for c in table.columns))
    for row in table.rows:
        print(" ".join(f"{v:20.3f}" for v in row))
    assert np.all(np.abs(table.rows[:, col["transient_rms_error"]]) < 3.0)
    assert np.all(np.abs(table.rows[:, col["mean_error"]]) < 3.0)
    assert np.all(np.abs(table.rows[:, col["range_error"]]) < 6.0)
    # the drive really modulates the force: natural modulation range > 10 % of F(U=1)
    assert np.ptp(table.natural_force[-500:], axis=0).min() > 0.1 * table.natural_force.max() / 2


def test_fit_w_command_writes_table_params_and_plot(tmp_path, capsys):
    code = cli_main(["fit-w", "--units", "20", "--fpcsa-slow", "0.3", "0.6", "--out",
                     str(tmp_path)])
    assert code == 0
    assert "refit_max_error_percent" in capsys.readouterr().out
    refit = load_model_params(tmp_path / "model_fit_w.yaml")
    assert refit.lumped.w_slow_poly != PARAMS.lumped.w_slow_poly
    rows = np.loadtxt(tmp_path / "fit_w.csv", delimiter=",", skiprows=1)
    assert rows.shape == (2, 3) and np.all(rows[:, 2] <= rows[:, 1] + 1e-9)
    assert (tmp_path / "fit_w.png").stat().st_size > 10_000


def test_drive_filter_fit_finds_the_shipped_constants_neighbourhood_from_far_off():
    """Started with every relative_drive constant 2.5x its shipped value (the fit's own training
    drive, two fibre mixes, 10 units per type, 5 ms steps to keep it short), the least-squares fit
    must bring the training error down to within 25 % of the shipped constants' error: the fit
    finds the optimum the shipped constants came from, and the shipped constants are near it."""
    setting = {"fpcsa_slow_grid": (0.3, 0.6), "units_per_type": 10, "dt": 0.005}
    lumped = PARAMS.lumped
    far = dataclasses.replace(PARAMS, lumped=dataclasses.replace(lumped, **{
        name: (tuple(2.5 * v for v in getattr(lumped, name))
               if isinstance(getattr(lumped, name), tuple) else 2.5 * getattr(lumped, name))
        for name in FILTER_FIELDS["relative_drive"]}))
    shipped = drive_filter_rms_percent(PARAMS, **setting)
    fit = fit_drive_filter(far, max_nfev=40, **setting)
    print(f"\nshipped {shipped}, from far {fit.rms_start_percent} -> {fit.rms_fitted_percent}")
    assert np.all(fit.rms_start_percent > 1.5 * shipped)  # the start really is far off
    assert np.all(fit.rms_fitted_percent < 1.25 * shipped)
