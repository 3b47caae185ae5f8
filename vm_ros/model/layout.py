"""The fixed step's data, declared once: state, the compiled kernel's constants, and outputs.

Every list that names these arrays is derived from the declarations below: the fields and docstring
of :class:`BankState`, the states integrated by the reference ODE, the shape check of
``MuscleBank.set_state``, the zero state of ``reset``, the kernel's argument lists (checked against
its signatures by test_model_layout.py), its warm-up arguments and the output record
(vm_ros.model.records.StepRecord). Adding a state is one :class:`Array` line in :data:`STATE` plus
the equations that move it.

Shapes name their axes: ``n`` muscles, ``P`` motor-unit pools (2 for lumped and continuous
recruitment, 2N for N natural units per fibre type), ``k`` steps (a series); numbers are fixed
sizes (2 fibre types, 3 energy components, POLY_TERMS coefficients of a polynomial).
"""

from __future__ import annotations

import dataclasses
from collections import namedtuple
from dataclasses import dataclass

import numpy as np

from vm_ros.errors import VmRosError


@dataclass(frozen=True)
class Array:
    """One array of the step: its name where Python holds it, its name in the kernel's signature,
    its shape (axis names or sizes), unit and meaning."""

    name: str
    kernel: str
    shape: tuple
    unit: str
    meaning: str
    dtype: type = float

    def shape_for(self, sizes: dict) -> tuple:
        """The concrete shape, axis names looked up in ``sizes`` ({"n": 3, "P": 2, ...})."""
        return tuple(sizes[axis] if isinstance(axis, str) else axis for axis in self.shape)

    def zeros(self, sizes: dict, leading: tuple = ()) -> np.ndarray:
        return np.zeros(leading + self.shape_for(sizes), dtype=self.dtype)

    def empty(self, sizes: dict, leading: tuple = ()) -> np.ndarray:
        return np.empty(leading + self.shape_for(sizes), dtype=self.dtype)


def table_rows(arrays) -> str:
    """Docstring rows ``| name | shape | unit | meaning |`` of ``arrays``."""
    rows = []
    for a in arrays:
        shape = "(" + ", ".join(str(axis) for axis in a.shape) + ("," if len(a.shape) == 1 else "")
        rows.append(f"    | {a.name} | {shape}) | {a.unit} | {a.meaning} |")
    return "\n".join(rows)


# --- state ---------------------------------------------------------------------------------------

TIME = Array("time_s", "", (), "s", "model time")
# In the kernel's argument order. Every state here is integrated by the reference ODE.
STATE = (
    Array("effective_drive", "effective_drive", ("n", 2), "1",
          "filtered drive Ueff per fibre type (slow, fast; U: natural)"),
    Array("firing_rate_intermediate", "f_int", ("n", "P"), "f0.5", "f_int of each pool"),
    Array("firing_rate_effective", "f_eff", ("n", "P"), "f0.5", "f_eff of each pool"),
    Array("sag", "sag", ("n", "P"), "1", "sag S of each pool (1 for slow)"),
    Array("yield_factor", "yield_factor", ("n", "P"), "1", "yield Y of each pool (1 for fast)"),
    Array("fascicle_length_m", "x_state", ("n",), "m", "fascicle length x"),
    Array("fascicle_velocity_m_per_s", "xdot_state", ("n",), "m/s",
          "fascicle velocity, negative when shortening"),
    Array("recovery_filter", "recovery_filter", ("n", 2, 2), "J",
          "recovery filter per fibre type (decay, rise); zero in static mode"),
    Array("energy_j", "energy", ("n", 2, 3), "J",
          "energy since reset per fibre type and component (activation, cross-bridge, recovery)"),
    Array("mechanical_work_j", "work", ("n",), "J", "mechanical work since reset"),
)
STATE_NAMES = tuple(a.name for a in STATE)
# states that feed nothing back into the dynamics (integrals of outputs)
OUTPUT_INTEGRALS = ("energy_j", "mechanical_work_j")


def _copy(self):
    return type(self)(time_s=self.time_s, **{name: getattr(self, name).copy()
                                             for name in STATE_NAMES})


