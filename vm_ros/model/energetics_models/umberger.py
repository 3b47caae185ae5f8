"""Umberger et al. 2003 and Umberger 2010 heat rates, as OpenSim 4.6's
Umberger2010MuscleMetabolicsProbe computes them (with Uchida et al. 2016's revisions as options).

Per kg of muscle (W/kg), with velocity V > 0 lengthening, V_n = V / L0 (L0/s), k the
muscle_effort_scaling_factor, u = k U and a = k A, S the aerobic_factor, F_iso the active
force-length multiplier at the current length, Vmax the max_contraction_velocity (L0/s):

    A_eff = u (u > a), (u + a) / 2 (u <= a)
    r' = r, or with use_Bhargava_recruitment_model u_slow / (u_slow + u_fast) (1 at u = 0),
         u_slow = r sin(pi u / 2), u_fast = (1 - r) (1 - cos(pi u / 2))
    h = 128 (1 - r') + 25
    AMdot = S A_eff^0.6 h (L <= L0);  S A_eff^0.6 (0.4 h + 0.6 h F_iso) (L > L0)
    alpha_fast = 153 / Vmax, alpha_slow = 100 / (Vmax / 2.5)
    Sdot = S A_eff^2 (min(-alpha_slow V_n, 100) r' + alpha_fast |V_n| (1 - r'))   (V <= 0)
    Sdot = S A_eff alpha_L alpha_slow V_n,  alpha_L = 4.0 with
           include_negative_mechanical_work, 0.3 without (Umberger 2010)          (V > 0)
    Sdot *= F_iso where L > L0
    Wdot = -max(F_active, 0) V / m  (V > 0 only with include_negative_mechanical_work; else 0)
    forbid_negative_total_power: where AMdot + Sdot + Wdot < 0, Sdot is raised to make it 0
    heat = AMdot + Sdot, not below minimum_heat_rate when enforce_minimum_heat_rate_per_muscle
           and both heat rates are on
    total = m (heat (or the heat rates that are on) + Wdot (if on))

F_active = k * active fibre force. Variants (config umberger_variants, from OpenSim's property
descriptions): umberger2003 (alpha_L 4.0 with negative work), umberger2010 (alpha_L 0.3, no
negative work), uchida2016 (OpenSim's defaults: Bhargava recruitment and no negative total power
added to umberger2003). Constants and sources: config/energetics_models.yaml (section umberger);
mapping from Virtual Muscle's state: docs/energetics_models.md.

References: Umberger BR, Gerritsen KG, Martin PE (2003) Comput Methods Biomech Biomed Engin
6:99-111; Umberger BR (2010) J R Soc Interface 7:1329-1340; Uchida TK et al. (2016) PLOS ONE
11(3):e0150378; all as implemented in OpenSim 4.6
(OpenSim/Simulation/Model/Umberger2010MuscleMetabolicsProbe.cpp).
"""

from __future__ import annotations

import numpy as np

from vm_ros.model.energetics_models.bhargava import (
    recruited_excitations_from_angle,
    recruitment_sin_cos,
)
from vm_ros.model.energetics_models.constants import UmbergerConstants
from vm_ros.model.energetics_models.state import (
    HeatRates,
    MuscleState,
    mechanical_work_rate,
    shortening_heat_for_nonnegative_total,
)
from vm_ros.model.jit import divide_where, jitable, maximum, minimum, where


def force_length_multiplier_from_state(state: MuscleState):
    """F_iso = isometric_force / (activation * F0) (1), where activation * F0 > 0; 1 elsewhere
    (where the state does not determine it: the lengthened-fibre heat rates then equal those at
    L <= L0). Exact for a force proportional to activation (OpenSim's muscles); for Virtual
    Muscle, whose active force is not, pass the force-length factor itself
    (docs/energetics_models.md section 7)."""
    denominator = np.asarray(state.activation, dtype=float) * state.max_isometric_force
    isometric = np.asarray(state.isometric_force, dtype=float)
    return np.divide(isometric, denominator, out=np.ones(np.broadcast(isometric,
                     denominator).shape), where=denominator > 0.0)


@jitable
def recruited_slow_share(excitation, u_slow, u_fast):
    """u_slow / (u_slow + u_fast), 1 at zero excitation: the slow fraction of the recruited
    fibres."""
    both = u_slow + u_fast
    return divide_where(u_slow, both, (excitation != 0.0) & (both != 0.0), 1.0)


def recruited_slow_fraction(excitation, slow_fraction):
    """Bhargava 2004's recruitment as OpenSim's Umberger probe uses it: the slow fraction of the
    recruited fibres, u_slow / (u_slow + u_fast), 1 at zero excitation."""
    u_slow, u_fast = recruited_excitations_from_angle(slow_fraction,
                                                      *recruitment_sin_cos(excitation))
    return recruited_slow_share(excitation, u_slow, u_fast)


@jitable
def effective_excitation(u, a):
    """A_eff: u where u > a, (u + a) / 2 elsewhere (scaled excitation u and activation a)."""
    return where(u > a, u, (u + a) / 2.0)


@jitable
def scaled_effective_excitation(scaling, excitation, activation):
    """A_eff of the excitation and activation scaled by the muscle_effort_scaling_factor."""
    return effective_excitation(scaling * excitation, scaling * activation)


def effective_excitation_powers(constants: UmbergerConstants, effective):
    """(A_eff, A_eff^0.6, A_eff^2) from A_eff, by NumPy on either path."""
    c = constants
    return (effective, effective ** c.activation_maintenance_exponent,
            effective ** c.shortening_exponent)


