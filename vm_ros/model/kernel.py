"""The fixed step compiled with Numba: each phase a loop over muscles that LLVM vectorises.

It calls the model's own equation functions (curves, activation, recruitment, mechanics,
energetics; each marked ``@jitable``), in the order the NumPy step
(vm_ros.model.numpy_step.NumpyStep.step) calls their array forms, phase by phase as
vm_ros.model.phases numbers them, so there is one source of every equation. Its arguments are the
flat list vm_ros.model.layout declares (test_model_layout.py checks the signature against it);
the packing of constants and the call live in vm_ros.model.compiled_step. A step is a series of
one. Run as plain Python (``_advance_series``) it equals the NumPy step to rounding
(test_model_layout.py, with or without Numba); compiled, to the fast-math tolerance of
test_kernel.py.

The bank uses this path when Numba is importable (see vm_ros.model.jit); otherwise the NumPy step.
"""

from __future__ import annotations

import os
import types

import numpy as np

from vm_ros.model import activation as act
from vm_ros.model import curves, layout
from vm_ros.model import energetics as en
from vm_ros.model import mechanics as mech
from vm_ros.model import recruitment as rc
from vm_ros.model.jit import (
    COMPILE_OPTIONS,
    HAVE_NUMBA,
    clip,
    compile_interruptibly,
    fixed_tuple,
    in_disk_cache,
    jitable,
    literal_unroll,
    model_cache_directory,
    numba,
    set_llvm_options,
)
from vm_ros.model.layout import N_TERMS, POLY_TERMS, M, P, S, T
from vm_ros.model.params import DRIVE_LAWS

SCHEME_CODES = {"lumped": 0, "natural": 1, "continuous": 2}
LUMPED, NATURAL = SCHEME_CODES["lumped"], SCHEME_CODES["natural"]
DRIVE_LAW_CODES = {law: code for code, law in enumerate(DRIVE_LAWS)}  # of the lumped scheme
RELATIVE_DRIVE = DRIVE_LAW_CODES["relative_drive"]
N_SHARED, N_TYPE_COLUMNS = len(S), len(T)
# the fibre types (slow, fast), for loops that Numba unrolls (their tuples' indices are constants)
FIBRE_TYPES = (0, 1)


def renamed(function, name: str):
    """A copy of ``function`` under another name (Numba caches each compiled copy by name)."""
    code = function.__code__.replace(co_name=name, co_qualname=name)
    copy = types.FunctionType(code, function.__globals__, name, function.__defaults__,
                              function.__closure__)
    copy.__qualname__, copy.__module__, copy.__doc__ = name, function.__module__, function.__doc__
    return copy


# --- the compiled loop -----------------------------------------------------------------------


# the terms of F_CE, and their slopes, that depend on (L, V) only, as kept per muscle
(
    FL_SLOW, FL_FAST, FV_SLOW, FV_FAST, PE1, PE2,
    DFL_SLOW, DFL_FAST, DFVDV_SLOW, DFVDV_FAST, DFVDL_SLOW, DFVDL_FAST, DPE1, DPE2,
) = range(N_TERMS)


@jitable
def _tables_as_tuples(shared, fibre_type, w_slow_poly):
    """The shared scalars, the two fibre types' rows and the W_S coefficients as tuples: values
    that inlined equations read without the reference counting of an array argument."""
    slow = fixed_tuple(fibre_type[0], N_TYPE_COLUMNS)
    fast = fixed_tuple(fibre_type[1], N_TYPE_COLUMNS)
    return fixed_tuple(shared[0], N_SHARED), (slow, fast), fixed_tuple(w_slow_poly, POLY_TERMS)


@jitable(inline=True)
def _fibre_terms(l, v, lmax, fibre_type, s):
    """The (L, V) terms at (L, V), in the order FL_SLOW ... DPE2: FL, FV of each fibre type, FPE1
    and FPE2, and their slopes (dFL/dL, dFV/dV, dFV/dL, dFPE1/dL, dFPE2/dL). ``fibre_type`` and
    ``s``: rows of the constant tables as tuples (:func:`_tables_as_tuples`). Inlined by Numba
    into its callers, where LLVM drops the terms a caller does not use."""
    fl_s, dfl_s, fv_s, dfv_dv_s, dfv_dl_s = curves.fibre_type_curves_and_slopes(
        l, v, fibre_type[0], s[S.fv_denominator_min])
    fl_f, dfl_f, fv_f, dfv_dv_f, dfv_dl_f = curves.fibre_type_curves_and_slopes(
        l, v, fibre_type[1], s[S.fv_denominator_min])
    pe1, dpe1 = curves.passive_parallel_elastic_and_slope_cheng2000(
        l, v, lmax, s[S.c1], s[S.k1], s[S.lr1], s[S.eta]
    )
    pe2, dpe2 = curves.thick_filament_compression_and_slope_cheng2000(
        l, s[S.c2], s[S.k2], s[S.lr2]
    )
    return (fl_s, fl_f, fv_s, fv_f, pe1, pe2, dfl_s, dfl_f, dfv_dv_s, dfv_dv_f, dfv_dl_s,
            dfv_dl_f, dpe1, dpe2)


