"""Lichtwark & Wilson heat rates, as Koelewijn et al. 2019 formulate them for one Hill muscle.

Per muscle (W), with V > 0 lengthening, v = -V / L0 the shortening velocity (L0/s), Vmax the
max_contraction_velocity (L0/s), a the activation, F_iso the active force-length multiplier, g
the force-velocity multiplier (active force over isometric force), t the time since stimulation
onset (s), G the force_velocity_curvature:

    gamma = C + 0.8 exp(-0.72 t) + 0.175 exp(-0.022 t)      (C = maintenance_decay_constant, 0)
    H_m = gamma Vmax / G^2                                       (v > 0)
    H_m = gamma Vmax / G^2 (0.3 + 0.7 exp(-7 Vmax (g - 1)))      (v <= 0)
    H_s = v / G  (v > 0),   0.5 g |v|  (v <= 0)                  (F0 L0 units, per second)
    AMdot = a H_m (0.3 + 0.7 F_iso) F0 L0
    Sdot = a F_iso H_s F0 L0
    Wdot = -F_active V  (V > 0 only with include_negative_mechanical_work; else 0)
    total = AMdot + Sdot + Wdot

Constants and sources: config/energetics_models.yaml (section lichtwark); mapping from Virtual
Muscle's state: docs/energetics_models.md.

References: Lichtwark GA, Wilson AM (2005) J Exp Biol 208:2831-2843 (gamma); Lichtwark GA,
Wilson AM (2007) J Biomech 40:1768-1775, supplement (the heat rates, G = 4); as Koelewijn AD,
Heinrich D, van den Bogert AJ (2019) PLoS ONE 14(9):e0222037 implement them.
"""

from __future__ import annotations

import numpy as np

from vm_ros.model.energetics_models.constants import LichtwarkConstants
from vm_ros.model.energetics_models.state import HeatRates, MuscleState, mechanical_work_rate
from vm_ros.model.jit import jitable, where


def force_velocity_multiplier_from_state(state: MuscleState):
    """g = active_fibre_force / isometric_force (1) where the isometric force is positive; 1
    elsewhere (there the activation, which scales every term g enters, is 0 for a Hill muscle)."""
    active = np.asarray(state.active_fibre_force, dtype=float)
    isometric = np.asarray(state.isometric_force, dtype=float)
    return np.divide(active, isometric, out=np.ones(np.broadcast(active, isometric).shape),
                     where=isometric > 0.0)


@jitable
def lichtwark2005_exponents(c, stimulation_duration, force_velocity_multiplier):
    """The arguments of the three exponentials (1): -0.72 t and -0.022 t of gamma, and
    -7 Vmax (g - 1) of the lengthening maintenance; t in s. NumPy arrays, or scalars in a
    compiled loop."""
    t = stimulation_duration
    return (-c.maintenance_decay_fast_rate * t, -c.maintenance_decay_slow_rate * t,
            -c.lengthening_maintenance_decay * c.max_contraction_velocity
            * (force_velocity_multiplier - 1.0))


@jitable
def maintenance_decay_from_exponentials(c, fast_exp, slow_exp):
    """gamma (1) = C + 0.8 fast_exp + 0.175 slow_exp, the exponentials of
    :func:`lichtwark2005_exponents`."""
    return (c.maintenance_decay_constant + c.maintenance_decay_fast_amplitude * fast_exp
            + c.maintenance_decay_slow_amplitude * slow_exp)


def maintenance_decay(stimulation_duration, constants: LichtwarkConstants):
    """gamma (1): C + 0.8 exp(-0.72 t) + 0.175 exp(-0.022 t), t in s; Lichtwark & Wilson 2005's
    decay with C = 0 (the default), a constant gamma with both amplitudes 0."""
    t = np.asarray(stimulation_duration, dtype=float)
    fast, slow, _ = lichtwark2005_exponents(constants, t, 1.0)
    return maintenance_decay_from_exponentials(constants, np.exp(fast), np.exp(slow))


