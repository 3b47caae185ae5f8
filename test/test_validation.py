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


def test_criteria_fail_outside_their_bounds():
    from vm_ros.validation import Criterion

    assert not Criterion("x", 2.0, None, 1.0).passed
    assert not Criterion("x", 0.5, 1.0, None).passed
    assert not Criterion("x", float("nan"), None, None).passed
    assert Criterion("x", 1.0, 1.0, 1.0).passed
