"""Lichtwark & Wilson, Houdijk et al. 2006, Margaria 1968 and Minetti & Alexander 1997
(vm_ros.model.energetics_models) against their papers' numbers and a second implementation.

The second implementation is scalar Python written here from the formulations of Koelewijn,
Heinrich & van den Bogert 2019 (PLoS ONE 14(9):e0222037; their published code, BioMAC-Sim-Toolbox
src/model/@Model/getErate_*.m), with the papers' numbers typed in, never read from the package.
Lichtwark & Wilson and Houdijk also have a third implementation here, by another group: scalar
Python written from Luis et al. 2024 (KTH; israelluis/MetabolicRateWalking,
metabolicCost/MC_LW07_R.m and MC_HO06_R.m), who implemented the papers independently of Koelewijn.
Their Lichtwark & Wilson uses a constant gamma = 1.5 (the 2007 supplement as they read it) where
Koelewijn uses the 2005 decay; the package holds both as constants (docs/energetics_models.md 3).
The grid (activation 0-1, fibre length 0.6-1.5 L0, shortening, isometric and lengthening
velocities, slow fraction 0, 0.4, 1) comes from a Gaussian force-length and a Hill force-velocity
curve, so that the state is consistent as a Hill muscle's is.
"""

from __future__ import annotations

import dataclasses
import itertools
import math

import numpy as np
import pytest
import yaml

from vm_ros.errors import ConfigError
from vm_ros.model.energetics_models import (
    MuscleState,
    force_length_multiplier_from_state,
    houdijk2006,
    lichtwark2005,
    load_houdijk_constants,
    load_lichtwark_constants,
    load_margaria_constants,
    load_minetti_constants,
    margaria1968,
    minetti1997,
)
from vm_ros.model.energetics_models.lichtwark import force_velocity_multiplier_from_state
from vm_ros.resources import config_dir

RTOL = 1e-12
F0, L0, MASS = 1000.0, 0.1, 0.42  # N, m, kg
VMAX = 10.0  # L0/s, the config's max_contraction_velocity
ACTIVATIONS = (0.0, 0.05, 0.5, 1.0)
FIBRE_LENGTHS_L0 = (0.6, 0.8, 1.0, 1.1, 1.3, 1.5)
VELOCITIES = (-0.8, -0.3, -0.05, 0.0, 0.05, 0.3, 0.8)  # m/s, lengthening positive
SLOW_FRACTIONS = (0.0, 0.4, 1.0)


def _force_length(length_l0):
    return math.exp(-((length_l0 - 1.0) / 0.56) ** 2)


def _force_velocity(v_l0_per_s):
    """Hill (shortening, a/F0 = 0.25) and a saturating lengthening branch up to 1.5."""
    if v_l0_per_s <= 0.0:
        return (VMAX + v_l0_per_s) / (VMAX - v_l0_per_s / 0.25)
    c = VMAX * 0.25 * 0.5 / 1.25
    return (1.5 * v_l0_per_s + c) / (v_l0_per_s + c)


def _grid():
    rows = []
    for a, length, v, r in itertools.product(ACTIVATIONS, FIBRE_LENGTHS_L0, VELOCITIES,
                                             SLOW_FRACTIONS):
        fl, fv = _force_length(length), _force_velocity(v / L0)
        rows.append({"a": a, "length": length * L0, "v": v, "r": r, "fl": fl, "fv": fv,
                     "force": a * fl * fv * F0, "iso": a * fl * F0})
    return rows


GRID = _grid()


def _state(rows=GRID) -> MuscleState:
    column = {key: np.array([row[key] for row in rows]) for key in rows[0]}
    n = len(rows)
    return MuscleState(
        excitation=column["a"], activation=column["a"], fibre_length=column["length"],
        optimal_fibre_length=np.full(n, L0), fibre_velocity=column["v"],
        active_fibre_force=column["force"], isometric_force=column["iso"],
        max_isometric_force=np.full(n, F0), mass=np.full(n, MASS), slow_fraction=column["r"])


COMPONENTS = ("activation_maintenance", "shortening_lengthening", "mechanical_work", "total")


def _assert_components_equal(rates, reference):
    """Every component of ``rates`` against the reference's columns (in COMPONENTS order)."""
    for k, name in enumerate(COMPONENTS):
        assert _close(getattr(rates, name), reference[:, k]) <= RTOL, name


def _close(ours, reference):
    """Worst relative difference; rates below 1 W are compared absolutely (to 1e-12 W at RTOL),
    as a total that forbid_negative_total_power raises to 0 is 0 only to rounding."""
    reference = np.asarray(reference, dtype=float)
    scale = np.maximum(np.abs(reference), 1.0)
    return np.max(np.abs(np.asarray(ours) - reference) / scale)


