"""Published muscle energetics models beside Tsianos 2012, computed from vm_ros's own muscle state.

Every model is a pure function ``model(state, constants) -> HeatRates`` over NumPy arrays (one
entry per muscle), its equations, constants and reference in its docstring, its constants in
``config/energetics_models.yaml`` with unit and source. The muscle state they take, and how it is
read from Virtual Muscle's state, is :class:`MuscleState` (docs/energetics_models.md).

| module | models |
| umberger | Umberger et al. 2003, Umberger 2010 (with Uchida et al. 2016's revisions as options) |
| bhargava | Bhargava et al. 2004 |
| others | Lichtwark & Wilson 2005, Houdijk et al. 2006, Margaria 1968, Minetti & Alexander 1997 |
"""

from __future__ import annotations

from vm_ros.energetics_models.bhargava import bhargava2004
from vm_ros.energetics_models.constants import (
    BhargavaConstants,
    UmbergerConstants,
    basal_rate,
    load_bhargava_constants,
    load_umberger_constants,
    muscle_mass,
)
from vm_ros.energetics_models.state import HeatRates, MuscleState
from vm_ros.energetics_models.umberger import umberger

__all__ = [
    "BhargavaConstants",
    "HeatRates",
    "MuscleState",
    "UmbergerConstants",
    "basal_rate",
    "bhargava2004",
    "load_bhargava_constants",
    "load_umberger_constants",
    "muscle_mass",
    "umberger",
]
