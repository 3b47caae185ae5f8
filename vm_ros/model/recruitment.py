"""Recruitment schemes: how drive U maps onto motor-unit pools and their weights.

A scheme describes P pools per muscle (P = 2 for lumped and continuous: one slow, one fast; P = 2N
for N natural units per type). Every pool fires through the same activation path (activation.py)
from its firing threshold; the scheme supplies, per muscle and pool:

| attribute / method | shape | meaning |
| ``fibre_index`` | (P,) | fibre type of each pool (0 slow, 1 fast) |
| ``thresholds`` | (n, P) | drive at which the pool starts firing (raw U) |
| ``pool_pcsa`` | (n, P) | PCSA fraction of the pool (sums to 1 per muscle) |
| ``drive_tau(u, ueff, rise, fall)`` | (n, 2) | time constant of the filtered drive Ueff of |
| | | each fibre type (None: no filter); lumped: by ``params.drive_law`` (DRIVE_LAWS); |
| | | ``rise``, ``fall`` (n, 2): m of each type on a rise (each lumped unit's |
| | | :func:`firing_match`) and on a fall (:func:`type_match`) |
| ``pool_weights(ueff)`` | (n, P) | weight so that effective activation = weight * Af |
| ``recruited_fraction(u, ueff)`` | (n, P) | recruited PCSA fraction of the pool |

``ueff`` is the filtered drive per fibre type, (n, 2) (slow, fast); :func:`drive_per_type` makes
it from one drive per muscle (n,). The filter acts on each type's Ueff alike; only the lumped
scheme's relative_drive law, which reads each type's own unit on a rise and holds a type's W once
U is below its threshold (:func:`type_match`), moves them apart.

References: Cheng, Brown & Loeb 2000 (natural units); Song et al. 2008 (continuous);
Tsianos, Rustin & Loeb 2012 Appendix A (lumped units).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from vm_ros.model.jit import clip, exp, expm1, jitable, power, where
from vm_ros.model.params import (
    FAST,
    SCHEMES,
    SLOW,
    ContinuousParams,
    LumpedParams,
    NaturalParams,
)

_TINY = 1e-12


def drive_per_type(ueff) -> np.ndarray:
    """Filtered drive per fibre type (..., n, 2): ``ueff`` as given when it has that form (two
    axes or more), else one drive per muscle (n,) for both types."""
    ueff = np.asarray(ueff, dtype=float)
    return ueff if ueff.ndim >= 2 else np.stack([ueff, ueff], axis=-1)


@jitable
def safe_ratio(numerator, denominator):
    """numerator / denominator with |denominator| held at or above 1e-12."""
    return numerator / where(np.abs(denominator) > _TINY, denominator, _TINY)


@jitable
def polyval_horner(coefficients, x):
    """Polynomial with ``coefficients`` (highest power first) at x, by Horner's rule."""
    result = 0.0 * x
    for c in coefficients:
        result = result * x + c
    return result


def fast_threshold(fpcsa_slow, ur):
    """U2 = Ur * Fpcsa_S, the drive at which the first fast unit is recruited."""
    return ur * fpcsa_slow


# --- Tsianos 2012 lumped units -------------------------------------------------------------------