@jitable
def _contractile_force(activity, terms, f0):
    """F_CE (N) from the (L, V) terms and the per-type effective activation."""
    active = 0.0
    for t in literal_unroll(FIBRE_TYPES):
        active += mech.active_force_term(
            activity[t], terms[FL_SLOW + t], terms[FV_SLOW + t], terms[PE2]
        )
    return f0 * mech.contractile_force_total(terms[PE1], active)


@jitable
def _contractile_force_and_slopes(activity, terms, f0, l0, s):
    """F_CE (N), dF_CE/dx (N/m) and dF_CE/dxdot (N s/m) from the (L, V) terms and slopes."""
    active = active_dl = active_dv = 0.0
    for t in literal_unroll(FIBRE_TYPES):
        active += mech.active_force_term(
            activity[t], terms[FL_SLOW + t], terms[FV_SLOW + t], terms[PE2]
        )
        dl, dv = mech.active_force_slopes(
            activity[t], terms[FL_SLOW + t], terms[DFL_SLOW + t], terms[FV_SLOW + t],
            terms[DFVDV_SLOW + t], terms[DFVDL_SLOW + t], terms[DPE2],
        )
        active_dl += dl
        active_dv += dv
    d_ce_dl, d_ce_dv = mech.contractile_force_slopes_total(
        terms[PE1], active, terms[DPE1], s[S.eta], active_dl, active_dv
    )
    scale = f0 / l0
    f_ce = f0 * mech.contractile_force_total(terms[PE1], active)
    return f_ce, scale * d_ce_dl, scale * d_ce_dv


@jitable
def _tendon_force(x, path_length, f0, l0t, s):
    """F_SE (N) at fascicle length x (m) and path length (m)."""
    l_se = mech.tendon_length_normalised(path_length, x, l0t)
    return f0 * curves.tendon_force_cheng2000(l_se, s[S.ct], s[S.kt], s[S.lrt])


@jitable
def _tendon_force_and_slope(x, path_length, f0, l0t, s):
    """F_SE (N) and dF_SE/dx (N/m), sharing one exp."""
    l_se = mech.tendon_length_normalised(path_length, x, l0t)
    force, stiffness = curves.tendon_force_and_stiffness_cheng2000(l_se, s[S.ct], s[S.kt],
                                                                   s[S.lrt])
    return f0 * force, mech.tendon_force_slope_from_stiffness(stiffness, f0, l0t)


@jitable
def _type_weights(lumped, ueff, ueff_f, threshold_s, threshold_f, fpcsa_s, fpcsa_f, lower_s,
                  lower_f, upper_s, upper_f, u2, ur, w_slow_at_u2, w_slow_amplitude, w_fast_b,
                  w_fast_c, w_fast_tau, w_slow_poly, s):
    """Weights of the slow and fast pools at each type's drive Ueff (``ueff`` slow, ``ueff_f``
    fast; lumped: rF W; continuous: Ueff W, from the slow type's Ueff, equal to the fast type's
    under its one filter; both evaluated, one selected)."""
    lumped_slow = rc.linear_recruited_fraction(ueff, fpcsa_s, lower_s, upper_s)
    lumped_slow *= rc.lumped_weight_slow(ueff, s[S.u1], u2, w_slow_poly, w_slow_at_u2,
                                         w_slow_amplitude, s[S.w_slow_tau])
    lumped_fast = rc.linear_recruited_fraction(ueff_f, fpcsa_f, lower_f, upper_f)
    lumped_fast *= rc.lumped_weight_fast(ueff_f, u2, ur, w_fast_b, w_fast_c, w_fast_tau,
                                         s[S.w_fast_offset], s[S.w_fast_rise])
    excess_s = rc.continuous_excess_song2008(ueff, threshold_s, fpcsa_s > 0.0)
    excess_f = rc.continuous_excess_song2008(ueff, threshold_f, fpcsa_f > 0.0)
    total = excess_s + excess_f
    continuous_slow = ueff * rc.continuous_share_song2008(excess_s, total)
    continuous_fast = ueff * rc.continuous_share_song2008(excess_f, total)
    if lumped:
        return lumped_slow, lumped_fast
    return continuous_slow, continuous_fast


# --- the step over a block of muscles as a structure of arrays ---------------------------------
#
# A block of muscles is held in two (rows, muscles) arrays: ``variable`` (state, the (L, V) terms
# kept between steps, the step's inputs and outputs, scratch) and ``constant`` (the muscle table's
# columns, each pool's threshold and PCSA fraction). Every phase is a loop over the muscles that
# reads and writes whole rows, each passed as its own contiguous 1-d array, so that LLVM runs
# several muscles at once in SIMD registers (a row of a 2-d array written in such a loop could,
# for all it can prove, overlap another row; separate arrays it checks once per loop).


def _row_starts(*sizes):
    """The first row of each group of rows of the given sizes, then the total."""
    starts, total = [], 0
    for size in sizes:
        starts.append(total)
        total += size
    return (*starts, total)


