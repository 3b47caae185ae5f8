"""A MuJoCo model driven only by vm_ros muscle forces, in one process (extra ``mujoco``).

MuJoCo's own actuation is disabled (``mjDSBL_ACTUATION``: its muscles produce no force). Each
step of dt, with MuJoCo's split step:

1. ``mj_step1``: positions, velocities, tendon lengths L (``ten_length``), lengthening velocities
   V (``ten_velocity``) and the tendon Jacobian J = dL/dqvel at time t.
2. ``MuscleBank.step(dt, U(t), L, V)``: the muscle tensions F at the end of the step (N).
3. ``qfrc_applied = -J^T F``: the tensions as generalized forces on every degree of freedom the
   tendons cross (dependent joints of joint equalities included; the equality constraint carries
   their share to the driving joint). For the independent coordinates this is tau = r^T F with
   r = -dL/dq (vm_ros.geometry.generalized_forces, the sign convention of vm_ros.geometry.paths).
4. ``mj_step2``: accelerations, constraints, integration to t + dt.

Energy bookkeeping (J), each power taken with the velocity v' that the step's position update uses
(MuJoCo's semi-implicit Euler: q' = q + dt v'):

- muscle work W = sum over steps of (-J^T F) . v' dt = -sum F . (J v') dt (= -integral F Ldot dt)
- damping loss D = sum of -qfrc_damper(v') . v' dt (joint and tendon damping; with MuJoCo's
  implicit Euler damping the damper acts at v')
- constraint work C = sum of qfrc_constraint . v' dt (joint limits, contacts, friction loss,
  equality constraints; 0 while none is active)
- other passive work P = sum of (qfrc_passive - qfrc_spring - qfrc_damper) . v' dt (fluid forces,
  gravity compensation; springs are potential energy)
- kinetic and potential energy E from MuJoCo (``mj_energyVel``/``mj_energyPos`` via the energy
  flag: 1/2 v^T M v with armature; gravity and joint/tendon springs).

Balance: W + C + P = Delta E + D; the residual is the integrator's own energy error (first order
in dt).
"""

from __future__ import annotations

import copy
import csv
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from vm_ros.errors import VmRosError
from vm_ros.geometry.mujoco_backend import MujocoGeometry, MuscleTendons, require_mujoco
from vm_ros.geometry.paths import generalized_forces

PULSE_DEFAULTS = (0.5, 0.2, 1.0)     # positive group drive, negative group drive, period (s)
BASELINE_DRIVE = 0.05                 # every muscle's drive outside its pulse
CROSSING_M = 1e-3                     # a muscle belongs to a pulse group when |r| > 1 mm


# ---------------------------------------------------------------------------- excitations


def _defined_at_every_time(start_s: float, end_s: float) -> list[str]:
    return []


@dataclass(frozen=True)
class Excitation:
    """Drive U(t) (n_muscles,) in [0, 1] for the loop, with a one-line description;
    ``coverage(start_s, end_s)``: the input warnings of a table that covers only part of the run
    [start_s, end_s] (s), VmRosError when it does not overlap it (vm_ros.cli.closed_loop: a
    file's drives; pulses and constants are defined at every time)."""

    function: Callable[[float], np.ndarray]
    description: str
    coverage: Callable[[float, float], list[str]] = _defined_at_every_time

    def __call__(self, t: float) -> np.ndarray:
        return self.function(t)


def pulse_excitation(moment_arm, coordinate: str, positive: float = PULSE_DEFAULTS[0],
                     negative: float = PULSE_DEFAULTS[1], period_s: float = PULSE_DEFAULTS[2],
                     baseline: float = BASELINE_DRIVE) -> Excitation:
    """Alternating drive pulses about one coordinate: the muscles with r > 1 mm on it get
    ``positive`` for the first half of each period, those with r < -1 mm get ``negative`` for the
    second half, every muscle ``baseline`` otherwise (on myoelbow: biceps and brachialis flex,
    then the triceps extend against less gravity)."""
    r = np.asarray(moment_arm, dtype=float)
    up, down = r > CROSSING_M, r < -CROSSING_M
    if not (0 <= baseline <= 1 and 0 <= positive <= 1 and 0 <= negative <= 1 and period_s > 0):
        raise VmRosError("pulse drives must lie in [0, 1] and the period be > 0 s")

    def drive(t: float) -> np.ndarray:
        first_half = (t % period_s) < period_s / 2
        u = np.full(r.shape, baseline)
        if first_half:
            u[up] = positive
        else:
            u[down] = negative
        return u

    return Excitation(drive, f"pulses about {coordinate}: {int(up.sum())} muscles (r > 0) at "
                      f"{positive:g} then {int(down.sum())} (r < 0) at {negative:g}, period "
                      f"{period_s:g} s, baseline {baseline:g}")