@dataclass(frozen=True)
class LumpedCoefficients:
    """The lumped model's coefficients that depend on U2 only, evaluated once per muscle (n,)."""

    t_rise: np.ndarray
    t_fall: np.ndarray
    relative_rise: np.ndarray
    relative_fall: np.ndarray
    w_slow_at_u2: np.ndarray
    w_slow_amplitude: np.ndarray
    w_fast_b: np.ndarray
    w_fast_c: np.ndarray
    w_fast_tau: np.ndarray

    @classmethod
    def tsianos2012(cls, u2, p: LumpedParams) -> LumpedCoefficients:
        """T_rise = 0.38 U2^2 + 0.8 U2 + 0.14; T_fall = -0.32 U2^4 + 0.82 U2^3 - 0.28 U2^2
        + 0.014 U2 + 0.09; W_S(U2); A = -1.99 U2^4 + 1.90 U2^3 - 1.75 U2^2 + 1.19 U2 + 0.13;
        B = 0.59 U2 + 0.39; C = -98.82 U2^5 + 155.7 U2^4 - 85.96 U2^3 + 19.32 U2^2 - 2.62 U2
        + 1.02; tau_f = -0.27 U2 + 0.25 (held above 1e-12). Constants for Ur = 0.8.
        T_r(U2) and T_f(U2) of the relative_drive law (fitted, vm_ros.model.lumped_fit)."""
        u2 = np.asarray(u2, dtype=float)
        return cls(
            t_rise=np.polyval(p.t_rise_poly, u2),
            t_fall=np.polyval(p.t_fall_poly, u2),
            relative_rise=np.polyval(p.relative_rise_poly, u2),
            relative_fall=np.polyval(p.relative_fall_poly, u2),
            w_slow_at_u2=np.polyval(p.w_slow_poly, u2),
            w_slow_amplitude=np.polyval(p.w_slow_a_poly, u2),
            w_fast_b=np.polyval(p.w_fast_b_poly, u2),
            w_fast_c=np.polyval(p.w_fast_c_poly, u2),
            w_fast_tau=np.maximum(np.polyval(p.w_fast_tau_poly, u2), _TINY),
        )


@jitable
def lumped_drive_tau(u, ueff, t_rise, t_fall, step_scale):
    """Time constant (s) of the lumped model's filtered drive Ueff.

    U >= Ueff: T_U = T_rise exp(-(U - Ueff) ln(1000 T_rise));  U < Ueff: T_U = T_fall.
    T_U is T_rise for small steps and 1 ms for a full 0 -> 1 step.
    """
    return lumped_drive_tau_from_rate(
        u, ueff, t_rise, t_fall, lumped_drive_rise_rate(t_rise, step_scale)
    )


@jitable
def lumped_drive_rise_rate(t_rise, step_scale):
    """ln(1000 T_rise) of :func:`lumped_drive_tau`, a constant of the muscle (1 per unit of U)."""
    return np.log(step_scale * t_rise)


@jitable
def lumped_drive_tau_from_rate(u, ueff, t_rise, t_fall, rise_rate):
    """:func:`lumped_drive_tau` given ``rise_rate`` = :func:`lumped_drive_rise_rate`."""
    rising = t_rise * exp(-(u - ueff) * rise_rate)
    return where(u >= ueff, rising, t_fall)


@jitable
def firing_match(f_eff, f_env):
    """How near a pool's firing rate is to its target, from either side: min(f_eff, f_env) /
    max(f_eff, f_env) (0 at rest or with no target)."""
    low, high = np.minimum(f_eff, f_env), np.maximum(f_eff, f_env)
    return where(high > 0.0, clip(safe_ratio(low, high), 0.0, 1.0), 0.0)


@jitable
def relative_drive_tau(u, ueff, rise_active, fall_share, t_rise, t_fall, fall_floor, tau_min):
    """Time constant (s) of a fibre type's filtered drive Ueff, relative_drive law (docs/model.md
    section 5d).

    U >= Ueff: T_U = T_r m_rise whatever the size of the rise (a power q of Ueff / U was fitted at
    its bound 0 and removed), m_rise (``rise_active``) the firing match of the type's own lumped
    unit (:func:`firing_match`): 0 from rest, where the unit's own firing-rate rise carries the lag
    as each natural unit's does (the fast unit too, when U crosses U2 on top of active slow
    units); up to T_r when units are recruited on top of active ones of the type, which build up
    behind them.
    U < Ueff: T_U = T_f0 + T_f (1 - m_fall)^p, ``fall_share`` = (1 - m_fall)^p
    (:func:`relative_fall_share`), m_fall (:func:`type_match`) the
    slow unit's firing match while U is at or above the type's threshold, 0 below it: T_f0 + T_f
    while the firing rate is still far above its new target or the type is released (m = 0: W
    held while the firing rate, and with it Af, decays as in natural units; a fall below U2
    releases every fast unit while the slow ones stay active); T_f0, the pace at which
    derecruited units let go, once the firing rate has come down to the target of a partial
    release (m -> 1).
    Held at or above ``tau_min``.
    """
    return np.maximum(where(u >= ueff, t_rise * rise_active, fall_floor + t_fall * fall_share),
                      tau_min)