(
    ROW_U_IN, ROW_LP, ROW_VP, ROW_DRIVE, ROW_X, ROW_XDOT, ROW_WORK, ROW_RECOVERY, ROW_ENERGY,
    ROW_TERMS, ROW_XV, ROW_OUT_U, ROW_OUT_FSE, ROW_OUT_FCE, ROW_OUT_POWER, ROW_ACTIVITY,
    ROW_STIMULATION, ROW_COMPONENTS, ROW_RATES, ROW_WEIGHT, ROW_POOLS,
) = _row_starts(1, 1, 1, 2, 1, 1, 1, 4, 6, N_TERMS, 2, 1, 1, 1, 1, 2, 2, 6, 4, 2)
# per pool, after ROW_POOLS: f_int, f_eff, sag, yield (the pool's row is ROW_POOLS + q * P + j)
POOL_F_INT, POOL_F_EFF, POOL_SAG, POOL_YIELD, POOL_VARIABLE_ROWS = range(5)
# constant rows: the muscle table's columns, then each pool's threshold and PCSA fraction
ROW_C_THRESHOLD = len(M)


@jitable
def _variable_rows(n_pools):
    return ROW_POOLS + POOL_VARIABLE_ROWS * n_pools


@jitable
def _pool_row(quantity, j, n_pools):
    return ROW_POOLS + quantity * n_pools + j


@jitable
def _move_rows(block, i0, count, arrays, first_rows, into_rows):
    """Between a block's rows and the (n, columns) arrays of muscles i0 ... i0 + count - 1:
    column c of ``arrays[a]`` is row ``first_rows[a] + c``; into the rows if ``into_rows``, else
    out of them."""
    for a in range(len(arrays)):
        array, first = arrays[a], first_rows[a]
        if into_rows:
            for c in range(array.shape[1]):
                for i in range(count):
                    block[first + c, i] = array[i0 + i, c]
        else:
            for i in range(count):
                for c in range(array.shape[1]):
                    array[i0 + i, c] = block[first + c, i]


@jitable
def _columns(array):
    """``array`` as (n, columns): its first axis the muscles, the others flattened."""
    return array.reshape(array.shape[0], -1)


@jitable
def _state_columns(effective_drive, f_int, f_eff, sag, yield_factor, x_state, xdot_state,
                   recovery_filter, energy, work):
    """The state arrays (layout.STATE) as (n, columns) and the first row of each in a block."""
    n_pools = f_int.shape[1]
    arrays = (_columns(effective_drive), _columns(x_state), _columns(xdot_state), _columns(work),
              _columns(recovery_filter), _columns(energy), f_int, f_eff, sag, yield_factor)
    first_rows = (ROW_DRIVE, ROW_X, ROW_XDOT, ROW_WORK, ROW_RECOVERY, ROW_ENERGY,
                  _pool_row(POOL_F_INT, 0, n_pools), _pool_row(POOL_F_EFF, 0, n_pools),
                  _pool_row(POOL_SAG, 0, n_pools), _pool_row(POOL_YIELD, 0, n_pools))
    return arrays, first_rows


@jitable
def _load_inputs(variable, i0, count, excitation, path_length, path_velocity):
    """One step's inputs of muscles i0 ... into a block's rows: 0, or 1 + the block's index of
    the first bad one (non-finite, path length <= 0)."""
    for i in range(count):
        g = i0 + i
        u, lp, vp = excitation[g], path_length[g], path_velocity[g]
        if not (np.isfinite(u) and np.isfinite(lp) and lp > 0.0 and np.isfinite(vp)):
            return i + 1
        variable[ROW_U_IN, i] = u
        variable[ROW_LP, i] = lp
        variable[ROW_VP, i] = vp
    return 0


@jitable
def _store_outputs(block, i0, count, out_excitation, out_f_se, out_f_ce, out_activity,
                   out_stimulation, out_components, out_rates, out_power, out_length,
                   out_velocity):
    """A block's output rows into one step's output arrays (layout.SERIES_OUTPUTS), muscles
    i0 ... i0 + count - 1. Written out rather than through _move_rows, whose loop over a tuple
    of arrays made a step slower (docs/performance.md)."""
    for i in range(count):
        g = i0 + i
        out_excitation[g] = block[ROW_OUT_U, i]
        out_f_se[g] = block[ROW_OUT_FSE, i]
        out_f_ce[g] = block[ROW_OUT_FCE, i]
        out_power[g] = block[ROW_OUT_POWER, i]
        out_length[g] = block[ROW_X, i]
        out_velocity[g] = block[ROW_XDOT, i]
        for t in range(2):
            out_activity[g, t] = block[ROW_ACTIVITY + t, i]
            out_stimulation[g, t] = block[ROW_STIMULATION + t, i]
            for c in range(3):
                out_components[g, t, c] = block[ROW_COMPONENTS + 3 * t + c, i]
        for c in range(4):
            out_rates[g, c] = block[ROW_RATES + c, i]


