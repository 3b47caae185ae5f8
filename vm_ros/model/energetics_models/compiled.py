"""The published models over a block of steps, their arithmetic compiled with Numba, to the bit
the values of the NumPy path (in_bank.BankModels without Numba).

Each model is written once (umberger, bhargava, lichtwark, houdijk, margaria, minetti): a
``*_transcendentals`` function over arrays (its powers, exponentials, sines and cosines, and the
piecewise-linear curve of Bhargava) and a ``@jitable`` ``*_rates`` function of everything else.
The NumPy path calls both over arrays; here the first runs over the block's arrays and the second
in a compiled loop over the block's muscle-steps, as does the mapping from Virtual Muscle's state
(vm_state.inputs_from_curves; the powers and exponentials of FL, FPE1 and FPE2 by NumPy,
their arithmetic and FV in loops). The two paths
give the same bits because:

- NumPy's exp, expm1, log1p and power (SIMD code chosen for the machine: on AVX-512, Intel's
  SVML, 1 ulp from libm's in about 5 % of arguments) are computed by NumPy on both paths; only
  +, -, *, /, comparisons and selections are compiled, and those are IEEE operations;
- the recruitment's sine and cosine are libm's on both paths: NumPy's float64 sin and cos call
  libm's (on this AVX-512 machine too), and the compiled loop calls it (LLVM joins the two
  calls into one sincos, which gives the same two values);
- the loops are compiled without fast-math flags: no a * b + c is fused into one rounding
  (LLVM fuses only under the ``contract`` flag, which the model step's kernel sets and these
  loops do not), nothing is reassociated;
- jit.maximum and jit.minimum give NumPy's result where the two arguments are equal (its second:
  max(-0.0, 0.0) is 0.0) and NaN where either is NaN;
- the equations these loops share with the kernel (curves.force_velocity_cheng2000,
  force_length_base, passive_parallel_elastic_argument) are compiled for them as copies of
  their own: Numba keeps one compile of a jitable function per
  argument types, made with the flags of whichever caller compiled it first, so that the kernel
  (with ``contract``) and these loops (without) would otherwise each get the other's in a
  process that compiles both, and their numbers would depend on the order. For the same
  reason the equations these loops compile raise nothing to a power: Numba compiles ``x ** 2``
  once per process for every caller (Lichtwark's G^2 is computed in Python).

test_energetics_compiled.py holds the two paths to the bit.
"""

from __future__ import annotations

import collections
import dataclasses

import numpy as np

from vm_ros.model import curves
from vm_ros.model.energetics_models import constants as model_constants
from vm_ros.model.energetics_models.bhargava import (
    bhargava2004,
    bhargava2004_rates,
    half_pi_sin_cos,
)
from vm_ros.model.energetics_models.houdijk import (
    houdijk2006,
    houdijk2006_exponents,
    houdijk2006_rates,
)
from vm_ros.model.energetics_models.lichtwark import (
    isometric_maintenance,
    lichtwark2005,
    lichtwark2005_exponents,
    lichtwark2005_rates,
)
from vm_ros.model.energetics_models.margaria import margaria1968, margaria1968_rates
from vm_ros.model.energetics_models.minetti import minetti1997, minetti1997_rates
from vm_ros.model.energetics_models.umberger import (
    effective_excitation_powers,
    scaled_effective_excitation,
    umberger2003,
    umberger2003_rates,
)
from vm_ros.model.energetics_models.vm_state import inputs_from_curves
from vm_ros.model.jit import (
    COMPILE_OPTIONS,
    HAVE_NUMBA,
    compile_interruptibly,
    in_disk_cache,
    jitable,
    maximum,
    model_cache_directory,
    numba,
)
from vm_ros.model.kernel import renamed
from vm_ros.model.layout import T, type_columns


def _named_tuple(cls):
    """A named tuple of the fields of the constants class ``cls``, named ``<cls>Compiled`` in
    this module (where Numba's disk cache finds it again in the next process)."""
    return collections.namedtuple(f"{cls.__name__}Compiled",
                                  [f.name for f in dataclasses.fields(cls)], module=__name__)


