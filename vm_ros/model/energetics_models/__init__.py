"""Published muscle energetics models beside Tsianos 2012, computed from vm_ros's own muscle state.

Every model is a pure function ``model(state, constants) -> HeatRates`` over NumPy arrays (one
entry per muscle), its equations, constants and reference in its docstring, its constants in
``config/energetics_models.yaml`` with unit and source. The muscle state they take, and how it is
read from Virtual Muscle's state, is :class:`MuscleState` (docs/energetics_models.md).

| module | models |
| umberger | Umberger et al. 2003 (umberger2003); Umberger 2010's, Uchida et al. 2016's revisions |
| bhargava | Bhargava et al. 2004 |
| lichtwark | Lichtwark & Wilson 2005/2007 (lichtwark2005, as Koelewijn et al. 2019 formulate it) |
| houdijk | Houdijk et al. 2006 (as Koelewijn et al. 2019 formulate it) |
| margaria | Margaria 1968 |
| minetti | Minetti & Alexander 1997 (minetti1997) |
| vm_state | Virtual Muscle's outputs as the models' inputs; PUBLISHED_MODELS; published_rates |
| compare | the scenario set of ``vm-ros compare-energetics`` (imported on its own) |
"""

from __future__ import annotations

import functools
import warnings

from vm_ros.model.energetics_models.bhargava import bhargava2004
from vm_ros.model.energetics_models.constants import (
    BhargavaConstants,
    HoudijkConstants,
    LichtwarkConstants,
    MargariaConstants,
    MinettiConstants,
    UmbergerConstants,
    basal_rate,
    load_bhargava_constants,
    load_houdijk_constants,
    load_lichtwark_constants,
    load_margaria_constants,
    load_minetti_constants,
    load_umberger_constants,
    muscle_mass,
    probe_total,
)
from vm_ros.model.energetics_models.houdijk import houdijk2006
from vm_ros.model.energetics_models.lichtwark import lichtwark2005
from vm_ros.model.energetics_models.margaria import margaria1968
from vm_ros.model.energetics_models.minetti import minetti1997
from vm_ros.model.energetics_models.state import HeatRates, MuscleState
from vm_ros.model.energetics_models.umberger import (
    force_length_multiplier_from_state,
    umberger2003,
)
from vm_ros.model.energetics_models.vm_state import (
    MODEL_NAMES,
    PUBLISHED_MODELS,
    PublishedModel,
    VmModelInputs,
    VmMuscleConstants,
    published_rates,
    rates_from_inputs,
    vm_model_inputs,
    vm_model_inputs_from_outputs,
)

__all__ = [
    "MODEL_NAMES",
    "PUBLISHED_MODELS",
    "PublishedModel",
    "VmModelInputs",
    "VmMuscleConstants",
    "published_rates",
    "rates_from_inputs",
    "vm_model_inputs",
    "vm_model_inputs_from_outputs",
    "BhargavaConstants",
    "HeatRates",
    "HoudijkConstants",
    "LichtwarkConstants",
    "MargariaConstants",
    "MinettiConstants",
    "MuscleState",
    "UmbergerConstants",
    "basal_rate",
    "bhargava2004",
    "houdijk2006",
    "force_length_multiplier_from_state",
    "lichtwark2005",
    "lichtwark_wilson",
    "load_bhargava_constants",
    "load_houdijk_constants",
    "load_lichtwark_constants",
    "load_margaria_constants",
    "load_minetti_constants",
    "load_umberger_constants",
    "margaria1968",
    "minetti1997",
    "minetti_alexander",
    "muscle_mass",
    "probe_total",
    "umberger",
    "umberger2003",
]


def _former_name(function, former: str):
    """``function`` under its former name, for one release: it warns (DeprecationWarning)."""

    @functools.wraps(function)
    def former_function(*args, **kwargs):
        warnings.warn(f"vm_ros.model.energetics_models.{former} is now {function.__name__}; "
                      "the former name goes in the next release", DeprecationWarning, stacklevel=2)
        return function(*args, **kwargs)

    return former_function


lichtwark_wilson = _former_name(lichtwark2005, "lichtwark_wilson")
minetti_alexander = _former_name(minetti1997, "minetti_alexander")
umberger = _former_name(umberger2003, "umberger")