@jitable
def _type_drive(dt, lumped, natural, relative_drive, u, ueff_old, f_eff, f_env, driven_share,
                relative_rise, relative_fall, t_rise, t_fall, t_rise_rate, s):
    """One fibre type's filtered drive Ueff after the step, the same for both types (the lumped
    relative-drive law: on a rise the firing match of the type's own unit, of firing rate
    ``f_eff`` and target ``f_env``; on a fall the slow unit's, whose (1 - m)^p is
    ``driven_share``, while the type is driven)."""
    tau_relative = rc.relative_drive_tau(
        u, ueff_old, rc.firing_match(f_eff, f_env), rc.type_fall_share(driven_share, f_env),
        relative_rise, relative_fall, s[S.relative_fall_floor], s[S.drive_tau_min],
    )
    tau_rate = rc.lumped_drive_tau_from_rate(u, ueff_old, t_rise, t_fall, t_rise_rate)
    tau_continuous = rc.continuous_drive_tau_song2008(
        u, ueff_old, s[S.continuous_tau_rise], s[S.continuous_tau_fall]
    )
    tau = (tau_relative if relative_drive else tau_rate) if lumped else tau_continuous
    return u if natural else act.lag_step(ueff_old, u, tau, dt)


@jitable
def _drive_loop(dt, count, lumped, natural, relative_drive, u_in, out_u, drive_s, drive_f,
                f_eff_slow, f_eff_fast, weight_s, weight_f, constant, s, w_slow_poly):
    """Phase 1 over a block's muscles (``drive_s``, ``drive_f``: each fibre type's Ueff;
    ``f_eff_slow``, ``f_eff_fast``: pools 0 and 1, a lumped muscle's slow and fast units)."""
    c = constant
    for i in range(count):
        u = min(max(u_in[i], 0.0), 1.0)
        out_u[i] = u
        # Phase 1, DRIVE: filtered drive Ueff of each type and the pool weights it sets. The
        # candidates of every scheme are computed and one is selected: branches on the scheme
        # inside the loop would stop its vectorisation (the other schemes' constants are NaN,
        # never selected).
        # lumped, relative-drive law: the slow pool (pool 0) says how active the units already
        # are; one power of its match serves both types' falls
        f_env_s = act.firing_envelope(u, c[ROW_C_THRESHOLD, i], s[S.fmin], s[S.fmax])
        f_env_f = act.firing_envelope(u, c[ROW_C_THRESHOLD + 1, i], s[S.fmin], s[S.fmax])
        driven_share = rc.relative_fall_share(rc.firing_match(f_eff_slow[i], f_env_s),
                                              s[S.relative_fall_power])
        drive_s[i] = _type_drive(
            dt, lumped, natural, relative_drive, u, drive_s[i], f_eff_slow[i], f_env_s,
            driven_share, c[M.relative_rise, i], c[M.relative_fall, i], c[M.t_rise, i],
            c[M.t_fall, i], c[M.t_rise_rate, i], s,
        )
        drive_f[i] = _type_drive(
            dt, lumped, natural, relative_drive, u, drive_f[i], f_eff_fast[i], f_env_f,
            driven_share, c[M.relative_rise, i], c[M.relative_fall, i], c[M.t_rise, i],
            c[M.t_fall, i], c[M.t_rise_rate, i], s,
        )
        weight_s[i], weight_f[i] = _type_weights(
            lumped, drive_s[i], drive_f[i], c[ROW_C_THRESHOLD, i], c[ROW_C_THRESHOLD + 1, i],
            c[M.fpcsa_s, i], c[M.fpcsa_f, i], c[M.rec_lower_s, i], c[M.rec_lower_f, i],
            c[M.rec_upper_s, i], c[M.rec_upper_f, i], c[M.u2, i], c[M.ur, i],
            c[M.w_slow_at_u2, i], c[M.w_slow_amplitude, i], c[M.w_fast_b, i], c[M.w_fast_c, i],
            c[M.w_fast_tau, i], w_slow_poly, s,
        )


@jitable
def _pool_loop(dt, count, u, x, xdot, f_int, f_eff, sag, yield_factor, activity, stimulation,
               weight, threshold, l0, p, sag_decay, yield_decay, s):
    """Phases 2 and 3 of one pool over a block's muscles (``p``: the pool's constants;
    ``weight``: its share of its type's activation per muscle)."""
    for i in range(count):
        l, v = x[i] / l0[i], xdot[i] / l0[i]
        # Phase 2, FIRING: rise/fall cascade, sag and yield of the pool
        l_pool = clip(l, s[S.l_activation_min], p[P.l_max])
        f_env = act.firing_envelope(u[i], threshold[i], s[S.fmin], s[S.fmax])
        fi_old, fe_old = f_int[i], f_eff[i]
        # Af at the old state enters the time constant only while falling
        af_old = curves.activation_frequency_brown1999(
            fe_old, l_pool, yield_factor[i], sag[i], p[P.af], p[P.nf0], p[P.nf1]
        )
        af_now = af_old if fi_old < fe_old else 0.0
        tf = act.rise_fall_time_constant(
            f_env, fi_old, fe_old, l_pool, af_now, p[P.tf1], p[P.tf2], p[P.tf3], p[P.tf4]
        )
        fi_new, fe_new = act.cascade_step(fi_old, fe_old, f_env, tf, dt)
        sag_new = act.lag_step_decayed(
            sag[i], act.sag_target(fe_old, p[P.as1], p[P.as2], p[P.sag_rate_threshold]),
            sag_decay,
        )
        yield_new = act.lag_step_decayed(
            yield_factor[i], act.yield_target(v, p[P.cy], p[P.vy]), yield_decay
        )
        f_int[i], f_eff[i], sag[i], yield_factor[i] = fi_new, fe_new, sag_new, yield_new
        # Phase 3, ACTIVATION: the pool's share of Acteff and stimulation of its type
        af = curves.activation_frequency_brown1999(
            fe_new, l_pool, yield_new, sag_new, p[P.af], p[P.nf0], p[P.nf1]
        )
        af_l0 = curves.activation_frequency_brown1999(
            fe_new, 1.0, 1.0, sag_new, p[P.af], p[P.nf0], p[P.nf1]
        )
        activity[i] += weight[i] * af
        stimulation[i] += weight[i] * af_l0


