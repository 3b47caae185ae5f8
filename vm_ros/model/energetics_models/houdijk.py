"""Houdijk et al. 2006 heat rates, as Koelewijn et al. 2019 formulate them for one Hill muscle.

Per muscle (W), with V > 0 lengthening, a the activation, r the slow fraction, m the mass, F0 the
maximal isometric force, F_iso the active force-length multiplier; each fibre-type constant is
mixed as x = x_slow r + x_fast (1 - r):

    g_bar = 0.45 * 24.4 (slow), 0.35 * 150 (fast)               activation heat at a = 1 (W/kg)
    h_bar = 24.4 - g_bar_slow (slow), 150 - g_bar_fast (fast)   maintenance heat (W/kg)
    a_bar = (0.16 (slow), 0.28 (fast)) F0                       shortening heat coefficient (N)
    nu = a^2,  nu_max = k3 + k4 a,  k3 = 6, 12,  k4 = 8, 14
    Adot = m g_bar nu (1 - exp(-0.25 - 18.2 / (nu nu_max))) / (1 - exp(-0.25 - 18.2 / nu_max))
           (0 at a = 0)
    Mdot = m (g_bar + h_bar) a (F_iso - g_bar / (g_bar + h_bar))
    Sdot = a_bar a F_iso (-V)  (V <= 0),  0  (V > 0)
    Wdot = -F_active V  (V > 0 only with include_negative_mechanical_work; else 0)
    forbid_negative_total_power: where Adot + Mdot + Sdot + Wdot < 0, Sdot is raised to make it 0
    total = Adot + Mdot + Sdot + Wdot

At a = 1 and F_iso = 1, Adot + Mdot = m (24.4 r + 150 (1 - r)). Mdot is negative where F_iso is
below g_bar / (g_bar + h_bar), as in Koelewijn's code. Constants and sources:
config/energetics_models.yaml (section houdijk); mapping from Virtual Muscle's state:
docs/energetics_models.md.

References: Houdijk H, Bobbert MF, de Haan A (2006) J Biomech 39:536-543; as Koelewijn AD,
Heinrich D, van den Bogert AJ (2019) PLoS ONE 14(9):e0222037 implement it (their code's nu and
nu_max, which the paper leaves ambiguous, follow R. Miller's implementation).
"""

from __future__ import annotations

import numpy as np

from vm_ros.model.energetics_models.constants import HoudijkConstants
from vm_ros.model.energetics_models.state import (
    HeatRates,
    MuscleState,
    mechanical_work_rate,
    shortening_heat_for_nonnegative_total,
)
from vm_ros.model.jit import divide_where, jitable, where


@jitable
def _mixed(slow_value, fast_value, slow):
    """A fibre-type constant mixed by the slow fraction: x_slow r + x_fast (1 - r)."""
    return slow_value * slow + fast_value * (1.0 - slow)


@jitable
def houdijk2006_exponents(c, activation, slow_fraction):
    """The arguments of the two exponentials of the activation heat: -0.25 - 18.2 / (nu
    nu_max) (0 where nu nu_max = 0: its exponential is not used there) and -0.25 - 18.2 /
    nu_max."""
    a = activation
    nu_max = (_mixed(c.max_frequency_base_slow_twitch, c.max_frequency_base_fast_twitch,
                     slow_fraction)
              + _mixed(c.max_frequency_slope_slow_twitch, c.max_frequency_slope_fast_twitch,
                       slow_fraction) * a)
    product = a * a * nu_max
    exponent = divide_where(c.activation_frequency_constant, product, product > 0.0, 0.0)
    return (-c.activation_frequency_offset - exponent,
            -c.activation_frequency_offset - c.activation_frequency_constant / nu_max)


def houdijk2006_transcendentals(constants: HoudijkConstants, activation, slow_fraction):
    """The two exponentials of the activation heat (:func:`houdijk2006_exponents`), computed
    by NumPy on either path, over arrays."""
    recruited, at_max = houdijk2006_exponents(constants, np.asarray(activation, dtype=float),
                                              np.asarray(slow_fraction, dtype=float))
    return np.exp(recruited), np.exp(at_max)


@jitable
def houdijk2006_rates(c, activation, mass, velocity, slow_fraction, max_isometric_force,
                      active_fibre_force, force_length_multiplier, recruited_exp, at_max_exp):
    """(activation + maintenance, shortening, work, total) rates (W) of :func:`houdijk2006`
    from its exponentials (:func:`houdijk2006_transcendentals`): NumPy arrays, or scalars in a
    compiled loop. ``c``: HoudijkConstants or its compiled form."""
    a = activation
    slow = slow_fraction
    f_iso = force_length_multiplier
    g_slow = c.activation_fraction_slow_twitch * c.total_heat_slow_twitch
    g_fast = c.activation_fraction_fast_twitch * c.total_heat_fast_twitch
    g_bar = _mixed(g_slow, g_fast, slow)
    total_bar = _mixed(c.total_heat_slow_twitch, c.total_heat_fast_twitch, slow)
    a_bar = _mixed(c.shortening_coefficient_slow_twitch, c.shortening_coefficient_fast_twitch,
                   slow) * max_isometric_force
    nu = a * a
    product = nu * (_mixed(c.max_frequency_base_slow_twitch, c.max_frequency_base_fast_twitch,
                           slow)
                    + _mixed(c.max_frequency_slope_slow_twitch,
                             c.max_frequency_slope_fast_twitch, slow) * a)
    recruited = where(product > 0.0, 1.0 - recruited_exp, 0.0)
    at_max = 1.0 - at_max_exp
    activation_heat = mass * g_bar * nu * recruited / at_max
    maintenance_heat = mass * a * (total_bar * f_iso - g_bar)
    shortening_heat = where(velocity <= 0.0, -a_bar * a * f_iso * velocity, 0.0)
    work = mechanical_work_rate(active_fibre_force, velocity, c.include_negative_mechanical_work)
    if c.forbid_negative_total_power:
        shortening_heat = shortening_heat_for_nonnegative_total(
            shortening_heat, activation_heat + maintenance_heat + shortening_heat + work)
    total = activation_heat + maintenance_heat + shortening_heat + work
    return activation_heat + maintenance_heat, shortening_heat, work, total


def houdijk2006(state: MuscleState, constants: HoudijkConstants, *,
                force_length_multiplier) -> HeatRates:
    """Heat and work rates (W per muscle) of Houdijk et al. 2006 (equations in the module
    docstring). ``force_length_multiplier`` F_iso (1) is required (for a Hill muscle,
    umberger.force_length_multiplier_from_state gives it from the state). ``basal`` is 0."""
    a = np.asarray(state.activation, dtype=float)
    slow = np.asarray(state.slow_fraction, dtype=float)
    recruited_exp, at_max_exp = houdijk2006_transcendentals(constants, a, slow)
    activation_maintenance, shortening, work, total = houdijk2006_rates(
        constants, a, np.asarray(state.mass, dtype=float),
        np.asarray(state.fibre_velocity, dtype=float), slow, state.max_isometric_force,
        np.asarray(state.active_fibre_force, dtype=float),
        np.asarray(force_length_multiplier, dtype=float), recruited_exp, at_max_exp)
    return HeatRates(
        activation_maintenance=activation_maintenance,
        shortening_lengthening=shortening,
        basal=np.zeros_like(total),
        mechanical_work=work,
        total=total,
    )