# --- second implementations, scalar, written from the papers as Koelewijn 2019 formulate them --


def lichtwark_reference(row, t=0.0, g_curvature=4.0, negative_work=True):
    """Koelewijn 2019 getErate_Lichtwark.m: Lichtwark & Wilson 2007 supplement, gamma of 2005."""
    a, fl, fv = row["a"], row["fl"], row["fv"]
    v = -row["v"] / L0  # shortening positive, L0/s
    gamma = 0.8 * math.exp(-0.72 * t) + 0.175 * math.exp(-0.022 * t)
    if v > 0.0:
        hm, hs = gamma * VMAX / g_curvature ** 2, v / g_curvature
    else:
        hm = (0.3 * gamma * VMAX / g_curvature ** 2
              + 0.7 * gamma * VMAX / g_curvature ** 2 * math.exp(-7.0 * VMAX * (fv - 1.0)))
        hs = -0.5 * fv * v
    am = (0.3 * a * hm + 0.7 * a * fl * hm) * F0 * L0
    sl = a * fl * hs * F0 * L0
    w = row["force"] * v * L0
    if not negative_work and v < 0.0:
        w = 0.0
    return am, sl, w, am + sl + w


def houdijk_reference(row, total_slow=24.4, forbid_negative=False):
    """Koelewijn 2019 getErate_Houdijk.m (Houdijk et al. 2006)."""
    a, fl, st = row["a"], row["fl"], row["r"]
    ft = 1.0 - st
    g_bar = 0.45 * total_slow * st + 0.35 * 150.0 * ft
    h_bar = (total_slow - 0.45 * total_slow) * st + (150.0 - 0.35 * 150.0) * ft
    k3, k4 = 6.0 * st + 12.0 * ft, 8.0 * st + 14.0 * ft
    a_bar = 0.16 * F0 * st + 0.28 * F0 * ft
    nu, nu_max = a ** 2, k3 + k4 * a
    if nu > 0.0:
        g = (MASS * g_bar * nu * (1.0 - math.exp(-0.25 - 18.2 / (nu * nu_max)))
             / (1.0 - math.exp(-0.25 - 18.2 / nu_max)))
    else:
        g = 0.0
    h = MASS * (g_bar + h_bar) * a * (fl - g_bar / (g_bar + h_bar))
    v = row["v"] / L0
    s = a_bar * a * fl * abs(v) * L0 if v <= 0.0 else 0.0
    w = -row["force"] * v * L0
    if forbid_negative and g + h + s + w < 0.0:
        s -= g + h + s + w
    return g + h, s, w, g + h + s + w


def lichtwark_luis(row, gamma=1.5):
    """Luis et al. 2024 MC_LW07_R.m: V_CE in m/s, lengthening positive; no basal rate."""
    a, fl, fv, v_ce = row["a"], row["fl"], row["fv"], row["v"]
    curvature, vmax = 4.0, VMAX
    x = a * fl
    if fv >= 1.0:  # their lengthening test, on the force-velocity multiplier
        hm = (0.3 * gamma * vmax / curvature ** 2
              + 0.7 * gamma * vmax / curvature ** 2 * math.exp(-7.0 * vmax * (fv - 1.0)))
    else:
        hm = gamma * vmax / curvature ** 2
    maintenance = (0.3 * a * hm + 0.7 * x * hm) * F0 * L0
    hsl = 0.5 * fv * v_ce / L0 if v_ce > 0.0 else -(v_ce / L0) / curvature
    heat_sl = hsl * x * F0 * L0
    work = -row["force"] * v_ce
    return maintenance, heat_sl, work, maintenance + heat_sl + work


