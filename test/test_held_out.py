"""Item 12 (vm_ros.validation.held_out): the held-out drives are what the docstring says, drawn
from fixed seeds; the measures are those of single-muscle runs; the criteria carry the item's
targets. The full set of seeds runs in `vm-ros validate`; here one seed."""

from __future__ import annotations

import numpy as np
import pytest

from vm_ros.validation import held_out as ho

SEED = (3101,)


@pytest.fixture(scope="module")
def cases():
    return ho.held_out_cases(SEED)


def test_cases_are_drawn_from_their_seeds_only():
    a, b = ho.held_out_cases(SEED), ho.held_out_cases(SEED)
    other = ho.held_out_cases((3102,))
    assert all(np.array_equal(x.drive, y.drive) and np.array_equal(x.length_l0, y.length_l0)
               for x, y in zip(a, b, strict=True))
    assert not np.array_equal(a[0].drive, other[0].drive)


def test_pulse_trains_hold_random_levels_50_to_400_ms(cases):
    trains = [c for c in cases if c.family in ("pulses_l0", "pulses_length", "moving",
                                               "library")]
    assert len(trains) == 6
    for c in trains:
        assert c.drive.min() >= 0.0 and c.drive.max() <= 1.0
        holds = np.diff(np.concatenate([[0], c.jumps])) * 1e-3  # s; the last hold is cut short
        assert len(c.jumps) >= 4000 / 400 - 1
        # two equal levels in a row merge (only at rest, with probability 1/25 per pair)
        assert np.all(holds >= 0.05 - 1e-9), holds
        assert np.all((holds <= 0.4 + 1e-9) | (c.drive[c.jumps - 1] == 0.0)), holds
        assert np.array_equal(c.jumps, np.flatnonzero(np.diff(c.drive)) + 1)


def test_lengths_paths_ramps_and_sines(cases):
    by = {}
    for c in cases:
        by.setdefault(c.family, []).append(c)
    assert np.all(by["pulses_l0"][0].length_l0 == 1.0)
    fixed = by["pulses_length"][0].length_l0
    assert np.ptp(fixed) == 0.0 and 0.8 <= fixed[0] <= 1.25
    moving = by["moving"][0]
    assert moving.length_l0.min() >= 0.8 - 1e-9 and moving.length_l0.max() <= 1.2 + 1e-9
    assert np.ptp(moving.length_l0) > 0.35  # the 4 s case crosses the whole range
    assert np.allclose(np.abs(moving.velocity_l0_per_s), 0.5)
    inner = np.sign(moving.velocity_l0_per_s[:-1]) == np.sign(moving.velocity_l0_per_s[1:])
    assert np.allclose(np.diff(moving.length_l0)[inner], 1e-3 * moving.velocity_l0_per_s[:-1][
        inner])
    for c, ramp_s in zip(by["ramps"], (0.5, 3.0), strict=True):
        slope = np.diff(c.drive[:int(ramp_s * 1e3)]) * 1e3
        assert np.allclose(slope, slope[0]) and 0.0 <= c.drive.min() <= c.drive.max() <= 1.0
        assert abs(slope[0] * ramp_s - (c.drive[int(ramp_s * 1e3) - 1] - c.drive[0])) < 1e-2
    low, high = (c.frequency_hz for c in by["sines"])
    assert low in (0.5, 1.0, 2.0) and high in (5.0, 10.0, 20.0)
    for c in by["sines"]:
        assert c.drive.min() >= 0.0 and c.drive.max() <= 1.0
    assert [c.muscle for c in by["library"]] == ["soleus", "rectus_femoris",
                                                 "first_dorsal_interosseous"]
    synthetic = [c.spec for c in cases if c.muscle == "synthetic"]
    assert all(0.05 <= s.fpcsa_slow <= 0.95 and 0.5 <= s.ur <= 0.8 for s in synthetic)