UmbergerConstantsCompiled = _named_tuple(model_constants.UmbergerConstants)
BhargavaConstantsCompiled = _named_tuple(model_constants.BhargavaConstants)
LichtwarkConstantsCompiled = _named_tuple(model_constants.LichtwarkConstants)
HoudijkConstantsCompiled = _named_tuple(model_constants.HoudijkConstants)
MargariaConstantsCompiled = _named_tuple(model_constants.MargariaConstants)
MinettiConstantsCompiled = _named_tuple(model_constants.MinettiConstants)
TUPLE_TYPES = {getattr(model_constants, cls.__name__.removesuffix("Compiled")): cls
               for cls in (UmbergerConstantsCompiled, BhargavaConstantsCompiled,
                           LichtwarkConstantsCompiled, HoudijkConstantsCompiled,
                           MargariaConstantsCompiled, MinettiConstantsCompiled)}


def compiled_constants(constants):
    """A model's constants (a frozen dataclass) as a named tuple of the same fields, which
    compiled code reads by name (tuples of numbers stay tuples, of floats)."""
    def value(v):
        return tuple(float(x) for x in v) if isinstance(v, tuple) else v

    return TUPLE_TYPES[type(constants)](**{f.name: value(getattr(constants, f.name))
                                           for f in dataclasses.fields(constants)})


def loop_constants(constants) -> tuple:
    """:func:`compiled_constants` as a plain tuple, as the loops take them (and make the named
    tuple again inside): Numba types a plain tuple in its fast C path when a loop is called,
    a named tuple field by field in Python (about 3 us per call with Umberger's 27 fields)."""
    return tuple(compiled_constants(constants))


# the curves' equations these loops share with the kernel, compiled for them alone (module
# docstring)
_force_velocity = jitable(renamed(curves.force_velocity_cheng2000,
                                  "force_velocity_cheng2000_without_contraction"))
_force_length_base = jitable(renamed(curves.force_length_base,
                                     "force_length_base_without_contraction"))
_passive_argument = jitable(renamed(curves.passive_parallel_elastic_argument,
                                    "passive_parallel_elastic_argument_without_contraction"))


# --- the compiled loops: one per model, over a block's muscle-steps as flat arrays --------------
#
# Every array is one value per muscle-step of the block (the per-muscle constants repeated per
# step), flat and contiguous, so that each loop is a plain loop over elements; ``out``: the
# model's component rows (in_bank.COMPONENTS: activation and maintenance, shortening and
# lengthening, basal (0), mechanical work, total), flat, each written by the loop (NaN where
# the model has no such component); ``c``: the model's constants as a plain
# tuple (loop_constants), made the named tuple again as the loop starts.


def _lengths_loop(x, xdot, activity, l0, lmax, passive_constants, with_passive, lengths,
                  passive):
    """``lengths``: L = x / L0, V = xdot / L0, max(L, 0) (FL's base) and the effective
    activation of each type (``activity`` (muscle-steps, 2) as rows); with ``with_passive``,
    ``passive``: FPE1's argument x, -|x| (the argument of its exp) and FPE2's expm1 argument
    (curves.passive_parallel_elastic_cheng2000, thick_filament_compression_cheng2000);
    ``passive_constants``: k1, Lr1, k2, Lr2."""
    k1, lr1, k2, lr2 = passive_constants
    # one loop per kind of row, without branches, so that each is vectorised
    for j in range(x.size):
        length = x[j] / l0[j]
        lengths[0, j] = length
        lengths[1, j] = xdot[j] / l0[j]
        lengths[2, j] = maximum(length, 0.0)
    for t in range(2):
        for j in range(x.size):
            lengths[3 + t, j] = activity[j, t]
    if with_passive:
        for j in range(x.size):
            argument = _passive_argument(lengths[0, j], lmax[j], k1, lr1)
            passive[0, j], passive[1, j] = argument, -np.abs(argument)
            passive[2, j] = curves.thick_filament_compression_exponent(lengths[0, j], k2, lr2)


