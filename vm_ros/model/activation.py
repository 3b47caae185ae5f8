"""Activation path per motor-unit pool: firing envelope, rise/fall filter, sag and yield.

Every state here obeys a first-order lag dy/dt = (target - y) / tau. Functions return the
(target, tau) pair, so the same numbers serve the continuous right-hand side handed to
``solve_ivp`` (:func:`lag_derivative`) and the fixed-step exact update (:func:`lag_step`), which is
unconditionally stable for any dt.

Rates in f0.5, time in s, L in L0, V in L0/s (negative shortening).
References: Brown & Loeb 2000; Cheng, Brown & Loeb 2000; docs/model.md section 3.
"""

from __future__ import annotations

import numpy as np

from vm_ros.model.jit import exp, expm1, jitable, where


@jitable
def lag_derivative(y, target, tau):
    """dy/dt of a first-order lag."""
    return (target - y) / tau


@jitable
def lag_decay(tau, dt):
    """exp(-dt / tau): how much of a first-order lag's distance to its target is left after dt."""
    return exp(-dt / tau)


@jitable
def lag_step_decayed(y, target, decay):
    """:func:`lag_step` given its ``decay`` = :func:`lag_decay` (tau, dt), which the compiled step
    evaluates once per call for time constants that are constants of the pool."""
    return target + (y - target) * decay


@jitable
def lag_step(y, target, tau, dt):
    """Exact update of a first-order lag over dt with target and tau held constant:
    y(t + dt) = target + (y - target) exp(-dt / tau)."""
    return lag_step_decayed(y, target, lag_decay(tau, dt))


@jitable
def cascade_step(y1, y2, target, tau, dt):
    """Exact update of two cascaded lags sharing one tau (dy1 = (target - y1)/tau,
    dy2 = (y1 - y2)/tau), target and tau held constant over dt. Returns (y1, y2)."""
    ratio = dt / tau
    decay = exp(-ratio)
    d1 = y1 - target
    return target + d1 * decay, target + ((y2 - target) + d1 * ratio) * decay


@jitable
def firing_envelope(u, u_threshold, fmin, fmax):
    """Firing rate (f0.5) of a unit of threshold Uth at drive U.

    f_env = fmin + (fmax - fmin) (U - Uth) / (1 - Uth)   for U >= Uth, else 0
    fmin = 0.5, fmax = 2.0 (VM 4.0).
    """
    span = np.maximum(1.0 - u_threshold, 1e-9)
    rate = fmin + (fmax - fmin) * (u - u_threshold) / span
    return where(u >= u_threshold, rate, 0.0)


@jitable
def rise_fall_time_constant(f_env, f_int, f_eff, l, af_value, tf1, tf2, tf3, tf4):
    """Shared time constant (s) of the two cascaded rise/fall stages.

    Tf = Tf1 L^2 + Tf2 f_env        if f_int >= f_eff   (rise)
       = (Tf3 + Tf4 Af) / L         otherwise           (fall)
    """
    rise = tf1 * l * l + tf2 * f_env
    fall = (tf3 + tf4 * af_value) / l
    return where(f_int >= f_eff, rise, fall)


@jitable
def sag_target(f_eff, as1, as2, threshold):
    """Sag target aS: aS1 below f_eff = 0.1 f0.5, aS2 above (fast fibres; neutral 1 for slow)."""
    return where(f_eff < threshold, as1, as2)


@jitable
def yield_target(v, cy, vy):
    """Yield target 1 - cY (1 - exp(-|V|/VY)) (slow fibres; cY = 0 makes it 1 for fast)."""
    return 1.0 - cy * (-expm1(-np.abs(v) / vy))


def activation_length_max(nf0, nf1, max_fraction):
    """Largest L (L0) used inside the activation relations: ``max_fraction`` of L_nf0 =
    nf1 / (nf1 - nf0), the length at which nf reaches zero (1.72 slow, 2.75 fast). The step
    clips L to [l_activation_min, this] per pool."""
    return max_fraction * nf1 / (nf1 - nf0)
