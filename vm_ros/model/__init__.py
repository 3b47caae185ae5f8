"""The Virtual Muscle model: pure NumPy/SciPy, no ROS.

Public API: :class:`MuscleBank` (vectorised muscles that own their state), its output records
:class:`StepOutput` and :class:`EnergyRates`, and the parameter loaders.
"""

from vm_ros.model.bank import (
    ENERGY_COMPONENTS,
    BankState,
    EnergyRates,
    MuscleBank,
    StepOutput,
    Trajectory,
)
from vm_ros.model.params import (
    FIBRE_TYPES,
    ModelParams,
    MuscleSpec,
    load_model_params,
    load_muscle_library,
)
from vm_ros.model.recruitment import SCHEMES

__all__ = [
    "ENERGY_COMPONENTS",
    "FIBRE_TYPES",
    "SCHEMES",
    "BankState",
    "EnergyRates",
    "ModelParams",
    "MuscleBank",
    "MuscleSpec",
    "StepOutput",
    "Trajectory",
    "load_model_params",
    "load_muscle_library",
]