def houdijk_luis(row, non_negative=False):
    """Luis et al. 2024 MC_HO06_R.m (their option 1: where E <= 0 the shortening heat is set so
    that E = 0); slow and fast constants typed as they give them (W/kg)."""
    a, fl, st = row["a"], row["fl"], row["r"]
    ft = 1.0 - st
    h_a = 52.50 * ft + 10.98 * st
    h_m = 97.50 * ft + 13.42 * st
    k3, k4 = 12.0 * ft + 6.0 * st, 14.0 * ft + 8.0 * st
    v_max_freq = k3 + k4 * a
    v_rel = a ** 2
    if v_rel > 0.0:
        h_a_rate = (MASS * h_a * v_rel * (1.0 - math.exp(-0.25 - 18.2 / (v_rel * v_max_freq)))
                    / (1.0 - math.exp(-0.25 - 18.2 / v_max_freq)))
    else:
        h_a_rate = 0.0  # MATLAB's 0 * (1 - exp(-inf)) / (...) = 0
    h_m_rate = MASS * (h_a + h_m) * a * (fl - h_a / (h_a + h_m))
    a_tilde = (0.28 * ft + 0.16 * st) * F0
    v_ce = row["v"]
    h_sl = -a_tilde * a * fl * v_ce if v_ce <= 0.0 else 0.0
    work = -row["force"] * v_ce
    if non_negative and h_a_rate + h_m_rate + h_sl + work <= 0.0:
        h_sl = -h_a_rate - h_m_rate - work
    return h_a_rate + h_m_rate, h_sl, work, h_a_rate + h_m_rate + h_sl + work


def margaria_reference(row, positive=0.25, negative_work=True):
    """Koelewijn 2019 getErate_margaria.m: 25 % efficient shortening, 120 % lengthening."""
    w = row["force"] * row["v"]  # absorbed power, W
    if row["v"] < 0.0:
        return -w / positive
    return w / 1.2 if negative_work else 0.0


def minetti_reference(row, c1=0.054):
    """Minetti & Alexander 1997 phi(v), per muscle as Koelewijn 2019 getErate_Minetti.m."""
    vmax = VMAX * L0
    v = -row["v"] / vmax
    phi = (c1 + 0.506 * v + 2.46 * v ** 2) / (1.0 - 1.13 * v + 12.8 * v ** 2 - 1.64 * v ** 3)
    return row["a"] * F0 * vmax * phi


# --- the papers' numbers ------------------------------------------------------------------------


def _one(a=1.0, length_l0=1.0, v=0.0, r=0.4, force=None):
    fl, fv = _force_length(length_l0), _force_velocity(v / L0)
    return _state([{"a": a, "length": length_l0 * L0, "v": v, "r": r, "fl": fl, "fv": fv,
                    "force": a * fl * fv * F0 if force is None else force,
                    "iso": a * fl * F0}])


def _lichtwark(state, constants, t=0.0, **given):
    """lichtwark2005 with the multipliers a Hill muscle's state determines, unless given."""
    extras = {"force_length_multiplier": force_length_multiplier_from_state(state),
              "force_velocity_multiplier": force_velocity_multiplier_from_state(state),
              "stimulation_duration": t}
    return lichtwark2005(state, constants, **{**extras, **given})


def _houdijk(state, constants, **given):
    """houdijk2006 with the force-length multiplier the state determines, unless given."""
    return houdijk2006(state, constants, **{
        "force_length_multiplier": force_length_multiplier_from_state(state), **given})


def test_lichtwark_worked_points():
    """Lichtwark & Wilson 2007 supplement / 2005 eq. for gamma, at L0, full activation: the
    isometric maintenance heat is gamma Vmax / G^2 F0 L0 = 0.975 * 10 / 16 * 100 W = 60.9375 W
    (gamma(0) = 0.8 + 0.175); shortening at 1 L0/s adds v / G F0 L0 = 25 W of shortening heat;
    after long stimulation gamma falls to 0.175 exp(-0.022 t)."""
    c = load_lichtwark_constants()
    rates = _lichtwark(_one(), c)
    assert rates.activation_maintenance[0] == pytest.approx(60.9375, rel=RTOL)
    assert rates.shortening_lengthening[0] == pytest.approx(0.0, abs=1e-12)
    shortening = _lichtwark(_one(v=-0.1), c, force_length_multiplier=1.0)
    assert shortening.shortening_lengthening[0] == pytest.approx(25.0, rel=RTOL)
    late = _lichtwark(_one(), c, t=100.0)
    assert late.activation_maintenance[0] == pytest.approx(
        0.175 * math.exp(-2.2) * 10 / 16 * 100, rel=RTOL)


def test_houdijk_worked_points():
    """Houdijk et al. 2006: at full activation and optimal length, activation plus maintenance
    heat is the fibre type's total, 24.4 W/kg (slow) and 150 W/kg (fast); isometric, so no
    shortening heat or work."""
    c = load_houdijk_constants()
    for r, per_kg in ((1.0, 24.4), (0.0, 150.0), (0.4, 0.4 * 24.4 + 0.6 * 150.0)):
        rates = _houdijk(_one(r=r), c)
        assert rates.activation_maintenance[0] == pytest.approx(MASS * per_kg, rel=RTOL)
        assert rates.total[0] == pytest.approx(MASS * per_kg, rel=RTOL)


