"""Every item of docs/validation.md, as `vm-ros validate` checks it: each check carries explicit
numeric criteria (bounds stated in vm_ros/validation/ next to the paper's claim); here every
criterion must hold. The values are printed so a failing run shows how far off it is."""

from __future__ import annotations

import pytest

from vm_ros.validation import CHECKS, JOINT_TORQUE_KNOWN_GAPS


def _assert_all(result):
    lines = [f"{c.description}: {c.value:.4g} in {c.bounds()} -> {'ok' if c.passed else 'FAIL'}"
             for c in result.criteria]
    print(f"\n{result.title}\n  " + "\n  ".join(lines))
    assert result.criteria, "a check without criteria proves nothing"
    assert result.passed, "\n".join(lines)


@pytest.mark.parametrize("name", ["fig2", "fig3", "fig4", "fig5", "fig6", "fig9", "cost", "steps"])
def test_validation_item(name):
    _assert_all(CHECKS[name]())


def _value(result, start):
    """The value of the one criterion whose description starts with ``start``."""
    found = [c for c in result.criteria if c.description.startswith(start)]
    assert len(found) == 1, [c.description for c in result.criteria]
    return found[0].value


# Muscle specific heat, 3.75 kJ/(kg K) (the paper's section III), written here on purpose instead
# of read from config/model.yaml, so that the conversion to temperature rate is checked.
SPECIFIC_HEAT_J_PER_KG_K = 3750.0


def test_fig5_and_fig6_compare_initial_energy_in_millikelvin_per_second():
    """Items 7-8: the compared rate is E_a + E_xb, in mK/s = 1e3 W / (kg x 3750 J/(kg K)),
    recomputed here by hand for vastus lateralis at MVC (U = 1 and 0.8); the correlation is on
    those initial rates; the total with static recovery is reported beside it and lies between
    (1 + R_fast) and (1 + R_slow) times the initial rate."""
    import numpy as np

    from vm_ros.model import MuscleBank, load_model_params
    from vm_ros.validation.paper import isometric_at

    params = load_model_params()
    fig5, fig6 = CHECKS["fig5"](params=params), CHECKS["fig6"](params=params)
    names = list(fig5.data["names"])
    vl = names.index("vastus_lateralis")
    bank = MuscleBank.from_config(["vastus_lateralis"], params=params)
    for u in (1.0, 0.8):
        out = isometric_at(bank, [u])
        watts = out.energy_rate.activation[0] + out.energy_rate.cross_bridge[0]
        mk_per_s = 1e3 * watts / (bank.mass_kg[0] * SPECIFIC_HEAT_J_PER_KG_K)
        assert 5.0 < mk_per_s < 500.0  # a working muscle warms by millikelvins per second
        assert fig5.data["rates_mk_per_s"]["initial"][u][vl] == pytest.approx(mk_per_s, rel=1e-6)
        assert _value(fig6, f"MVC at U = {u}: initial dT/dt at 100 % MVC") == pytest.approx(
            mk_per_s, rel=1e-6)
        total = out.energy_rate.total[0] * 1e3 / (bank.mass_kg[0] * SPECIFIC_HEAT_J_PER_KG_K)
        assert _value(fig6, f"MVC at U = {u}: total dT/dt at 100 % MVC") == pytest.approx(
            total, rel=1e-6)

        initial = fig5.data["rates_mk_per_s"]["initial"][u]
        r = np.corrcoef(fig5.data["fast_percent"], initial)[0, 1]
        assert _value(fig5, f"U = {u} at MVC: Pearson r, initial") == pytest.approx(r)
        assert _value(fig5, f"U = {u} at MVC: initial dT/dt, highest") == pytest.approx(
            initial.max())
        assert _value(fig5, f"U = {u} at MVC: initial dT/dt, lowest") == pytest.approx(
            initial.min())
        ratio = fig5.data["rates_mk_per_s"]["total"][u] / initial
        recovery = params.energetics.recovery_ratio
        assert params.energetics.recovery_mode == "static"
        assert np.all(ratio >= 1 + recovery.min() - 1e-9)
        assert np.all(ratio <= 1 + recovery.max() + 1e-9)
        # Fig. 6's shape criteria are on the initial rate, in mK/s
        series = fig6.data["series"][u]
        assert _value(fig6, f"MVC at U = {u}: min rise of initial") == pytest.approx(
            np.diff(series["initial"]).min())


