"""Minetti & Alexander 1997: metabolic rate from activation and normalised shortening velocity.

Per muscle (W), with V > 0 lengthening, Vmax the max_contraction_velocity (L0/s), a the
activation and F0 the maximal isometric force:

    v = -V / (Vmax L0)                                        shortening positive (1)
    phi(v) = (0.054 + 0.506 v + 2.46 v^2) / (1 - 1.13 v + 12.8 v^2 - 1.64 v^3)
    total = a F0 Vmax L0 phi(v)

phi(0) = 0.054 (isometric); the formula is applied unchanged to lengthening (v < 0), as in
Koelewijn et al. 2019. Its denominator has one real root, v = 7.73 (far beyond Vmax). The model
has no components (activation_maintenance, shortening_lengthening and mechanical_work are NaN).
Constants and sources: config/energetics_models.yaml (section minetti).

References: Minetti AE, Alexander RMcN (1997) J Theor Biol 186:467-476; per muscle as Koelewijn
AD, Heinrich D, van den Bogert AJ (2019) PLoS ONE 14(9):e0222037 apply it.
"""

from __future__ import annotations

import numpy as np

from vm_ros.model.energetics_models.constants import MinettiConstants
from vm_ros.model.energetics_models.state import HeatRates, MuscleState
from vm_ros.model.jit import jitable


@jitable
def polynomial_value(x, coefficients):
    """sum_i coefficients[i] x^i by Horner's rule, as numpy.polynomial.polynomial.polyval
    computes it (c[-1] + 0 x, then c[-i] + previous x), operation for operation: the same
    values to the bit, and callable from a compiled loop, which polyval is not."""
    value = coefficients[-1] + x * 0
    for i in range(2, len(coefficients) + 1):
        value = coefficients[-i] + value * x
    return value


@jitable
def phi(normalised_shortening_velocity, constants: MinettiConstants):
    """Minetti & Alexander 1997's phi(v) (1), v the shortening velocity over Vmax."""
    v = normalised_shortening_velocity
    return (polynomial_value(v, constants.phi_numerator)
            / polynomial_value(v, constants.phi_denominator))


@jitable
def minetti1997_rates(c, activation, max_isometric_force, optimal_fibre_length, velocity):
    """The total rate (W) of :func:`minetti1997`: NumPy arrays, or scalars in a compiled loop.
    ``c``: MinettiConstants or its compiled form."""
    vmax = c.max_contraction_velocity * optimal_fibre_length
    v = -velocity / vmax
    return activation * max_isometric_force * vmax * phi(v, c)


def minetti1997(state: MuscleState, constants: MinettiConstants) -> HeatRates:
    """Metabolic rate (W per muscle) of Minetti & Alexander 1997 (equations in the module
    docstring). ``basal`` is 0; the other components are NaN."""
    total = minetti1997_rates(constants, np.asarray(state.activation, dtype=float),
                              state.max_isometric_force,
                              np.asarray(state.optimal_fibre_length, dtype=float),
                              np.asarray(state.fibre_velocity, dtype=float))
    missing = np.full(np.shape(total), np.nan)
    return HeatRates(
        activation_maintenance=missing,
        shortening_lengthening=missing.copy(),
        basal=np.zeros_like(total),
        mechanical_work=missing.copy(),
        total=total,
    )