# _fibre_terms compiled as a function of its own, called rather than inlined: for the rare
# refresh of the kept terms below, where inlining it only costs compile time
_fibre_terms_called = jitable(renamed(_fibre_terms, "_fibre_terms_called"))


@jitable
def _refresh_terms(count, x, xdot, xv_x, xv_xdot, terms, constant, fibre, s):
    """The kept (L, V) terms recomputed where (x, xdot) moved since they were computed (a reset
    or set_state): they are reused while (x, xdot) are bit-for-bit the same."""
    c = constant
    t0, t1, t2, t3, t4, t5, t6, t7, t8, t9, t10, t11, t12, t13 = terms
    for i in range(count):
        if not (xv_x[i] == x[i] and xv_xdot[i] == xdot[i]):
            l0 = c[M.l0, i]
            terms_now = _fibre_terms_called(x[i] / l0, xdot[i] / l0, c[M.lmax, i], fibre, s)
            (t0[i], t1[i], t2[i], t3[i], t4[i], t5[i], t6[i], t7[i], t8[i], t9[i], t10[i],
             t11[i], t12[i], t13[i]) = terms_now


@jitable
def _mechanics_loop(dt, count, lp_in, vp_in, x_state, xdot_state, activity_s, activity_f, terms,
                    xv_x, xv_xdot, out_f_se, out_f_ce, out_power, constant, fibre, s):
    """Phase 4 and the end state's forces and terms over a block's muscles."""
    c = constant
    # the terms' rows as names (a helper taking the tuple would count references in the loop)
    t0, t1, t2, t3, t4, t5, t6, t7, t8, t9, t10, t11, t12, t13 = terms
    for i in range(count):
        lp, vp, x, xdot = lp_in[i], vp_in[i], x_state[i], xdot_state[i]
        activity = (activity_s[i], activity_f[i])
        l0, l0t, f0, lmax, m_eff = c[M.l0, i], c[M.l0t, i], c[M.f0, i], c[M.lmax, i], c[M.m_eff, i]
        # Phase 4, MECHANICS (ROS2, activation held over the step, analytic Jacobian)
        f_se, d_se_dx = _tendon_force_and_slope(x, lp, f0, l0t, s)
        start_terms = (t0[i], t1[i], t2[i], t3[i], t4[i], t5[i], t6[i], t7[i], t8[i], t9[i],
                       t10[i], t11[i], t12[i], t13[i])
        f_ce, d_ce_dx, d_ce_dv = _contractile_force_and_slopes(activity, start_terms, f0, l0, s)
        accel, a_x, a_v, a_p = mech.ros2_jacobian(f_se, f_ce, d_se_dx, d_ce_dx, d_ce_dv, m_eff)
        k1_x, k1_v, x2, v2 = mech.ros2_stage1(x, xdot, vp, dt, accel, a_x, a_v, a_p)
        stage2_terms = _fibre_terms(x2 / l0, v2 / l0, lmax, fibre, s)
        accel2 = (
            _tendon_force(x2, lp + dt * vp, f0, l0t, s)
            - _contractile_force(activity, stage2_terms, f0)
        ) / m_eff
        x_new, xdot_new = mech.ros2_stage2(x, xdot, vp, dt, a_x, a_v, a_p, k1_x, k1_v, v2, accel2)
        floor = s[S.l_activation_min] * l0
        below = x_new < floor
        x_new = floor if below else x_new
        xdot_new = max(xdot_new, 0.0) if below else xdot_new
        x_state[i], xdot_state[i] = x_new, xdot_new
        # the forces and the (L, V) terms at the step's end state, kept for the next step
        end_terms = _fibre_terms(x_new / l0, xdot_new / l0, lmax, fibre, s)
        (t0[i], t1[i], t2[i], t3[i], t4[i], t5[i], t6[i], t7[i], t8[i], t9[i], t10[i], t11[i],
         t12[i], t13[i]) = end_terms
        xv_x[i], xv_xdot[i] = x_new, xdot_new
        f_ce = _contractile_force(activity, end_terms, f0)
        out_f_se[i] = _tendon_force(x_new, lp + dt * vp, f0, l0t, s)
        out_f_ce[i] = f_ce
        out_power[i] = -f_ce * xdot_new