def test_fig3_ratio_on_total_energy_is_the_initial_ratio_times_the_recovery_factors():
    """Item 2: the paper's "more than five times" is held on initial energy; the ratio on total
    energy is reported beside it and equals the initial one x (1 + R_fast) / (1 + R_slow) under
    static recovery (R = 1.0 / 1.5 in config: 0.8 x)."""
    from vm_ros.model import load_model_params
    from vm_ros.model.params import FAST, SLOW

    params = load_model_params()
    result = CHECKS["fig3"](params=params)
    initial = _value(result, "fast/slow initial energy per newton")
    total = _value(result, "fast/slow total energy per newton")
    r = params.energetics.recovery_ratio
    assert initial >= 5.0
    assert total == pytest.approx(initial * (1 + r[FAST]) / (1 + r[SLOW]), rel=1e-6)


def test_fig4_peak_is_relative_to_the_isometric_force_with_yield_on_and_off():
    """Item 3: the stretched peak is divided by the U = 1 isometric force (computed here again),
    not by F0; yield off (cy = 0) leaves the isometric force unchanged and cannot lower the
    stretched peak (yield only ever scales the slow fibres' activation down)."""
    import dataclasses

    import numpy as np

    from vm_ros.model import MuscleBank, load_model_params
    from vm_ros.validation.paper import isometric_at, without_yield

    params = load_model_params()
    off = without_yield(params)
    assert np.all(off.fibre.cy == 0.0) and np.any(params.fibre.cy > 0.0)
    assert dataclasses.replace(off, fibre=params.fibre) == params  # nothing else changed
    iso = {}
    for name, p in (("on", params), ("off", off)):
        bank = MuscleBank.from_config(["biceps_long_head"], params=p)
        iso[name] = isometric_at(bank, [1.0]).force[0] / bank.f0[0]
    assert iso["off"] == pytest.approx(iso["on"], rel=1e-9)
    assert 0.5 < iso["on"] < 1.0  # W and Af below 1 at the top firing rate

    result = CHECKS["fig4"](params=params)
    d = result.data
    stretch = d["velocity"] > 1.0
    peak_f0 = d["force_f0"][-1, stretch].max()
    assert _value(result, "U=1 max force stretched > 1 L0/s / U=1 isometric force, yield on") \
        == pytest.approx(peak_f0 / iso["on"], rel=1e-6)
    assert _value(result, "U=1 max force stretched > 1 L0/s (F0") == pytest.approx(peak_f0)
    yield_off = _value(result, "the same, yield off")
    assert yield_off == pytest.approx(d["force_f0_no_yield"][stretch].max() / iso["off"],
                                      rel=1e-6)
    assert yield_off >= _value(result, "U=1 max force stretched > 1 L0/s / U=1 isometric") - 1e-9


def test_fig10_lumped_vs_natural_sinusoidal():
    _assert_all(CHECKS["fig10"]())


@pytest.mark.slow
def test_fig7_knee_extension_180s():
    """Item 9 over the paper's full 180 s (about 15 s with the compiled step, minutes with NumPy;
    `-m "not slow"` skips it). Held: initial energy constant to 1 %, recovery rising, total rate
    rising 0.40 +- 0.10, net fascicle work / total energy in 0.25-0.60 (measured 0.32-0.56,
    Krustrup 2003).

    Known gap, asserted as such: the model's total energy is about 18.8 kJ, 0.538 of the paper's
    ~35 000 J, below the experiment's 30 000-40 000 J; the criterion keeps the experiment's band
    and is a declared known gap (GAP, not a pass). Why: test/validation/REPORT.md, item 9."""
    from vm_ros.validation import FIG7_EXPERIMENT_BAND_J

    result = CHECKS["fig7"]()
    assert result.data["time"][-1] > 179.0, "the check must run the full 180 s"
    gaps = [c for c in result.criteria if c.status == "GAP"]
    assert [c.description for c in gaps] == [
        "total energy / paper's 35 000 J (experiment 30-40 kJ)"], (
        "the Fig. 7 gaps changed: update the Fig. 7 criteria and test/validation/REPORT.md")
    assert (gaps[0].low, gaps[0].high) == pytest.approx((30 / 35, 40 / 35))
    assert result.data["total_energy_j"] < FIG7_EXPERIMENT_BAND_J[0]
    result.criteria.remove(gaps[0])
    _assert_all(result)


def test_criteria_fail_outside_their_bounds():
    from vm_ros.validation import Criterion

    assert not Criterion("x", 2.0, None, 1.0).passed
    assert not Criterion("x", 0.5, 1.0, None).passed
    assert not Criterion("x", float("nan"), None, None).passed
    assert Criterion("x", 1.0, 1.0, 1.0).passed