def _force_length_base_loop(omega, powers):
    """powers[t] = |z| = |(L^beta_t - 1) / omega_t| in place, from L^beta_t (curves'
    _force_length_parts)."""
    for t in range(powers.shape[0]):
        for j in range(powers.shape[1]):
            powers[t, j] = np.abs(_force_length_base(powers[t, j], omega[t]))


def _inputs_loop(lengths, fl, passive, with_passive, passive_constants, f0,
                 fpcsa_slow, fpcsa_fast, fv_columns, denominator_min, out):
    """vm_state.inputs_from_curves at every muscle-step, FV of each type and FPE1 and FPE2 (from
    the values in ``passive``: x, ln(1 + exp(-|x|)) and FPE2's expm1; 0 without
    ``with_passive``) computed here; ``out``: activation, active, isometric and passive force,
    FL and FV multipliers."""
    slow, fast = fv_columns
    c1, k1, eta, c2 = passive_constants
    for j in range(f0.size):
        length, velocity = lengths[0, j], lengths[1, j]
        fv_slow = _force_velocity(velocity, length, *slow, denominator_min)
        fv_fast = _force_velocity(velocity, length, *fast, denominator_min)
        pe1 = pe2 = 0.0
        if with_passive:
            pe1 = curves.passive_parallel_elastic_from_log(passive[0, j], passive[1, j],
                                                           velocity, c1, k1, eta)
            pe2 = curves.thick_filament_compression_from_expm1(passive[2, j], c2)
        (out[0][j], out[1][j], out[2][j], out[3][j], out[4][j], out[5][j]) = inputs_from_curves(
            lengths[3, j], lengths[4, j], fl[0, j], fl[1, j], fv_slow, fv_fast, pe1, pe2,
            f0[j], fpcsa_slow[j], fpcsa_fast[j])


def _sin_cos_loop(scaling, excitation, out):
    """out[0], out[1] = bhargava.half_pi_sin_cos(scaling * excitation): libm's sine and
    cosine, which NumPy calls (module docstring), one sincos per element."""
    for j in range(excitation.size):
        out[0, j], out[1, j] = half_pi_sin_cos(scaling * excitation[j])


def _effective_excitation_loop(scaling, excitation, activation, out):
    for j in range(excitation.size):
        out[j] = scaled_effective_excitation(scaling, excitation[j], activation[j])


def _umberger_loop(c, excitation, mass, velocity, lengths, active, slow, fl_multiplier,
                   effective, maintenance_power, shortening_power, sin_angle, cos_angle, out):
    """``lengths``: L and V (:func:`_lengths_loop`)."""
    c = UmbergerConstantsCompiled(*c)
    for j in range(velocity.size):
        out[2][j] = 0.0
        out[0][j], out[1][j], out[3][j], out[4][j] = umberger2003_rates(
            c, excitation[j], mass[j], velocity[j], lengths[1, j], lengths[0, j], active[j],
            slow[j], fl_multiplier[j], effective[j], maintenance_power[j], shortening_power[j],
            sin_angle[j], cos_angle[j])


def _bhargava_loop(c, mass, velocity, active, passive, isometric, lengths, slow, sin_angle,
                   cos_angle, out):
    """``lengths``: L (row 0, :func:`_lengths_loop`)."""
    c = BhargavaConstantsCompiled(*c)
    for j in range(velocity.size):
        out[2][j] = 0.0
        out[0][j], out[1][j], out[3][j], out[4][j] = bhargava2004_rates(
            c, mass[j], velocity[j], active[j], passive[j], isometric[j], lengths[0, j],
            slow[j], sin_angle[j], cos_angle[j])


def _lichtwark_exponents_loop(c, duration, fv_multiplier, out):
    c = LichtwarkConstantsCompiled(*c)
    for j in range(fv_multiplier.size):
        out[0, j], out[1, j], out[2, j] = lichtwark2005_exponents(c, duration[j],
                                                                  fv_multiplier[j])


