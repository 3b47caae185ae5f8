"""The muscle state the energetics models take, and the rates they give (SI, arrays over muscles).

| MuscleState field | unit | meaning |
| excitation | 1 | neural drive u, 0-1 |
| activation | 1 | activation a, 0-1: the factor that scales the active force |
| fibre_length | m | fibre (fascicle) length |
| optimal_fibre_length | m | fibre length at which the isometric force peaks |
| fibre_velocity | m/s | fibre lengthening velocity (negative shortening) |
| active_fibre_force | N | active fibre force (no passive) |
| isometric_force | N | active force at the current length and activation with V = 0 |
| max_isometric_force | N | maximal isometric force F0 |
| mass | kg | muscle (wet) mass |
| slow_fraction | 1 | fraction of slow-twitch fibres |

How these are read from Virtual Muscle's state is docs/energetics_models.md.

HeatRates: per muscle, W (positive: heat or work done by the muscle), components a model has and
NaN for those it has not: ``activation_maintenance``, ``shortening_lengthening``, ``basal``,
``mechanical_work`` (the muscle's mechanical power, -F V, positive when shortening) and ``total``
(what the model reports as the muscle's metabolic rate, with its own options applied).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vm_ros.model.jit import jitable, where


@dataclass(frozen=True)
class MuscleState:
    excitation: np.ndarray
    activation: np.ndarray
    fibre_length: np.ndarray
    optimal_fibre_length: np.ndarray
    fibre_velocity: np.ndarray
    active_fibre_force: np.ndarray
    isometric_force: np.ndarray
    max_isometric_force: np.ndarray
    mass: np.ndarray
    slow_fraction: np.ndarray


@dataclass(frozen=True)
class HeatRates:
    activation_maintenance: np.ndarray
    shortening_lengthening: np.ndarray
    basal: np.ndarray
    mechanical_work: np.ndarray
    total: np.ndarray


@jitable
def mechanical_work_rate(force, velocity, include_negative_mechanical_work: bool):
    """-F V (W; positive while shortening, V < 0), and 0 while lengthening (V > 0) unless
    ``include_negative_mechanical_work``: the models' shared work term and its option."""
    return where(include_negative_mechanical_work | (velocity <= 0.0), -force * velocity, 0.0)


@jitable
def shortening_heat_for_nonnegative_total(shortening_heat, total):
    """The models' ``forbid_negative_total_power`` (OpenSim's name): where ``total`` is below 0
    the shortening heat is raised by the deficit, so the total becomes 0."""
    return where(total < 0.0, shortening_heat - total, shortening_heat)