@jitable
def _energy_loop(dt, count, dynamic_recovery, xdot, activity, stimulation, fl, recovery_filter,
                 energy, work, components, rates, out_power, constant, fibre, s, recovery_decay,
                 recovery_rise):
    """Phases 5 to 7 over a block's muscles (activity, stimulation, fl: the rows of the two fibre
    types; recovery_filter, energy, components: of type t and component k at 2t + k, 3t + k)."""
    c = constant
    for i in range(count):
        v_new = xdot[i] / c[M.l0, i]
        rate_a = rate_xb = rate_r = 0.0
        for t in literal_unroll(FIBRE_TYPES):
            ft = fibre[t]
            # Phase 5, INITIAL_ENERGY: E_a and E_xb at the step's end state (STEPs 1-5)
            e_act, e_xb = en.initial_energy_rates_tsianos2012(
                stimulation[t][i], activity[t][i], fl[t][i], v_new, c[M.dry_mass, i],
                ft[T.e1], ft[T.e2], ft[T.e3], ft[T.e4], s[S.activation_fraction], ft[T.vmax],
            )
            initial = e_act + e_xb
            # Phase 6, RECOVERY: STEP 6 (static) or the Appendix B filter (dynamic)
            z_decay = en.recovery_state_step_decayed(
                recovery_filter[2 * t][i], initial, s[S.recovery_tau_decay], recovery_decay
            )
            z_rise = en.recovery_state_step_decayed(
                recovery_filter[2 * t + 1][i], initial, s[S.recovery_tau_rise], recovery_rise
            )
            dynamic = en.recovery_rate_from_filter(
                z_decay, z_rise, ft[T.recovery_ratio], s[S.recovery_tau_rise],
                s[S.recovery_tau_decay],
            )
            static = en.static_recovery_rate(initial, ft[T.recovery_ratio])
            recovery = dynamic if dynamic_recovery else static
            if dynamic_recovery:  # (static: the filter is not touched)
                recovery_filter[2 * t][i] = z_decay
                recovery_filter[2 * t + 1][i] = z_rise
            # Phase 7, TOTALS: rates summed (STEP 7), energies and work integrated
            components[3 * t][i] = e_act
            components[3 * t + 1][i] = e_xb
            components[3 * t + 2][i] = recovery
            energy[3 * t][i] += dt * e_act
            energy[3 * t + 1][i] += dt * e_xb
            energy[3 * t + 2][i] += dt * recovery
            rate_a += e_act
            rate_xb += e_xb
            rate_r += recovery
        rates[0][i], rates[1][i], rates[2][i] = rate_a, rate_xb, rate_r
        rates[3][i] = rate_a + rate_xb + rate_r
        work[i] += dt * out_power[i]


# the loops that carry the phases, in order (test_model_layout.py reads their comments)
PHASE_LOOPS = (_drive_loop, _pool_loop, _mechanics_loop, _energy_loop)


@jitable
def _rows_tuple4(variable, first):
    return (variable[first], variable[first + 1], variable[first + 2], variable[first + 3])


@jitable
def _rows_tuple6(variable, first):
    return (variable[first], variable[first + 1], variable[first + 2], variable[first + 3],
            variable[first + 4], variable[first + 5])


@jitable
def _pool_decays(dt, pool):
    """The decays over dt of each pool's sag and yield lags (time constants of the pool)."""
    pool_decay = np.empty((pool.shape[0], 2))
    for j in range(pool.shape[0]):
        pool_decay[j, 0] = act.lag_decay(pool[j, P.ts], dt)
        pool_decay[j, 1] = act.lag_decay(pool[j, P.ty], dt)
    return pool_decay