def test_force_rms_is_that_of_each_case_run_alone():
    """The batched comparison gives each case what a bank of that muscle alone gives, stepped
    one step at a time, with the RMS and the scale computed here."""
    import dataclasses

    from vm_ros.model import MuscleBank, load_model_params
    from vm_ros.model.curves import tendon_length_at_force

    params = load_model_params()
    cases = [c for c in ho.held_out_cases(SEED, case_s=0.6, library=()) if c.family in (
        "pulses_length", "moving")]
    run, = ho.compare_held_out(params, cases)
    g = params.generic
    natural_params = dataclasses.replace(params, natural=dataclasses.replace(
        params.natural, units_per_type=20))
    for i, c in enumerate(cases):
        forces = []
        for p, scheme in ((natural_params, "natural"), (params, "lumped")):
            bank = MuscleBank([c.spec], p, scheme)
            tendon = bank.l0t_m[0] * tendon_length_at_force(0.5, g.ct, g.kt, g.lrt)
            reference = 1.0 if c.family == "moving" else c.length_l0[0]
            f1 = bank.reset([bank.l0_m[0] * reference + tendon], excitation=[1.0]).force[0]
            lp = bank.l0_m[0] * c.length_l0 + tendon
            bank.reset([lp[0]], excitation=[c.drive[0]])
            forces.append([bank.step(1e-3, [u], [x], [bank.l0_m[0] * v]).force[0]
                           for u, x, v in zip(c.drive, lp, c.velocity_l0_per_s, strict=True)])
            if scheme == "natural":
                scale = f1
        rms = 100 * np.sqrt(np.mean((np.array(forces[1]) - np.array(forces[0])) ** 2)) / scale
        assert run.force_rms_percent[i] == pytest.approx(rms, rel=1e-6, abs=1e-9)
    # each counted jump names its case and the step at which that case's drive jumps
    assert len(run.jump_step) == len(run.jump_case) == len(run.jump_energy_ratio) > 0
    for case, step in zip(run.jump_case, run.jump_step, strict=True):
        drive = cases[case].drive
        assert step in cases[case].jumps and drive[step] != drive[step - 1]


def test_reduced_check_carries_the_targets():
    """One seed (the full set runs in `vm-ros validate --only held_out`): the bounded criteria
    hold the item's targets, written here as the issue states them; each passes or is the
    declared known gap; the paper's law is reported beside."""
    result = ho.check_held_out(seeds=SEED)
    bounded = {c.description.split(" (")[0]: (c.low, c.high) for c in result.criteria
               if c.bounded}
    assert bounded["pulse trains at L0: force RMS % F(U=1), median"] == (None, 1.5)
    assert bounded["pulse trains at L0: force RMS % F(U=1), worst"] == (None, 3.0)
    assert bounded["pulses_length: force RMS % F(U=1), worst"] == (None, 4.0)
    assert bounded["moving: force RMS % F(U=1), worst"] == (None, 4.0)
    assert bounded["jumps with initial energy ratio in 0.8-1.25"] == (0.97, None)
    assert bounded["total energy ratio per 1 s window, min"] == (0.9, None)
    assert bounded["total energy ratio per 1 s window, max"] == (None, 1.1)
    for muscle in ("soleus", "rectus_femoris", "first_dorsal_interosseous"):
        assert bounded[f"library {muscle}: worst force RMS / the same with the tsianos2012 "
                       "law"] == (None, 1.0)
    for band in ("below 5 Hz", "5-20 Hz"):
        for measure in ("force RMS", "|steady mean error|"):
            assert bounded[f"sines {band}: worst {measure} / the same with the tsianos2012 "
                           "law"] == (None, 1.0)
    assert len(bounded) == 14
    assert {c.status for c in result.criteria if c.bounded} <= {"pass", "GAP"}
    assert all(np.isfinite(c.value) for c in result.criteria)
    assert any(c.description.startswith("tsianos2012 law") for c in result.criteria)


def test_summary_line_of_a_made_up_run(cases):
    """fit-w --drive-filter prints this line: the numbers of a HeldOutRun made up here."""
    family = [c.family for c in cases]
    rms = np.array([{"pulses_l0": 1.0, "pulses_length": 4.5, "moving": 2.0}.get(f, 9.0)
                    for f in family])
    run = ho.HeldOutRun(rms, np.zeros(len(cases)), np.array([0.7, 0.9, 1.0, 1.3]),
                        np.zeros(4, dtype=int), np.array([0.95, 1.2]))
    assert ho.held_out_summary(cases, run) == (
        "pulse trains at L0 force RMS 1.00 / 1.00 %, off L0 and moving worst 4.50 %, jumps "
        "within 0.8-1.25 50.0%, windows 0.95-1.20")
