"""Recruitment schemes against the numbers of docs/model.md sections 5 and 9."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from vm_ros.model import recruitment as rc
from vm_ros.model.params import load_model_params

P = load_model_params()
LP = P.lumped


def test_weighting_endpoints_for_u2_032():
    # docs/model.md section 9: W_S(U1)=0.872, W_S(U2)=0.660, W_S(1)=1.005, W_F(U2)=0.811,
    # W_F(Ur)=0.768, W_F(1)=1.015 for U2 = 0.32 (Ur = 0.8)
    r = _lumped(0.4)  # U2 = 0.32, Ur = 0.8
    u2 = r.u2[0]  # 0.32 to rounding (0.8 * 0.4)
    assert u2 == pytest.approx(0.32)
    ws = lambda u: r.weighting(np.array([u]))[0, 0]  # noqa: E731
    wf = lambda u: r.weighting(np.array([u]))[0, 1]  # noqa: E731
    assert ws(0.01) == pytest.approx(0.872, abs=0.0006)
    assert ws(u2) == pytest.approx(0.660, abs=0.0006)
    assert ws(1.0) == pytest.approx(1.005, abs=0.0012)
    assert wf(u2) == pytest.approx(0.811, abs=0.0006)
    assert wf(0.8) == pytest.approx(0.768, abs=0.0006)
    assert wf(1.0) == pytest.approx(1.015, abs=0.0012)
    assert ws(0.005) == 0.0 and wf(0.31) == 0.0


def test_lumped_drive_filter_is_one_ms_for_full_step_and_t_rise_for_small():
    u2 = 0.32
    t_rise = 0.38 * u2**2 + 0.8 * u2 + 0.14
    t_fall = -0.32 * u2**4 + 0.82 * u2**3 - 0.28 * u2**2 + 0.014 * u2 + 0.09
    r = _lumped(0.4, params=dataclasses.replace(LP, drive_law="tsianos2012"))  # U2 = 0.32

    def tau(u, ueff):
        slow, fast = r.drive_tau(np.array([u]), np.array([ueff]), np.ones((1, 2)),
                                 np.ones((1, 2)))[0]
        assert slow == fast  # one law of (U, Ueff): both types' Ueff alike
        return slow

    assert tau(1.0, 0.0) == pytest.approx(0.001, rel=1e-9)
    assert tau(0.5, 0.5) == pytest.approx(t_rise, rel=1e-12)
    assert tau(0.2, 0.5) == pytest.approx(t_fall, rel=1e-12)


def test_relative_drive_law_at_its_limits():
    # docs/model.md section 5c, with hand-chosen constants
    lumped = dataclasses.replace(LP, drive_law="relative_drive", relative_rise_poly=(0.1,),
                                 relative_fall_poly=(0.6,),
                                 relative_fall_power=4.0, relative_fall_floor=0.05,
                                 drive_tau_min=1e-4)
    r = _lumped(0.4, params=lumped)

    def tau(u, ueff, active=1.0):
        m = np.array([[active, active]])
        slow, fast = r.drive_tau(np.array([u]), np.array([[ueff, ueff]]), m, m)[0]
        assert slow == fast  # both types by the same law
        return slow

    # rises: T_r m, by the firing match m, not by the size of the rise
    assert tau(0.5, 0.0, active=0.0) == 1e-4  # from rest, no unit firing: no lag beyond the floor
    assert tau(0.6, 0.3, active=0.0) == 1e-4  # units no longer firing: as from rest
    assert tau(0.0, 0.0, active=0.0) == 1e-4  # at rest
    assert tau(0.6, 0.3) == pytest.approx(0.1)
    assert tau(0.9, 0.1) == pytest.approx(0.1)  # a larger rise, the same T_U
    assert tau(0.6, 0.3, active=0.5) == pytest.approx(0.1 * 0.5)
    assert tau(0.5, 0.5) == pytest.approx(0.1)  # caught up and firing: T_r
    # falls: by the firing match m, not by the size of the fall
    assert tau(0.0, 0.8, active=0.0) == pytest.approx(0.05 + 0.6)  # release, not firing: T_f0 + T_f
    assert tau(0.3, 0.6, active=0.5) == pytest.approx(0.05 + 0.6 * 0.5**4)
    assert tau(0.3, 0.6) == pytest.approx(0.05)  # firing rate down at its target: T_f0
    assert tau(0.59, 0.6, active=0.9) == pytest.approx(0.05 + 0.6 * 0.1**4)
    # each type's m on a fall: the slow unit's firing match while U is at or above the type's
    # threshold, 0 below it. A fall from 0.6 to 0.2 with U2 = 0.32: the slow unit near its target
    # (m 0.9), every fast unit released (W_F held as on a release to rest: T_f0 + T_f)
    f_env = np.where(r.thresholds <= 0.2, 1.0, 0.0)  # the slow type driven at 0.2, the fast not
    fall = rc.type_match(np.array([[0.9]]), f_env)
    assert fall.tolist() == [[0.9, 0.0]]
    taus = r.drive_tau(np.array([0.2]), np.array([[0.6, 0.6]]), np.ones((1, 2)), fall)[0]
    assert taus == pytest.approx([0.05 + 0.6 * 0.1**4, 0.05 + 0.6])
    # on a rise each type's own unit: from 0.3 to 0.6 across U2, the slow unit firing at its
    # target (m 1: T_r), the fast unit not yet firing (m 0: from rest, no lag)
    rise = np.array([[1.0, 0.0]])
    taus = r.drive_tau(np.array([0.6]), np.array([[0.3, 0.3]]), rise, np.ones((1, 2)))[0]
    assert taus == pytest.approx([0.1, 1e-4])


def test_one_power_of_the_slow_match_gives_each_types_fall_share():
    # (1 - m_fall)^p of each type: the slow unit's match m while the type is driven, 0 (share 1)
    # below its threshold; the compiled step takes one power per muscle for both types
    slow_match = np.array([0.0, 0.5, 0.9, 1.0, 0.3])
    f_env = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [1.0, 1.0], [1.0, 0.0]])
    driven = rc.relative_fall_share(slow_match, 2.5)
    assert driven == pytest.approx((1 - slow_match) ** 2.5, rel=1e-15)
    shares = rc.type_fall_share(driven[:, None], f_env)
    assert shares.tolist() == [[1.0, 1.0], [0.5**2.5, 1.0], [driven[2], driven[2]],
                               [0.0, 0.0], [0.7**2.5, 1.0]]
    assert np.array_equal(shares, rc.relative_fall_share(rc.type_match(slow_match[:, None],
                                                                       f_env), 2.5))


def test_firing_match():
    f = rc.firing_match(np.array([0.0, 0.5, 2.0, 1.0, 0.0]), np.array([1.0, 1.0, 1.0, 0.0, 0.0]))
    assert f.tolist() == [0.0, 0.5, 0.5, 0.0, 0.0]


def _lumped(fs, ur=0.8, params=LP):
    return rc.LumpedRecruitment(np.array([[fs, 1 - fs]]), np.array([ur]), params)


def test_lumped_recruitment_capped_at_full_recruitment_of_each_type():
    r = _lumped(0.4)  # U2 = 0.32
    assert r.u2[0] == pytest.approx(0.32)
    rf = r.recruited_fraction(None, np.array([0.32]))
    assert rf[0, 0] == pytest.approx(0.4) and rf[0, 1] == 0.0
    rf = r.recruited_fraction(None, np.array([0.8]))
    assert rf[0] == pytest.approx([0.4, 0.6])
    rf = r.recruited_fraction(None, np.array([0.56]))
    assert rf[0, 1] == pytest.approx(0.6 * 0.5)


@pytest.mark.parametrize("scheme", rc.SCHEMES)
@pytest.mark.parametrize("fs", [0.0, 1.0])
def test_pure_muscles_have_no_absent_type_and_finite_weights(scheme, fs):
    r = rc.make_recruitment(scheme, np.array([[fs, 1 - fs]]), np.array([0.8]), P)
    absent = 1 if fs == 1.0 else 0
    members = r.fibre_index == absent
    for u in np.linspace(0, 1, 41):
        w = r.pool_weights(np.array([u]))
        assert np.all(np.isfinite(w))
        assert np.all(w[0, members] == 0.0)
        assert np.all(np.isfinite(r.recruited_fraction(np.array([u]), np.array([u]))))


def test_natural_thresholds_equal_apportioning():
    n = 10
    params = P.natural.__class__(units_per_type=n, apportioning="equal", geometric_ratio=10.0,
                                 u_threshold_min=0.001)
    r = rc.NaturalRecruitment(np.array([[0.4, 0.6]]), np.array([0.8]), params)
    p = r.pool_pcsa[0]
    assert p[:n] == pytest.approx(np.full(n, 0.04)) and p[n:] == pytest.approx(np.full(n, 0.06))
    th = r.thresholds[0]
    # Uth_j = Ur * cumulative PCSA up to and including j; last unit at Ur
    assert th[0] == pytest.approx(0.8 * 0.04) and th[-1] == pytest.approx(0.8)
    assert th[n - 1] == pytest.approx(0.32)  # last slow unit at U2
    assert np.all(np.diff(th) > 0)


def test_natural_geometric_apportioning_sizes_grow_by_ratio():
    params = P.natural.__class__(units_per_type=5, apportioning="geometric", geometric_ratio=10.0,
                                 u_threshold_min=0.001)
    r = rc.NaturalRecruitment(np.array([[0.5, 0.5]]), np.array([0.8]), params)
    p = r.pool_pcsa[0]
    assert p[4] / p[0] == pytest.approx(10.0) and p[:5].sum() == pytest.approx(0.5)


def test_continuous_weights_follow_song2008():
    r = rc.ContinuousRecruitment(np.array([[0.5, 0.5]]), np.array([0.8]), P.continuous)
    assert r.thresholds[0] == pytest.approx([0.001, 0.4])
    w = r.pool_weights(np.array([0.6]))[0]
    d = (0.6 - 0.001) + (0.6 - 0.4)
    assert w == pytest.approx([0.6 * (0.599 / d), 0.6 * (0.2 / d)])
    m = np.ones((1, 2))
    assert r.drive_tau(np.array([1.0]), np.array([0.0]), m, m)[0].tolist() == [0.03] * 2
    falling = r.drive_tau(np.array([0.0]), np.array([1.0]), m, m)[0]
    assert all(math.isclose(float(t), 0.15) for t in falling)