@jitable
def relative_fall_share(fall_active, fall_power):
    """(1 - m_fall)^p of :func:`relative_drive_tau` (1 for m_fall = 0: a released type)."""
    return power(clip(1.0 - fall_active, 0.0, 1.0), fall_power)


@jitable
def type_fall_share(driven_share, f_env):
    """:func:`relative_fall_share` of a type's m_fall (:func:`type_match`) given ``driven_share``,
    that of the slow unit's firing match: it while the type is driven (``f_env`` > 0), 1 once U is
    below its threshold (m_fall 0; the power of 1 is 1 exactly). One power per muscle serves both
    types."""
    return where(f_env > 0.0, driven_share, 1.0)


@jitable
def type_match(slow_match, f_env):
    """m of a fibre type's filtered drive on a fall: the slow unit's firing match while the type
    is driven (its firing target ``f_env`` > 0, U at or above its threshold), 0 once U is below
    its threshold (every unit of the type released)."""
    return where(f_env > 0.0, slow_match, 0.0)


@jitable
def linear_recruited_fraction(ueff, fpcsa, lower, upper):
    """rF = Fpcsa clip((Ueff - lower) / (upper - lower), 0, 1); 0 for an absent type."""
    fraction = clip(safe_ratio(ueff - lower, upper - lower), 0.0, 1.0)
    return where(fpcsa > 0.0, fpcsa * fraction, 0.0)


def lumped_recruited_fraction_tsianos2012(ueff, fpcsa, lower, upper):
    """rF_i = Fpcsa_i clip((Ueff_i - lower_i) / (upper_i - lower_i), 0, 1); 0 for an absent type
    (``ueff`` per type, (n, 2)).

    lower = (U1, U2); upper = (U2, Ur) capped (docs/model.md 5b note) or (1, 1) as the paper reads.
    """
    return linear_recruited_fraction(drive_per_type(ueff), fpcsa, lower, upper)


@jitable
def lumped_weight_slow(ueff, u1, u2, w_slow_poly, at_u2, amplitude, tau):
    """W_S(Ueff): 0 below U1; 1.56 Ueff^2 - 1.20 Ueff + 0.884 up to U2;
    W_S(U2) + A (1 - exp(-(Ueff - U2)/0.26)) above."""
    quadratic = polyval_horner(w_slow_poly, np.minimum(ueff, u2))
    above = at_u2 - amplitude * expm1(-np.maximum(ueff - u2, 0.0) / tau)
    return where(ueff < u1, 0.0, where(ueff <= u2, quadratic, above))


@jitable
def lumped_weight_fast(ueff, u2, ur, b, c, tau_f, offset, rise):
    """W_F(Ueff): 0 below U2; ((Ueff - B)/C)^2 + 0.65 up to Ur;
    W_F(Ur) + 0.35 (1 - exp(-(Ueff - Ur)/tau_f)) above."""
    quadratic = safe_ratio(np.minimum(ueff, ur) - b, c) ** 2 + offset
    at_ur = safe_ratio(ur - b, c) ** 2 + offset
    above = at_ur - rise * expm1(-np.maximum(ueff - ur, 0.0) / tau_f)
    return where(ueff < u2, 0.0, where(ueff < ur, quadratic, above))


@dataclass(frozen=True)
class _OnePoolPerFibreType:
    """Schemes with one pool per fibre type (lumped, continuous): the pools are the types."""

    fpcsa: np.ndarray  # (n, 2)
    ur: np.ndarray  # (n,)

    @cached_property
    def fibre_index(self):
        return np.array([SLOW, FAST])

    @cached_property
    def pool_pcsa(self):
        return self.fpcsa


