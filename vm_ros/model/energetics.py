"""Fibre-type energetics of Tsianos, Rustin & Loeb 2012 (STEPs 1-7, Appendix B).

Energy rates are computed per fibre type from the tetanic energy-velocity relation of Barclay 1996
(mouse soleus = slow, EDL = fast), in W per kg of dry muscle, then scaled by the effective
activation, FL, and the muscle's dry mass. Velocities in L0/s, negative when shortening.

| quantity | meaning |
| E_tet(V) | tetanic initial energy rate at L0 (Barclay 1996), V <= 0 |
| E_a | activation (ion pumping) energy rate; depends on stimulation only (STEP 5) |
| E_xb | cross-bridge cycling energy rate; depends on activation, FL and V (STEP 4) |
| E_i = E_a + E_xb | initial energy rate |
| E_rec | recovery (ATP/PCr resynthesis) energy rate, R x E_i (static) or filtered (dynamic) |

References: Barclay CJ 1996 J Physiol 497:781; Tsianos, Rustin & Loeb 2012 IEEE TNSRE 20:117;
docs/model.md sections 6-7.
"""

from __future__ import annotations

import numpy as np

from vm_ros.model.jit import exp, jitable, where


@jitable
def tetanic_energy_rate_barclay1996(v, e1, e2, e3, e4):
    """E_tet(V) = (e1 V^2 + e2 V + e3) / (e4 - V), W/kg dry, for V <= 0 (V clipped at 0).

    slow e = (-76.6, -792, 124, 0.72); fast e = (145, -3322, 1530, 1.45). E_tet(0) = e3/e4:
    172.2 (slow), 1055.2 (fast) W/kg dry.
    """
    v = np.minimum(v, 0.0)
    return (e1 * v * v + e2 * v + e3) / (e4 - v)


@jitable
def cross_bridge_tetanic_rate_tsianos2012(v, e1, e2, e3, e4, activation_fraction, vmax):
    """Cross-bridge part of the tetanic rate, W/kg dry (STEPs 2-3).

    Shortening (V <= 0): E_xb_tet(V) = E_tet(V) - a E_tet(0)        (V held at or above Vmax)
    Lengthening (V > 0): E_xb_tet(V) = max(0, E_xb_tet(0) + s V),  s = (e2 e4 + e3) / e4^2,
    the tangent at V = 0; zero beyond +0.134 (slow) / +0.452 (fast) L0/s. Never negative.
    """
    e_tet_0 = e3 / e4
    e_xb_0 = (1.0 - activation_fraction) * e_tet_0
    shortening = tetanic_energy_rate_barclay1996(np.maximum(v, vmax), e1, e2, e3, e4) - (
        activation_fraction * e_tet_0
    )
    slope = (e2 * e4 + e3) / (e4 * e4)
    lengthening = e_xb_0 + slope * np.maximum(v, 0.0)
    return np.maximum(where(v <= 0.0, shortening, lengthening), 0.0)


@jitable
def activation_tetanic_rate_tsianos2012(e3, e4, activation_fraction):
    """E_a_tet = a E_tet(0) = a/(1-a) E_xb_tet(0), W/kg dry (STEPs 1, 5)."""
    return activation_fraction * e3 / e4


@jitable
def initial_energy_rates_tsianos2012(
    stimulation_activity,
    contractile_activity,
    fl,
    v,
    dry_mass_kg,
    e1,
    e2,
    e3,
    e4,
    activation_fraction,
    vmax,
):
    """Activation and cross-bridge energy rates (W), per fibre type.

    E_a_i  = M m_wet a E_tet_i(0) * sum_pools(weight * Af(f_eff, L=1, sag, no yield))   (STEP 5)
    E_xb_i = M m_wet E_xb_tet_i(V) * Acteff_i * FL_i(L)                                 (STEP 4)

    ``stimulation_activity`` and ``contractile_activity`` are (..., 2) per fibre type (recruitment,
    weighting and Af summed over the type's pools); ``dry_mass_kg`` = M m_wet broadcast to (..., 1).
    """
    e_a_tet = activation_tetanic_rate_tsianos2012(e3, e4, activation_fraction)
    e_xb_tet = cross_bridge_tetanic_rate_tsianos2012(v, e1, e2, e3, e4, activation_fraction, vmax)
    activation = dry_mass_kg * e_a_tet * stimulation_activity
    cross_bridge = dry_mass_kg * e_xb_tet * contractile_activity * fl
    return activation, cross_bridge


# --- recovery (STEP 6 and Appendix B) -------------------------------------------------------------


@jitable
def static_recovery_rate(initial_rate, recovery_ratio):
    """E_rec = R E_i (STEP 6): R = 1.5 slow, 1.0 fast."""
    return recovery_ratio * initial_rate


@jitable
def recovery_rate_from_filter(z_decay, z_rise, recovery_ratio, tau_rise, tau_decay):
    """E_rec = R (z_d - z_r) / (td - tr) from the two recovery filter states.

    The states obey dz_k/dt = E_i - z_k / tau_k (see :func:`recovery_state_step`), so E_rec is the
    convolution of E_i with h(t) = R (exp(-t/td) - exp(-t/tr)) / (td - tr), whose integral is R.
    """
    return recovery_ratio * (z_decay - z_rise) / (tau_decay - tau_rise)


def dynamic_recovery_rate(filter_states, recovery_ratio, tau_rise, tau_decay):
    """:func:`recovery_rate_from_filter` for states z = (z_d, z_r) on the last axis."""
    return recovery_rate_from_filter(
        filter_states[..., 0], filter_states[..., 1], recovery_ratio, tau_rise, tau_decay
    )


def recovery_filter_taus(tau_rise, tau_decay):
    """Time constants of the two recovery filter states, ordered (decay, rise)."""
    return np.array([tau_decay, tau_rise])


def recovery_filter_derivative(filter_states, initial_rate, taus):
    """dz/dt = E_i - z / tau for each of the two states (last axis)."""
    return initial_rate[..., None] - filter_states / taus


@jitable
def recovery_state_step(z, initial_rate, tau, dt):
    """Exact update of one recovery state dz/dt = E_i - z / tau for E_i held constant over dt."""
    return recovery_state_step_decayed(z, initial_rate, tau, exp(-dt / tau))


@jitable
def recovery_state_step_decayed(z, initial_rate, tau, decay):
    """:func:`recovery_state_step` given decay = exp(-dt / tau) (a constant of the step):
    z(t + dt) = z decay + E_i tau (1 - decay)."""
    return z * decay + initial_rate * tau * (1.0 - decay)


def recovery_filter_step(filter_states, initial_rate, taus, dt):
    """:func:`recovery_state_step` for both states (last axis, ordered as ``taus``)."""
    return recovery_state_step(filter_states, initial_rate[..., None], taus, dt)