def _lichtwark_loop(c, activation, l0, f0, velocity, active, fl_multiplier, fv_multiplier,
                    exponentials, curvature_squared, out):
    """``exponentials``: those of lichtwark2005_exponents' arguments, (3, muscle-steps)."""
    c = LichtwarkConstantsCompiled(*c)
    for j in range(velocity.size):
        maintenance = isometric_maintenance(c, exponentials[0, j], exponentials[1, j],
                                            curvature_squared)
        out[2][j] = 0.0
        out[0][j], out[1][j], out[3][j], out[4][j] = lichtwark2005_rates(
            c, activation[j], l0[j], f0[j], velocity[j], active[j], fl_multiplier[j],
            fv_multiplier[j], maintenance, exponentials[2, j])


def _houdijk_exponents_loop(c, activation, slow, out):
    c = HoudijkConstantsCompiled(*c)
    for j in range(activation.size):
        out[0, j], out[1, j] = houdijk2006_exponents(c, activation[j], slow[j])


def _houdijk_loop(c, activation, mass, velocity, slow, f0, active, fl_multiplier, recruited_exp,
                  at_max_exp, out):
    c = HoudijkConstantsCompiled(*c)
    for j in range(velocity.size):
        out[2][j] = 0.0
        out[0][j], out[1][j], out[3][j], out[4][j] = houdijk2006_rates(
            c, activation[j], mass[j], velocity[j], slow[j], f0[j], active[j],
            fl_multiplier[j], recruited_exp[j], at_max_exp[j])


def _margaria_loop(c, active, velocity, out):
    c = MargariaConstantsCompiled(*c)
    for j in range(velocity.size):
        out[0][j] = out[1][j] = np.nan
        out[2][j] = 0.0
        out[3][j], out[4][j] = margaria1968_rates(c, active[j], velocity[j])


def _minetti_loop(c, activation, f0, l0, velocity, out):
    c = MinettiConstantsCompiled(*c)
    for j in range(velocity.size):
        out[0][j] = out[1][j] = out[3][j] = np.nan
        out[2][j] = 0.0
        out[4][j] = minetti1997_rates(c, activation[j], f0[j], l0[j], velocity[j])


def _integrate_loop(energy, totals, dt, start, stop, out):
    """out[m, j, i] for start <= j < stop = the energy after step j - 1 (out[m, j - 1, i], or
    energy[m, i] for j = 0) + totals[m, j, i] dt[j], added step after step (E += rate dt), as
    step-by-step integration adds them."""
    n = out.shape[2]
    for m in range(out.shape[0]):
        rates, energies = totals[m], out[m]
        for i in range(n):
            previous = energy[m, i] if start == 0 else energies[start - 1, i]
            energies[start, i] = previous + rates[start, i] * dt[start]
        for j in range(start + 1, stop):
            for i in range(n):
                energies[j, i] = energies[j - 1, i] + rates[j, i] * dt[j]


def _stimulation_duration_loop(time_s, excitation, onset_s, out):
    """in_bank.BankModels.stimulation_duration in one pass: out[j, i] = time since the drive
    last rose above 0 (0 where it is 0), ``onset_s`` (n,) advanced in place."""
    steps, n = excitation.shape
    drive_on = np.empty(n, dtype=np.bool_)
    for i in range(n):
        drive_on[i] = not np.isnan(onset_s[i])
    for j in range(steps):
        t = time_s[j]
        for i in range(n):
            on = excitation[j, i] > 0.0
            if on and not drive_on[i]:
                onset_s[i] = t
            out[j, i] = t - onset_s[i] if on else 0.0
            drive_on[i] = on
    for i in range(n):
        if not drive_on[i]:
            onset_s[i] = np.nan


# no fast-math flags (module docstring); divisions by zero give inf or NaN, as NumPy's
OPTIONS = {"cache": True, "nogil": True, "error_model": "numpy", "fastmath": False,
           **COMPILE_OPTIONS}
LOOPS = (_lengths_loop, _force_length_base_loop, _inputs_loop, _sin_cos_loop,
         _effective_excitation_loop, _umberger_loop, _bhargava_loop, _lichtwark_exponents_loop,
         _lichtwark_loop, _houdijk_exponents_loop, _houdijk_loop, _margaria_loop, _minetti_loop,
         _integrate_loop, _stimulation_duration_loop)