def _advance_series(
    dt, excitation, path_length, path_velocity, scheme, dynamic_recovery,
    muscle, pool, pool_type, thresholds, pool_pcsa, fibre_type, shared, w_slow_poly,
    effective_drive, f_int, f_eff, sag, yield_factor, x_state, xdot_state, recovery_filter,
    energy, work, terms_end, xv_end, out_excitation,
    out_f_se, out_f_ce, out_activity, out_stimulation, out_components, out_rates, out_power,
    out_length, out_velocity, snapshot_every, snap_effective_drive, snap_f_int, snap_f_eff,
    snap_sag, snap_yield_factor, snap_x_state, snap_xdot_state, snap_recovery_filter,
    snap_energy, snap_work, chunk,
):
    """Advance every muscle by dt, k times (k the leading axis of the inputs and outputs, (k, n,
    ...)), in place in the state arrays, and fill the outputs. out_rates: the energy rates summed
    over fibre types (activation, cross-bridge, recovery, total). terms_end (n, N_TERMS) and
    xv_end (n, 2): the (L, V) terms of F_CE at the (x, xdot) in xv_end, kept between calls (any
    content is valid: they are recomputed where xv_end does not match the state). Bad inputs:
    non-finite, or a path length <= 0.

    The state arrays end at the last step, and with ``snapshot_every`` m > 0 the ``snap_``
    arrays (k // m, ...) take the state at the end of steps m, 2m, ... Returns 0, or 1 + the
    flat index step * n + muscle of the first bad input (the caller discards the state
    arrays).

    The muscles are split into blocks of ``chunk`` (0: one block). Muscles do not interact, so
    each block runs all k steps in its rows on its own: in parallel where this is compiled with
    ``parallel`` (advance_series_parallel: ``prange``, one parallel region per series), in turn
    otherwise. A block stops at its first bad input; the series' is the earliest of the blocks'.
    Every muscle takes the same arithmetic either way. A step is a series of one
    (CompiledStep.step), so the model is compiled once for both."""
    n, n_pools = excitation.shape[1], pool.shape[0]
    size = chunk if chunk > 0 else max(n, 1)
    blocks = (n + size - 1) // size
    pool_decay = _pool_decays(dt, pool)
    recovery_decay = act.lag_decay(shared[0, S.recovery_tau_decay], dt)
    recovery_rise = act.lag_decay(shared[0, S.recovery_tau_rise], dt)
    variable = np.empty((blocks, _variable_rows(n_pools), size))
    constant = np.empty((blocks, ROW_C_THRESHOLD + 2 * n_pools, size))
    status = np.zeros(blocks, dtype=np.int64)  # per block: 0, or 1 + its first bad input's index
    for b in prange(blocks):
        i0 = b * size
        count = min(n, i0 + size) - i0
        v, c = variable[b], constant[b]
        # (tuples made here, inside the parallel region, which takes arrays and scalars only)
        s, fibre, w_slow = _tables_as_tuples(shared, fibre_type, w_slow_poly)
        state_arrays, state_rows = _state_columns(effective_drive, f_int, f_eff, sag,
                                                  yield_factor, x_state, xdot_state,
                                                  recovery_filter, energy, work)
        _move_rows(c, i0, count, (muscle, thresholds, pool_pcsa),
                   (0, ROW_C_THRESHOLD, ROW_C_THRESHOLD + n_pools), True)
        _move_rows(v, i0, count, state_arrays, state_rows, True)
        _move_rows(v, i0, count, (terms_end, xv_end), (ROW_TERMS, ROW_XV), True)
        # the scheme as flags: tests of one code against several constants in a loop would
        # become a switch, which stops its vectorisation
        lumped, natural = scheme == LUMPED, scheme == NATURAL
        relative_drive = s[S.drive_law_code] == RELATIVE_DRIVE
        # the rows the loops take as tuples, the same views for every step
        terms = (v[ROW_TERMS], v[ROW_TERMS + 1], v[ROW_TERMS + 2], v[ROW_TERMS + 3],
                 v[ROW_TERMS + 4], v[ROW_TERMS + 5], v[ROW_TERMS + 6], v[ROW_TERMS + 7],
                 v[ROW_TERMS + 8], v[ROW_TERMS + 9], v[ROW_TERMS + 10], v[ROW_TERMS + 11],
                 v[ROW_TERMS + 12], v[ROW_TERMS + 13])
        activity = (v[ROW_ACTIVITY], v[ROW_ACTIVITY + 1])
        stimulation = (v[ROW_STIMULATION], v[ROW_STIMULATION + 1])
        fl = (v[ROW_TERMS + FL_SLOW], v[ROW_TERMS + FL_FAST])
        recovery = _rows_tuple4(v, ROW_RECOVERY)
        energy_rows = _rows_tuple6(v, ROW_ENERGY)
        components = _rows_tuple6(v, ROW_COMPONENTS)
        rates = _rows_tuple4(v, ROW_RATES)
        # the kept terms are stale only where the state was set since (reset, set_state): in a
        # series only the mechanics loop moves (x, xdot), and it keeps the terms at its end state
        _refresh_terms(count, v[ROW_X], v[ROW_XDOT], v[ROW_XV], v[ROW_XV + 1], terms, c, fibre, s)
        for k in range(excitation.shape[0]):
            bad = _load_inputs(v, i0, count, excitation[k], path_length[k], path_velocity[k])
            if bad != 0:
                status[b] = k * n + i0 + bad
                break
            # one step of the block; its inputs are in the rows ROW_U_IN, ROW_LP, ROW_VP
            _drive_loop(dt, count, lumped, natural, relative_drive, v[ROW_U_IN], v[ROW_OUT_U],
                        v[ROW_DRIVE], v[ROW_DRIVE + 1], v[_pool_row(POOL_F_EFF, 0, n_pools)],
                        v[_pool_row(POOL_F_EFF, 1, n_pools)], v[ROW_WEIGHT], v[ROW_WEIGHT + 1],
                        c, s, w_slow)
            for t in range(2):
                for i in range(count):
                    v[ROW_ACTIVITY + t, i] = 0.0
                    v[ROW_STIMULATION + t, i] = 0.0
            # every pool: its activation path, then its share of the type's activation
            for j in range(n_pools):
                t = pool_type[j]
                # natural units: a unit's own PCSA share; else its type's weight this step
                weight = c[ROW_C_THRESHOLD + n_pools + j] if natural else v[ROW_WEIGHT + t]
                _pool_loop(
                    dt, count, v[ROW_OUT_U], v[ROW_X], v[ROW_XDOT],
                    v[_pool_row(POOL_F_INT, j, n_pools)], v[_pool_row(POOL_F_EFF, j, n_pools)],
                    v[_pool_row(POOL_SAG, j, n_pools)], v[_pool_row(POOL_YIELD, j, n_pools)],
                    v[ROW_ACTIVITY + t], v[ROW_STIMULATION + t], weight,
                    c[ROW_C_THRESHOLD + j], c[M.l0], pool[j], pool_decay[j, 0],
                    pool_decay[j, 1], s,
                )
            _mechanics_loop(dt, count, v[ROW_LP], v[ROW_VP], v[ROW_X], v[ROW_XDOT],
                            activity[0], activity[1], terms, v[ROW_XV],
                            v[ROW_XV + 1], v[ROW_OUT_FSE], v[ROW_OUT_FCE], v[ROW_OUT_POWER], c,
                            fibre, s)
            _energy_loop(dt, count, dynamic_recovery, v[ROW_XDOT], activity, stimulation, fl,
                         recovery, energy_rows, v[ROW_WORK], components, rates,
                         v[ROW_OUT_POWER], c, fibre, s, recovery_decay, recovery_rise)
            _store_outputs(v, i0, count, out_excitation[k], out_f_se[k], out_f_ce[k],
                           out_activity[k], out_stimulation[k], out_components[k], out_rates[k],
                           out_power[k], out_length[k], out_velocity[k])
            if snapshot_every > 0 and (k + 1) % snapshot_every == 0:
                j = (k + 1) // snapshot_every - 1
                snap_arrays, _ = _state_columns(
                    snap_effective_drive[j], snap_f_int[j], snap_f_eff[j], snap_sag[j],
                    snap_yield_factor[j], snap_x_state[j], snap_xdot_state[j],
                    snap_recovery_filter[j], snap_energy[j], snap_work[j])
                _move_rows(v, i0, count, snap_arrays, state_rows, False)
        _move_rows(v, i0, count, state_arrays, state_rows, False)
        _move_rows(v, i0, count, (terms_end, xv_end), (ROW_TERMS, ROW_XV), False)
    first_bad = 0
    for b in range(blocks):
        if status[b] != 0 and (first_bad == 0 or status[b] < first_bad):
            first_bad = status[b]
    return first_bad


