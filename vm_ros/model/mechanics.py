"""Musculotendon mechanics: contractile and tendon forces, the fascicle-mass equation, its
fixed-step integrator, and the equilibrium used to start a run.

    L_SE = (L_path - L0 L) / L0T
    F_SE = F0 FSE(L_SE)
    F_CE = F0 max(0, FPE1(L, V) + sum_i Acteff_i (FL_i(L) FV_i(V, L) + FPE2(L)))
    m_eff d2x/dt2 = F_SE - F_CE,   m_eff = mass / 2,   x = L0 L (m)

The fascicle mass against a stiff tendon is a stiff system: when active its fast eigenvalue is
about -1e5 /s for a human muscle. :func:`rosenbrock_step` integrates it with the two-stage,
second-order, L-stable Rosenbrock W-method ROS2 (Verwer, Spee, Blom & Hundsdorfer 1999, SIAM J Sci
Comput 20:1456), a W-method that stays second order with any Jacobian; the one used here is
analytic, from the slopes of the curves. Activation
is held over the step (it varies on time scales of 1 ms and longer).

References: Cheng, Brown & Loeb 2000; docs/model.md section 4.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vm_ros.model import curves, roots
from vm_ros.model.jit import jitable, where
from vm_ros.model.layout import type_columns
from vm_ros.model.params import FibreTypeParams, GenericParams, MuscleSpec

ROS2_GAMMA = 1.0 + 1.0 / np.sqrt(2.0)


def lmax_from_path_length_max(path_length_max_m, l0_m, l0t_m, g: GenericParams):
    """Lmax (L0): the fascicle length at the maximum path length, where PE1 carries
    F* = c1 k1 ln(exp((1 - Lr1)/k1) + 1) and the tendon is at the length carrying F*.

    Lmax = (L_path_max - L0T L_SE*) / L0,  L_SE* = kT ln(exp(F*/(cT kT)) - 1) + LrT.
    """
    f_star = g.c1 * g.k1 * np.logaddexp(0.0, (1.0 - g.lr1) / g.k1)
    l_se_star = curves.tendon_length_at_force(f_star, g.ct, g.kt, g.lrt)
    return (np.asarray(path_length_max_m) - np.asarray(l0t_m) * l_se_star) / np.asarray(l0_m)


@dataclass(frozen=True)
class MuscleGeometry:
    """Per-muscle constants in SI, arrays of shape (n,).

    | field | unit | meaning |
    | f0 | N | tetanic isometric force at L0, sigma * mass / (rho * L0); sigma the muscle's |
    |  |  | specific_tension_pa where its entry gives one, else generic.specific_tension |
    | l0 | m | optimal fascicle length |
    | l0t | m | tendon length at F0 |
    | mass | kg | wet muscle mass |
    | m_eff | kg | fascicle mass moving with the fascicle, mass / 2 |
    | lmax | L0 | fascicle length at the maximum path length |
    """

    f0: np.ndarray
    l0: np.ndarray
    l0t: np.ndarray
    mass: np.ndarray
    m_eff: np.ndarray
    lmax: np.ndarray

    @classmethod
    def from_specs(cls, specs: list[MuscleSpec], g: GenericParams) -> MuscleGeometry:
        mass = np.array([s.mass_kg for s in specs], dtype=float)
        l0 = np.array([s.l0_m for s in specs], dtype=float)
        l0t = np.array([s.l0t_m for s in specs], dtype=float)
        pcsa = mass / (g.muscle_density * l0)
        sigma = np.array([g.specific_tension if s.specific_tension_pa is None
                          else s.specific_tension_pa for s in specs], dtype=float)
        lmax = np.array(
            [
                s.lmax
                if s.lmax is not None
                else float(lmax_from_path_length_max(s.path_length_max_m, s.l0_m, s.l0t_m, g))
                for s in specs
            ]
        )
        return cls(
            f0=sigma * pcsa, l0=l0, l0t=l0t, mass=mass, m_eff=mass / 2.0, lmax=lmax
        )


def contractile_force_normalised(l, v, activity, lmax, fibre: FibreTypeParams, g: GenericParams):
    """F_CE / F0 and the per-type FL, FV.

    ``l``, ``v``: (..., n) in L0 and L0/s; ``activity``: (n, 2) effective activation per fibre
    type; ``fibre`` arrays of shape (2,). Returns (f_ce (..., n), fl (..., n, 2), fv (..., n, 2)).
    """
    lt, vt = l[..., None], v[..., None]
    fl, fv = curves.fibre_type_curves(lt, vt, type_columns(fibre), g.fv_denominator_min)
    pe1 = curves.passive_parallel_elastic_cheng2000(l, v, lmax, g.c1, g.k1, g.lr1, g.eta)
    pe2 = curves.thick_filament_compression_cheng2000(lt, g.c2, g.k2, g.lr2)
    active = active_force_term(activity, fl, fv, pe2).sum(axis=-1)
    return contractile_force_total(pe1, active), fl, fv


def contractile_force_and_slopes_normalised(
    l, v, activity, lmax, fibre: FibreTypeParams, g: GenericParams
):
    """F_CE/F0, d(F_CE/F0)/dL and d(F_CE/F0)/dV, each (..., n), the slopes analytic from the
    curves'. Same arguments as :func:`contractile_force_normalised`; the slopes are zero where
    F_CE is clipped at 0."""
    lt, vt = l[..., None], v[..., None]
    fl, dfl, fv, dfv_dv, dfv_dl = curves.fibre_type_curves_and_slopes(
        lt, vt, type_columns(fibre), g.fv_denominator_min)
    pe1, dpe1 = curves.passive_parallel_elastic_and_slope_cheng2000(l, v, lmax, g.c1, g.k1,
                                                                     g.lr1, g.eta)
    pe2, dpe2 = curves.thick_filament_compression_and_slope_cheng2000(lt, g.c2, g.k2, g.lr2)
    active = active_force_term(activity, fl, fv, pe2).sum(axis=-1)
    active_dl, active_dv = active_force_slopes(activity, fl, dfl, fv, dfv_dv, dfv_dl, dpe2)
    d_dl, d_dv = contractile_force_slopes_total(
        pe1, active, dpe1, g.eta, active_dl.sum(axis=-1), active_dv.sum(axis=-1)
    )
    return contractile_force_total(pe1, active), d_dl, d_dv


@jitable
def active_force_slopes(activity, fl, dfl, fv, dfv_dv, dfv_dl, dpe2):
    """One fibre type's share of d(F_CE/F0)/dL and /dV:
    Acteff (FL' FV + FL dFV/dL + FPE2'),  Acteff FL dFV/dV."""
    return activity * (dfl * fv + fl * dfv_dl + dpe2), activity * fl * dfv_dv


@jitable
def contractile_force_slopes_total(pe1, active_sum, dpe1_dl, eta, active_dl, active_dv):
    """(d/dL, d/dV) of F_CE/F0 = max(0, FPE1 + sum of active terms); zero where it clips."""
    on = pe1 + active_sum > 0.0
    return where(on, dpe1_dl + active_dl, 0.0), where(on, eta + active_dv, 0.0)


@jitable
def active_force_term(activity, fl, fv, pe2):
    """One fibre type's share of F_CE / F0: Acteff (FL FV + FPE2)."""
    return activity * (fl * fv + pe2)


