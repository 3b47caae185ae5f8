"""The model's equations over arrays (all muscles at once) and the fixed step built from them.

:class:`NumpyStep` holds the constants the equations need, derived once from a bank's muscles,
parameters and recruitment scheme, and offers:

- :meth:`NumpyStep.step`: one fixed step, its phases labelled as vm_ros.model.phases numbers them:
  the first-order activation states (drive filter, rise/fall, sag, yield) by their exact exponential
  update with rates taken at the start of the step, then the stiff fascicle mechanics by the
  L-stable ROS2 method with activation held over the step, then energetics at the new state;
- :meth:`NumpyStep.derivatives`: the same equations as a continuous right-hand side, for
  ``scipy.integrate.solve_ivp`` (vm_ros.model.reference);
- :meth:`NumpyStep.evaluate`: the outputs at a state (reset, the reference solve).

The compiled kernel (vm_ros.model.kernel) runs the same equation functions in the same order.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vm_ros.model import activation as act
from vm_ros.model import energetics as en
from vm_ros.model import recruitment as rc
from vm_ros.model.curves import activation_frequency_brown1999
from vm_ros.model.layout import BankState
from vm_ros.model.mechanics import (
    MuscleGeometry,
    musculotendon_forces,
    musculotendon_forces_and_slopes,
    rosenbrock_step,
)
from vm_ros.model.params import ModelParams
from vm_ros.model.records import StepRecord


@dataclass(frozen=True)
class LagTargets:
    """Targets and time constants of every first-order state at one state and drive."""

    l: np.ndarray  # (n,) L0
    v: np.ndarray  # (n,) L0/s
    drive_tau: np.ndarray | None  # (n, 2) s, per fibre type; None: no drive filter (natural)
    f_env: np.ndarray  # (n, P) f0.5
    tf: np.ndarray  # (n, P) s
    sag_target: np.ndarray  # (n, P)
    yield_target: np.ndarray  # (n, P)


class NumpyStep:
    """The equations of one bank over arrays (see the module docstring).

    Attributes: ``geometry``, ``params``, ``recruitment``, ``recovery_mode``; ``pool_fibre``
    (fibre-type parameters per pool), ``membership`` ((P, 2) pool -> fibre type),
    ``pool_l_max`` ((P,) L0, largest L in the activation relations), ``dry_mass`` ((n, 1) kg,
    M m_wet), ``recovery_taus`` (s, (decay, rise)).
    """

    def __init__(self, geometry: MuscleGeometry, params: ModelParams, recruitment,
                 recovery_mode: str):
        self.geometry = geometry
        self.params = params
        self.recruitment = recruitment
        self.recovery_mode = recovery_mode
        index = recruitment.fibre_index
        self.pool_fibre = params.fibre.take(index)
        self.membership = np.eye(2)[index]  # (P, 2)
        self.pool_l_max = act.activation_length_max(
            self.pool_fibre.nf0, self.pool_fibre.nf1, params.generic.l_activation_max_fraction
        )
        e = params.energetics
        self.dry_mass = (e.dry_to_wet_mass * geometry.mass)[:, None]
        self.recovery_taus = en.recovery_filter_taus(e.recovery_tau_rise, e.recovery_tau_decay)

    @property
    def n(self) -> int:
        return int(self.geometry.f0.shape[0])

    # --- equations at one state -------------------------------------------------------------

    def per_type_mean(self, pool_values):
        """PCSA-weighted mean over each fibre type's pools, (n, P) -> (n, 2)."""
        pcsa = self.recruitment.pool_pcsa
        weight = pcsa @ self.membership
        return (pcsa * pool_values) @ self.membership / np.where(weight > 0, weight, 1.0)

    def pool_length(self, l):
        """L (n,) as the activation relations of each pool use it, (n, P)."""
        return np.clip(l[:, None], self.params.generic.l_activation_min, self.pool_l_max)

    def effective_activation(self, weights, f_eff, sag, yield_factor, l):
        """Per-type effective activation (n, 2) and stimulation activity (n, 2), from the pool
        weights (recruitment.pool_weights(Ueff)) and the pool states.

        Acteff_type = sum over the type's pools of weight(Ueff) Af(f_eff, L, Y, S)
        stimulation  = sum over the type's pools of weight(Ueff) Af(f_eff, L=1, Y=1, S) (STEP 5)
        """
        p = self.pool_fibre
        l_pool = self.pool_length(l)
        af = activation_frequency_brown1999(f_eff, l_pool, yield_factor, sag, p.af, p.nf0, p.nf1)
        af_l0 = activation_frequency_brown1999(f_eff, 1.0, 1.0, sag, p.af, p.nf0, p.nf1)
        return (weights * af) @ self.membership, (weights * af_l0) @ self.membership

    def lag_targets(self, state: BankState, u) -> LagTargets:
        """Targets and time constants of every first-order state, at ``state`` and drive ``u``."""
        p, g = self.pool_fibre, self.params.generic
        l = state.fascicle_length_m / self.geometry.l0
        v = state.fascicle_velocity_m_per_s / self.geometry.l0
        l_pool = self.pool_length(l)
        f_env = act.firing_envelope(u[:, None], self.recruitment.thresholds, g.fmin, g.fmax)
        af_now = activation_frequency_brown1999(
            state.firing_rate_effective, l_pool, state.yield_factor, state.sag, p.af, p.nf0, p.nf1
        )
        tf = act.rise_fall_time_constant(
            f_env, state.firing_rate_intermediate, state.firing_rate_effective, l_pool, af_now,
            p.tf1, p.tf2, p.tf3, p.tf4,
        )
        return LagTargets(
            l=l,
            v=v,
            # pools 0 and 1, a lumped muscle's slow and fast units: on a rise each type's own unit
            # says how active it already is, on a fall the slow unit (recruited first, firing
            # whenever any unit does) while U is above the type's threshold
            drive_tau=self.recruitment.drive_tau(
                u, state.effective_drive,
                rc.firing_match(state.firing_rate_effective[:, :2], f_env[:, :2]),
                rc.type_match(
                    rc.firing_match(state.firing_rate_effective[:, :1], f_env[:, :1]),
                    f_env[:, :2],
                ),
            ),
            f_env=f_env,
            tf=tf,
            sag_target=act.sag_target(
                state.firing_rate_effective, p.as1, p.as2, p.sag_rate_threshold
            ),
            yield_target=act.yield_target(v[:, None], p.cy, p.vy),
        )

    def initial_energy(self, activity, stimulation, fl, xdot):
        """Activation and cross-bridge energy rates (W), each (n, 2) (Tsianos 2012 STEPs 1-5)."""
        e, fibre = self.params.energetics, self.params.fibre
        v = xdot / self.geometry.l0
        return en.initial_energy_rates_tsianos2012(
            stimulation, activity, fl, v[:, None], self.dry_mass, e.e1, e.e2, e.e3, e.e4,
            e.activation_fraction, fibre.vmax,
        )

    def recovery_rate(self, recovery_filter, initial):
        """Recovery energy rate (W), (n, 2): R E_i (static, STEP 6) or from the filter states
        (dynamic, Appendix B)."""
        e = self.params.energetics
        if self.recovery_mode == "static":
            return en.static_recovery_rate(initial, e.recovery_ratio)
        return en.dynamic_recovery_rate(
            recovery_filter, e.recovery_ratio, e.recovery_tau_rise, e.recovery_tau_decay
        )

    @staticmethod
    def record(u, f_se, f_ce, activity, stimulation, components, xdot) -> StepRecord:
        """The step record, with the rates summed over fibre types (STEP 7)."""
        summed = components.sum(axis=1)
        return StepRecord(
            excitation=u,
            force=f_se,
            contractile_force=f_ce,
            effective_activation=activity,
            stimulation=stimulation,
            energy_components=components,
            energy_rates=np.concatenate([summed, summed.sum(axis=-1, keepdims=True)], axis=-1),
            mechanical_power=-f_ce * xdot,
        )

    def evaluate(self, state: BankState, u, lp):
        """The record at ``state`` for drive ``u`` (as used) and path length ``lp`` (m), and the
        initial energy rate (n, 2) that drives the recovery filter."""
        l = state.fascicle_length_m / self.geometry.l0
        activity, stimulation = self.effective_activation(
            self.recruitment.pool_weights(state.effective_drive),
            state.firing_rate_effective, state.sag, state.yield_factor, l,
        )
        x, xdot = state.fascicle_length_m, state.fascicle_velocity_m_per_s
        p = self.params
        f_se, f_ce, fl = musculotendon_forces(x, xdot, lp, activity, self.geometry, p.fibre,
                                              p.generic)
        e_act, e_xb = self.initial_energy(activity, stimulation, fl, xdot)
        initial = e_act + e_xb
        recovery = self.recovery_rate(state.recovery_filter, initial)
        components = np.stack([e_act, e_xb, recovery], axis=-1)
        return self.record(u, f_se, f_ce, activity, stimulation, components, xdot), initial

    def derivatives(self, state: BankState, u, lp) -> BankState:
        """Time derivatives of every state (a BankState of rates; time_s holds 1)."""
        r = self.lag_targets(state, u)
        record, initial = self.evaluate(state, u, lp)
        n = self.n
        d_drive = (np.zeros((n, 2)) if r.drive_tau is None
                   else act.lag_derivative(state.effective_drive, u[:, None], r.drive_tau))
        return BankState(
            time_s=1.0,
            effective_drive=d_drive,
            firing_rate_intermediate=act.lag_derivative(
                state.firing_rate_intermediate, r.f_env, r.tf
            ),
            firing_rate_effective=act.lag_derivative(
                state.firing_rate_effective, state.firing_rate_intermediate, r.tf
            ),
            sag=act.lag_derivative(state.sag, r.sag_target, self.pool_fibre.ts),
            yield_factor=act.lag_derivative(
                state.yield_factor, r.yield_target, self.pool_fibre.ty
            ),
            fascicle_length_m=state.fascicle_velocity_m_per_s.copy(),
            fascicle_velocity_m_per_s=(record.force - record.contractile_force)
            / self.geometry.m_eff,
            recovery_filter=(
                en.recovery_filter_derivative(state.recovery_filter, initial, self.recovery_taus)
                if self.recovery_mode == "dynamic"
                else np.zeros((n, 2, 2))
            ),
            energy_j=record.energy_components,
            mechanical_work_j=record.mechanical_power,
        )

    def steady_activation(self, u) -> dict:
        """Activation states at steady state for constant drive ``u`` (clipped; V = 0):
        f_int = f_eff = f_env, Ueff = U (each type's), sag at its target, yield = 1."""
        p, g = self.pool_fibre, self.params.generic
        f_env = act.firing_envelope(u[:, None], self.recruitment.thresholds, g.fmin, g.fmax)
        sag = act.sag_target(f_env, p.as1, p.as2, p.sag_rate_threshold) * np.ones_like(f_env)
        return {
            "effective_drive": rc.drive_per_type(u),
            "firing_rate_intermediate": f_env.copy(),
            "firing_rate_effective": f_env.copy(),
            "sag": sag,
            "yield_factor": np.ones_like(f_env),
        }

    # --- the fixed step ---------------------------------------------------------------------

    def advance_activation(self, old: BankState, u, dt):
        """Phases 1-3: a new state with the first-order activation states advanced (exact lag
        updates, rates taken at the start of the step); returns it with the per-type effective
        activation and stimulation activity at the start-of-step length."""
        r = self.lag_targets(old, u)
        p = self.pool_fibre
        new = old.copy()
        # Phase 1, DRIVE: filtered drive Ueff of each fibre type and the pool weights it sets
        if r.drive_tau is None:
            new.effective_drive = rc.drive_per_type(u)
        else:
            new.effective_drive = act.lag_step(old.effective_drive, u[:, None], r.drive_tau, dt)
        weights = self.recruitment.pool_weights(new.effective_drive)
        # Phase 2, FIRING: rise/fall cascade, sag and yield of every pool
        new.firing_rate_intermediate, new.firing_rate_effective = act.cascade_step(
            old.firing_rate_intermediate, old.firing_rate_effective, r.f_env, r.tf, dt
        )
        new.sag = act.lag_step(old.sag, r.sag_target, p.ts, dt)
        new.yield_factor = act.lag_step(old.yield_factor, r.yield_target, p.ty, dt)
        # Phase 3, ACTIVATION: Acteff and stimulation per fibre type
        activity, stimulation = self.effective_activation(
            weights, new.firing_rate_effective, new.sag, new.yield_factor, r.l
        )
        return new, activity, stimulation

    def step(self, old: BankState, u, lp, vp, dt):
        """One fixed step from ``old`` for checked inputs (drive clipped, path length and velocity
        finite); returns (new state, StepRecord). ``old`` is not modified."""
        new, activity, stimulation = self.advance_activation(old, u, dt)
        p = self.params
        geometry, fibre, g = self.geometry, p.fibre, p.generic

        def forces(x, xdot, lp_now):
            return musculotendon_forces(x, xdot, lp_now, activity, geometry, fibre, g)[:2]

        def forces_and_slopes(x, xdot, lp_now):
            return musculotendon_forces_and_slopes(x, xdot, lp_now, activity, geometry, fibre, g)

        # Phase 4, MECHANICS: ROS2 with activation held, then the length floor
        x, xdot = rosenbrock_step(
            old.fascicle_length_m, old.fascicle_velocity_m_per_s, lp, vp, dt, forces,
            forces_and_slopes, geometry.m_eff,
        )
        floor = g.l_activation_min * geometry.l0
        at_floor = x < floor
        x = new.fascicle_length_m = np.where(at_floor, floor, x)
        xdot = new.fascicle_velocity_m_per_s = np.where(at_floor, np.maximum(xdot, 0.0), xdot)
        new.time_s = old.time_s + dt
        # Phase 5, INITIAL_ENERGY: E_a, E_xb at the step's end state (Tsianos 2012 STEPs 1-5)
        f_se, f_ce, fl = musculotendon_forces(x, xdot, lp + dt * vp, activity, geometry, fibre, g)
        e_act, e_xb = self.initial_energy(activity, stimulation, fl, xdot)
        initial = e_act + e_xb
        # Phase 6, RECOVERY: STEP 6 (static) or the Appendix B filter (dynamic)
        if self.recovery_mode == "dynamic":
            new.recovery_filter = en.recovery_filter_step(
                old.recovery_filter, initial, self.recovery_taus, dt
            )
        recovery = self.recovery_rate(new.recovery_filter, initial)
        # Phase 7, TOTALS: rates summed (STEP 7), energies and work integrated
        components = np.stack([e_act, e_xb, recovery], axis=-1)
        record = self.record(u, f_se, f_ce, activity, stimulation, components, xdot)
        new.energy_j = old.energy_j + dt * components
        new.mechanical_work_j = old.mechanical_work_j + dt * record.mechanical_power
        return new, record


__all__ = ["LagTargets", "NumpyStep"]
