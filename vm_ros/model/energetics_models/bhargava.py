"""Bhargava et al. 2004 heat rates, as OpenSim 4.6's Bhargava2004MuscleMetabolicsProbe computes
them.

Per muscle (W), with velocity V > 0 lengthening, k the muscle_effort_scaling_factor, u = k U and
a = k A the scaled excitation and activation, r the slow fraction, m the mass:

    u_slow = r sin(pi u / 2)             u_fast = (1 - r) (1 - cos(pi u / 2))
    Adot = m * decay * (A_slow u_slow + A_fast u_fast)
    Mdot = m * g(L / L0) * (M_slow u_slow + M_fast u_fast)     g piecewise linear
    Sdot = -alpha V,  alpha = 0.25 F_total (V <= 0), 0 (V > 0); or, with
           use_force_dependent_shortening_prop_constant, 0.16 F_iso + 0.18 F_total (V <= 0),
           0.157 F_total (V > 0)
    Wdot = -F_active V  (V > 0 only with include_negative_mechanical_work; else 0)
    forbid_negative_total_power: where Adot + Mdot + Sdot + Wdot < 0, Sdot is raised to make it 0
    heat = Adot + Mdot + Sdot, not below minimum_heat_rate * m when
           enforce_minimum_heat_rate_per_muscle and all three heat rates are on
    total = heat (or the heat rates that are on) + Wdot (if on)

F_active = k * active fibre force, F_total = F_active + passive fibre force, F_iso = k *
isometric_force (= a * force-length multiplier * F0 in OpenSim). Constants and their sources:
config/energetics_models.yaml (section bhargava); equations and mapping from Virtual Muscle's
state: docs/energetics_models.md.

Reference: Bhargava LJ, Pandy MG, Anderson FC (2004) J Biomech 37:81-88, as implemented in
OpenSim 4.6 (OpenSim/Simulation/Model/Bhargava2004MuscleMetabolicsProbe.cpp).
"""

from __future__ import annotations

import numpy as np

from vm_ros.model.energetics_models.constants import BhargavaConstants
from vm_ros.model.energetics_models.state import (
    HeatRates,
    MuscleState,
    mechanical_work_rate,
    shortening_heat_for_nonnegative_total,
)
from vm_ros.model.jit import jitable, where


@jitable
def recruited_excitations_from_angle(slow_fraction, sin_angle, cos_angle):
    """:func:`recruited_excitations` from sin and cos of pi u / 2."""
    return slow_fraction * sin_angle, (1.0 - slow_fraction) * (1.0 - cos_angle)


def recruited_excitations(excitation, slow_fraction):
    """Bhargava 2004's recruitment: the slow- and fast-twitch excitations (1),
    r sin(pi u / 2) and (1 - r) (1 - cos(pi u / 2))."""
    return recruited_excitations_from_angle(slow_fraction, *recruitment_sin_cos(excitation))


@jitable
def _segment(x, xp, fp, j):
    """The line through points j and j + 1 at x."""
    return fp[j] + (x - xp[j]) * ((fp[j + 1] - fp[j]) / (xp[j + 1] - xp[j]))


@jitable
def piecewise_linear(x, xp, fp):
    """OpenSim's PiecewiseLinearFunction: linear between the points, extended beyond the ends
    with the slope of the end segments. ``xp``, ``fp``: sequences of the points (xp rising);
    x: an array, or a scalar in a compiled loop. The segment is the last whose first point is
    at or below x (the first below xp[0] and for NaN); above xp[-1] the line through the last
    point."""
    value = _segment(x, xp, fp, 0)
    for j in range(1, len(xp) - 1):
        value = where(x >= xp[j], _segment(x, xp, fp, j), value)
    last = len(xp) - 1
    return where(x > xp[last], fp[last] + (x - xp[last]) * ((fp[last] - fp[last - 1])
                                                            / (xp[last] - xp[last - 1])), value)


@jitable
def half_pi_sin_cos(excitation):
    """sin and cos of pi u / 2 (u: the scaled excitation): NumPy's over arrays, libm's for a
    scalar in a compiled loop. The two agree to the bit where NumPy's float64 sine and cosine
    are libm's (they are on x86-64 with AVX-512, where its exp and power are not;
    test_energetics_compiled.py checks it on the machine)."""
    half_pi_u = 0.5 * np.pi * excitation
    return np.sin(half_pi_u), np.cos(half_pi_u)


