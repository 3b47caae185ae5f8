"""Virtual Muscle's state read as the published energetics models' inputs, and every published
model computed from it (docs/energetics_models.md section 7).

Pure functions over arrays: one step's outputs (shape (n,)) or many steps' ((k, n)) map to a
:class:`~vm_ros.model.energetics_models.state.MuscleState` plus the extras some models take as
keywords.
Per muscle, with Acteff_i the effective activation of fibre type i (which already carries the
type's recruited share of F0, docs/model.md section 5), L = x / L0, V = xdot / L0:

    excitation            U (drive as used)
    activation            a = sum_i Acteff_i                 (1)
    fibre length, speed   x (m), xdot (m/s, lengthening positive); L0 (m)
    active fibre force    F0 sum_i Acteff_i FL_i(L) FV_i(V, L)            (N)
    isometric force       F0 sum_i Acteff_i FL_i(L)          (FV = 1)     (N)
    passive fibre force   F_CE - active = F0 (max(0, FPE1 + sum_i Acteff_i (FL_i FV_i + FPE2))
                          - sum_i Acteff_i FL_i FV_i): the parallel elements FPE1(L, V) +
                          sum_i Acteff_i FPE2(L), and where F_CE is clipped at 0 the clip (N)
    max isometric force   F0 (N);  mass: the library's mass_kg;  slow fraction: fpcsa_slow
    force-length mult.    isometric / (a F0) = sum_i Acteff_i FL_i / a; sum_i fpcsa_i FL_i at a = 0
    force-velocity mult.  active / isometric; sum_i fpcsa_i FL_i FV_i / sum_i fpcsa_i FL_i at a = 0
    stimulation duration  time since U last rose above 0 (s; a series only, 0 for one step)

FL, FV, FPE1 and FPE2 are vm_ros.model.curves' Cheng 2000 curves with the bank's parameters, as
the step evaluates them (vm_ros.model.mechanics.contractile_force_normalised).

:data:`PUBLISHED_MODELS` is the one registry of model names, functions, constants loaders and
the extras each takes; :func:`published_rates` computes any of them from a bank and its outputs.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import partial

import numpy as np

from vm_ros.errors import InputError
from vm_ros.model import curves
from vm_ros.model.energetics_models.bhargava import bhargava2004
from vm_ros.model.energetics_models.constants import (
    load_bhargava_constants,
    load_houdijk_constants,
    load_lichtwark_constants,
    load_margaria_constants,
    load_minetti_constants,
    load_umberger_constants,
)
from vm_ros.model.energetics_models.houdijk import houdijk2006
from vm_ros.model.energetics_models.lichtwark import lichtwark2005
from vm_ros.model.energetics_models.margaria import margaria1968
from vm_ros.model.energetics_models.minetti import minetti1997
from vm_ros.model.energetics_models.state import HeatRates, MuscleState
from vm_ros.model.energetics_models.umberger import umberger2003
from vm_ros.model.jit import divide_where, jitable, maximum
from vm_ros.model.layout import type_columns
from vm_ros.model.params import FibreTypeParams, GenericParams


@dataclass(frozen=True)
class VmMuscleConstants:
    """What the mapping needs of a bank, per muscle (n,) unless stated.

    | field | unit | meaning |
    | f0 | N | maximal isometric force F0 |
    | l0 | m | optimal fascicle length L0 |
    | mass | kg | wet muscle mass (the library's mass_kg) |
    | fpcsa | 1, (n, 2) | PCSA fraction of the slow and fast fibres |
    | lmax | L0 | fascicle length at the maximum path length (scales PE1) |
    | fibre | FibreTypeParams | FL and FV parameters per fibre type |
    | generic | GenericParams | PE1 and PE2 parameters |
    """

    f0: np.ndarray
    l0: np.ndarray
    mass: np.ndarray
    fpcsa: np.ndarray
    lmax: np.ndarray
    fibre: FibreTypeParams
    generic: GenericParams

    @classmethod
    def from_bank(cls, bank) -> VmMuscleConstants:
        """From a MuscleBank (its f0, l0_m, mass_kg, fpcsa, lmax and parameters)."""
        return cls(f0=np.asarray(bank.f0, dtype=float), l0=np.asarray(bank.l0_m, dtype=float),
                   mass=np.asarray(bank.mass_kg, dtype=float),
                   fpcsa=np.asarray(bank.fpcsa, dtype=float),
                   lmax=np.asarray(bank.lmax, dtype=float), fibre=bank.params.fibre,
                   generic=bank.params.generic)


@dataclass(frozen=True)
class VmModelInputs:
    """The published models' inputs read from Virtual Muscle's state (shapes (n,) or (k, n)).

    | field | unit | meaning |
    | state | MuscleState | the common state (module docstring) |
    | force_length_multiplier | 1 | F_iso of Umberger, Houdijk, Lichtwark & Wilson |
    | force_velocity_multiplier | 1 | g of Lichtwark & Wilson |
    | passive_fibre_force | N | F_CE - active force: Bhargava's F_total - F_active |
    | stimulation_duration | s | time since the drive last rose from 0 (Lichtwark's gamma) |
    """

    state: MuscleState
    force_length_multiplier: np.ndarray
    force_velocity_multiplier: np.ndarray
    passive_fibre_force: np.ndarray
    stimulation_duration: np.ndarray


def fibre_curves(length_l0, velocity_l0_per_s, fibre: FibreTypeParams, generic: GenericParams):
    """FL (1) and FV (1) per fibre type, each (..., 2), at fascicle length L (L0) and velocity V
    (L0/s, negative shortening), each (...,): vm_ros.model.curves' Cheng 2000 relations."""
    fl, fv = fibre_curves_by_type(length_l0, velocity_l0_per_s, fibre, generic)
    return np.moveaxis(fl, 0, -1), np.moveaxis(fv, 0, -1)


def fibre_curves_by_type(length_l0, velocity_l0_per_s, fibre: FibreTypeParams,
                         generic: GenericParams):
    """:func:`fibre_curves` with the fibre type first, (2, ...) each: the same values, computed
    with the muscles (not the two fibre types) as NumPy's innermost loop."""
    l = np.asarray(length_l0, dtype=float)
    v = np.asarray(velocity_l0_per_s, dtype=float)
    return curves.fibre_type_curves(l[None], v[None], type_columns(fibre, (2,) + (1,) * l.ndim),
                                    generic.fv_denominator_min)


def time_since_onset(time_s, excitation):
    """Time (s) since the drive last rose above 0, per step and muscle (k, n), from times (k,)
    and drive (k, n); 0 where the drive is 0, and counted from the first step where the drive
    is already on there."""
    t = np.asarray(time_s, dtype=float)
    on = np.asarray(excitation, dtype=float) > 0.0
    rows = np.arange(on.shape[0])[:, None]
    rising = on & ~np.vstack([np.zeros((1, on.shape[1]), dtype=bool), on[:-1]])
    last_onset = np.maximum.accumulate(np.where(rising, rows, 0), axis=0)
    return np.where(on, t[:, None] - t[last_onset], 0.0)


def passive_curves(length_l0, velocity_l0_per_s, constants: VmMuscleConstants):
    """FPE1 and FPE2 (F0) at fascicle length L (L0) and velocity V (L0/s): the bank's
    parallel elastic elements (vm_ros.model.curves)."""
    g = constants.generic
    return (curves.passive_parallel_elastic_cheng2000(length_l0, velocity_l0_per_s,
                                                      constants.lmax, g.c1, g.k1, g.lr1, g.eta),
            curves.thick_filament_compression_cheng2000(length_l0, g.c2, g.k2, g.lr2))


@jitable
def inputs_from_curves(a_slow, a_fast, fl_slow, fl_fast, fv_slow, fv_fast, pe1, pe2, f0,
                       fpcsa_slow, fpcsa_fast):
    """(activation (1), active fibre force (N), isometric force (N), passive fibre force (N),
    force-length multiplier (1), force-velocity multiplier (1)) from the effective activation
    and the curves per fibre type (module docstring): NumPy arrays, or scalars in a compiled
    loop. Sums over the two types are a_slow + a_fast, as sum(axis=-1) adds two terms."""
    flv_slow, flv_fast = fl_slow * fv_slow, fl_fast * fv_fast
    activation = a_slow + a_fast
    isometric_norm = a_slow * fl_slow + a_fast * fl_fast
    active_norm = a_slow * flv_slow + a_fast * flv_fast
    contractile_norm = maximum(0.0, pe1 + (a_slow * (flv_slow + pe2) + a_fast * (flv_fast + pe2)))
    passive_norm = contractile_norm - active_norm
    at_rest_fl = fpcsa_slow * fl_slow + fpcsa_fast * fl_fast
    at_rest_fv = divide_where(fpcsa_slow * flv_slow + fpcsa_fast * flv_fast, at_rest_fl,
                              at_rest_fl > 0.0, 1.0)
    on = activation > 0.0
    fl_multiplier = divide_where(isometric_norm, activation, on, at_rest_fl)
    fv_multiplier = divide_where(active_norm, isometric_norm, on & (isometric_norm > 0.0),
                                 at_rest_fv)
    return (activation, f0 * active_norm, f0 * isometric_norm, f0 * passive_norm, fl_multiplier,
            fv_multiplier)


def vm_model_inputs(constants: VmMuscleConstants, excitation, effective_activation,
                    fascicle_length_m, fascicle_velocity_m_per_s,
                    stimulation_duration=None) -> VmModelInputs:
    """The published models' inputs (module docstring) from one step's outputs ((n,), and
    effective_activation (n, 2)) or many steps' ((k, n), (k, n, 2)). ``stimulation_duration``
    (s) defaults to 0."""
    c = constants
    u = np.asarray(excitation, dtype=float)
    activity = np.asarray(effective_activation, dtype=float)
    x = np.asarray(fascicle_length_m, dtype=float)
    xdot = np.asarray(fascicle_velocity_m_per_s, dtype=float)
    shape = x.shape
    l, v = x / c.l0, xdot / c.l0
    # per fibre type (slow, fast) first: (2, ...)
    fl, fv = fibre_curves_by_type(l, v, c.fibre, c.generic)
    pe1, pe2 = passive_curves(l, v, c)
    f0 = np.broadcast_to(c.f0, shape)
    activation, active, isometric, passive, fl_multiplier, fv_multiplier = inputs_from_curves(
        activity[..., 0], activity[..., 1], fl[0], fl[1], fv[0], fv[1], pe1, pe2, f0,
        c.fpcsa[:, 0], c.fpcsa[:, 1])
    state = MuscleState(
        excitation=u,
        activation=activation,
        fibre_length=x,
        optimal_fibre_length=np.broadcast_to(c.l0, shape),
        fibre_velocity=xdot,
        active_fibre_force=active,
        isometric_force=isometric,
        max_isometric_force=f0,
        mass=np.broadcast_to(c.mass, shape),
        slow_fraction=np.broadcast_to(c.fpcsa[:, 0], shape),
    )
    duration = (np.zeros(shape) if stimulation_duration is None
                else np.broadcast_to(np.asarray(stimulation_duration, dtype=float), shape))
    return VmModelInputs(state, fl_multiplier, fv_multiplier, passive, duration)


def vm_model_inputs_from_outputs(bank, outputs) -> VmModelInputs:
    """:func:`vm_model_inputs` for a MuscleBank and what its ``step`` (a StepOutput) or ``run``
    (a Trajectory) returned; for a Trajectory the stimulation duration is counted from its time
    and excitation series (:func:`time_since_onset`)."""
    excitation = np.asarray(outputs.excitation, dtype=float)
    duration = None
    if excitation.ndim == 2:
        duration = time_since_onset(outputs.time_s, excitation)
    return vm_model_inputs(VmMuscleConstants.from_bank(bank), excitation,
                           outputs.effective_activation, outputs.fascicle_length,
                           outputs.fascicle_velocity, duration)


@dataclass(frozen=True)
class PublishedModel:
    """One published model: its function, the loader of its constants (no argument: the shipped
    config) and the names of the VmModelInputs extras it takes as keywords."""

    name: str
    function: Callable[..., HeatRates]
    load_constants: Callable[[], object]
    extras: tuple = ()
    reference: str = ""


# The registry: model names, in the order tables and plots list them.
PUBLISHED_MODELS = (
    PublishedModel("umberger2003", umberger2003, partial(load_umberger_constants,
                                                         "umberger2003"),
                   ("force_length_multiplier",), "Umberger et al. 2003"),
    PublishedModel("umberger2010", umberger2003, partial(load_umberger_constants,
                                                         "umberger2010"),
                   ("force_length_multiplier",), "Umberger 2010"),
    PublishedModel("uchida2016", umberger2003, partial(load_umberger_constants, "uchida2016"),
                   ("force_length_multiplier",), "Uchida et al. 2016 (OpenSim defaults)"),
    PublishedModel("bhargava2004", bhargava2004, load_bhargava_constants,
                   ("passive_fibre_force",), "Bhargava et al. 2004"),
    PublishedModel("lichtwark2005", lichtwark2005, load_lichtwark_constants,
                   ("force_length_multiplier", "force_velocity_multiplier",
                    "stimulation_duration"), "Lichtwark & Wilson 2005/2007"),
    PublishedModel("houdijk2006", houdijk2006, load_houdijk_constants,
                   ("force_length_multiplier",), "Houdijk et al. 2006"),
    PublishedModel("margaria1968", margaria1968, load_margaria_constants, (), "Margaria 1968"),
    PublishedModel("minetti1997", minetti1997, load_minetti_constants, (),
                   "Minetti & Alexander 1997"),
)
MODELS = {model.name: model for model in PUBLISHED_MODELS}
MODEL_NAMES = tuple(MODELS)
# Former names (before every name became author + year), accepted for one release: old logs
# and scripts name them. RENAMED[old] is the current name.
RENAMED = {"lichtwark_wilson": "lichtwark2005", "minetti_alexander": "minetti1997"}


def current_model_name(name: str) -> str:
    """``name``, or its current name when it is a former one (RENAMED)."""
    return RENAMED.get(name, name)


def published_model(name: str) -> PublishedModel:
    """The registry entry ``name``; InputError naming the known models otherwise."""
    current = current_model_name(name)
    if current not in MODELS:
        raise InputError("energetics model", name, f"unknown; known: {', '.join(MODEL_NAMES)}")
    return MODELS[current]


def rates_from_inputs(inputs: VmModelInputs, models=MODEL_NAMES, constants=None) -> dict:
    """{model name: HeatRates (W)} for each of ``models`` at ``inputs``. ``constants`` maps a
    name to the constants to use (default: each model's shipped config)."""
    constants = dict(constants or {})
    rates = {}
    for name in models:
        model = published_model(name)
        values = constants[name] if name in constants else model.load_constants()
        extras = {key: getattr(inputs, key) for key in model.extras}
        rates[name] = model.function(inputs.state, values, **extras)
    return rates


def published_rates(bank, outputs, models=MODEL_NAMES, constants=None) -> dict:
    """{model name: HeatRates (W, per muscle, (n,) or (k, n))} of the published models on the
    state of a MuscleBank's step (StepOutput) or run (Trajectory)."""
    return rates_from_inputs(vm_model_inputs_from_outputs(bank, outputs), models, constants)


__all__ = [
    "MODELS",
    "MODEL_NAMES",
    "PUBLISHED_MODELS",
    "PublishedModel",
    "RENAMED",
    "VmModelInputs",
    "VmMuscleConstants",
    "current_model_name",
    "fibre_curves",
    "fibre_curves_by_type",
    "published_model",
    "published_rates",
    "rates_from_inputs",
    "time_since_onset",
    "vm_model_inputs",
    "vm_model_inputs_from_outputs",
]