AVAILABLE = HAVE_NUMBA
if HAVE_NUMBA:
    with model_cache_directory():
        (_lengths_loop, _force_length_base_loop, _inputs_loop, _sin_cos_loop,
         _effective_excitation_loop, _umberger_loop, _bhargava_loop, _lichtwark_exponents_loop,
         _lichtwark_loop, _houdijk_exponents_loop, _houdijk_loop, _margaria_loop, _minetti_loop,
         _integrate_loop, _stimulation_duration_loop) = LOOPS = tuple(
            numba.njit(**OPTIONS)(loop) for loop in LOOPS)


# --- one model over a block: its transcendentals by NumPy, then its loop -------------------------


@dataclasses.dataclass(frozen=True)
class Block:
    """A block's arrays, flat (one value per muscle-step): its outputs (``duration`` None: 0 s,
    as no selected model takes it), L and V as rows of ``lengths`` (:func:`_lengths_loop`), the
    mapped inputs and the bank's per-muscle constants repeated per step; ``memo``:
    transcendentals computed for it (:func:`_memo`)."""

    excitation: np.ndarray
    length: np.ndarray
    velocity: np.ndarray
    lengths: np.ndarray
    duration: np.ndarray | None
    activation: np.ndarray
    active: np.ndarray
    isometric: np.ndarray
    passive: np.ndarray
    fl_multiplier: np.ndarray
    fv_multiplier: np.ndarray
    l0: np.ndarray
    f0: np.ndarray
    mass: np.ndarray
    slow: np.ndarray
    memo: dict


def _memo(b: Block, key, compute):
    """compute(), or its value for the same key earlier in this block (models of the same
    constants share their transcendentals: the three Umberger variants their powers, Uchida and
    Bhargava the recruitment's sine and cosine)."""
    if key not in b.memo:
        b.memo[key] = compute()
    return b.memo[key]


def _recruitment_sin_cos(b: Block, scaling):
    def compute():
        out = np.empty((2, b.excitation.size))
        _sin_cos_loop(scaling, b.excitation, out)
        return out

    return _memo(b, ("recruitment", scaling), compute)


def _umberger(c, b: Block, constants, out):
    key = ("umberger powers", constants.muscle_effort_scaling_factor,
           constants.activation_maintenance_exponent, constants.shortening_exponent)
    def compute():
        effective = np.empty(b.excitation.size)
        _effective_excitation_loop(constants.muscle_effort_scaling_factor, b.excitation,
                                   b.activation, effective)
        return effective_excitation_powers(constants, effective)

    effective, maintenance, shortening = _memo(b, key, compute)
    sin_angle = cos_angle = effective  # not used without Bhargava's recruitment
    if constants.use_Bhargava_recruitment_model:
        sin_angle, cos_angle = _recruitment_sin_cos(b, constants.muscle_effort_scaling_factor)
    _umberger_loop(c, b.excitation, b.mass, b.velocity, b.lengths, b.active, b.slow,
                   b.fl_multiplier, effective, maintenance, shortening, sin_angle, cos_angle, out)


def _bhargava(c, b: Block, constants, out):
    sin_angle, cos_angle = _recruitment_sin_cos(b, constants.muscle_effort_scaling_factor)
    _bhargava_loop(c, b.mass, b.velocity, b.active, b.passive, b.isometric, b.lengths, b.slow,
                   sin_angle, cos_angle, out)


def _lichtwark(c, b: Block, constants, out):
    duration = np.zeros(b.length.size) if b.duration is None else b.duration
    exponentials = np.empty((3, b.length.size))
    _lichtwark_exponents_loop(c, duration, b.fv_multiplier, exponentials)
    np.exp(exponentials, out=exponentials)
    _lichtwark_loop(c, b.activation, b.l0, b.f0, b.velocity, b.active, b.fl_multiplier,
                    b.fv_multiplier, exponentials, constants.force_velocity_curvature ** 2, out)