@jitable
def contractile_force_total(pe1, active_sum):
    """F_CE / F0 = max(0, FPE1 + sum over types of the active terms)."""
    return np.maximum(0.0, pe1 + active_sum)


@jitable
def tendon_length_normalised(path_length, x, l0t):
    """L_SE = (L_path - x) / L0T."""
    return (path_length - x) / l0t


def musculotendon_forces(
    x,
    xdot,
    path_length,
    activity,
    geometry: MuscleGeometry,
    fibre: FibreTypeParams,
    g: GenericParams,
):
    """Tendon and contractile forces (N), each (..., n), for fascicle length x (m), velocity xdot
    (m/s) and path length (m); also the per-type FL (..., n, 2) they used."""
    l_se = tendon_length_normalised(path_length, x, geometry.l0t)
    f_se = geometry.f0 * curves.tendon_force_cheng2000(l_se, g.ct, g.kt, g.lrt)
    f_ce, fl, _ = contractile_force_normalised(
        x / geometry.l0, xdot / geometry.l0, activity, geometry.lmax, fibre, g
    )
    return f_se, geometry.f0 * f_ce, fl


def musculotendon_forces_and_slopes(
    x, xdot, path_length, activity, geometry: MuscleGeometry, fibre: FibreTypeParams,
    g: GenericParams,
):
    """The forces of :func:`musculotendon_forces` (N) with their slopes: (F_SE, F_CE,
    dF_SE/dx, dF_CE/dx (N/m), dF_CE/dxdot (N s/m)), each (..., n). F_SE depends on x through
    L_SE = (L_path - x) / L0T."""
    l_se = tendon_length_normalised(path_length, x, geometry.l0t)
    force, stiffness = curves.tendon_force_and_stiffness_cheng2000(l_se, g.ct, g.kt, g.lrt)
    f_se = geometry.f0 * force
    d_se_dx = tendon_force_slope_from_stiffness(stiffness, geometry.f0, geometry.l0t)
    f_ce, d_ce_dl, d_ce_dv = contractile_force_and_slopes_normalised(
        x / geometry.l0, xdot / geometry.l0, activity, geometry.lmax, fibre, g
    )
    scale = geometry.f0 / geometry.l0
    return f_se, geometry.f0 * f_ce, d_se_dx, scale * d_ce_dl, scale * d_ce_dv