def constant_excitation(n: int, level: float) -> Excitation:
    if not 0 <= level <= 1:
        raise VmRosError(f"constant drive {level} is outside [0, 1]")
    u = np.full(n, float(level))
    return Excitation(lambda t: u.copy(), f"constant {level:g} on every muscle")


# ---------------------------------------------------------------------------- the loop


@dataclass
class EnergyLedger:
    """Energy bookkeeping of a run (J); see the module docstring."""

    kinetic_start_j: float = 0.0
    potential_start_j: float = 0.0
    kinetic_j: float = 0.0
    potential_j: float = 0.0
    muscle_work_j: float = 0.0
    damping_loss_j: float = 0.0
    constraint_work_j: float = 0.0
    other_passive_work_j: float = 0.0

    @property
    def mechanical_change_j(self) -> float:
        return (self.kinetic_j - self.kinetic_start_j) + (self.potential_j
                                                          - self.potential_start_j)

    @property
    def residual_j(self) -> float:
        """W + C + P - (Delta E + D): 0 for exact bookkeeping."""
        return (self.muscle_work_j + self.constraint_work_j + self.other_passive_work_j
                - self.mechanical_change_j - self.damping_loss_j)

    @property
    def relative_residual(self) -> float:
        """residual / |W| (muscle work)."""
        return self.residual_j / max(abs(self.muscle_work_j), 1e-12)

    @property
    def largest_term_j(self) -> float:
        """The largest |term| of the balance (W, C, P, kinetic and potential change, D): the
        scale of the residual when the muscles' net work is small beside gravity's."""
        return max(abs(self.muscle_work_j), abs(self.constraint_work_j),
                   abs(self.other_passive_work_j), abs(self.kinetic_j - self.kinetic_start_j),
                   abs(self.potential_j - self.potential_start_j), abs(self.damping_loss_j))