def _houdijk(c, b: Block, constants, out):
    exponents = np.empty((2, b.activation.size))
    _houdijk_exponents_loop(c, b.activation, b.slow, exponents)
    recruited_exp, at_max_exp = np.exp(exponents)
    _houdijk_loop(c, b.activation, b.mass, b.velocity, b.slow, b.f0, b.active, b.fl_multiplier,
                  recruited_exp, at_max_exp, out)


def _margaria(c, b: Block, constants, out):
    _margaria_loop(c, b.active, b.velocity, out)


def _minetti(c, b: Block, constants, out):
    _minetti_loop(c, b.activation, b.f0, b.l0, b.velocity, out)


# each published model's function (vm_state.PUBLISHED_MODELS) -> its run over a block
BLOCK_RUNS = {umberger2003: _umberger, bhargava2004: _bhargava, lichtwark2005: _lichtwark,
              houdijk2006: _houdijk, margaria1968: _margaria, minetti1997: _minetti}


def integrate_energies(energy_j, totals, dt, rows, out) -> None:
    """out[:, rows] (M, k, n) = cumulative energies (J) after the steps ``rows`` (a slice) of k,
    from ``energy_j`` (M, n) before step 0 and out[:, rows.start - 1] after it, the totals
    (M, k, n) W over steps of dt (k,) s: E += rate dt step after step
    (in_bank.BankModels.advance)."""
    _integrate_loop(energy_j, totals, dt, rows.start, rows.stop, out)


def stimulation_duration(time_s, excitation, onset_s):
    """(time since the drive last rose above 0 (k, n) s, the onsets after) of k steps ending at
    ``time_s`` (k,) with drive (k, n), from the onsets ``onset_s`` (n,) (NaN: drive off)."""
    onset = np.array(onset_s, dtype=float)
    drive = np.ascontiguousarray(excitation, dtype=float)
    out = np.empty(drive.shape)
    _stimulation_duration_loop(np.ascontiguousarray(time_s, dtype=float), drive, onset, out)
    return out, onset