@jitable
def isometric_maintenance(c, fast_exp, slow_exp, curvature_squared):
    """gamma Vmax / G^2 (L0/s), from the exponentials of gamma
    (:func:`maintenance_decay_from_exponentials`) and G^2 (computed in Python: the power of a
    float would be compiled once for the model step's kernel and these loops alike)."""
    return (maintenance_decay_from_exponentials(c, fast_exp, slow_exp)
            * c.max_contraction_velocity / curvature_squared)


def lichtwark2005_transcendentals(constants: LichtwarkConstants, stimulation_duration,
                                  force_velocity_multiplier):
    """The parts of the heat rates computed by NumPy on either path, over arrays: the isometric
    maintenance gamma Vmax / G^2 (:func:`isometric_maintenance`) and the lengthening
    maintenance's exp(-7 Vmax (g - 1)); the exponentials' arguments are
    :func:`lichtwark2005_exponents`."""
    c = constants
    fast, slow, lengthening = (np.exp(x) for x in lichtwark2005_exponents(
        c, np.asarray(stimulation_duration, dtype=float),
        np.asarray(force_velocity_multiplier, dtype=float)))
    return isometric_maintenance(c, fast, slow, c.force_velocity_curvature ** 2), lengthening


@jitable
def lichtwark2005_rates(c, activation, optimal_fibre_length, max_isometric_force, velocity,
                        active_fibre_force, force_length_multiplier, force_velocity_multiplier,
                        isometric_maintenance, lengthening_decay):
    """(activation maintenance, shortening, work, total) rates (W) of :func:`lichtwark2005` from
    its transcendental parts (:func:`lichtwark2005_transcendentals`): NumPy arrays, or scalars
    in a compiled loop. ``c``: LichtwarkConstants or its compiled form."""
    a = activation
    l0 = optimal_fibre_length
    shortening_velocity = -velocity / l0
    f_iso = force_length_multiplier
    g = force_velocity_multiplier
    curvature = c.force_velocity_curvature
    shortening = shortening_velocity > 0.0

    floor = c.lengthening_maintenance_floor
    maintenance = where(shortening, isometric_maintenance, isometric_maintenance * (
        floor + (1.0 - floor) * lengthening_decay))
    shortening_heat = where(shortening, shortening_velocity / curvature,
                            -c.lengthening_heat_coefficient * g * shortening_velocity)
    scale = max_isometric_force * l0
    stable = c.stable_maintenance_fraction
    activation_maintenance = a * maintenance * (stable + (1.0 - stable) * f_iso) * scale
    shortening_lengthening = a * f_iso * shortening_heat * scale
    work = mechanical_work_rate(active_fibre_force, velocity, c.include_negative_mechanical_work)
    total = activation_maintenance + shortening_lengthening + work
    return activation_maintenance, shortening_lengthening, work, total


def lichtwark2005(state: MuscleState, constants: LichtwarkConstants, *,
                  force_length_multiplier, force_velocity_multiplier,
                  stimulation_duration) -> HeatRates:
    """Heat and work rates (W per muscle) of Lichtwark & Wilson (equations in the module
    docstring). Required, since MuscleState does not hold them: ``force_length_multiplier``
    F_iso (1) and ``force_velocity_multiplier`` g (1) (for a Hill muscle,
    umberger.force_length_multiplier_from_state and :func:`force_velocity_multiplier_from_state`
    give them from the state), ``stimulation_duration`` t (s; 0 gives the unfatigued gamma
    0.975). ``basal`` is 0."""
    g = np.asarray(force_velocity_multiplier, dtype=float)
    isometric_maintenance, lengthening_decay = lichtwark2005_transcendentals(
        constants, stimulation_duration, g)
    activation_maintenance, shortening_lengthening, work, total = lichtwark2005_rates(
        constants, np.asarray(state.activation, dtype=float),
        np.asarray(state.optimal_fibre_length, dtype=float),
        np.asarray(state.max_isometric_force, dtype=float),
        np.asarray(state.fibre_velocity, dtype=float),
        np.asarray(state.active_fibre_force, dtype=float),
        np.asarray(force_length_multiplier, dtype=float), g, isometric_maintenance,
        lengthening_decay)
    return HeatRates(
        activation_maintenance=activation_maintenance,
        shortening_lengthening=shortening_lengthening,
        basal=np.zeros_like(total),
        mechanical_work=work,
        total=total,
    )
