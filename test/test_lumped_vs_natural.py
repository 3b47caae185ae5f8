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

import numpy as np
import pytest

from vm_ros.cli import main as cli_main
from vm_ros.model import load_model_params
from vm_ros.model.lumped_fit import (
    DRIVE_FILTER_START,
    compare_sinusoidal,
    compare_steady,
    fit_drive_filter,
    fit_weighting,
    with_lumped,
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


# Known relative_drive constants, chosen by hand (not any fit's output) inside FILTER_BOUNDS and
# away from the fit's start (DRIVE_FILTER_START), for the reduced fits below.
KNOWN = {"relative_rise_poly": (0.05, 0.06),
         "relative_fall_poly": (0.3, 0.25), "relative_fall_power": 3.0,
         "relative_fall_floor": 0.07}
# the reduced fit: two muscles (U2 = 0.16 and 0.42), 5 ms steps
REDUCED = {"grid": ((0.2, 0.8), (0.7, 0.6)), "dt": 0.005}


def test_drive_filter_fit_recovers_known_constants_from_lumped_units_made_with_them():
    """The fit's target is the lumped units' own activation with KNOWN constants (a reference
    whose constants are known); started from DRIVE_FILTER_START (the start of `vm-ros fit-w
    --drive-filter`), the fit must bring the training error near 0 and return KNOWN: within 2 %
    for the time constants, 0.1 for the power (bounds set before the fit was run)."""
    known = with_lumped(PARAMS, **KNOWN)
    start = DRIVE_FILTER_START["relative_drive"]
    fit = fit_drive_filter(known, reference="lumped", start=start, max_nfev=120, **REDUCED)
    got = fit.params.lumped
    print(f"\nstatus {fit.status}, {fit.evaluations} evaluations, RMS {fit.rms_start_percent} -> "
          f"{fit.rms_fitted_percent}; " + ", ".join(f"{k} {getattr(got, k)}" for k in KNOWN))
    # the start really is off: 6x the bound below (measured 0.90 and 0.45 % with a filtered drive
    # per fibre type, 2026-12-03; the bound was 0.5 % while both types shared one)
    assert np.all(fit.rms_start_percent > 0.3)
    assert np.all(fit.rms_fitted_percent < 0.05)
    # T_r and T_f at the two muscles' U2 (the polynomials' values, which the data determine)
    for name in ("relative_rise_poly", "relative_fall_poly"):
        u2 = np.array([0.16, 0.42])
        assert np.polyval(getattr(got, name), u2) == pytest.approx(
            np.polyval(KNOWN[name], u2), rel=0.02)
    assert got.relative_fall_floor == pytest.approx(KNOWN["relative_fall_floor"], rel=0.02)
    assert got.relative_fall_power == pytest.approx(KNOWN["relative_fall_power"], abs=0.1)


def test_drive_filter_fit_is_deterministic_and_starts_where_told():
    """Two runs of the same reduced fit against natural units give the same constants, bit for
    bit; the start is DRIVE_FILTER_START, not the parameter file's constants (a fit started from
    the same point gives the same result whatever the file holds)."""
    setting = dict(REDUCED, units_per_type=5, max_nfev=6,
                   start=DRIVE_FILTER_START["relative_drive"])
    first = fit_drive_filter(PARAMS, **setting)
    second = fit_drive_filter(with_lumped(PARAMS, **KNOWN), **setting)
    for name in first.fields:
        assert getattr(first.params.lumped, name) == getattr(second.params.lumped, name)
    np.testing.assert_array_equal(first.rms_fitted_percent, second.rms_fitted_percent)
    assert np.all(first.rms_fitted_percent < first.rms_start_percent)