def test_a_number_without_bounds_is_reported_not_passed():
    from vm_ros.validation import Criterion

    assert Criterion("x", 3.0).status == "reported"
    assert Criterion("x", 3.0, None, 1.0, known_gap="why").status == "GAP"
    assert Criterion("x", 0.5, None, 1.0, known_gap="why").status == "pass"
    assert Criterion("x", 0.5, 1.0, None).status == "FAIL"


def _fake_check(criteria):
    from vm_ros.validation import CheckResult

    return lambda params=None: CheckResult("0", "fake", "claim", list(criteria))


@pytest.mark.parametrize("failing, status", [(False, 0), (True, 1)])
def test_validate_counts_bounded_criteria_apart_from_reported_numbers(
        monkeypatch, tmp_path, capsys, failing, status):
    """The headline counts bounded criteria (passed / failed / known gaps) and, apart, numbers
    without a bound; the exit status follows the bounded criteria only (a reported NaN or a
    known gap does not fail the run, an unexplained miss does)."""
    import argparse
    import csv

    from vm_ros.cli import validate
    from vm_ros.validation import Criterion

    criteria = [Criterion("a", 1.0, 0.0, 2.0), Criterion("b", 5.0, None, 1.0, known_gap="why"),
                Criterion("c", float("nan")), Criterion("d", 7.0),
                Criterion("e", 3.0 if failing else 0.5, None, 1.0)]
    monkeypatch.setitem(validate.CHECKS, "fig2", _fake_check(criteria))
    args = argparse.Namespace(out=tmp_path, only=["fig2"], params=None, quick=False,
                              no_plots=True)
    assert validate.run(args) == status
    out = capsys.readouterr().out
    passed, failed = (1, 1) if failing else (2, 0)
    assert f"3 criteria bounded: {passed} passed / {failed} failed / 1 known gaps" in out
    assert "2 numbers reported without a bound" in out
    with open(tmp_path / "validation.csv", encoding="utf-8") as handle:
        rows = list(csv.DictReader(handle))
    assert [r["status"] for r in rows] == ["pass", "GAP", "reported", "reported",
                                           "FAIL" if failing else "pass"]


def test_joint_torque_against_human_dynamometry():
    """Item 10 (paper's Appendix B): maximal isometric knee-extension torque (myo-sim myolegs,
    hip 80 deg) and elbow-flexion torque (myoelbow) against joint angle, from MuJoCo's exact
    paths and moment arms and the steady isometric state of MuscleBank (agonists U = 1, every
    other muscle crossing the joint U = 0). Criteria (vm_ros.validation.JOINT_TORQUE_BANDS):
    knee peak 55-85 deg, torque/peak 0.2-0.6 at 20 deg and 0.6-0.95 at 100 deg; elbow peak
    50-110 deg, 0.4-0.8 at 20 deg and 0.4-0.9 at 130 deg; agonist paths within 0.1 L0 of the
    OpenSim models their l0/l0t come from; reset is the steady state (1e-4 F0 over 2 s); peak
    torque within 15 % of the published peak (Anderson 2007 204.7 N m; Tsunoda 1993 69.5 N m, and
    the biceps + brachialis share 0.81 of it, Kawakami et al.)."""
    pytest.importorskip("mujoco", reason="the joint-torque check needs the mujoco extra "
                        "(pip install 'vm_ros[mujoco]')")
    pytest.importorskip("myo_sim", reason="the joint-torque check needs myo-sim (the mujoco "
                        "extra: pip install 'vm_ros[mujoco]')")
    result = CHECKS["joint_torque"]()
    lines = [f"{c.description}: {c.value:.4g} in {c.bounds()} -> {'ok' if c.passed else 'FAIL'}"
             for c in result.criteria]
    print(f"\n{result.title}\n  " + "\n  ".join(lines))
    assert len(result.criteria) == 13
    failing = {c.description for c in result.criteria if not c.passed}
    # The criteria keep the published bands; the ones the model misses today are declared, with
    # why, in JOINT_TORQUE_KNOWN_GAPS (vm-ros validate reports them as GAP). This pins that set,
    # so that a change that closes a gap (or opens another) is seen.
    assert failing == set(JOINT_TORQUE_KNOWN_GAPS), (
        "the joint-torque failures changed: update JOINT_TORQUE_KNOWN_GAPS and "
        "test/validation/REPORT.md item 10\n" + "\n".join(lines))


def test_joint_torque_is_skipped_without_mujoco(monkeypatch):
    """Without the mujoco extra the item is skipped with a reason, not failed."""
    import importlib.util

    from vm_ros.validation import CheckSkippedError

    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec",
                        lambda name, *a: None if name == "mujoco" else real(name, *a))
    with pytest.raises(CheckSkippedError, match="mujoco"):
        CHECKS["joint_torque"]()


