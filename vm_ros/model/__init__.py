"""The Virtual Muscle model: pure NumPy/SciPy, no ROS.

Public API: :class:`MuscleBank` (vectorised muscles that own their state), its output records
:class:`StepOutput`, :class:`Trajectory` and :class:`EnergyRates` (vm_ros.model.records), the
state's declared layout (vm_ros.model.layout), the step's phases (vm_ros.model.phases) and the
parameter loaders.
"""

from vm_ros.model.bank import MuscleBank
from vm_ros.model.layout import BankState
from vm_ros.model.params import (
    FIBRE_TYPES,
    ModelParams,
    MuscleSpec,
    load_model_params,
    load_muscle_library,
)
from vm_ros.model.phases import Phase
from vm_ros.model.records import ENERGY_COMPONENTS, EnergyRates, StepOutput, StepRecord, Trajectory
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
    "Phase",
    "StepOutput",
    "StepRecord",
    "Trajectory",
    "load_model_params",
    "load_muscle_library",
]