@jitable
def tendon_force_slope_from_stiffness(stiffness, f0, l0t):
    """dF_SE/dx (N/m) = -F0 / L0T * dFSE/dL_SE, given dFSE/dL_SE (``stiffness``, F0 per L0T):
    x is the fascicle's share of the path."""
    return -f0 / l0t * stiffness


@jitable
def ros2_jacobian(f_se, f_ce, d_se_dx, d_ce_dx, d_ce_dv, m_eff):
    """Acceleration and its Jacobian from the forces and their analytic slopes.
    Returns (accel, d accel/dx, d accel/dv, d accel/d path length)."""
    accel = (f_se - f_ce) / m_eff
    a_x = (d_se_dx - d_ce_dx) / m_eff
    a_v = -d_ce_dv / m_eff
    a_p = -d_se_dx / m_eff  # F_SE depends on (Lp - x)
    return accel, a_x, a_v, a_p


@jitable
def ros2_solve(a_x, a_v, gh, r_x, r_v):
    """Solve (I - gamma h J) k = r for the 2x2 Jacobian [[0, 1], [a_x, a_v]]."""
    det = (1.0 - gh * a_v) - gh * gh * a_x
    det = where(np.abs(det) > 1e-12, det, 1e-12)
    return ((1.0 - gh * a_v) * r_x + gh * r_v) / det, (gh * a_x * r_x + r_v) / det


@jitable
def ros2_stage1(x, xdot, path_velocity, dt, accel, a_x, a_v, a_p):
    """First ROS2 stage: k1 and the point (x2, v2) where the second stage evaluates forces."""
    gh = ROS2_GAMMA * dt
    k1_x, k1_v = ros2_solve(a_x, a_v, gh, xdot, accel + gh * a_p * path_velocity)
    return k1_x, k1_v, x + dt * k1_x, xdot + dt * k1_v


