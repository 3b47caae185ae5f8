"""The Virtual Muscle model: pure NumPy/SciPy, no ROS.

Public API: :class:`MuscleBank` (vectorised muscles that own their state), its output records
:class:`StepOutput`, :class:`Trajectory` and :class:`EnergyRates` (vm_ros.model.records), the
state's declared layout (vm_ros.model.layout), the step's phases (vm_ros.model.phases) and the
parameter loaders.

They are imported when first used (``from vm_ros.model import MuscleBank``), so that importing a
light submodule such as vm_ros.model.params does not import the bank, SciPy and Numba.
"""

from __future__ import annotations

import importlib

# public name -> its module under vm_ros.model
_EXPORTS = {
    "MuscleBank": "bank",
    "BankState": "layout",
    "FIBRE_TYPES": "params",
    "ModelParams": "params",
    "MuscleSpec": "params",
    "load_model_params": "params",
    "load_muscle_library": "params",
    "Phase": "phases",
    "ENERGY_COMPONENTS": "records",
    "EnergyRates": "records",
    "StepOutput": "records",
    "StepRecord": "records",
    "Trajectory": "records",
    "SCHEMES": "recruitment",
}


def __getattr__(name: str):
    if name not in _EXPORTS:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(f"{__name__}.{_EXPORTS[name]}"), name)
    globals()[name] = value
    return value


def __dir__():
    return sorted({*globals(), *_EXPORTS})


__all__ = sorted(_EXPORTS)