BankState = dataclasses.make_dataclass(
    "BankState",
    [(TIME.name, float)] + [(a.name, np.ndarray) for a in STATE],
    namespace={"copy": _copy},
)
BankState.__module__ = __name__  # pickles by this module's name
BankState.__doc__ = (
    "The bank's dynamic state (fields from vm_ros.model.layout.STATE).\n\n"
    "    | field | shape | unit | meaning |\n" + table_rows((TIME, *STATE)) + "\n"
)
BankState.copy.__doc__ = "A copy whose arrays are fresh."


def state_sizes(n: int, pools: int) -> dict:
    return {"n": n, "P": pools}


def zero_state(n: int, pools: int, time_s: float = 0.0) -> BankState:
    """Every state array at zero."""
    sizes = state_sizes(n, pools)
    return BankState(time_s=float(time_s), **{a.name: a.zeros(sizes) for a in STATE})


def checked_state(state, n: int, pools: int) -> BankState:
    """A float, C-ordered copy of ``state``; ValueError naming the first array of another shape."""
    sizes = state_sizes(n, pools)
    arrays = {}
    for a in STATE:
        array = np.array(getattr(state, a.name), dtype=float)
        if array.shape != a.shape_for(sizes):
            raise ValueError(f"state.{a.name} has shape {array.shape}; "
                             f"this bank needs {a.shape_for(sizes)}")
        arrays[a.name] = array
    return BankState(time_s=float(state.time_s), **arrays)


# --- kernel constants ----------------------------------------------------------------------------


class MissingConstantError(VmRosError, LookupError):
    """A constant the compiled step reads is in none of the sources it is packed from."""

    def __init__(self, table: str, column: str):
        self.table, self.column = table, column
        super().__init__(f"kernel constant {table}.{column} is in none of its sources "
                         "(renamed model parameter?)")


def _columns(name, columns):
    """Column indices of a constants table, by field name (Numba folds them as constants), with
    the unit of each column in ``UNITS``."""
    table = namedtuple(name, [c for c, _ in columns])(*range(len(columns)))
    return table, dict(columns)


# per muscle; the lumped-only columns are NaN for the other schemes
M, M_UNITS = _columns("MuscleColumns", (
    ("f0", "N"), ("l0", "m"), ("l0t", "m"), ("m_eff", "kg"), ("lmax", "L0"), ("dry_mass", "kg"),
    ("ur", "1"), ("u2", "1"), ("fpcsa_s", "1"), ("fpcsa_f", "1"),
    ("rec_lower_s", "1"), ("rec_lower_f", "1"), ("rec_upper_s", "1"), ("rec_upper_f", "1"),
    ("t_rise", "s"), ("t_fall", "s"), ("w_slow_at_u2", "1"), ("w_slow_amplitude", "1"),
    ("w_fast_b", "1"), ("w_fast_c", "1"), ("w_fast_tau", "1"), ("relative_rise", "s"),
    ("relative_fall", "s"), ("t_rise_rate", "1"),
))
LUMPED_ONLY = ("u2", "rec_lower_s", "rec_lower_f", "rec_upper_s", "rec_upper_f", "t_rise",
               "t_fall", "w_slow_at_u2", "w_slow_amplitude", "w_fast_b", "w_fast_c", "w_fast_tau",
               "relative_rise", "relative_fall", "t_rise_rate")
# per motor-unit pool (shared by every muscle)
P, P_UNITS = _columns("PoolColumns", (
    ("af", "f0.5"), ("nf0", "1"), ("nf1", "1"), ("tf1", "s"), ("tf2", "s"), ("tf3", "s"),
    ("tf4", "s"), ("as1", "1"), ("as2", "1"), ("sag_rate_threshold", "f0.5"), ("ts", "s"),
    ("cy", "1"), ("vy", "L0/s"), ("ty", "s"), ("l_max", "L0"),
))
# per fibre type
T, T_UNITS = _columns("TypeColumns", (
    ("omega", "1"), ("beta", "1"), ("rho", "1"), ("vmax", "L0/s"), ("cv0", "1"), ("cv1", "1"),
    ("av0", "1"), ("av1", "1"), ("av2", "1"), ("bv", "L0/s"), ("e1", "W s/(kg L0)"),
    ("e2", "W/kg"), ("e3", "W L0/(kg s)"), ("e4", "L0/s"), ("recovery_ratio", "1"),
))
def type_columns(fibre, shape=None) -> tuple:
    """Fibre-type parameters (FibreTypeParams: arrays over the fibre-type axis) as a tuple indexed
    by the columns T, as the compiled kernel reads its rows (None where ``fibre`` lacks a column:
    the energetics ones are packed from elsewhere); each array reshaped to ``shape`` if given."""
    def column(name):
        value = getattr(fibre, name, None)
        return value if value is None or shape is None else np.reshape(value, shape)

    return tuple(column(name) for name in T._fields)