# LLVM may contract a*b + c into fused multiply-adds; nothing else (reassociation or reciprocals
# would make a vectorised loop's muscles and its scalar remainder's differ in the last bits, and
# then the parallel build would no longer equal the serial one to the bit); NaN and infinity keep
# their IEEE meaning (the input checks rely on them). Results differ from the NumPy step by
# rounding, which the stiff fascicle dynamics carry on (test_kernel: measured at most 8e-8 of the
# largest velocity, 4e-10 of force; held to 1e-5 of each field's scale).
FASTMATH = {"contract"}
prange = range
advance_series = advance_series_parallel = None
if HAVE_NUMBA:
    prange = numba.prange
    set_llvm_options()
    with model_cache_directory():
        _options = {"cache": True, "nogil": True, "error_model": "numpy", "fastmath": FASTMATH,
                    **COMPILE_OPTIONS}
        advance_series = numba.njit(**_options)(_advance_series)
        advance_series_parallel = numba.njit(parallel=True, **_options)(
            renamed(_advance_series, "_advance_series_parallel"))
AVAILABLE = advance_series is not None

# The parallel switch (CompiledStep(parallel=...), or this environment variable) and the bank
# size below which the step stays serial even when it is on: below about 64 muscles the threads
# cost more than they save, and with the other cores busy they lose at any size, hence off by
# default (docs/performance.md).
PARALLEL_ENV = "VM_ROS_PARALLEL"
PARALLEL_MIN_MUSCLES = 64


def parallel_wanted(parallel=None) -> bool:
    """The parallel switch: ``parallel`` if given, else the environment variable VM_ROS_PARALLEL
    ("1", "true", "on" or "yes" switch it on; default off). False without Numba."""
    if parallel is None:
        parallel = os.environ.get(PARALLEL_ENV, "0").strip().lower() in ("1", "true", "on", "yes")
    return bool(parallel) and AVAILABLE


def parallel_chunk(n: int, threads: int | None = None) -> int:
    """Muscles per parallel block for a bank of n: 0 (serial) below PARALLEL_MIN_MUSCLES or with
    one thread, else n split evenly over Numba's threads."""
    if not AVAILABLE:
        return 0
    threads = threads or numba.get_num_threads()
    if n < PARALLEL_MIN_MUSCLES or threads < 2:
        return 0
    return -(-n // threads)


# The kernel's first compile, for the line warm_up prints: from an idle machine to both cores
# busy (docs/performance.md)
COMPILE_TIME = "about 10-40 s"


def warm_up(parallel: bool = False) -> None:
    """Compile the kernel (step and run share it) or load it from Numba's disk cache now rather
    than in the first step: about 11-12 s the first time on a machine (for a Python and vm_ros
    version: vm_ros.model.jit.cache_root), 0.3 s after; with ``parallel`` its parallel build too.
    A compile says so on stderr first, and SIGINT/SIGTERM end the process during it
    (jit.compile_interruptibly)."""
    if not AVAILABLE:
        return
    pending = [function for wanted, function in ((True, advance_series),
                                                 (parallel, advance_series_parallel))
               if wanted and not function.signatures]

    def compile_now():
        for function in pending:
            function(*layout.dummy_arguments(LUMPED))

    if all(in_disk_cache(function) for function in pending):
        compile_now()
    else:
        compile_interruptibly(compile_now, "the model step", COMPILE_TIME)


__all__ = [
    "AVAILABLE",
    "COMPILE_TIME",
    "PARALLEL_ENV",
    "PARALLEL_MIN_MUSCLES",
    "advance_series",
    "advance_series_parallel",
    "parallel_chunk",
    "parallel_wanted",
    "warm_up",
]