def test_margaria_efficiencies():
    """Margaria 1968: positive work at 25 % efficiency (100 W of work costs 400 W), negative
    work at -120 % (120 W absorbed costs 100 W)."""
    c = load_margaria_constants()
    assert margaria1968(_one(v=-0.1, force=1000.0), c).total[0] == pytest.approx(400.0, rel=RTOL)
    assert margaria1968(_one(v=0.12, force=1000.0), c).total[0] == pytest.approx(100.0, rel=RTOL)
    assert margaria1968(_one(v=0.0, force=1000.0), c).total[0] == 0.0
    without = dataclasses.replace(c, include_negative_mechanical_work=False)
    assert margaria1968(_one(v=0.12, force=1000.0), without).total[0] == 0.0
    assert np.isnan(margaria1968(_one(), c).activation_maintenance[0])


def test_minetti_phi_values():
    """Minetti & Alexander 1997 phi(v): 0.054 isometric (F0 Vmax a 0.054 = 54 W here), and
    3.02 / 11.03 at v = Vmax (hand-evaluated from the paper's coefficients)."""
    c = load_minetti_constants()
    assert minetti1997(_one(), c).total[0] == pytest.approx(0.054 * F0 * VMAX * L0,
                                                                  rel=RTOL)
    at_vmax = minetti1997(_one(v=-VMAX * L0, force=0.0), c).total[0]
    assert at_vmax == pytest.approx(3.02 / 11.03 * F0 * VMAX * L0, rel=RTOL)
    half = minetti1997(_one(a=0.5), c).total[0]
    assert half == pytest.approx(0.5 * 0.054 * F0 * VMAX * L0, rel=RTOL)


# --- the grid against the second implementations --------------------------------------------------


def test_the_grid_covers_what_it_claims():
    state = _state()
    assert state.activation.min() == 0.0
    assert state.fibre_velocity.min() < 0.0 < state.fibre_velocity.max()
    assert np.any(state.fibre_length > L0) and np.any(state.fibre_length < L0)


@pytest.mark.parametrize(("option", "kwargs"), [
    ("default", {}),
    ("no_negative_work", {"negative_work": False}),
    ("late", {"t": 30.0}),
])
def test_lichtwark_equals_second_implementation(option, kwargs):
    c = load_lichtwark_constants()
    if option == "no_negative_work":
        c = dataclasses.replace(c, include_negative_mechanical_work=False)
    rates = _lichtwark(_state(), c, t=kwargs.get("t", 0.0))
    reference = np.array([lichtwark_reference(row, **kwargs) for row in GRID])
    _assert_components_equal(rates, reference)


@pytest.mark.parametrize("implementation", ["koelewijn2019", "luis2024"])
@pytest.mark.parametrize("forbid", [False, True])
def test_houdijk_equals_second_implementation(forbid, implementation):
    """Against Koelewijn et al.'s and Luis et al.'s implementations, with and without
    forbid_negative_total_power (Luis et al.'s option 1)."""
    c = dataclasses.replace(load_houdijk_constants(), forbid_negative_total_power=forbid)
    rates = _houdijk(_state(), c)
    if implementation == "koelewijn2019":
        reference = [houdijk_reference(row, forbid_negative=forbid) for row in GRID]
    else:
        reference = [houdijk_luis(row, non_negative=forbid) for row in GRID]
    _assert_components_equal(rates, np.array(reference))
    if forbid:
        assert rates.total.min() >= -1e-9
    else:
        assert rates.total.min() < 0.0  # the switch is exercised


def test_lichtwark_equals_luis_2024_with_their_gamma():
    """Every term of Luis et al.'s implementation, with their constant gamma = 1.5 given as the
    package's constants (decay constant 1.5, both amplitudes 0); with Koelewijn's default decay
    the maintenance heat differs by gamma, the shortening heat and work do not."""
    luis = dataclasses.replace(load_lichtwark_constants(), maintenance_decay_constant=1.5,
                               maintenance_decay_fast_amplitude=0.0,
                               maintenance_decay_slow_amplitude=0.0)
    reference = np.array([lichtwark_luis(row) for row in GRID])
    for when in (0.0, 30.0):
        rates = _lichtwark(_state(), luis, t=when)
        _assert_components_equal(rates, reference)
    default = _lichtwark(_state(), load_lichtwark_constants())
    assert _close(default.shortening_lengthening, reference[:, 1]) <= RTOL
    on = reference[:, 0] > 1.0
    assert np.allclose(default.activation_maintenance[on] / reference[on, 0], 0.975 / 1.5,
                       rtol=RTOL)