@jitable
def ros2_stage2(x, xdot, path_velocity, dt, a_x, a_v, a_p, k1_x, k1_v, v2, accel2):
    """Second ROS2 stage and the update: returns (x, xdot) at the end of the step."""
    gh = ROS2_GAMMA * dt
    k2_x, k2_v = ros2_solve(
        a_x, a_v, gh, v2 - 2.0 * k1_x, accel2 - 2.0 * k1_v - gh * a_p * path_velocity
    )
    return x + dt * (1.5 * k1_x + 0.5 * k2_x), xdot + dt * (1.5 * k1_v + 0.5 * k2_v)


def rosenbrock_step(x, xdot, path_length, path_velocity, dt, forces, forces_and_slopes, m_eff):
    """Advance (x, xdot) by dt with ROS2, the path length moving at ``path_velocity``.

    ``forces(x, xdot, path_length) -> (f_se, f_ce)`` and ``forces_and_slopes(x, xdot,
    path_length) -> (f_se, f_ce, dF_SE/dx, dF_CE/dx, dF_CE/dxdot)`` broadcast over the muscles.
    The Jacobian is analytic (the curves' slopes); the path length enters as a third state with
    dLp/dt = path_velocity (so the step is exact for a linear path ramp).

        (I - gamma h J) k1 = F(y_n)
        (I - gamma h J) k2 = F(y_n + h k1) - 2 k1
        y_{n+1} = y_n + h (3 k1 + k2) / 2,      gamma = 1 + 1/sqrt(2)
    """
    accel, a_x, a_v, a_p = ros2_jacobian(*forces_and_slopes(x, xdot, path_length), m_eff)
    k1_x, k1_v, x2, v2 = ros2_stage1(x, xdot, path_velocity, dt, accel, a_x, a_v, a_p)
    f_se2, f_ce2 = forces(x2, v2, path_length + dt * path_velocity)
    return ros2_stage2(
        x, xdot, path_velocity, dt, a_x, a_v, a_p, k1_x, k1_v, v2, (f_se2 - f_ce2) / m_eff
    )


def equilibrium_fascicle_length(
    path_length,
    geometry: MuscleGeometry,
    activity_at,
    fibre: FibreTypeParams,
    g: GenericParams,
    l_min: float,
):
    """Fascicle length (m) at which F_SE = F_CE with zero velocity, per muscle.

    ``activity_at(l, index)`` gives the (k, 2) effective activation of muscles ``index`` at
    normalised lengths ``l`` (k,). Solved with a bracketing root finder over arrays
    (vm_ros.model.roots, Chandrupatla's method) on [l_min L0, the length at which the tendon is
    slack]; where the bracket holds no sign change (a path length outside the muscle's range)
    the end with the smaller imbalance is returned.
    """
    n = geometry.f0.shape[0]
    index = np.arange(n)

    def imbalance(x, idx):
        l0, l0t = geometry.l0[idx], geometry.l0t[idx]
        f_se = curves.tendon_force_cheng2000((path_length[idx] - x) / l0t, g.ct, g.kt, g.lrt)
        l = x / l0
        f_ce, _, _ = contractile_force_normalised(
            l, np.zeros_like(l), activity_at(l, idx), geometry.lmax[idx], fibre, g
        )
        return f_se - f_ce

    slack = path_length - geometry.l0t * (g.lrt - 30.0 * g.kt)
    upper = np.minimum(slack, geometry.lmax * geometry.l0 * 1.5)
    lower = np.minimum(l_min * geometry.l0, upper - 1e-6 * geometry.l0)
    g_low, g_up = imbalance(lower, index), imbalance(upper, index)
    bracketed = np.sign(g_low) != np.sign(g_up)
    result = np.where(np.abs(g_low) < np.abs(g_up), lower, upper)
    if np.any(bracketed):
        muscles = index[bracketed]
        result[bracketed] = roots.find_root(
            lambda x, i: imbalance(x, muscles[i]), lower[bracketed], upper[bracketed],
            xatol=1e-12, xrtol=1e-12)
    return result