class CompiledModels:
    """The selected models (vm_state.PublishedModel entries and their loaded constants) of a
    bank (vm_state.VmMuscleConstants), run over blocks of its outputs."""

    def __init__(self, models, constants, muscle):
        self._runs = [BLOCK_RUNS[model.function] for model in models]
        self._constants = list(constants)
        self._compiled = [loop_constants(c) for c in constants]
        self.muscle = muscle
        n = len(np.atleast_1d(muscle.f0))
        # per muscle: l0, f0, mass, slow and fast PCSA fractions, lmax
        self._per_muscle = np.stack([np.broadcast_to(np.asarray(a, dtype=float), (n,)) for a in (
            muscle.l0, muscle.f0, muscle.mass, muscle.fpcsa[:, 0], muscle.fpcsa[:, 1],
            muscle.lmax)])
        self._fl_columns = type_columns(muscle.fibre, (2, 1))
        # FPE1 and FPE2 enter the passive force alone, which Bhargava's model alone takes (the
        # registry's extras): without it they are left at 0 (the other models never read it)
        self._passive = any("passive_fibre_force" in model.extras for model in models)
        self._repeated = {}  # rows -> per-muscle constants repeated over them, block buffers
        columns = type_columns(muscle.fibre)
        self._fv_columns = tuple(tuple(float(np.asarray(columns[name])[t]) for name in (
            T.vmax, T.cv0, T.cv1, T.av0, T.av1, T.av2, T.bv)) for t in range(2))
        self._omega = np.ascontiguousarray(np.asarray(columns[T.omega], dtype=float).reshape(2))
        g = muscle.generic
        self._passive_arguments = tuple(float(a) for a in (g.k1, g.lr1, g.k2, g.lr2))
        self._passive_factors = tuple(float(a) for a in (g.c1, g.k1, g.eta, g.c2))

    def fill(self, out, excitation, effective_activation, length_m, velocity_m_per_s,
             stimulation_duration) -> None:
        """out[m, c] (M, C, rows, n) = component c of model m at a block's outputs (rows, n)
        (effective activation (rows, n, 2); stimulation duration (s) or None for 0)."""
        shape = np.shape(length_m)
        u, x, xdot = (np.ascontiguousarray(a, dtype=float).reshape(-1)
                      for a in (excitation, length_m, velocity_m_per_s))
        activity = np.ascontiguousarray(effective_activation, dtype=float).reshape(-1, 2)
        duration = (None if stimulation_duration is None
                    else np.ascontiguousarray(stimulation_duration, dtype=float).reshape(-1))
        if shape[0] not in self._repeated:  # a new (writable) array for any number of rows, so
            # that the loops warm_up compiles are the ones a block calls, and the block's
            # buffers for that many rows (nothing outlives the block's fill)
            size = x.size
            self._repeated[shape[0]] = (
                np.tile(self._per_muscle, (1, shape[0])), np.empty((5, size)),
                np.empty((3, size) if self._passive else (3, 0)), np.empty((2, size)),
                np.empty((6, size)))
        per_muscle, lengths, passive, fl, inputs = self._repeated[shape[0]]
        l0, f0, mass, fpcsa_slow, fpcsa_fast, lmax = per_muscle
        _lengths_loop(x, xdot, activity, l0, lmax, self._passive_arguments, self._passive,
                      lengths, passive)
        # FL of each type (curves.force_length_cheng2000: its powers and exp by NumPy)
        ft = self._fl_columns
        np.power(lengths[2:3], ft[T.beta], out=fl)
        _force_length_base_loop(self._omega, fl)
        np.power(fl, ft[T.rho], out=fl)
        np.exp(np.negative(fl, out=fl), out=fl)
        if self._passive:  # ln(1 + exp(-|x|)) and expm1 of FPE1 and FPE2, by NumPy
            np.log1p(np.exp(passive[1], out=passive[1]), out=passive[1])
            np.expm1(passive[2], out=passive[2])
        _inputs_loop(lengths, fl, passive, self._passive, self._passive_factors, f0,
                     fpcsa_slow, fpcsa_fast, self._fv_columns,
                     float(self.muscle.generic.fv_denominator_min), tuple(inputs))
        block = Block(u, x, xdot, lengths, duration, *inputs, l0, f0, mass, fpcsa_slow, {})
        rows = np.reshape(out, (*out.shape[:2], -1), copy=False)  # (M, C, muscle-steps) view
        for run, c, constants, model_rows in zip(self._runs, self._compiled, self._constants,
                                                 rows, strict=True):
            run(c, block, constants, tuple(model_rows))


# The loops' first compile, for the line warm_up prints (docs/performance.md)
COMPILE_TIME = "about 5-15 s"


def warm_up(compiled_models: CompiledModels) -> None:
    """Compile the loops ``compiled_models`` runs (or load them from Numba's disk cache) now,
    on a block of one step, rather than in its first block; a compile says so on stderr first
    (jit.compile_interruptibly)."""
    n = compiled_models._per_muscle.shape[1]
    models = len(compiled_models._runs)

    def compile_now():
        zeros = np.zeros((1, n))
        compiled_models.fill(np.empty((models, 5, 1, n)), zeros, np.zeros((1, n, 2)),
                             np.ones((1, n)), zeros, zeros)
        rates = np.zeros((models, 5, 2, n))
        integrate_energies(np.zeros((models, n)), rates[:, 4], np.ones(2), slice(0, 2),
                           np.empty((models, 2, n)))
        stimulation_duration(np.zeros(1), zeros, np.full(n, np.nan))

    loops = [loop for loop in LOOPS if not loop.signatures]
    if all(in_disk_cache(loop) for loop in loops):
        compile_now()
    else:
        compile_interruptibly(compile_now, "the published energetics models", COMPILE_TIME)


__all__ = ["AVAILABLE", "BLOCK_RUNS", "COMPILE_TIME", "CompiledModels", "compiled_constants",
           "integrate_energies", "loop_constants", "stimulation_duration", "warm_up"]