def test_validate_cli_reports_a_skipped_check(monkeypatch, tmp_path, capsys):
    """`vm-ros validate --only joint_torque` without the extra: exit 0, 'skipped' with the reason
    in the table and in validation.csv."""
    import argparse
    import importlib.util

    from vm_ros.cli import validate

    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec",
                        lambda name, *a: None if name == "mujoco" else real(name, *a))
    args = argparse.Namespace(out=tmp_path, only=["joint_torque"], params=None, quick=False,
                              no_plots=True)
    assert validate.run(args) == 0
    out = capsys.readouterr().out
    assert "joint_torque skipped: mujoco" in out and "not installed" in out
    assert "pip install 'vm_ros[mujoco]'" in out
    assert "skipped" in (tmp_path / "validation.csv").read_text(encoding="utf-8")


def test_short_fig7_run_says_its_duration_and_is_not_compared_with_the_180s_total(tmp_path):
    from vm_ros.validation.knee_extension import FIG7_PAPER_TOTAL_J
    from vm_ros.validation.knee_extension_plot import fig7_paper_comparison, plot_fig7

    result = CHECKS["fig7"](duration_s=3.0)
    assert result.title.startswith("Fig. 7: 3 s ") and "180" not in result.title
    d = result.data
    assert d["duration_s"] == 3.0 and d["paper_duration_s"] == 180.0
    text = fig7_paper_comparison(d["total_energy_j"], 3.0, FIG7_PAPER_TOTAL_J, 180.0)
    assert "not comparable" in text and " x " not in text
    same = fig7_paper_comparison(11_600.0, 180.0, FIG7_PAPER_TOTAL_J, 180.0)
    assert same.startswith(f"{11_600.0 / FIG7_PAPER_TOTAL_J:.2f} x the paper's 35 kJ")
    pytest.importorskip("matplotlib")
    plot_fig7(result, tmp_path / "fig7.png")
    assert (tmp_path / "fig7.png").stat().st_size > 0


def test_fig7_legends_cover_no_curve(monkeypatch, tmp_path):
    """Fig. 7's legends (panel 1's once covered the total-energy line, panels 2 and 3's the
    curves): no vertex of any plotted line lies inside any legend, after the figure's layout."""
    pytest.importorskip("matplotlib")
    from vm_ros.validation import knee_extension_plot

    drawn = []

    def keep(fig, result, path):
        fig.canvas.draw()  # finish's layout without closing the figure
        fig.tight_layout(rect=(0, 0, 1, 0.9))
        fig.canvas.draw()
        drawn.append(fig)

    monkeypatch.setattr(knee_extension_plot, "finish", keep)
    knee_extension_plot.plot_fig7(CHECKS["fig7"](duration_s=3.0), tmp_path / "fig7.png")
    fig, = drawn
    renderer = fig.canvas.get_renderer()
    legends = [ax.get_legend() for ax in fig.axes if ax.get_legend() is not None]
    assert len(legends) >= 3
    for legend in legends:
        box = legend.get_window_extent(renderer)
        for ax in fig.axes:
            for line in ax.get_lines():
                xy = line.get_transform().transform(line.get_xydata())
                inside = ((xy[:, 0] > box.x0) & (xy[:, 0] < box.x1)
                          & (xy[:, 1] > box.y0) & (xy[:, 1] < box.y1))
                assert not inside.any(), f"a legend covers {line.get_label()!r}"


def test_the_cost_figure_says_under_which_load_it_was_measured(monkeypatch, tmp_path):
    """The natural / lumped ratio moves with the machine's load (56x on a busy machine against
    4.8x idle): the figure's title states the load average it was measured under."""
    from vm_ros.validation import plots
    from vm_ros.validation.results import CheckResult

    drawn = []
    monkeypatch.setattr(plots, "finish", lambda fig, result, path: drawn.append(fig))
    sizes = [1, 100]
    seconds = {("lumped", 1): 2e-5, ("natural", 1): 4e-5, ("lumped", 100): 1e-4,
               ("natural", 100): 5.6e-3}
    for data in ({"load_average": 12.5, "cpus": 2}, {}):
        result = CheckResult("cost", "cost", "claim", data={
            "seconds_per_step": seconds, "sizes": sizes, **data})
        plots.plot_cost(result, tmp_path / "cost.png")
    loaded, idle = (fig.axes[0].get_title() for fig in drawn)
    assert "measured under load 12.5 (1-minute load average, 2 CPUs)" in " ".join(
        loaded.split())
    assert "load" not in idle
    assert {t.get_text() for t in drawn[0].axes[0].texts} == {"x2.0", "x56.0"}
    for fig in drawn:
        plots.plt.close(fig)