@dataclass(frozen=True)
class LumpedRecruitment(_OnePoolPerFibreType):
    """One lumped unit per fibre type (Tsianos 2012 Appendix A), the default scheme."""

    params: LumpedParams
    name: str = "lumped"

    @cached_property
    def u2(self):
        return fast_threshold(self.fpcsa[:, SLOW], self.ur)

    @cached_property
    def thresholds(self):
        return np.stack([np.full_like(self.ur, self.params.u1), self.u2], axis=-1)

    @cached_property
    def coefficients(self) -> LumpedCoefficients:
        return LumpedCoefficients.tsianos2012(self.u2, self.params)

    @cached_property
    def w_slow_poly(self) -> np.ndarray:
        return np.asarray(self.params.w_slow_poly, dtype=float)

    def drive_tau(self, u, ueff, rise, fall):
        """T_U of each fibre type's Ueff (n, 2); ``rise``, ``fall`` (n, 2): m of each type on a
        rise and on a fall (:func:`relative_drive_tau`)."""
        c, p = self.coefficients, self.params
        u, ueff = np.asarray(u, dtype=float)[:, None], drive_per_type(ueff)
        if p.drive_law == "relative_drive":
            return relative_drive_tau(u, ueff, rise,
                                      relative_fall_share(fall, p.relative_fall_power),
                                      c.relative_rise[:, None], c.relative_fall[:, None],
                                      p.relative_fall_floor, p.drive_tau_min)
        return lumped_drive_tau(u, ueff, c.t_rise[:, None], c.t_fall[:, None],
                                p.t_rise_step_scale)

    @cached_property
    def recruitment_range(self):
        """Drive (lower, upper), each (n, 2), over which rF rises from 0 to Fpcsa: (U1, U2) to
        (U2, Ur) capped at full recruitment, or (1, 1) as the paper reads."""
        lower = self.thresholds
        if self.params.cap_recruitment_at_full:
            upper = np.stack([self.u2, self.ur], axis=-1)
        else:
            upper = np.ones_like(lower)
        return lower, upper

    def recruited_fraction(self, u, ueff):
        lower, upper = self.recruitment_range
        return lumped_recruited_fraction_tsianos2012(ueff, self.fpcsa, lower, upper)

    def weighting(self, ueff):
        """Weighting (W_S, W_F) at each type's filtered drive Ueff (n, 2) (or one drive (n,)),
        shape (n, 2)."""
        c, p, u2 = self.coefficients, self.params, self.u2
        ueff = drive_per_type(ueff)
        return np.stack(
            [
                lumped_weight_slow(
                    ueff[..., SLOW], p.u1, u2, self.w_slow_poly, c.w_slow_at_u2, c.w_slow_amplitude,
                    p.w_slow_tau,
                ),
                lumped_weight_fast(
                    ueff[..., FAST], u2, self.ur, c.w_fast_b, c.w_fast_c, c.w_fast_tau,
                    p.w_fast_offset, p.w_fast_rise,
                ),
            ],
            axis=-1,
        )

    def pool_weights(self, ueff):
        return self.recruited_fraction(ueff, ueff) * self.weighting(ueff)


# --- Cheng 2000 natural (discrete) units ---------------------------------------------------------


def natural_unit_pcsa_cheng2000(fpcsa, units_per_type: int, apportioning: str, ratio: float):
    """PCSA fraction of each unit, slow units then fast, shape (n, 2 N).

    equal: each of a type's N units gets Fpcsa_t / N.
    geometric: within a type unit sizes grow geometrically from smallest (recruited first) to
    largest, largest/smallest = ``ratio``; normalised to Fpcsa_t.
    """
    n = int(units_per_type)
    if apportioning == "geometric" and n > 1:
        shape = ratio ** (np.arange(n) / (n - 1))
    else:
        shape = np.ones(n)
    shape = shape / shape.sum()
    return np.concatenate([fpcsa[:, SLOW, None] * shape, fpcsa[:, FAST, None] * shape], axis=-1)


def natural_thresholds_cheng2000(unit_pcsa, ur, u_min):
    """Uth_j = max(u_min, Ur * sum_{k <= j} p_k): the last unit is recruited at Ur."""
    return np.maximum(u_min, ur[:, None] * np.cumsum(unit_pcsa, axis=-1))


