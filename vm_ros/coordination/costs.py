"""The costs a coordination minimises, chosen by name (COSTS, as vm_ros.model.energetics_models.
vm_state.PUBLISHED_MODELS names the energetics models).

Every cost is the integral over the motion of a per-muscle rate c_i(t), weighted per muscle:

    C(U) = sum_i w_i int_0^T c_i(t) dt

- ``tsianos2012`` (default, J): c_i = VM's total metabolic rate of muscle i (activation,
  maintenance, shortening/lengthening, recovery; docs/model.md section 6); Tsianos, Rustin &
  Loeb 2012.
- ``drive2`` (s): c_i = U_i(t)^2, the drive squared; the classic static-optimisation criterion
  (OpenSim SO's sum a^2).
- each name of vm_ros.model.energetics_models.vm_state.MODEL_NAMES (J): c_i = that published model's
  total rate on VM's state (docs/energetics_models.md); the model's paper.

drive2 is quadratic in the drive nodes (exactly; the solver uses its Hessian); the energy costs
are linearised around each iterate from the perturbed forward runs (vm_ros.coordination.
forward), their curvature left to the solver's damping.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import partial

import numpy as np

from vm_ros.errors import VmRosError
from vm_ros.model.energetics_models.vm_state import PUBLISHED_MODELS

TOTAL_RATE = 3        # column of StepRecord.energy_rates: VM's total rate (W)
MODEL_TOTAL = 4       # component of energy_rate_models: the model's total (W)


def vm_rate(trajectory, drive) -> np.ndarray:
    """(k, n) W: VM's total metabolic rate per muscle (Tsianos 2012) of each step."""
    return trajectory.record.energy_rates[:, :, TOTAL_RATE]


def drive_squared(trajectory, drive) -> np.ndarray:
    """(k, n): each step's drive squared."""
    return drive * drive


def model_rate(index: int, trajectory, drive) -> np.ndarray:
    """(k, n) W: the total rate of the bank's published model ``index``."""
    return trajectory.energy_rate_models[:, :, index, MODEL_TOTAL]


@dataclass(frozen=True)
class Cost:
    """A cost by name: ``rate(trajectory, drive, models)`` -> (k, n) per-muscle rate, with
    ``models`` the bank's energetics models; ``bank_models``: the published models the bank
    must run for it; ``quadratic``: the cost is int U^2 dt (exact Hessian); ``unit`` of C."""

    name: str
    description: str
    unit: str
    reference: str
    bank_models: tuple = ()
    quadratic: bool = False

    def rate(self, trajectory, drive, models=()) -> np.ndarray:
        if self.quadratic:
            return drive_squared(trajectory, drive)
        if self.bank_models:
            return model_rate(models.index(self.bank_models[0]), trajectory, drive)
        return vm_rate(trajectory, drive)

    def rate_function(self, models=()) -> Callable:
        return partial(self.rate, models=tuple(models))


COSTS = {cost.name: cost for cost in (
    Cost("tsianos2012", "VM's own predicted metabolic energy", "J",
         "Tsianos, Rustin & Loeb 2012"),
    Cost("drive2", "integral of the drive squared", "s",
         "static optimisation's sum a^2 (Crowninshield & Brand 1981 family)", quadratic=True),
    *(Cost(model.name, f"metabolic energy by {model.reference or model.name} on VM's state",
           "J", model.reference or model.name, bank_models=(model.name,))
      for model in PUBLISHED_MODELS),
)}
DEFAULT_COST = "tsianos2012"
COST_NAMES = tuple(COSTS)


def cost_named(name: str) -> Cost:
    """The registry entry ``name``; VmRosError naming the known costs otherwise."""
    try:
        return COSTS[name]
    except KeyError:
        raise VmRosError(f"cost {name!r} is not known; known: {', '.join(COST_NAMES)}") \
            from None
