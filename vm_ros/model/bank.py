"""MuscleBank: a vectorised set of Virtual Muscles that owns the model state.

    bank = MuscleBank.from_config(muscles=["vasti", "rectus_femoris"], recruitment="lumped")
    bank.reset(path_length=np.array([0.30, 0.42]))
    out = bank.step(0.001, excitation=np.array([0.5, 0.2]), path_length=np.array([0.30, 0.42]))

One ``step`` advances every muscle: the first-order activation states (drive filter, rise/fall,
sag, yield, recovery) by their exact exponential update, then the stiff fascicle mechanics by the
L-stable ROS2 method with activation held over the step, then energetics at the new state.
:meth:`MuscleBank.derivatives` exposes the same equations as a continuous right-hand side so they
can be handed to ``scipy.integrate.solve_ivp`` (see vm_ros.model.reference).

Shapes: n muscles, P motor-unit pools (2 for lumped/continuous, 2N for natural units), 2 fibre
types (slow, fast).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import numpy as np

from vm_ros.errors import InputError
from vm_ros.model import activation as act
from vm_ros.model import energetics as en
from vm_ros.model import kernel
from vm_ros.model.curves import activation_frequency_brown1999
from vm_ros.model.mechanics import (
    MuscleGeometry,
    equilibrium_fascicle_length,
    musculotendon_forces,
    musculotendon_forces_and_slopes,
    rosenbrock_step,
)
from vm_ros.model.params import (
    FAST,
    RECOVERY_MODES,
    SLOW,
    ModelParams,
    MuscleSpec,
    load_model_params,
    resolve_muscles,
)
from vm_ros.model.recruitment import SCHEMES, make_recruitment

ENERGY_COMPONENTS = ("activation", "cross_bridge", "recovery", "total")
BACKENDS = ("auto", "numba", "numpy")


def _valid_dt(dt) -> bool:
    """dt is a finite real number > 0 (not a bool)."""
    return (isinstance(dt, (int, float, np.floating)) and not isinstance(dt, bool)
            and math.isfinite(dt) and dt > 0)


@dataclass(frozen=True)
class EnergyRates:
    """Energy partition. Rates in W (or, for cumulative records, energies in J).

    | field | shape | meaning |
    | activation | (n,) or (n, 2) | ion pumping (Ca2+, Na+/K+), depends on stimulation only |
    | cross_bridge | same | cross-bridge cycling |
    | recovery | same | ATP/PCr resynthesis |
    | total | same | sum of the three |
    """

    activation: np.ndarray
    cross_bridge: np.ndarray
    recovery: np.ndarray
    total: np.ndarray

    @classmethod
    def from_components(cls, components: np.ndarray) -> EnergyRates:
        """From an array whose last axis is (activation, cross_bridge, recovery)."""
        return cls(
            components[..., 0], components[..., 1], components[..., 2], components.sum(axis=-1)
        )

    def as_array(self) -> np.ndarray:
        """Stack as (..., 4) in the order of ENERGY_COMPONENTS."""
        return np.stack([self.activation, self.cross_bridge, self.recovery, self.total], axis=-1)

    def summed_over_fibres(self) -> EnergyRates:
        return EnergyRates(*(getattr(self, f.name).sum(axis=-1) for f in dataclasses.fields(self)))


class StepOutput:
    """What one step reports (SI unless the name says otherwise).

    Every field is a fresh array (changing it does not touch the bank); the derived ones are
    computed on first access, so a step costs only what the caller reads.

    | field | shape | unit | meaning |
    | time_s | () | s | model time at the end of the step |
    | force | (n,) | N | tendon force F_SE (VM's output force) |
    | contractile_force | (n,) | N | F_CE |
    | fascicle_length | (n,) | m | |
    | fascicle_velocity | (n,) | m/s | negative when shortening |
    | length_l0 | (n,) | L0 | normalised fascicle length |
    | velocity_l0_per_s | (n,) | L0/s | normalised fascicle velocity |
    | excitation | (n,) | 1 | drive U as used (clipped to [0, 1]) |
    | effective_drive | (n,) | 1 | filtered drive Ueff (U for natural units) |
    | firing_rate_f05 | (n, 2) | f0.5 | f_eff per fibre type (PCSA-weighted mean over units) |
    | recruited_fraction | (n, 2) | 1 | recruited PCSA fraction per fibre type |
    | effective_activation | (n, 2) | 1 | Acteff per fibre type (recruitment x weighting x Af) |
    | energy_rate | EnergyRates (n,) | W | per muscle |
    | energy_rate_by_fiber | EnergyRates (n, 2) | W | per muscle and fibre type |
    | energy | EnergyRates (n,) | J | cumulative since reset |
    | energy_by_fiber | EnergyRates (n, 2) | J | cumulative since reset |
    | mechanical_power | (n,) | W | -F_CE * fascicle velocity (positive when shortening) |
    | mechanical_work | (n,) | J | cumulative |
    | total_energy_rate | () | W | whole bank |
    | total_energy | () | J | whole bank, cumulative |
    """

    FIELDS = (
        "time_s", "force", "contractile_force", "fascicle_length", "fascicle_velocity",
        "length_l0", "velocity_l0_per_s", "excitation", "effective_drive", "firing_rate_f05",
        "recruited_fraction", "effective_activation", "energy_rate", "energy_rate_by_fiber",
        "energy", "energy_by_fiber", "mechanical_power", "mechanical_work", "total_energy_rate",
        "total_energy",
    )  # fmt: skip

    def __init__(self, bank: MuscleBank, state: BankState, ev: dict, excitation):
        self._bank = bank
        self._state = state  # never modified once published (every step works on a copy)
        self._ev = ev
        self.time_s = float(state.time_s)
        self.force = ev["f_se"]
        self.contractile_force = ev["f_ce"]
        self.effective_activation = ev["activity"]
        self.mechanical_power = ev["mechanical_power"]
        self.excitation = np.array(excitation, dtype=float)

    def __repr__(self) -> str:
        return f"StepOutput(time_s={self.time_s}, force={self.force!r})"

    @cached_property
    def fascicle_length(self) -> np.ndarray:
        return self._state.fascicle_length_m.copy()

    @cached_property
    def fascicle_velocity(self) -> np.ndarray:
        return self._state.fascicle_velocity_m_per_s.copy()

    @cached_property
    def length_l0(self) -> np.ndarray:
        return self._state.fascicle_length_m / self._bank.l0_m

    @cached_property
    def velocity_l0_per_s(self) -> np.ndarray:
        return self._state.fascicle_velocity_m_per_s / self._bank.l0_m

    @cached_property
    def effective_drive(self) -> np.ndarray:
        return self._state.effective_drive.copy()

    @cached_property
    def firing_rate_f05(self) -> np.ndarray:
        return self._bank._per_type_mean(self._state.firing_rate_effective)

    @cached_property
    def recruited_fraction(self) -> np.ndarray:
        bank = self._bank
        recruited = bank.recruitment.recruited_fraction(
            self.excitation, self._state.effective_drive
        )
        return recruited @ bank._membership

    @cached_property
    def energy_rate_by_fiber(self) -> EnergyRates:
        return EnergyRates.from_components(self._ev["components"])

    @cached_property
    def _rates(self) -> np.ndarray:
        """(n, 4) energy rates summed over fibre types: the compiled step writes them."""
        rates = self._ev.get("rates")
        if rates is None:
            summed = self._ev["components"].sum(axis=1)
            rates = np.concatenate([summed, summed.sum(axis=-1, keepdims=True)], axis=-1)
        return rates

    @cached_property
    def energy_rate(self) -> EnergyRates:
        rates = self._rates
        return EnergyRates(rates[:, 0], rates[:, 1], rates[:, 2], rates[:, 3])

    @cached_property
    def energy_by_fiber(self) -> EnergyRates:
        return EnergyRates.from_components(self._state.energy_j.copy())

    @cached_property
    def energy(self) -> EnergyRates:
        return EnergyRates.from_components(self._state.energy_j.sum(axis=1))

    @cached_property
    def mechanical_work(self) -> np.ndarray:
        return self._state.mechanical_work_j.copy()

    @cached_property
    def total_energy_rate(self) -> float:
        return float(self._rates[:, 3].sum())

    @cached_property
    def total_energy(self) -> float:
        return float(self._state.energy_j.sum())


@dataclass(frozen=True)
class Trajectory:
    """Every step of :meth:`MuscleBank.run` (k steps, n muscles; SI as in StepOutput).

    | field | shape | unit |
    | time_s | (k,) | s, model time at the end of each step |
    | excitation | (k, n) | 1, as used (clipped) |
    | force, contractile_force | (k, n) | N |
    | fascicle_length, fascicle_velocity | (k, n) | m, m/s |
    | effective_activation | (k, n, 2) | 1 |
    | energy_rate_by_fiber | EnergyRates (k, n, 2) | W |
    | mechanical_power | (k, n) | W |
    | last | StepOutput | the last step, with the cumulative energies and work |
    """

    time_s: np.ndarray
    excitation: np.ndarray
    force: np.ndarray
    contractile_force: np.ndarray
    fascicle_length: np.ndarray
    fascicle_velocity: np.ndarray
    effective_activation: np.ndarray
    energy_rate_by_fiber: EnergyRates
    mechanical_power: np.ndarray
    last: StepOutput

    @property
    def energy_rate(self) -> EnergyRates:
        """Per muscle (k, n), summed over the fibre types."""
        return self.energy_rate_by_fiber.summed_over_fibres()


@dataclass
class BankState:
    """The bank's dynamic state. Pools: (n, P); recovery filter: (n, 2 types, 2 states) in J.

    | field | shape | unit |
    | time_s | () | s |
    | fascicle_length_m, fascicle_velocity_m_per_s | (n,) | m, m/s |
    | effective_drive | (n,) | 1 |
    | firing_rate_intermediate, firing_rate_effective | (n, P) | f0.5 |
    | sag, yield_factor | (n, P) | 1 |
    | recovery_filter | (n, 2, 2) | J |
    | energy_j | (n, 2, 3) | J, per fibre type and component (activation, cross-bridge, recovery) |
    | mechanical_work_j | (n,) | J |
    """

    time_s: float
    fascicle_length_m: np.ndarray
    fascicle_velocity_m_per_s: np.ndarray
    effective_drive: np.ndarray
    firing_rate_intermediate: np.ndarray
    firing_rate_effective: np.ndarray
    sag: np.ndarray
    yield_factor: np.ndarray
    recovery_filter: np.ndarray
    energy_j: np.ndarray
    mechanical_work_j: np.ndarray

    def copy(self) -> BankState:
        copied = {name: getattr(self, name).copy() for name in ODE_FIELDS}
        return BankState(time_s=self.time_s, **copied)


# Order and layout of the states integrated by the reference ODE (vm_ros.model.reference).
ODE_FIELDS = (
    "fascicle_length_m",
    "fascicle_velocity_m_per_s",
    "effective_drive",
    "firing_rate_intermediate",
    "firing_rate_effective",
    "sag",
    "yield_factor",
    "recovery_filter",
    "energy_j",
    "mechanical_work_j",
)


@dataclass(frozen=True)
class _Dynamics:
    """Everything the activation path and energetics derive from one state (internal)."""

    u: np.ndarray
    l: np.ndarray
    v: np.ndarray
    drive_tau: np.ndarray | None
    f_env: np.ndarray
    tf: np.ndarray
    sag_target: np.ndarray
    yield_target: np.ndarray


class MuscleBank:
    """A vectorised bank of Virtual Muscles (see module docstring).

    Attributes: ``names`` (tuple), ``f0`` (N), ``mass_kg``, ``l0_m``, ``l0t_m``, ``lmax`` (L0),
    ``fpcsa`` ((n, 2) slow/fast PCSA fractions), ``recruitment`` (scheme object),
    ``recovery_mode`` ("static" | "dynamic"), ``params`` (ModelParams).
    """

    def __init__(
        self,
        specs: list[MuscleSpec],
        params: ModelParams,
        recruitment: str = "lumped",
        recovery_mode: str | None = None,
        backend: str = "auto",
    ):
        if backend not in BACKENDS:
            raise ValueError(f"backend must be one of {BACKENDS}, got {backend!r}")
        if backend == "numba" and not kernel.AVAILABLE:
            raise ValueError(
                "backend 'numba' needs the numba package (pip install 'vm_ros[fast]'); "
                "it is not importable or VM_ROS_NUMBA=0 is set"
            )
        if recruitment not in SCHEMES:
            raise ValueError(f"recruitment must be one of {SCHEMES}, got {recruitment!r}")
        recovery_mode = recovery_mode or params.energetics.recovery_mode
        if recovery_mode not in RECOVERY_MODES:
            raise ValueError(
                f"recovery_mode must be one of {RECOVERY_MODES}, got {recovery_mode!r}"
            )
        self.params = params
        self.specs = tuple(specs)
        self.names = tuple(s.name for s in specs)
        self.geometry = MuscleGeometry.from_specs(list(specs), params.generic)
        fpcsa_slow = np.array([s.fpcsa_slow for s in specs], dtype=float)
        self.fpcsa = np.stack([fpcsa_slow, 1.0 - fpcsa_slow], axis=-1)
        self.ur = np.array([s.ur for s in specs], dtype=float)
        self.recruitment = make_recruitment(recruitment, self.fpcsa, self.ur, params)
        self.recovery_mode = recovery_mode
        index = self.recruitment.fibre_index
        self._pool_fibre = params.fibre.take(index)
        self._membership = np.eye(2)[index]  # (P, 2)
        g = params.generic
        self._pool_l_max = (
            g.l_activation_max_fraction
            * self._pool_fibre.nf1
            / (self._pool_fibre.nf1 - self._pool_fibre.nf0)
        )
        e = params.energetics
        self._dry_mass = (e.dry_to_wet_mass * self.geometry.mass)[:, None]
        self._recovery_taus = en.recovery_filter_taus(e.recovery_tau_rise, e.recovery_tau_decay)
        self._state: BankState | None = None
        self.backend = "numpy" if backend == "numpy" or not kernel.AVAILABLE else "numba"
        self._kernel_constants = None
        if self.backend == "numba":
            self._kernel_constants = kernel.KernelConstants.from_bank(self)
            kernel.warm_up()
        # the (L, V) terms of F_CE at the (x, xdot) of the last compiled step's end (NaN: none)
        self._terms_end = np.zeros((self.n, kernel.N_TERMS))
        self._xv_end = np.full((self.n, 2), np.nan)
        self._zeros = np.zeros(self.n)

    # --- construction ---------------------------------------------------------------------

    @classmethod
    def from_config(
        cls,
        muscles,
        recruitment: str = "lumped",
        overrides: Mapping | None = None,
        library: str | Path | None = None,
        params: ModelParams | str | Path | None = None,
        recovery_mode: str | None = None,
        units_per_type: int | None = None,
        backend: str = "auto",
    ):
        """Build a bank from the muscle library (default: the shipped ``config/muscles.yaml``).

        muscles: names from the library; overrides: ``{name: {field: value}}``; params: a
        ModelParams or a path to a model YAML; units_per_type: natural units per fibre type;
        backend: "auto" (the compiled step when Numba is importable), "numba" or "numpy".
        """
        if not isinstance(params, ModelParams):
            params = load_model_params(params)
        if units_per_type is not None:
            params = dataclasses.replace(
                params,
                natural=dataclasses.replace(params.natural, units_per_type=int(units_per_type)),
            )
        specs = resolve_muscles(muscles, library, overrides, params.generic.ur_default)
        return cls(
            specs, params, recruitment=recruitment, recovery_mode=recovery_mode, backend=backend
        )

    @property
    def n(self) -> int:
        return len(self.names)

    @property
    def f0(self) -> np.ndarray:
        return self.geometry.f0

    @property
    def mass_kg(self) -> np.ndarray:
        return self.geometry.mass

    @property
    def l0_m(self) -> np.ndarray:
        return self.geometry.l0

    @property
    def l0t_m(self) -> np.ndarray:
        return self.geometry.l0t

    @property
    def lmax(self) -> np.ndarray:
        return self.geometry.lmax

    @property
    def n_pools(self) -> int:
        return int(self._membership.shape[0])

    @property
    def state(self) -> BankState:
        """A copy of the current state."""
        return self._require_state().copy()

    def set_state(self, state: BankState) -> None:
        """Replace the state by a copy of ``state`` (from :attr:`state` of a bank with the same
        muscles and recruitment); raises ValueError for arrays of another shape."""
        shapes = {
            "effective_drive": (self.n,), "fascicle_length_m": (self.n,),
            "fascicle_velocity_m_per_s": (self.n,), "mechanical_work_j": (self.n,),
            "firing_rate_intermediate": (self.n, self.n_pools),
            "firing_rate_effective": (self.n, self.n_pools), "sag": (self.n, self.n_pools),
            "yield_factor": (self.n, self.n_pools), "recovery_filter": (self.n, 2, 2),
            "energy_j": (self.n, 2, 3),
        }  # fmt: skip
        arrays = {}
        for name, shape in shapes.items():
            array = np.array(getattr(state, name), dtype=float)  # a float, C-ordered copy
            if array.shape != shape:
                raise ValueError(f"state.{name} has shape {array.shape}; this bank needs {shape}")
            arrays[name] = array
        self._state = BankState(time_s=float(state.time_s), **arrays)

    @property
    def time_s(self) -> float:
        return float(self._require_state().time_s)

    def _require_state(self) -> BankState:
        if self._state is None:
            raise RuntimeError("call reset(path_length=...) before stepping the bank")
        return self._state

    # --- inputs ---------------------------------------------------------------------------

    def _vector(self, name, value, allow_none=False):
        if value is None:
            if allow_none:
                return None
            raise InputError(name, value, "required")
        array = np.asarray(value, dtype=float)
        if array.shape == ():
            array = np.full(self.n, float(array))
        if array.shape != (self.n,):
            raise InputError(name, array.shape, f"expected shape ({self.n},)")
        if not np.all(np.isfinite(array)):
            raise InputError(name, array.tolist(), "must be finite")
        return array

    def check_inputs(self, excitation, path_length, path_velocity=None):
        """Validate and convert inputs; returns (U clipped to [0, 1], path length, velocity)."""
        u = np.clip(self._vector("excitation", excitation), 0.0, 1.0)
        lp = self._vector("path_length", path_length)
        if np.any(lp <= 0.0):
            raise InputError("path_length", lp.tolist(), "must be > 0 m")
        vp = self._vector("path_velocity", path_velocity, allow_none=True)
        return u, lp, (np.zeros(self.n) if vp is None else vp)

    # --- reset ----------------------------------------------------------------------------

    def steady_activation(self, excitation) -> dict:
        """Activation states at steady state for constant drive (V = 0): f_int = f_eff = f_env,
        Ueff = U, sag at its target, yield = 1."""
        u = np.clip(self._vector("excitation", excitation), 0.0, 1.0)
        p = self._pool_fibre
        f_env = act.firing_envelope(
            u[:, None],
            self.recruitment.thresholds,
            self.params.generic.fmin,
            self.params.generic.fmax,
        )
        sag = act.sag_target(f_env, p.as1, p.as2, p.sag_rate_threshold) * np.ones_like(f_env)
        return {
            "effective_drive": u,
            "firing_rate_intermediate": f_env.copy(),
            "firing_rate_effective": f_env.copy(),
            "sag": sag,
            "yield_factor": np.ones_like(f_env),
        }

    def reset(self, path_length, excitation=None, time_s: float = 0.0) -> StepOutput:
        """Start a run at static equilibrium (V = 0) for the given path lengths (m).

        With ``excitation`` the activation states start at their steady state for that constant
        drive; without, at rest (U = 0, sag at aS1). Energies and work start at zero.
        """
        _, lp, _ = self.check_inputs(np.zeros(self.n), path_length)
        activation = self.steady_activation(np.zeros(self.n) if excitation is None else excitation)
        n, pools = self.n, self.n_pools
        proto = BankState(
            time_s=float(time_s),
            fascicle_length_m=np.zeros(n),
            fascicle_velocity_m_per_s=np.zeros(n),
            recovery_filter=np.zeros((n, 2, 2)),
            energy_j=np.zeros((n, 2, 3)),
            mechanical_work_j=np.zeros(n),
            **activation,
        )
        assert proto.sag.shape == (n, pools)

        weights = self.recruitment.pool_weights(proto.effective_drive)

        def activity_at(l, idx):
            return self._effective_activation(
                weights[idx],
                proto.firing_rate_effective[idx],
                proto.sag[idx],
                proto.yield_factor[idx],
                l,
            )[0]

        proto.fascicle_length_m = equilibrium_fascicle_length(
            lp,
            self.geometry,
            activity_at,
            self.params.fibre,
            self.params.generic,
            self.params.generic.l_activation_min,
        )
        self._state = proto
        u = proto.effective_drive if excitation is not None else np.zeros(n)
        return self._output(proto, self._evaluate(proto, lp), u)

    # --- the equations --------------------------------------------------------------------

    def _pool_length(self, l):
        g = self.params.generic
        return np.clip(l[:, None], g.l_activation_min, self._pool_l_max)

    def _effective_activation(self, weights, f_eff, sag, yield_factor, l):
        """Per-type effective activation (n, 2) and stimulation activity (n, 2), from the pool
        weights (recruitment.pool_weights(Ueff)) and the pool states.

        Acteff_type = sum over the type's pools of weight(Ueff) Af(f_eff, L, Y, S)
        stimulation  = sum over the type's pools of weight(Ueff) Af(f_eff, L=1, Y=1, S) (STEP 5)
        """
        p = self._pool_fibre
        l_pool = self._pool_length(l)
        af = activation_frequency_brown1999(f_eff, l_pool, yield_factor, sag, p.af, p.nf0, p.nf1)
        af_l0 = activation_frequency_brown1999(f_eff, 1.0, 1.0, sag, p.af, p.nf0, p.nf1)
        return (weights * af) @ self._membership, (weights * af_l0) @ self._membership

    def _rates(self, state: BankState, u) -> _Dynamics:
        """Targets and time constants of every first-order state, at ``state`` and drive ``u``."""
        p, g = self._pool_fibre, self.params.generic
        l = state.fascicle_length_m / self.geometry.l0
        v = state.fascicle_velocity_m_per_s / self.geometry.l0
        l_pool = self._pool_length(l)
        f_env = act.firing_envelope(u[:, None], self.recruitment.thresholds, g.fmin, g.fmax)
        af_now = activation_frequency_brown1999(
            state.firing_rate_effective, l_pool, state.yield_factor, state.sag, p.af, p.nf0, p.nf1
        )
        tf = act.rise_fall_time_constant(
            f_env,
            state.firing_rate_intermediate,
            state.firing_rate_effective,
            l_pool,
            af_now,
            p.tf1,
            p.tf2,
            p.tf3,
            p.tf4,
        )
        return _Dynamics(
            u=u,
            l=l,
            v=v,
            drive_tau=self.recruitment.drive_tau(u, state.effective_drive),
            f_env=f_env,
            tf=tf,
            sag_target=act.sag_target(
                state.firing_rate_effective, p.as1, p.as2, p.sag_rate_threshold
            ),
            yield_target=act.yield_target(v[:, None], p.cy, p.vy),
        )

    def _evaluate(self, state: BankState, lp):
        """Forces, activation and energy rates at ``state`` (instantaneous, for output and ODE)."""
        l = state.fascicle_length_m / self.geometry.l0
        activity, stimulation = self._effective_activation(
            self.recruitment.pool_weights(state.effective_drive),
            state.firing_rate_effective, state.sag, state.yield_factor, l,
        )
        return self._instant(state, activity, stimulation, lp)

    def _instant(self, state: BankState, activity, stimulation, lp):
        fibre, g, e = self.params.fibre, self.params.generic, self.params.energetics
        x, xdot = state.fascicle_length_m, state.fascicle_velocity_m_per_s
        f_se, f_ce, fl = musculotendon_forces(x, xdot, lp, activity, self.geometry, fibre, g)
        v = xdot / self.geometry.l0
        e_act, e_xb = en.initial_energy_rates_tsianos2012(
            stimulation,
            activity,
            fl,
            v[:, None],
            self._dry_mass,
            e.e1,
            e.e2,
            e.e3,
            e.e4,
            e.activation_fraction,
            fibre.vmax,
        )
        initial = e_act + e_xb
        if self.recovery_mode == "static":
            recovery = en.static_recovery_rate(initial, e.recovery_ratio)
        else:
            recovery = en.dynamic_recovery_rate(
                state.recovery_filter, e.recovery_ratio, e.recovery_tau_rise, e.recovery_tau_decay
            )
        return {
            "f_se": f_se,
            "f_ce": f_ce,
            "activity": activity,
            "stimulation": stimulation,
            "components": np.stack([e_act, e_xb, recovery], axis=-1),
            "initial": initial,
            "mechanical_power": -f_ce * xdot,
        }

    def forces_at(self, state: BankState, path_length):
        """Tendon and contractile force (N) at ``state`` and path length (m)."""
        ev = self._evaluate(state, np.asarray(path_length, dtype=float))
        return ev["f_se"], ev["f_ce"]

    def derivatives(
        self, state: BankState, excitation, path_length, path_velocity=None
    ) -> BankState:
        """Time derivatives of every state (a BankState of rates), for reference integration."""
        u, lp, _ = self.check_inputs(excitation, path_length, path_velocity)
        r = self._rates(state, u)
        ev = self._evaluate(state, lp)
        d_drive = (
            np.zeros(self.n)
            if r.drive_tau is None
            else act.lag_derivative(state.effective_drive, u, r.drive_tau)
        )
        return BankState(
            time_s=1.0,
            fascicle_length_m=state.fascicle_velocity_m_per_s.copy(),
            fascicle_velocity_m_per_s=(ev["f_se"] - ev["f_ce"]) / self.geometry.m_eff,
            effective_drive=d_drive,
            firing_rate_intermediate=act.lag_derivative(
                state.firing_rate_intermediate, r.f_env, r.tf
            ),
            firing_rate_effective=act.lag_derivative(
                state.firing_rate_effective, state.firing_rate_intermediate, r.tf
            ),
            sag=act.lag_derivative(state.sag, r.sag_target, self._pool_fibre.ts),
            yield_factor=act.lag_derivative(
                state.yield_factor, r.yield_target, self._pool_fibre.ty
            ),
            recovery_filter=(
                en.recovery_filter_derivative(
                    state.recovery_filter, ev["initial"], self._recovery_taus
                )
                if self.recovery_mode == "dynamic"
                else np.zeros((self.n, 2, 2))
            ),
            energy_j=ev["components"],
            mechanical_work_j=ev["mechanical_power"],
        )

    # --- the fixed step -------------------------------------------------------------------

    def _advance_activation(self, old: BankState, u, dt):
        """New state with the first-order activation states advanced (exact lag updates, rates
        taken at the start of the step); returns it with the per-type effective activation and
        stimulation activity at the start-of-step length."""
        r = self._rates(old, u)
        p = self._pool_fibre
        new = old.copy()
        if r.drive_tau is None:
            new.effective_drive = u.copy()
        else:
            new.effective_drive = act.lag_step(old.effective_drive, u, r.drive_tau, dt)
        new.firing_rate_intermediate, new.firing_rate_effective = act.cascade_step(
            old.firing_rate_intermediate, old.firing_rate_effective, r.f_env, r.tf, dt
        )
        new.sag = act.lag_step(old.sag, r.sag_target, p.ts, dt)
        new.yield_factor = act.lag_step(old.yield_factor, r.yield_target, p.ty, dt)
        activity, stimulation = self._effective_activation(
            self.recruitment.pool_weights(new.effective_drive),
            new.firing_rate_effective, new.sag, new.yield_factor, r.l,
        )
        return new, activity, stimulation

    def steady_effective_activation(self, excitation, length_l0: float = 1.0) -> np.ndarray:
        """Steady-state effective activation per fibre type (n, 2) for constant drive, with the
        fascicles held at ``length_l0`` (isometric): rF W Af (lumped), sum p_j Af_j (natural)."""
        s = self.steady_activation(excitation)
        l = np.full(self.n, float(length_l0))
        weights = self.recruitment.pool_weights(s["effective_drive"])
        return self._effective_activation(weights, s["firing_rate_effective"], s["sag"],
                                          s["yield_factor"], l)[0]

    def activation_trace(self, dt: float, excitation, length_l0: float = 1.0) -> np.ndarray:
        """Effective activation per fibre type, shape (k, n, 2), for a drive series (k, n) with
        every fascicle held at ``length_l0`` (isometric, no mechanics), starting from the current
        activation state. The bank's state is not changed."""
        state = self._require_state().copy()
        state.fascicle_length_m = length_l0 * self.geometry.l0
        state.fascicle_velocity_m_per_s = np.zeros(self.n)
        trace = []
        for u in np.asarray(excitation, dtype=float):
            state, activity, _ = self._advance_activation(state, np.clip(u, 0.0, 1.0), dt)
            trace.append(activity)
        return np.array(trace)

    def step(self, dt: float, excitation, path_length, path_velocity=None) -> StepOutput:
        """Advance every muscle by ``dt`` seconds.

        excitation: drive U (n,), clipped to [0, 1]; path_length: musculotendon path length (m) at
        the start of the step; path_velocity: its rate (m/s) over the step (None: held constant).
        Raises InputError (state untouched) for non-finite values, wrong shapes, dt <= 0.
        """
        if not _valid_dt(dt):
            raise InputError("dt", dt, "must be a finite number > 0 s")
        old = self._require_state()
        if self._kernel_constants is not None:
            out = self._step_compiled(old, float(dt), excitation, path_length, path_velocity)
            if out is not None:
                return out
        u, lp, vp = self.check_inputs(excitation, path_length, path_velocity)
        new, activity, stimulation = self._advance_activation(old, u, dt)

        fibre, g = self.params.fibre, self.params.generic

        def forces(x, xdot, lp_now):
            return musculotendon_forces(x, xdot, lp_now, activity, self.geometry, fibre, g)[:2]

        def forces_and_slopes(x, xdot, lp_now):
            return musculotendon_forces_and_slopes(
                x, xdot, lp_now, activity, self.geometry, fibre, g
            )

        x, xdot = rosenbrock_step(
            old.fascicle_length_m,
            old.fascicle_velocity_m_per_s,
            lp,
            vp,
            dt,
            forces,
            forces_and_slopes,
            self.geometry.m_eff,
        )
        floor = g.l_activation_min * self.geometry.l0
        at_floor = x < floor
        new.fascicle_length_m = np.where(at_floor, floor, x)
        new.fascicle_velocity_m_per_s = np.where(at_floor, np.maximum(xdot, 0.0), xdot)
        new.time_s = old.time_s + dt
        lp_end = lp + dt * vp
        ev = self._instant(new, activity, stimulation, lp_end)
        if self.recovery_mode == "dynamic":
            new.recovery_filter = en.recovery_filter_step(
                old.recovery_filter, ev["initial"], self._recovery_taus, dt
            )
            ev["components"][..., 2] = en.dynamic_recovery_rate(
                new.recovery_filter,
                self.params.energetics.recovery_ratio,
                self.params.energetics.recovery_tau_rise,
                self.params.energetics.recovery_tau_decay,
            )
        new.energy_j = old.energy_j + dt * ev["components"]
        new.mechanical_work_j = old.mechanical_work_j + dt * ev["mechanical_power"]
        self._state = new
        return self._output(new, ev, u)

    def run(self, dt: float, excitation, path_length, path_velocity=None) -> Trajectory:
        """Advance k steps of ``dt`` s in one call, inputs given per step as (k, n) arrays (row j
        drives step j, as :meth:`step` takes them); returns every step's outputs as arrays.

        With the compiled back end the whole loop runs in compiled code (for long offline runs
        and sweeps). On a bad input InputError names the step, and the state is left as it was
        before the call.
        """
        if not _valid_dt(dt):
            raise InputError("dt", dt, "must be a finite number > 0 s")
        old = self._require_state()
        u = self._series("excitation", excitation)
        k, n = u.shape
        lp = self._series("path_length", path_length, rows=k)
        vp = (np.zeros((k, n)) if path_velocity is None
              else self._series("path_velocity", path_velocity, rows=k))
        if self._kernel_constants is None:
            return self._run_stepwise(dt, u, lp, vp)
        c = self._kernel_constants
        new = old.copy()
        clipped = np.empty((k, n))
        f_se, f_ce, power, length, velocity = (np.empty((k, n)) for _ in range(5))
        activity, stimulation = np.empty((k, n, 2)), np.empty((k, n, 2))
        components, rates = np.empty((k, n, 2, 3)), np.empty((k, n, 4))
        status = kernel.advance_series(
            float(dt), u, lp, vp, clipped, *c.arguments(), *kernel.state_arguments(new),
            self._terms_end, self._xv_end,
            f_se, f_ce, activity, stimulation, components, rates, power, length, velocity,
        )  # fmt: skip
        if status != 0:
            row = (status - 1) // n
            try:
                self.check_inputs(u[row], lp[row], vp[row])
            except InputError as error:
                raise InputError(f"{error.name} at step {row}", error.value, error.reason) from None
            raise RuntimeError(f"compiled run stopped at step {row} without a bad input")
        # model times as repeated steps add them up (t + dt + dt ...), to the last bit
        times = np.add.accumulate(np.concatenate(([old.time_s], np.full(k, float(dt)))))[1:]
        new.time_s = float(times[-1])
        self._state = new
        last = StepOutput(self, new, {
            "f_se": f_se[-1].copy(), "f_ce": f_ce[-1].copy(), "activity": activity[-1].copy(),
            "stimulation": stimulation[-1].copy(), "components": components[-1].copy(),
            "rates": rates[-1].copy(), "mechanical_power": power[-1].copy(),
        }, clipped[-1])  # fmt: skip
        return Trajectory(
            time_s=times,
            excitation=clipped,
            force=f_se,
            contractile_force=f_ce,
            fascicle_length=length,
            fascicle_velocity=velocity,
            effective_activation=activity,
            energy_rate_by_fiber=EnergyRates.from_components(components),
            mechanical_power=power,
            last=last,
        )

    def _series(self, name, value, rows: int | None = None) -> np.ndarray:
        array = np.asarray(value, dtype=float)
        expected = (rows if rows is not None else "k >= 1", self.n)
        if (array.ndim != 2 or array.shape[1] != self.n or array.shape[0] < 1
                or (rows is not None and array.shape[0] != rows)):
            raise InputError(name, array.shape, f"expected shape ({expected[0]}, {self.n})")
        writable = array.flags.c_contiguous and array.flags.writeable
        return array if writable else array.copy()

    def _run_stepwise(self, dt, u, lp, vp) -> Trajectory:
        """:meth:`run` by repeated :meth:`step` (the NumPy back end)."""
        saved = self._require_state()
        outs = []
        try:
            for row in range(u.shape[0]):
                outs.append(self.step(dt, u[row], lp[row], vp[row]))
        except InputError as error:
            self._state = saved
            raise InputError(f"{error.name} at step {len(outs)}", error.value,
                             error.reason) from None
        return Trajectory(
            time_s=np.array([o.time_s for o in outs]),
            excitation=np.array([o.excitation for o in outs]),
            force=np.array([o.force for o in outs]),
            contractile_force=np.array([o.contractile_force for o in outs]),
            fascicle_length=np.array([o.fascicle_length for o in outs]),
            fascicle_velocity=np.array([o.fascicle_velocity for o in outs]),
            effective_activation=np.array([o.effective_activation for o in outs]),
            energy_rate_by_fiber=EnergyRates.from_components(
                np.array([o._ev["components"] for o in outs])
            ),
            mechanical_power=np.array([o.mechanical_power for o in outs]),
            last=outs[-1],
        )

    def _raw_vector(self, value):
        """``value`` as a float (n,) array without checks (a scalar is broadcast); None if the
        shape is wrong."""
        array = np.asarray(value, dtype=float)
        if array.shape == ():
            return np.full(self.n, float(array))
        if array.shape != (self.n,):
            return None
        # the kernel is compiled for writable C-ordered arrays: anything else would recompile it
        return array if array.flags.c_contiguous and array.flags.writeable else array.copy()

    def _step_compiled(self, old: BankState, dt: float, excitation, path_length, path_velocity):
        """:meth:`step` by the compiled kernel (vm_ros.model.kernel): same equations, same order.

        The kernel checks the inputs itself (finite, path length > 0) and works on a copy of the
        state; on a bad input this returns None and :meth:`step` raises the InputError."""
        c = self._kernel_constants
        n = self.n
        u = self._raw_vector(excitation)
        lp = self._raw_vector(path_length)
        vp = self._zeros if path_velocity is None else self._raw_vector(path_velocity)
        if u is None or lp is None or vp is None:
            return None
        new = old.copy()
        clipped = np.empty(n)
        ev = {
            "f_se": np.empty(n),
            "f_ce": np.empty(n),
            "activity": np.empty((n, 2)),
            "stimulation": np.empty((n, 2)),
            "components": np.empty((n, 2, 3)),
            "rates": np.empty((n, 4)),
            "mechanical_power": np.empty(n),
        }
        status = kernel.advance(
            dt, u, lp, vp, clipped, *c.arguments(), *kernel.state_arguments(new),
            self._terms_end, self._xv_end,
            ev["f_se"], ev["f_ce"], ev["activity"], ev["stimulation"], ev["components"],
            ev["rates"], ev["mechanical_power"],
        )  # fmt: skip
        if status != 0:
            return None
        new.time_s = old.time_s + dt
        self._state = new
        return self._output(new, ev, clipped)

    # --- output ---------------------------------------------------------------------------

    def _per_type_mean(self, pool_values):
        pcsa = self.recruitment.pool_pcsa
        weight = pcsa @ self._membership
        return (pcsa * pool_values) @ self._membership / np.where(weight > 0, weight, 1.0)

    def _output(self, state: BankState, ev: dict, u) -> StepOutput:
        return StepOutput(self, state, ev, u)


__all__ = [
    "ENERGY_COMPONENTS",
    "FAST",
    "SLOW",
    "BankState",
    "EnergyRates",
    "MuscleBank",
    "StepOutput",
    "Trajectory",
]