# shared scalars
S, S_UNITS = _columns("SharedColumns", (
    ("fmin", "f0.5"), ("fmax", "f0.5"), ("c1", "1"), ("k1", "1"), ("lr1", "1"),
    ("eta", "F0 s/L0"), ("c2", "1"), ("k2", "1"), ("lr2", "1"), ("ct", "1"), ("kt", "1"),
    ("lrt", "1"), ("l_activation_min", "L0"), ("fv_denominator_min", "1"),
    ("activation_fraction", "1"), ("recovery_tau_rise", "s"), ("recovery_tau_decay", "s"),
    ("u1", "1"), ("t_rise_step_scale", "1/s"), ("w_slow_tau", "1"), ("w_fast_offset", "1"),
    ("w_fast_rise", "1"), ("continuous_tau_rise", "s"), ("continuous_tau_fall", "s"),
    ("drive_law_code", "1"), ("relative_fall_power", "1"),
    ("relative_fall_floor", "s"), ("drive_tau_min", "s"),
))

# The kernel reads a polynomial's coefficients as a tuple of this fixed length (leading zeros
# change nothing in Horner's rule): a degree of up to POLY_TERMS - 1.
POLY_TERMS = 8


def padded_polynomial(coefficients) -> np.ndarray:
    """``coefficients`` (highest power first) with leading zeros up to POLY_TERMS; ValueError
    for a degree above POLY_TERMS - 1."""
    coefficients = np.asarray(coefficients, dtype=float).reshape(-1)
    if coefficients.size > POLY_TERMS:
        raise ValueError(f"a polynomial of {coefficients.size} coefficients: the compiled step "
                         f"takes at most {POLY_TERMS}")
    return np.concatenate([np.zeros(POLY_TERMS - coefficients.size), coefficients])


# In the kernel's argument order.
CONSTANTS = (
    Array("scheme", "scheme", (), "1", "recruitment scheme code (SCHEME_CODES)", int),
    Array("dynamic_recovery", "dynamic_recovery", (), "1", "recovery filter on", bool),
    Array("muscle", "muscle", ("n", len(M)), "M_UNITS", "per-muscle table, columns M"),
    Array("pool", "pool", ("P", len(P)), "P_UNITS", "per-pool table, columns P"),
    Array("pool_type", "pool_type", ("P",), "1", "fibre type of each pool (0 slow, 1 fast)",
          np.int64),
    Array("thresholds", "thresholds", ("n", "P"), "1", "drive at which each pool fires"),
    Array("pool_pcsa", "pool_pcsa", ("n", "P"), "1", "PCSA fraction of each pool"),
    Array("fibre_type", "fibre_type", (2, len(T)), "T_UNITS", "per-fibre-type table, columns T"),
    Array("shared", "shared", (1, len(S)), "S_UNITS", "shared scalars, columns S"),
    Array("w_slow_poly", "w_slow_poly", (POLY_TERMS,), "1",
          "W_S polynomial in Ueff, highest first, padded with leading zeros"),
)


def table(name: str, columns, rows: int, sources) -> np.ndarray:
    """A (rows, columns) float table with each column taken from the first source that has it
    (a mapping's key or an object's attribute); MissingConstantError names a column none has."""
    values = np.empty((rows, len(columns)))
    for column, index in columns._asdict().items():
        for source in sources:
            if isinstance(source, dict):
                if column in source:
                    values[:, index] = source[column]
                    break
            elif hasattr(source, column):
                values[:, index] = getattr(source, column)
                break
        else:
            raise MissingConstantError(name, column)
    return values


# --- the kernel's cache, inputs and outputs -----------------------------------------------------