@dataclass
class ClosedLoopResult:
    """One run, sampled at every step start (k steps: k + 1 samples of the state).

    | field | shape | unit |
    | --- | --- | --- |
    | time_s | (k + 1,) | s |
    | q, qdot | (k + 1, n_q) | rad or m, per s: the independent coordinates |
    | excitation | (k, n) | 1: drive U of each step |
    | force | (k, n) | N: tensions applied over each step |
    | path_length | (k, n) | m: at each step's start |
    | torque | (k, n_q) | N m or N: tau = r^T F on the coordinates |
    | kinetic, potential | (k + 1,) | J |
    | muscle_work, damping_loss, constraint_work | (k + 1,) | J, cumulative |
    """

    coordinate_names: tuple
    muscle_names: tuple
    dt_s: float
    time_s: np.ndarray
    q: np.ndarray
    qdot: np.ndarray
    excitation: np.ndarray
    force: np.ndarray
    path_length: np.ndarray
    torque: np.ndarray
    kinetic: np.ndarray
    potential: np.ndarray
    muscle_work: np.ndarray
    damping_loss: np.ndarray
    constraint_work: np.ndarray
    ledger: EnergyLedger
    wall_s: float
    limit_steps: int = 0
    notes: list = field(default_factory=list)

    @property
    def wall_per_sim_s(self) -> float:
        return self.wall_s / max(self.time_s[-1] - self.time_s[0], 1e-12)

    def write_csv(self, path) -> Path:
        """One row per step start: time, q, qdot, torque, U, F, L, energies (SI, named)."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        k = len(self.force)
        header = (["time_s"] + [f"q.{c}" for c in self.coordinate_names]
                  + [f"qdot.{c}" for c in self.coordinate_names]
                  + [f"torque.{c}" for c in self.coordinate_names]
                  + [f"excitation.{m}" for m in self.muscle_names]
                  + [f"force.{m}" for m in self.muscle_names]
                  + [f"path_length.{m}" for m in self.muscle_names]
                  + ["kinetic_j", "potential_j", "muscle_work_j", "damping_loss_j",
                     "constraint_work_j"])
        table = np.column_stack([self.time_s[:k], self.q[:k], self.qdot[:k], self.torque,
                                 self.excitation, self.force, self.path_length,
                                 self.kinetic[:k], self.potential[:k], self.muscle_work[:k],
                                 self.damping_loss[:k], self.constraint_work[:k]])
        with open(path, "w", newline="", encoding="utf-8") as handle:
            writer = csv.writer(handle)
            writer.writerow(header)
            writer.writerows([[repr(float(v)) for v in row] for row in table])
        return path


class ClosedLoop:
    """The loop of the module docstring: a MuJoCo model (copied, actuation off, energy on,
    timestep dt) and a MuscleBank whose muscles are the geometry's muscles (by name; muscles
    missing from the bank apply no force).

    ``reset(q0, excitation)`` places the coordinates (dependent joints from their equalities, at
    rest) and starts the bank at static equilibrium; ``run(duration_s, excitation)`` steps.
    """

    def __init__(self, geometry: MujocoGeometry, bank, dt_s: float):
        mujoco = require_mujoco()
        if not (np.isfinite(dt_s) and dt_s > 0):
            raise VmRosError(f"dt must be > 0 s (got {dt_s})")
        self.geometry = geometry
        self.bank = bank
        self.dt_s = float(dt_s)
        m = self.model = copy.deepcopy(geometry.model)
        m.opt.timestep = self.dt_s
        m.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_ACTUATION)
        m.opt.enableflags |= int(mujoco.mjtEnableBit.mjENBL_ENERGY)
        self.data = mujoco.MjData(m)
        names = list(geometry.muscle_names)
        unknown = [n for n in bank.names if n not in names]
        if unknown:
            raise VmRosError(f"bank muscles {unknown} are not muscles of the model")
        self.rows = np.array([names.index(n) for n in bank.names], dtype=np.int64)
        self.tendon_ids = geometry.tendon_ids[self.rows]
        self._jacobian = MuscleTendons(m, self.tendon_ids)
        self._mujoco = mujoco

    def reset(self, q0=None, excitation=None) -> None:
        """Coordinates at q0 (default: the middle of each box), velocities 0, time 0; the bank at
        static equilibrium for ``excitation`` (drive of the bank's muscles; default rest)."""
        g, d = self.geometry, self.data
        q0 = (g.lower + g.upper) / 2 if q0 is None else np.asarray(q0, dtype=float)
        q0, _ = g.check_pose(q0, None)
        self._mujoco.mj_resetData(self.model, d)
        g.set_pose(q0)
        d.qpos[:] = g.data.qpos
        self._mujoco.mj_forward(self.model, d)
        self.bank.reset(path_length=d.ten_length[self.tendon_ids].copy(), excitation=excitation)

    def moment_arms(self) -> np.ndarray:
        """r = -dL/dq (n_bank, n_q) of the bank's muscles on the coordinates at the current
        simulated pose (after mj_forward or mj_step1)."""
        jac = self._jacobian.jacobian(self.data)
        return -jac @ self.geometry.velocity_map(self.data.qpos)

    def run(self, duration_s: float, excitation: Callable[[float], np.ndarray],
            should_stop: Callable[[], bool] | None = None) -> ClosedLoopResult:
        """Step for ``duration_s`` from the state set by ``reset``; ``excitation(t)`` gives the
        drive of the geometry's muscles (n_geometry,) at each step start."""
        mj = self._mujoco
        m, d, g, bank, dt = self.model, self.data, self.geometry, self.bank, self.dt_s
        n = int(round(duration_s / dt))
        if n < 1:
            raise VmRosError(f"duration {duration_s} s is shorter than one step of {dt} s")
        n_q, n_m = len(g.coordinates), bank.n
        q = np.zeros((n + 1, n_q))
        qdot = np.zeros((n + 1, n_q))
        u_rec = np.zeros((n, n_m))
        f_rec = np.zeros((n, n_m))
        l_rec = np.zeros((n, n_m))
        tau_rec = np.zeros((n, n_q))
        kinetic = np.zeros(n + 1)
        potential = np.zeros(n + 1)
        work = np.zeros(n + 1)
        damping = np.zeros(n + 1)
        constraint = np.zeros(n + 1)
        ledger = EnergyLedger()
        qadr, dofadr = g.qpos_addresses, g.dof_addresses
        limit_type = int(mj.mjtConstraint.mjCNSTR_LIMIT_JOINT)
        limit_steps = 0
        t_start = d.time
        w = c = p = 0.0
        dmp = 0.0
        wall0 = time.perf_counter()
        k = 0
        for k in range(n + 1):
            mj.mj_step1(m, d)
            if k > 0:  # the damper at v' of the previous step (implicit Euler damping)
                dmp += -float(d.qfrc_damper @ d.qvel) * dt
            q[k] = d.qpos[qadr]
            qdot[k] = d.qvel[dofadr]
            kinetic[k], potential[k] = d.energy[1], d.energy[0]
            work[k], damping[k], constraint[k] = w, dmp, c
            if k == n or (should_stop is not None and should_stop()):
                break
            u = np.asarray(excitation(d.time - t_start), dtype=float)[self.rows]
            length = d.ten_length[self.tendon_ids].copy()
            jac = self._jacobian.jacobian(d)
            out = bank.step(dt, u, length, d.ten_velocity[self.tendon_ids].copy())
            force = out.force
            qfrc = -jac.T @ force
            d.qfrc_applied[:] = qfrc
            tau_rec[k] = generalized_forces(-jac @ g.velocity_map(d.qpos), force)
            other = d.qfrc_passive - d.qfrc_spring - d.qfrc_damper
            mj.mj_step2(m, d)
            v_new = d.qvel
            w += float(qfrc @ v_new) * dt
            c += float(d.qfrc_constraint @ v_new) * dt
            p += float(other @ v_new) * dt
            if d.nefc and np.any(d.efc_type[:d.nefc] == limit_type):
                limit_steps += 1
            u_rec[k], f_rec[k], l_rec[k] = u, force, length
        wall = time.perf_counter() - wall0
        steps = k
        ledger = EnergyLedger(kinetic[0], potential[0], kinetic[steps], potential[steps],
                              w, dmp, c, p)
        result = ClosedLoopResult(
            g.coordinate_names, tuple(bank.names), dt, t_start + dt * np.arange(steps + 1),
            q[:steps + 1], qdot[:steps + 1], u_rec[:steps], f_rec[:steps], l_rec[:steps],
            tau_rec[:steps], kinetic[:steps + 1], potential[:steps + 1], work[:steps + 1],
            damping[:steps + 1], constraint[:steps + 1], ledger, wall, limit_steps)
        return result


# ---------------------------------------------------------------------------- plot


def plot_result(result: ClosedLoopResult, path, title: str = "") -> Path:
    """PNG: coordinates (deg for rotational), coordinate torques, energy balance (matplotlib)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = result.time_s
    fig, axes = plt.subplots(3, 1, figsize=(8, 9), sharex=True)
    shown = np.argsort(-np.ptp(result.q, axis=0))[:8]  # the coordinates that move most
    for j in shown:
        axes[0].plot(t, np.degrees(result.q[:, j]), label=result.coordinate_names[j])
        axes[1].plot(t[:-1], result.torque[:, j], label=result.coordinate_names[j])
    axes[0].set_ylabel("coordinate (deg)")
    axes[1].set_ylabel("torque r^T F (N m)")
    ledger_change = (result.kinetic - result.kinetic[0]) + (result.potential
                                                            - result.potential[0])
    axes[2].plot(t, result.muscle_work, label="muscle work W")
    axes[2].plot(t, ledger_change, label="kinetic + potential change")
    axes[2].plot(t, result.damping_loss, label="damping loss D")
    if np.any(result.constraint_work):
        axes[2].plot(t, result.constraint_work, label="constraint work C")
    axes[2].plot(t, result.muscle_work + result.constraint_work - ledger_change
                 - result.damping_loss, "k--", label="residual")
    axes[2].set_ylabel("energy (J)")
    axes[2].set_xlabel("time (s)")
    for ax in axes:
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="best")
    fig.suptitle(title or "closed loop")
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


__all__ = ["BASELINE_DRIVE", "ClosedLoop", "ClosedLoopResult", "EnergyLedger", "Excitation",
           "PULSE_DEFAULTS", "constant_excitation", "plot_result", "pulse_excitation"]
