"""MuscleBank: a vectorised set of Virtual Muscles that owns the model state.

    bank = MuscleBank.from_config(muscles=["vasti", "rectus_femoris"], recruitment="lumped")
    bank.reset(path_length=np.array([0.30, 0.42]))
    out = bank.step(0.001, excitation=np.array([0.5, 0.2]), path_length=np.array([0.30, 0.42]))

One ``step`` advances every muscle through the phases vm_ros.model.phases numbers: the first-order
activation states (drive filter, rise/fall, sag, yield) by their exact exponential update, then the
stiff fascicle mechanics by the L-stable ROS2 method with activation held over the step, then
energetics at the new state. The bank checks inputs, owns the state and hands the step to one of
two executors of the same equations: the NumPy step (vm_ros.model.numpy_step) or the compiled
kernel (vm_ros.model.compiled_step, vm_ros.model.kernel). :meth:`MuscleBank.derivatives` exposes
the same equations as a continuous right-hand side so they can be handed to
``scipy.integrate.solve_ivp`` (see vm_ros.model.reference).

Shapes: n muscles, P motor-unit pools (2 for lumped/continuous, 2N for natural units), 2 fibre
types (slow, fast); the state's layout is declared in vm_ros.model.layout, the output records in
vm_ros.model.records.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from vm_ros.errors import InputError
from vm_ros.model import kernel, layout
from vm_ros.model.compiled_step import CompiledStep, KernelConstants
from vm_ros.model.energetics_models.in_bank import BankModels, model_names
from vm_ros.model.energetics_models.vm_state import VmMuscleConstants
from vm_ros.model.layout import BankState
from vm_ros.model.mechanics import MuscleGeometry, equilibrium_fascicle_length
from vm_ros.model.numpy_step import NumpyStep
from vm_ros.model.params import (
    DRIVE_LAWS,
    FAST,
    RECOVERY_MODES,
    SLOW,
    ModelParams,
    MuscleSpec,
    load_model_params,
    resolve_muscles,
)
from vm_ros.model.records import (
    ENERGY_COMPONENTS,
    EnergyRates,
    StepOutput,
    StepRecord,
    Trajectory,
)
from vm_ros.model.recruitment import SCHEMES, make_recruitment

BACKENDS = ("auto", "numba", "numpy")
# step(): the published energetics models of at most this many muscle-steps wait to be computed
# in one batch (when read, or when this many are pending); 10 steps of 1000 muscles
PENDING_MUSCLE_STEPS = 10_000


def _valid_dt(dt) -> bool:
    """dt is a finite real number > 0 (not a bool)."""
    return (isinstance(dt, (int, float, np.floating)) and not isinstance(dt, bool)
            and math.isfinite(dt) and dt > 0)


class MuscleBank:
    """A vectorised bank of Virtual Muscles (see module docstring).

    Attributes: ``names`` (tuple), ``f0`` (N), ``mass_kg``, ``l0_m``, ``l0t_m``, ``lmax`` (L0),
    ``fpcsa`` ((n, 2) slow/fast PCSA fractions), ``recruitment`` (scheme object),
    ``recovery_mode`` ("static" | "dynamic"), ``params`` (ModelParams), ``equations``
    (the NumPy step, vm_ros.model.numpy_step.NumpyStep), ``backend`` ("numba" | "numpy").

    ``parallel``: run blocks of muscles on Numba's threads (compiled back end, banks of
    kernel.PARALLEL_MIN_MUSCLES muscles or more; bit-identical to serial); None: the
    VM_ROS_PARALLEL environment variable, off by default (it loses when the other cores are
    busy: README, measured speed).
    """

    def __init__(
        self,
        specs: list[MuscleSpec],
        params: ModelParams,
        recruitment: str = "lumped",
        recovery_mode: str | None = None,
        backend: str = "auto",
        energetics_models=(),
        parallel: bool | None = None,
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
        self.recruitment_scheme = recruitment
        self.equations = NumpyStep(self.geometry, params, self.recruitment, recovery_mode)
        self._state: BankState | None = None
        self.backend = "numpy" if backend == "numpy" or not kernel.AVAILABLE else "numba"
        self._compiled = None
        if self.backend == "numba":
            self._compiled = CompiledStep(KernelConstants.from_bank(self), self.n,
                                          parallel=parallel)
            kernel.warm_up()
        self._models = None
        self._pending: list = []  # (dt, StepOutput) of steps whose models wait for a batch
        if energetics_models:
            names = model_names(energetics_models)
            if names:
                self._models = BankModels(names, VmMuscleConstants.from_bank(self),
                                          compile_models=self.backend == "numba")

    def replicated(self, copies: int) -> MuscleBank:
        """A new bank of ``copies`` copies of every muscle (muscle order repeated ``copies``
        times), with the same parameters, recruitment, recovery, back end and energetics models:
        one call then evaluates many inputs of the same muscles."""
        # each spec's lmax resolved once (a root per muscle otherwise)
        specs = [dataclasses.replace(s, lmax=float(lmax)) for s, lmax in zip(self.specs,
                                                                              self.lmax,
                                                                              strict=True)]
        return MuscleBank(specs * int(copies), self.params, self.recruitment_scheme,
                          self.recovery_mode, self.backend, self.energetics_models)

    @property
    def energetics_models(self) -> tuple:
        """Names of the published energetics models the bank runs (() for none), in the order
        of the model axis of ``energy_rate_models`` and ``energy_models``."""
        return self._models.names if self._models is not None else ()

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
        drive_law: str | None = None,
        energetics_models=(),
        parallel: bool | None = None,
    ):
        """Build a bank from the muscle library (default: the shipped ``config/muscles.yaml``).

        muscles: names from the library; overrides: ``{name: {field: value}}``; params: a
        ModelParams or a path to a model YAML; units_per_type: natural units per fibre type;
        backend: "auto" (the compiled step when Numba is importable), "numba" or "numpy";
        drive_law: the lumped drive filter's law (DRIVE_LAWS; None: the model file's);
        energetics_models: published models to run beside Tsianos 2012 (names of
        vm_ros.model.energetics_models.MODEL_NAMES, or "all"; an unknown name is an InputError that
        lists the known ones); parallel: see the constructor.
        """
        if not isinstance(params, ModelParams):
            params = load_model_params(params)
        if drive_law is not None:
            if drive_law not in DRIVE_LAWS:
                raise ValueError(f"drive_law must be one of {DRIVE_LAWS}, got {drive_law!r}")
            params = dataclasses.replace(
                params, lumped=dataclasses.replace(params.lumped, drive_law=drive_law))
        if units_per_type is not None:
            params = dataclasses.replace(
                params,
                natural=dataclasses.replace(params.natural, units_per_type=int(units_per_type)),
            )
        specs = resolve_muscles(muscles, library, overrides, params.generic.ur_default)
        return cls(
            specs, params, recruitment=recruitment, recovery_mode=recovery_mode, backend=backend,
            energetics_models=energetics_models, parallel=parallel,
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
        return int(self.equations.membership.shape[0])

    @property
    def state(self) -> BankState:
        """A copy of the current state."""
        return self._require_state().copy()

    def restore_point(self) -> BankState:
        """The current state object itself, without the copy :attr:`state` makes, for
        :meth:`set_state` to return to: step, run and reset replace the bank's state and never
        modify one in place (each StepOutput keeps its own), so it stays as it is. Read it, do
        not modify it."""
        return self._require_state()

    def set_state(self, state: BankState) -> None:
        """Replace the state by a copy of ``state`` (from :attr:`state` of a bank with the same
        muscles and recruitment); raises ValueError for arrays of another shape."""
        checked = layout.checked_state(state, self.n, self.n_pools)
        if self._models is not None:
            self._flush_models()
        self._state = checked

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
        return self.equations.steady_activation(
            np.clip(self._vector("excitation", excitation), 0.0, 1.0)
        )

    def reset(self, path_length, excitation=None, time_s: float = 0.0) -> StepOutput:
        """Start a run at static equilibrium (V = 0) for the given path lengths (m).

        With ``excitation`` the activation states start at their steady state for that constant
        drive; without, at rest (U = 0, sag at aS1). Energies and work start at zero.
        """
        _, lp, _ = self.check_inputs(np.zeros(self.n), path_length)
        if self._models is not None:
            self._flush_models()  # the steps before the reset keep their values
        activation = self.steady_activation(np.zeros(self.n) if excitation is None else excitation)
        proto = layout.zero_state(self.n, self.n_pools, time_s)
        for name, value in activation.items():
            setattr(proto, name, value)
        eq = self.equations
        weights = self.recruitment.pool_weights(proto.effective_drive)

        def activity_at(l, idx):
            return eq.effective_activation(
                weights[idx], proto.firing_rate_effective[idx], proto.sag[idx],
                proto.yield_factor[idx], l,
            )[0]

        g = self.params.generic
        proto.fascicle_length_m = equilibrium_fascicle_length(
            lp, self.geometry, activity_at, self.params.fibre, g, g.l_activation_min
        )
        self._state = proto
        # the drive as used (clipped): the steady Ueff, equal for both fibre types
        u = proto.effective_drive[:, 0] if excitation is not None else np.zeros(self.n)
        out = StepOutput(eq, proto, eq.evaluate(proto, u.copy(), lp)[0])
        if self._models is not None:
            self._models.reset()
            out.set_models(self._models.at_rest(out.excitation, out.effective_activation,
                                                proto.fascicle_length_m,
                                                proto.fascicle_velocity_m_per_s),
                           self._models.energy_j.copy())
        return out

    # --- the equations at a state ---------------------------------------------------------

    def forces_at(self, state: BankState, path_length):
        """Tendon and contractile force (N) at ``state`` and path length (m)."""
        record, _ = self.equations.evaluate(
            state, np.zeros(self.n), np.asarray(path_length, dtype=float)
        )
        return record.force, record.contractile_force

    def derivatives(
        self, state: BankState, excitation, path_length, path_velocity=None
    ) -> BankState:
        """Time derivatives of every state (a BankState of rates), for reference integration."""
        u, lp, _ = self.check_inputs(excitation, path_length, path_velocity)
        return self.equations.derivatives(state, u, lp)

    def steady_effective_activation(self, excitation, length_l0: float = 1.0) -> np.ndarray:
        """Steady-state effective activation per fibre type (n, 2) for constant drive, with the
        fascicles held at ``length_l0`` (isometric): rF W Af (lumped), sum p_j Af_j (natural)."""
        s = self.steady_activation(excitation)
        l = np.full(self.n, float(length_l0))
        weights = self.recruitment.pool_weights(s["effective_drive"])
        return self.equations.effective_activation(
            weights, s["firing_rate_effective"], s["sag"], s["yield_factor"], l
        )[0]

    def activation_trace(self, dt: float, excitation, length_l0: float = 1.0) -> np.ndarray:
        """Effective activation per fibre type, shape (k, n, 2), for a drive series (k, n) with
        every fascicle held at ``length_l0`` (isometric, no mechanics), starting from the current
        activation state. The bank's state is not changed."""
        state = self._require_state().copy()
        state.fascicle_length_m = length_l0 * self.geometry.l0
        state.fascicle_velocity_m_per_s = np.zeros(self.n)
        trace = []
        for u in np.asarray(excitation, dtype=float):
            state, activity, _ = self.equations.advance_activation(
                state, np.clip(u, 0.0, 1.0), dt
            )
            trace.append(activity)
        return np.array(trace)

    # --- the fixed step -------------------------------------------------------------------

    def step(self, dt: float, excitation, path_length, path_velocity=None) -> StepOutput:
        """Advance every muscle by ``dt`` seconds.

        excitation: drive U (n,), clipped to [0, 1]; path_length: musculotendon path length (m) at
        the start of the step; path_velocity: its rate (m/s) over the step (None: held constant).
        Raises InputError (state untouched) for non-finite values, wrong shapes, dt <= 0.
        With ``energetics_models`` the published models then run on the step's outputs
        (vm_ros.model.energetics_models.in_bank; StepOutput.energy_rate_models, energy_models): when
        first read, or every PENDING_MUSCLE_STEPS muscle-steps, for all the steps taken since
        the last time in one batch (as :meth:`run` does), which gives each step's numbers.
        """
        out = self._step_model(dt, excitation, path_length, path_velocity)
        if self._models is not None:
            self._pending.append((float(dt), out))
            out.defer_models(self._flush_models)
            if len(self._pending) * self.n >= PENDING_MUSCLE_STEPS:
                self._flush_models()
        return out

    def _flush_models(self) -> None:
        """The published models of the steps taken since the last flush, in one batch over
        their (k, n) outputs (the same numbers as one step at a time: elementwise, and the
        energies summed step by step); each step's StepOutput gets its own."""
        pending, self._pending = self._pending, []
        if not pending:
            return
        outs = [out for _, out in pending]
        states = [out._state for out in outs]
        rates, energies = self._models.advance(
            np.array([dt for dt, _ in pending]), np.array([out.time_s for out in outs]),
            np.array([out.excitation for out in outs]),
            np.array([out.effective_activation for out in outs]),
            np.array([state.fascicle_length_m for state in states]),
            np.array([state.fascicle_velocity_m_per_s for state in states]))
        for j, out in enumerate(outs):
            out.set_models(rates[j], energies[j])

    def _step_model(self, dt, excitation, path_length, path_velocity) -> StepOutput:
        """:meth:`step` without the published energetics models."""
        if not _valid_dt(dt):
            raise InputError("dt", dt, "must be a finite number > 0 s")
        old = self._require_state()
        stepped = None
        if self._compiled is not None:
            stepped = self._compiled.step(old, float(dt), excitation, path_length, path_velocity)
        if stepped is None:  # the NumPy step, or a bad input for the compiled one
            u, lp, vp = self.check_inputs(excitation, path_length, path_velocity)
            stepped = self.equations.step(old, u, lp, vp, dt)
        new, record = stepped
        self._state = new
        return StepOutput(self.equations, new, record)

    def run(self, dt: float, excitation, path_length, path_velocity=None,
            snapshot_every: int = 0) -> Trajectory:
        """Advance k steps of ``dt`` s in one call, inputs given per step as (k, n) arrays (row j
        drives step j, as :meth:`step` takes them); returns every step's outputs as arrays.

        ``snapshot_every`` m > 0 also keeps the state at the end of steps m, 2m, ...
        (``Trajectory.snapshots``: with ``Trajectory.record`` what :meth:`step` reports there,
        cumulative energies included), so that a run with outputs every m steps is one call.
        With the compiled back end the whole loop runs in compiled code (for long
        offline runs and sweeps). On a bad input InputError names the step, and the state is
        left as it was before the call. With ``energetics_models`` the published models run
        once over the run's (k, n) outputs (Trajectory.energy_rate_models, energy_models),
        giving what :meth:`step` gives step by step.
        """
        if not _valid_dt(dt):
            raise InputError("dt", dt, "must be a finite number > 0 s")
        if isinstance(snapshot_every, bool) or not isinstance(snapshot_every, (int, np.integer)) \
                or snapshot_every < 0:
            raise InputError("snapshot_every", snapshot_every, "must be an integer >= 0 steps")
        old = self._require_state()
        if self._models is not None:
            self._flush_models()  # the models' state (onset, energies) goes step after step
        u = self._series("excitation", excitation)
        k, n = u.shape
        lp = self._series("path_length", path_length, rows=k)
        vp = (np.zeros((k, n)) if path_velocity is None
              else self._series("path_velocity", path_velocity, rows=k))
        if self._compiled is None:
            return self._with_models(dt, self._run_stepwise(dt, u, lp, vp, int(snapshot_every)))
        status, new, series, length, velocity, snapshots = self._compiled.series(
            old, float(dt), u, lp, vp, int(snapshot_every))
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
        last = StepOutput(self.equations, new, series.row(-1))
        return self._with_models(dt, Trajectory.from_series(
            times, series, length, velocity, last,
            self._snapshots(times, snapshot_every, snapshots)))

    def _with_models(self, dt, trajectory: Trajectory) -> Trajectory:
        """The trajectory with the published models' rates and energies of every step (none
        without models): computed at once over its (k, n) arrays."""
        if self._models is None:
            return trajectory
        rates, energies = self._models.advance(
            dt, trajectory.time_s, trajectory.excitation, trajectory.effective_activation,
            trajectory.fascicle_length, trajectory.fascicle_velocity)
        trajectory.last.set_models(rates[-1].copy(), energies[-1].copy())
        return dataclasses.replace(trajectory, energy_rate_models=rates, energy_models=energies)

    def _snapshots(self, times, every: int, arrays) -> BankState | None:
        """The snapshot states as one BankState whose fields carry a leading snapshot axis."""
        if not every:
            return None
        return BankState(time_s=times[every - 1::every][:len(arrays[0])],
                         **dict(zip(layout.STATE_NAMES, arrays, strict=True)))

    def _series(self, name, value, rows: int | None = None) -> np.ndarray:
        array = np.asarray(value, dtype=float)
        expected = (rows if rows is not None else "k >= 1", self.n)
        if (array.ndim != 2 or array.shape[1] != self.n or array.shape[0] < 1
                or (rows is not None and array.shape[0] != rows)):
            raise InputError(name, array.shape, f"expected shape ({expected[0]}, {self.n})")
        writable = array.flags.c_contiguous and array.flags.writeable
        return array if writable else array.copy()

    def _run_stepwise(self, dt, u, lp, vp, snapshot_every: int = 0) -> Trajectory:
        """:meth:`run` by repeated :meth:`step` (the NumPy back end)."""
        saved = self._require_state()
        outs, states = [], []
        try:
            for row in range(u.shape[0]):
                outs.append(self._step_model(dt, u[row], lp[row], vp[row]))
                if snapshot_every and (row + 1) % snapshot_every == 0:
                    states.append(self._state)  # never modified in place (restore_point)
        except InputError as error:
            self._state = saved
            raise InputError(f"{error.name} at step {len(outs)}", error.value,
                             error.reason) from None
        times = np.array([o.time_s for o in outs])
        series = StepRecord.stack([o.record for o in outs])
        arrays = [np.array([getattr(state, name) for state in states]).reshape(
            (len(states), *getattr(saved, name).shape)) for name in layout.STATE_NAMES]
        return Trajectory.from_series(
            times, series,
            np.array([o.fascicle_length for o in outs]),
            np.array([o.fascicle_velocity for o in outs]),
            outs[-1], self._snapshots(times, snapshot_every, arrays),
        )


__all__ = [
    "BACKENDS",
    "ENERGY_COMPONENTS",
    "FAST",
    "SLOW",
    "BankState",
    "EnergyRates",
    "MuscleBank",
    "StepOutput",
    "Trajectory",
]
