"""Every item of spec/validation.md, as `vm-ros validate` checks it: each check carries explicit
numeric criteria (bounds stated in vm_ros/validation.py next to the paper's claim); here every
criterion must hold. The values are printed so a failing run shows how far off it is."""

from __future__ import annotations

import pytest

from vm_ros.validation import CHECKS


def _assert_all(result):
    lines = [f"{c.description}: {c.value:.4g} in {c.bounds()} -> {'ok' if c.passed else 'FAIL'}"
             for c in result.criteria]
    print(f"\n{result.title}\n  " + "\n  ".join(lines))
    assert result.criteria, "a check without criteria proves nothing"
    assert result.passed, "\n".join(lines)


@pytest.mark.parametrize("name", ["fig2", "fig3", "fig4", "fig5", "fig6", "fig9", "cost"])
def test_validation_item(name):
    _assert_all(CHECKS[name]())


def test_fig10_lumped_vs_natural_sinusoidal():
    _assert_all(CHECKS["fig10"]())


@pytest.mark.slow
def test_fig7_knee_extension_180s():
    """Item 9 over the paper's full 180 s (about 15 s with the compiled step, minutes with NumPy;
    `-m "not slow"` skips it). Held: initial energy constant to 1 %, recovery rising, total rate
    rising 0.40 +- 0.10, net fascicle work / total energy in 0.25-0.60 (measured 0.32-0.56,
    Krustrup 2003).

    Known gap, asserted as such: the model's total energy is about 11.6 kJ, a third of the paper's
    ~35 000 J (experiment 30 000-40 000 J); the criterion pins the ratio to 0.30-0.37 so that a
    change is noticed. Why the model stays below the band: test/validation/REPORT.md, item 9."""
    from vm_ros.validation import FIG7_EXPERIMENT_BAND_J

    result = CHECKS["fig7"]()
    assert result.data["time"][-1] > 179.0, "the check must run the full 180 s"
    _assert_all(result)
    assert result.data["total_energy_j"] < FIG7_EXPERIMENT_BAND_J[0], (
        "the model now reaches the experiment's band: update the Fig. 7 criteria and REPORT.md")


def test_criteria_fail_outside_their_bounds():
    from vm_ros.validation import Criterion

    assert not Criterion("x", 2.0, None, 1.0).passed
    assert not Criterion("x", 0.5, 1.0, None).passed
    assert not Criterion("x", float("nan"), None, None).passed
    assert Criterion("x", 1.0, 1.0, 1.0).passed