N_TERMS = 14  # the (L, V) terms of F_CE and their slopes kept per muscle (kernel.FL_SLOW...)
CACHE = (
    Array("terms_end", "terms_end", ("n", N_TERMS), "mixed",
          "the (L, V) terms of F_CE at xv_end (kernel.FL_SLOW ... DPE2)"),
    Array("xv_end", "xv_end", ("n", 2), "m, m/s",
          "(x, xdot) at which terms_end holds (NaN: none)"),
)
INPUTS = (
    Array("dt", "dt", (), "s", "step"),
    Array("excitation", "excitation", ("n",), "1", "drive U (not yet clipped)"),
    Array("path_length", "path_length", ("n",), "m", "musculotendon path length at the start"),
    Array("path_velocity", "path_velocity", ("n",), "m/s", "its rate over the step"),
)
OUTPUTS = (
    Array("excitation", "out_excitation", ("n",), "1", "drive U as used (clipped to [0, 1])"),
    Array("force", "out_f_se", ("n",), "N", "tendon force F_SE (VM's output force)"),
    Array("contractile_force", "out_f_ce", ("n",), "N", "F_CE"),
    Array("effective_activation", "out_activity", ("n", 2), "1", "Acteff per fibre type"),
    Array("stimulation", "out_stimulation", ("n", 2), "1",
          "weight x Af(f_eff, L=1, Y=1, S) per fibre type (Tsianos 2012 STEP 5)"),
    Array("energy_components", "out_components", ("n", 2, 3), "W",
          "energy rates per fibre type and component (activation, cross-bridge, recovery)"),
    Array("energy_rates", "out_rates", ("n", 4), "W",
          "energy rates summed over fibre types (activation, cross-bridge, recovery, total)"),
    Array("mechanical_power", "out_power", ("n",), "W", "-F_CE x fascicle velocity"),
)
# a series (MuscleBank.run) also writes the fascicle state of every step
SERIES_OUTPUTS = OUTPUTS + (
    Array("fascicle_length", "out_length", ("n",), "m", "fascicle length at the step's end"),
    Array("fascicle_velocity", "out_velocity", ("n",), "m/s", "its velocity"),
)


# and, when asked (MuscleBank.run's snapshot_every m > 0), the state at the end of every m-th
# step: each state array with a leading axis of k // m snapshots
SNAPSHOT_EVERY = Array("snapshot_every", "snapshot_every", (), "1",
                       "steps between state snapshots (0: none)", int)
SNAPSHOTS = tuple(Array(a.name, f"snap_{a.kernel}", a.shape, a.unit, a.meaning) for a in STATE)
# and the muscles per block of the parallel kernel (0: one block)
CHUNK = Array("chunk", "chunk", (), "1", "muscles per block (0: all in one)", int)


def kernel_parameters() -> tuple:
    """The kernel's parameter names, in order (kernel._advance_series)."""
    return tuple(a.kernel for a in (*INPUTS, *CONSTANTS, *STATE, *CACHE, *SERIES_OUTPUTS,
                                    SNAPSHOT_EVERY, *SNAPSHOTS, CHUNK))


def dummy_arguments(scheme: int = 0) -> tuple:
    """Arguments of every declared type of the series kernel (kernel._advance_series) for a bank
    of no muscles, one step and no snapshots: they compile it."""
    sizes = {"n": 0, "P": 2}
    scalars = {"dt": 1e-3, "scheme": scheme, "dynamic_recovery": False, "snapshot_every": 0,
               "chunk": 0}

    def arrays(declared, leading=()):
        return tuple(scalars[a.name] if a.shape == () else a.zeros(sizes, leading)
                     for a in declared)

    return (*arrays(INPUTS[:1]), *arrays(INPUTS[1:], (1,)), *arrays((*CONSTANTS, *STATE, *CACHE)),
            *arrays(SERIES_OUTPUTS, (1,)), scalars["snapshot_every"], *arrays(SNAPSHOTS, (0,)),
            scalars["chunk"])


__all__ = [
    "CACHE", "CHUNK", "CONSTANTS", "INPUTS", "N_TERMS", "OUTPUTS", "POLY_TERMS", "SERIES_OUTPUTS",
    "SNAPSHOTS",
    "SNAPSHOT_EVERY", "STATE", "STATE_NAMES",
    "TIME", "Array", "BankState", "M", "MissingConstantError", "P", "S", "T",
    "checked_state", "dummy_arguments", "kernel_parameters", "padded_polynomial", "table",
    "type_columns", "zero_state",
]