def umberger2003_powers(constants: UmbergerConstants, excitation, activation):
    """(A_eff, A_eff^0.6, A_eff^2) over arrays (:func:`scaled_effective_excitation`,
    :func:`effective_excitation_powers`)."""
    return effective_excitation_powers(constants, scaled_effective_excitation(
        constants.muscle_effort_scaling_factor, np.asarray(excitation, dtype=float),
        np.asarray(activation, dtype=float)))


def umberger2003_transcendentals(constants: UmbergerConstants, excitation, activation):
    """The powers and the recruitment's sine and cosine the heat rates take, over arrays
    (computed by NumPy on either path, so that both give its values to the bit): (A_eff,
    A_eff^0.6, A_eff^2, sin(pi u / 2), cos(pi u / 2)); the last two None without Bhargava's
    recruitment."""
    c = constants
    powers = umberger2003_powers(c, excitation, activation)
    if not c.use_Bhargava_recruitment_model:
        return (*powers, None, None)
    return (*powers, *recruitment_sin_cos(c.muscle_effort_scaling_factor
                                          * np.asarray(excitation, dtype=float)))


@jitable
def umberger2003_rates(c, excitation, mass, velocity, velocity_norm, length_norm,
                       active_fibre_force, slow_fraction, force_length_multiplier, effective,
                       maintenance_power, shortening_power, sin_angle, cos_angle):
    """(activation maintenance, shortening, work, total) rates (W) of :func:`umberger2003`
    from its transcendental parts (:func:`umberger2003_transcendentals`) and the fibre's
    velocity (m/s) and its velocity and length over L0 (L0/s, L0): NumPy arrays, or scalars in
    a compiled loop. ``c``: UmbergerConstants, or its compiled form (a named tuple of the same
    fields)."""
    k = c.muscle_effort_scaling_factor
    u = k * excitation
    f_active = maximum(k * active_fibre_force, 0.0)
    f_iso = force_length_multiplier
    slow = slow_fraction
    if c.use_Bhargava_recruitment_model:
        u_slow, u_fast = recruited_excitations_from_angle(slow_fraction, sin_angle, cos_angle)
        slow = recruited_slow_share(u, u_slow, u_fast)
    lengthened = length_norm > 1.0

    h = c.activation_maintenance_fast_rate * (1.0 - slow) + c.activation_maintenance_base_rate
    fraction = c.lengthened_activation_maintenance_fraction
    activation_maintenance = c.aerobic_factor * maintenance_power * (
        where(lengthened, fraction * h + (1.0 - fraction) * h * f_iso, h))

    alpha_fast = c.shortening_heat_fast_at_vmax / c.max_contraction_velocity
    alpha_slow = c.shortening_heat_slow_at_vmax / (c.max_contraction_velocity
                                                   / c.fast_to_slow_vmax_ratio)
    slow_term = minimum(-alpha_slow * velocity_norm, c.max_slow_shortening_heat_rate)
    fast_term = alpha_fast * velocity_norm * (1.0 - slow)
    shortening_rate = c.aerobic_factor * shortening_power * (slow_term * slow - fast_term)
    coefficient = (c.lengthening_coefficient_with_negative_work
                   if c.include_negative_mechanical_work else c.lengthening_coefficient)
    lengthening_rate = c.aerobic_factor * effective * (coefficient * alpha_slow * velocity_norm)
    shortening = where(velocity_norm <= 0.0, shortening_rate, lengthening_rate)
    shortening = where(lengthened, shortening * f_iso, shortening)

    work = mechanical_work_rate(f_active, velocity, c.include_negative_mechanical_work) / mass

    if c.forbid_negative_total_power:
        shortening = shortening_heat_for_nonnegative_total(
            shortening, activation_maintenance + shortening + work)

    if c.activation_maintenance_rate_on and c.shortening_rate_on:
        heat = activation_maintenance + shortening
        if c.enforce_minimum_heat_rate_per_muscle:
            heat = where(heat < c.minimum_heat_rate, c.minimum_heat_rate, heat)
    else:
        heat = (c.activation_maintenance_rate_on * activation_maintenance
                + c.shortening_rate_on * shortening)
    total = (heat + c.mechanical_work_rate_on * work) * mass
    return activation_maintenance * mass, shortening * mass, work * mass, total


def umberger2003(state: MuscleState, constants: UmbergerConstants, *,
                 force_length_multiplier) -> HeatRates:
    """Heat and work rates (W per muscle) of Umberger 2003, and its 2010 and Uchida 2016
    revisions (equations in the module docstring; the variant is in ``constants``).
    ``force_length_multiplier`` (1) is F_iso, required: MuscleState does not determine it for
    every muscle (for a Hill muscle, :func:`force_length_multiplier_from_state` gives it; for
    Virtual Muscle, whose active force is not proportional to activation, it gave 1.43x
    OpenSim's activation heat at 1.3 L0). ``basal`` is 0: the basal rate is whole-body
    (constants.basal_rate, probe_total)."""
    excitation = np.asarray(state.excitation, dtype=float)
    parts = umberger2003_transcendentals(constants, excitation, state.activation)
    velocity = np.asarray(state.fibre_velocity, dtype=float)
    activation_maintenance, shortening, work, total = umberger2003_rates(
        constants, excitation, np.asarray(state.mass, dtype=float), velocity,
        velocity / state.optimal_fibre_length,
        np.asarray(state.fibre_length, dtype=float) / state.optimal_fibre_length,
        np.asarray(state.active_fibre_force, dtype=float),
        np.asarray(state.slow_fraction, dtype=float),
        np.asarray(force_length_multiplier, dtype=float), *parts)
    return HeatRates(
        activation_maintenance=activation_maintenance,
        shortening_lengthening=shortening,
        basal=np.zeros_like(total),
        mechanical_work=work,
        total=total,
    )