def recruitment_sin_cos(excitation):
    """:func:`half_pi_sin_cos` over an array."""
    return half_pi_sin_cos(np.asarray(excitation, dtype=float))


def bhargava2004_transcendentals(constants: BhargavaConstants, excitation):
    """The transcendental parts of the heat rates, over arrays: sin and cos of pi u / 2 (u the
    scaled excitation; :func:`recruitment_sin_cos`)."""
    return recruitment_sin_cos(constants.muscle_effort_scaling_factor
                               * np.asarray(excitation, dtype=float))


@jitable
def bhargava2004_rates(c, mass, velocity, active_fibre_force, passive_fibre_force,
                       isometric_force, length_norm, slow_fraction, sin_angle, cos_angle):
    """(activation + maintenance, shortening, work, total) rates (W) of :func:`bhargava2004`
    from its transcendental parts (:func:`bhargava2004_transcendentals`): NumPy arrays, or
    scalars in a compiled loop. ``c``: BhargavaConstants or its compiled form."""
    k = c.muscle_effort_scaling_factor
    f_active = k * active_fibre_force
    f_total = f_active + passive_fibre_force
    f_iso = k * isometric_force

    u_slow, u_fast = recruited_excitations_from_angle(slow_fraction, sin_angle, cos_angle)
    activation_heat = mass * c.decay_function_value * (
        c.activation_constant_slow_twitch * u_slow + c.activation_constant_fast_twitch * u_fast)
    length_dependence = piecewise_linear(length_norm, c.maintenance_length_dependence_x,
                                         c.maintenance_length_dependence_y)
    maintenance_heat = mass * length_dependence * (
        c.maintenance_constant_slow_twitch * u_slow + c.maintenance_constant_fast_twitch * u_fast)

    shortening = velocity <= 0.0
    if c.use_force_dependent_shortening_prop_constant:
        alpha = where(shortening,
                      c.shortening_isometric_coefficient * f_iso
                      + c.shortening_total_force_coefficient * f_total,
                      c.lengthening_total_force_coefficient * f_total)
    else:
        alpha = where(shortening, c.shortening_coefficient * f_total, 0.0)
    shortening_heat = -alpha * velocity

    work = mechanical_work_rate(f_active, velocity, c.include_negative_mechanical_work)

    if c.forbid_negative_total_power:
        shortening_heat = shortening_heat_for_nonnegative_total(
            shortening_heat, activation_heat + maintenance_heat + shortening_heat + work)

    if c.activation_rate_on and c.maintenance_rate_on and c.shortening_rate_on:
        heat = activation_heat + maintenance_heat + shortening_heat
        if c.enforce_minimum_heat_rate_per_muscle:
            floor = c.minimum_heat_rate * mass
            heat = where(heat < floor, floor, heat)
    else:
        heat = (c.activation_rate_on * activation_heat + c.maintenance_rate_on * maintenance_heat
                + c.shortening_rate_on * shortening_heat)
    total = heat + c.mechanical_work_rate_on * work
    return activation_heat + maintenance_heat, shortening_heat, work, total


def bhargava2004(state: MuscleState, constants: BhargavaConstants, *,
                 passive_fibre_force) -> HeatRates:
    """Heat and work rates (W per muscle) of Bhargava et al. 2004 (equations in the module
    docstring). ``passive_fibre_force`` (N, OpenSim's getPassiveFiberForce) enters F_total; it is
    not in MuscleState and is required (0 makes F_total the active force alone,
    docs/energetics_models.md section 3). ``basal`` is 0: the basal rate is whole-body
    (constants.basal_rate, probe_total)."""
    length_norm = np.asarray(state.fibre_length, dtype=float) / state.optimal_fibre_length
    sin_angle, cos_angle = bhargava2004_transcendentals(constants, state.excitation)
    activation_maintenance, shortening, work, total = bhargava2004_rates(
        constants, np.asarray(state.mass, dtype=float),
        np.asarray(state.fibre_velocity, dtype=float),
        np.asarray(state.active_fibre_force, dtype=float),
        np.asarray(passive_fibre_force, dtype=float),
        np.asarray(state.isometric_force, dtype=float), length_norm,
        np.asarray(state.slow_fraction, dtype=float), sin_angle, cos_angle)
    return HeatRates(
        activation_maintenance=activation_maintenance,
        shortening_lengthening=shortening,
        basal=np.zeros_like(total),
        mechanical_work=work,
        total=total,
    )
