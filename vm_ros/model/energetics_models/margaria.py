"""Margaria 1968: metabolic rate from the muscle's mechanical power at fixed efficiencies.

Per muscle (W), with V > 0 lengthening and F_active the active fibre force:

    Wdot = -F_active V                                  mechanical power (positive shortening)
    total = Wdot / 0.25    (Wdot >= 0)                  positive work at 25 % efficiency
    total = Wdot / (-1.2)  (Wdot < 0)                   negative work at -120 % efficiency;
                                                        0 without include_negative_mechanical_work

The model has no heat components (activation_maintenance and shortening_lengthening are NaN):
Koelewijn et al. 2019 apply it to the muscles' mechanical power alone, without an activation or
maintenance term, and so does this function. Constants and sources: config/energetics_models.yaml
(section margaria).

References: Margaria R (1968) Int Z angew Physiol 25:339-351; as Koelewijn AD, Heinrich D, van den
Bogert AJ (2019) PLoS ONE 14(9):e0222037 apply it per muscle.
"""

from __future__ import annotations

import numpy as np

from vm_ros.model.energetics_models.constants import MargariaConstants
from vm_ros.model.energetics_models.state import HeatRates, MuscleState
from vm_ros.model.jit import jitable, where


@jitable
def margaria1968_rates(c, active_fibre_force, velocity):
    """(mechanical power, total) (W) of :func:`margaria1968`: NumPy arrays, or scalars in a
    compiled loop. ``c``: MargariaConstants or its compiled form."""
    power = -active_fibre_force * velocity
    negative = power < 0.0
    power = where(negative & (not c.include_negative_mechanical_work), 0.0, power)
    total = where(negative, power / c.negative_work_efficiency,
                  power / c.positive_work_efficiency)
    return power, total


def margaria1968(state: MuscleState, constants: MargariaConstants) -> HeatRates:
    """Metabolic rate (W per muscle) of Margaria 1968 (equations in the module docstring).
    ``basal`` is 0; the heat components are NaN."""
    power, total = margaria1968_rates(constants,
                                      np.asarray(state.active_fibre_force, dtype=float),
                                      np.asarray(state.fibre_velocity, dtype=float))
    missing = np.full(np.shape(total), np.nan)
    return HeatRates(
        activation_maintenance=missing,
        shortening_lengthening=missing.copy(),
        basal=np.zeros_like(total),
        mechanical_work=power,
        total=total,
    )