@dataclass(frozen=True)
class NaturalRecruitment:
    """N discrete units per fibre type (Cheng 2000; VM 4.0 'natural discrete', no Leff)."""

    fpcsa: np.ndarray  # (n, 2)
    ur: np.ndarray  # (n,)
    params: NaturalParams
    name: str = "natural"

    @cached_property
    def units_per_type(self) -> int:
        return int(self.params.units_per_type)

    @cached_property
    def fibre_index(self):
        return np.repeat([SLOW, FAST], self.units_per_type)

    @cached_property
    def pool_pcsa(self):
        return natural_unit_pcsa_cheng2000(
            self.fpcsa, self.units_per_type, self.params.apportioning, self.params.geometric_ratio
        )

    @cached_property
    def thresholds(self):
        return natural_thresholds_cheng2000(self.pool_pcsa, self.ur, self.params.u_threshold_min)

    def drive_tau(self, u, ueff, rise, fall):
        return None

    def recruited_fraction(self, u, ueff):
        return np.where(u[..., None] >= self.thresholds, self.pool_pcsa, 0.0)

    def pool_weights(self, ueff):
        return self.pool_pcsa


# --- Song 2008 continuous recruitment ------------------------------------------------------------


@jitable
def continuous_excess_song2008(ueff, threshold, present):
    """max(Ueff - Uth_i, 0) for a present fibre type, else 0."""
    return where(present, np.maximum(ueff - threshold, 0.0), 0.0)


@jitable
def continuous_share_song2008(excess, total_excess):
    """W_i = excess_i / D, D = sum_i excess_i (1 where D = 0)."""
    return excess / where(total_excess > 0.0, total_excess, 1.0)


@jitable
def continuous_drive_tau_song2008(u, ueff, tau_rise, tau_fall):
    """Time constant (s) of the filtered drive: tau_rise while U >= Ueff, else tau_fall."""
    return where(u >= ueff, tau_rise, tau_fall)


def continuous_weighting_song2008(ueff, thresholds, present):
    """W_i = max(Ueff - Uth_i, 0) / D, D = sum_i max(Ueff - Uth_i, 0) (1 if 0); absent types 0."""
    excess = continuous_excess_song2008(ueff[:, None], thresholds, present)
    return continuous_share_song2008(excess, excess.sum(axis=-1, keepdims=True))


@dataclass(frozen=True)
class ContinuousRecruitment(_OnePoolPerFibreType):
    """Continuous recruitment (Song 2008; VM 4.0 'natural continuous')."""

    params: ContinuousParams
    name: str = "continuous"

    @cached_property
    def thresholds(self):
        u_min = self.params.u_threshold_min
        u2 = np.maximum(fast_threshold(self.fpcsa[:, SLOW], self.ur), u_min)
        return np.stack([np.full_like(u2, u_min), u2], axis=-1)

    def drive_tau(self, u, ueff, rise, fall):
        return continuous_drive_tau_song2008(np.asarray(u, dtype=float)[:, None],
                                             drive_per_type(ueff), self.params.tau_rise,
                                             self.params.tau_fall)

    def recruited_fraction(self, u, ueff):
        """Reported as the lumped scheme's linear recruitment (it does not enter the force)."""
        lower = self.thresholds
        upper = np.stack([lower[:, FAST], self.ur], axis=-1)
        return lumped_recruited_fraction_tsianos2012(ueff, self.fpcsa, lower, upper)

    def pool_weights(self, ueff):
        """Ueff W_i, with the slow type's Ueff (one filter: both types' Ueff are equal)."""
        ueff = drive_per_type(ueff)[..., SLOW]
        weighting = continuous_weighting_song2008(ueff, self.thresholds, self.fpcsa > 0.0)
        return ueff[:, None] * weighting


def make_recruitment(scheme: str, fpcsa, ur, params):
    """Build the scheme named ``scheme`` from (n, 2) PCSA fractions, (n,) Ur and ModelParams."""
    if scheme == "lumped":
        return LumpedRecruitment(fpcsa, ur, params.lumped)
    if scheme == "natural":
        return NaturalRecruitment(fpcsa, ur, params.natural)
    if scheme == "continuous":
        return ContinuousRecruitment(fpcsa, ur, params.continuous)
    raise ValueError(f"unknown recruitment scheme {scheme!r}; choose one of {SCHEMES}")