@pytest.mark.parametrize("negative_work", [True, False])
def test_margaria_equals_second_implementation(negative_work):
    c = dataclasses.replace(load_margaria_constants(),
                            include_negative_mechanical_work=negative_work)
    reference = [margaria_reference(row, negative_work=negative_work) for row in GRID]
    assert _close(margaria1968(_state(), c).total, reference) <= RTOL


def test_minetti_equals_second_implementation():
    reference = [minetti_reference(row) for row in GRID]
    assert _close(minetti1997(_state(), load_minetti_constants()).total, reference) <= RTOL


def test_a_perturbed_constant_fails_the_comparison():
    """The comparisons can fail: each reference with one constant changed by a few per cent."""
    state = _state()
    lichtwark = _lichtwark(state, load_lichtwark_constants()).total
    assert _close(lichtwark, [lichtwark_reference(r, g_curvature=4.2)[3] for r in GRID]) > 1e-3
    houdijk = _houdijk(state, load_houdijk_constants()).total
    assert _close(houdijk, [houdijk_reference(r, total_slow=25.0)[3] for r in GRID]) > 1e-3
    assert _close(lichtwark, [lichtwark_luis(r, gamma=0.975)[3] for r in GRID]) <= RTOL
    assert _close(lichtwark, [lichtwark_luis(r, gamma=1.0)[3] for r in GRID]) > 1e-3
    margaria = margaria1968(state, load_margaria_constants()).total
    assert _close(margaria, [margaria_reference(r, positive=0.26) for r in GRID]) > 1e-3
    minetti = minetti1997(state, load_minetti_constants()).total
    assert _close(minetti, [minetti_reference(r, c1=0.055) for r in GRID]) > 1e-3


def test_explicit_multipliers_equal_the_derived_ones_where_activation_is_on():
    state = _state()
    fl = np.array([row["fl"] for row in GRID])
    fv = np.array([row["fv"] for row in GRID])
    on = state.activation > 0.0
    derived = _lichtwark(state, load_lichtwark_constants())
    given = _lichtwark(state, load_lichtwark_constants(), force_length_multiplier=fl,
                       force_velocity_multiplier=fv)
    assert _close(derived.total[on], given.total[on]) <= 1e-12
    assert np.array_equal(derived.total[~on], given.total[~on])
    assert _close(houdijk2006(state, load_houdijk_constants(), force_length_multiplier=fl).total,
                  _houdijk(state, load_houdijk_constants()).total) <= 1e-12


# --- the loaders ----------------------------------------------------------------------------------


def _write_bad(tmp_path, edit):
    data = yaml.safe_load((config_dir() / "energetics_models.yaml").read_text(encoding="utf-8"))
    edit(data)
    path = tmp_path / "energetics_models.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    return path


@pytest.mark.parametrize(("loader", "edit", "field", "words"), [
    (load_lichtwark_constants, lambda d: d["lichtwark"]["max_contraction_velocity"].update(
        unit="m/s"), "lichtwark.max_contraction_velocity.unit", "not an accepted unit"),
    (load_lichtwark_constants, lambda d: d["lichtwark"].pop("force_velocity_curvature"),
     "lichtwark.force_velocity_curvature", "missing"),
    (load_houdijk_constants, lambda d: d["houdijk"]["total_heat_slow_twitch"].update(value="x"),
     "houdijk.total_heat_slow_twitch.value", "finite number"),
    (load_houdijk_constants, lambda d: d["houdijk"]["forbid_negative_total_power"].pop("source"),
     "houdijk.forbid_negative_total_power.source", "missing"),
    (load_margaria_constants, lambda d: d["margaria"]["negative_work_efficiency"].update(
        value=1.2), "margaria.negative_work_efficiency", "must be negative"),
    (load_margaria_constants, lambda d: d["margaria"]["positive_work_efficiency"].update(
        value=0.0), "margaria.positive_work_efficiency", "must be positive"),
    (load_minetti_constants, lambda d: d["minetti"]["phi_denominator"].update(
        value=[1.0, -1.13, 12.8]), "minetti.phi_denominator", "4 coefficients"),
    (load_minetti_constants, lambda d: d["minetti"].update(
        extra={"value": 1, "unit": "1", "tag": "L", "source": "x"}), "minetti.extra",
     "unknown parameter"),
])
def test_a_bad_entry_is_a_one_line_config_error(tmp_path, loader, edit, field, words):
    with pytest.raises(ConfigError) as caught:
        loader(path=_write_bad(tmp_path, edit))
    message = str(caught.value)
    assert f"'{field}'" in message and words in message and "\n" not in message
