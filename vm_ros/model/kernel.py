"""The fixed step compiled with Numba: one loop over muscles and pools, scalars in registers.

It calls the model's own equation functions (curves, activation, recruitment, mechanics,
energetics; each marked ``@jitable``), in the order the NumPy step
(vm_ros.model.numpy_step.NumpyStep.step) calls their array forms, phase by phase as
vm_ros.model.phases numbers them, so there is one source of every equation. Its arguments are the
flat list vm_ros.model.layout declares (test_model_layout.py checks both signatures against it);
the packing of constants and the call live in vm_ros.model.compiled_step. Run as plain Python
(``_advance``) it equals the NumPy step to rounding (test_model_layout.py, with or without Numba);
compiled, to the fast-math tolerance of test_kernel.py.

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
from vm_ros.model.jit import HAVE_NUMBA, clip, jitable, model_cache_directory, numba
from vm_ros.model.layout import N_TERMS, M, P, S, T
from vm_ros.model.params import DRIVE_LAWS

SCHEME_CODES = {"lumped": 0, "natural": 1, "continuous": 2}
LUMPED, NATURAL, CONTINUOUS = 0, 1, 2
DRIVE_LAW_CODES = {law: code for code, law in enumerate(DRIVE_LAWS)}  # of the lumped scheme
RELATIVE_DRIVE = DRIVE_LAW_CODES["relative_drive"]


# --- the compiled loop -----------------------------------------------------------------------


# the terms of F_CE, and their slopes, that depend on (L, V) only, as kept per muscle
(
    FL_SLOW, FL_FAST, FV_SLOW, FV_FAST, PE1, PE2,
    DFL_SLOW, DFL_FAST, DFVDV_SLOW, DFVDV_FAST, DFVDL_SLOW, DFVDL_FAST, DPE1, DPE2,
) = range(N_TERMS)


@jitable
def _fibre_terms(l, v, m, fibre_type, s, terms, with_slopes):
    """FL, FV of each fibre type, FPE1 and FPE2 at (L, V), into terms; with their slopes (dFL/dL,
    dFV/dV, dFV/dL, dFPE1/dL, dFPE2/dL) if ``with_slopes``."""
    for t in range(2):
        ft = fibre_type[t]
        fl, dfl = curves.force_length_and_slope_cheng2000(l, ft[T.omega], ft[T.beta], ft[T.rho])
        terms[FL_SLOW + t] = fl
        terms[DFL_SLOW + t] = dfl
        fv_args = (ft[T.vmax], ft[T.cv0], ft[T.cv1], ft[T.av0], ft[T.av1], ft[T.av2], ft[T.bv],
                   s[S.fv_denominator_min])
        terms[FV_SLOW + t] = curves.force_velocity_cheng2000(v, l, *fv_args)
        if with_slopes:
            dfv_dv, dfv_dl = curves.force_velocity_slopes_cheng2000(v, l, *fv_args)
            terms[DFVDV_SLOW + t] = dfv_dv
            terms[DFVDL_SLOW + t] = dfv_dl
    if with_slopes:
        terms[PE1], terms[DPE1] = curves.passive_parallel_elastic_and_slope_cheng2000(
            l, v, m[M.lmax], s[S.c1], s[S.k1], s[S.lr1], s[S.eta]
        )
        terms[PE2], terms[DPE2] = curves.thick_filament_compression_and_slope_cheng2000(
            l, s[S.c2], s[S.k2], s[S.lr2]
        )
    else:
        terms[PE1] = curves.passive_parallel_elastic_cheng2000(
            l, v, m[M.lmax], s[S.c1], s[S.k1], s[S.lr1], s[S.eta]
        )
        terms[PE2] = curves.thick_filament_compression_cheng2000(l, s[S.c2], s[S.k2], s[S.lr2])


@jitable
def _contractile_force(activity, terms, m):
    """F_CE (N) from the (L, V) terms and the per-type effective activation."""
    active = 0.0
    for t in range(2):
        active += mech.active_force_term(
            activity[t], terms[FL_SLOW + t], terms[FV_SLOW + t], terms[PE2]
        )
    return m[M.f0] * mech.contractile_force_total(terms[PE1], active)


@jitable
def _contractile_force_and_slopes(activity, terms, m, s):
    """F_CE (N), dF_CE/dx (N/m) and dF_CE/dxdot (N s/m) from the (L, V) terms and slopes."""
    active = active_dl = active_dv = 0.0
    for t in range(2):
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
    scale = m[M.f0] / m[M.l0]
    f_ce = m[M.f0] * mech.contractile_force_total(terms[PE1], active)
    return f_ce, scale * d_ce_dl, scale * d_ce_dv


@jitable
def _tendon_force(x, path_length, m, s):
    """F_SE (N) at fascicle length x (m) and path length (m)."""
    l_se = mech.tendon_length_normalised(path_length, x, m[M.l0t])
    return m[M.f0] * curves.tendon_force_cheng2000(l_se, s[S.ct], s[S.kt], s[S.lrt])


@jitable
def _tendon_force_and_slope(x, path_length, m, s):
    """F_SE (N) and dF_SE/dx (N/m), sharing one exp."""
    l_se = mech.tendon_length_normalised(path_length, x, m[M.l0t])
    force, stiffness = curves.tendon_force_and_stiffness_cheng2000(l_se, s[S.ct], s[S.kt],
                                                                   s[S.lrt])
    return m[M.f0] * force, mech.tendon_force_slope_from_stiffness(stiffness, m[M.f0], m[M.l0t])


@jitable
def _type_weights(scheme, ueff, m, threshold_s, threshold_f, w_slow_poly, s):
    """Weights of the slow and fast pools at drive Ueff (lumped: rF W; continuous: Ueff W)."""
    if scheme == LUMPED:
        slow = rc.linear_recruited_fraction(
            ueff, m[M.fpcsa_s], m[M.rec_lower_s], m[M.rec_upper_s]
        ) * rc.lumped_weight_slow(
            ueff, s[S.u1], m[M.u2], w_slow_poly, m[M.w_slow_at_u2], m[M.w_slow_amplitude],
            s[S.w_slow_tau],
        )
        fast = rc.linear_recruited_fraction(
            ueff, m[M.fpcsa_f], m[M.rec_lower_f], m[M.rec_upper_f]
        ) * rc.lumped_weight_fast(
            ueff, m[M.u2], m[M.ur], m[M.w_fast_b], m[M.w_fast_c], m[M.w_fast_tau],
            s[S.w_fast_offset], s[S.w_fast_rise],
        )
        return slow, fast
    excess_s = rc.continuous_excess_song2008(ueff, threshold_s, m[M.fpcsa_s] > 0.0)
    excess_f = rc.continuous_excess_song2008(ueff, threshold_f, m[M.fpcsa_f] > 0.0)
    total = excess_s + excess_f
    return (
        ueff * rc.continuous_share_song2008(excess_s, total),
        ueff * rc.continuous_share_song2008(excess_f, total),
    )


def _advance(
    dt, excitation, path_length, path_velocity, scheme, dynamic_recovery,
    muscle, pool, pool_type, thresholds, pool_pcsa, fibre_type, shared, w_slow_poly,
    effective_drive, f_int, f_eff, sag, yield_factor, x_state, xdot_state, recovery_filter,
    energy, work, terms_end, xv_end, out_excitation,
    out_f_se, out_f_ce, out_activity, out_stimulation, out_components, out_rates, out_power,
):
    """Advance every muscle by dt in place (state arrays) and fill the outputs.

    out_rates (n, 4): the energy rates summed over fibre types (activation, cross-bridge,
    recovery, total). Returns 0, or 1 + the index of the first muscle with a bad input
    (non-finite, path length <= 0), having stopped there: the caller then discards the partly
    updated arrays.

    terms_end (n, N_TERMS) and xv_end (n, 2): the (L, V) terms of F_CE at the (x, xdot) in
    xv_end, kept between calls (any content is valid: they are recomputed where xv_end does not
    match the state).
    """
    s = shared[0]
    terms_tmp = np.empty(N_TERMS)
    n_pools = pool.shape[0]
    # the decays over dt of the lags whose time constants are constants of the pool or shared
    pool_decay = np.empty((n_pools, 2))
    for j in range(n_pools):
        pool_decay[j, 0] = act.lag_decay(pool[j, P.ts], dt)
        pool_decay[j, 1] = act.lag_decay(pool[j, P.ty], dt)
    recovery_decay = act.lag_decay(s[S.recovery_tau_decay], dt)
    recovery_rise = act.lag_decay(s[S.recovery_tau_rise], dt)
    for i in range(excitation.shape[0]):
        m = muscle[i]
        lp, vp = path_length[i], path_velocity[i]
        if not (np.isfinite(excitation[i]) and np.isfinite(lp) and lp > 0.0 and np.isfinite(vp)):
            return i + 1
        u = min(max(excitation[i], 0.0), 1.0)
        out_excitation[i] = u
        x, xdot = x_state[i], xdot_state[i]
        l, v = x / m[M.l0], xdot / m[M.l0]
        # Phase 1, DRIVE: filtered drive Ueff and the pool weights it sets
        if scheme == LUMPED:
            if s[S.drive_law_code] == RELATIVE_DRIVE:
                # the slow pool (pool 0) says how active the lumped units already are
                active = rc.firing_fraction(
                    f_eff[i, 0], act.firing_envelope(u, thresholds[i, 0], s[S.fmin], s[S.fmax])
                )
                tau = rc.relative_drive_tau(
                    u, effective_drive[i], active, m[M.relative_rise], s[S.relative_rise_power],
                    m[M.relative_fall],
                    rc.mid_activation_fall_time_constant(pool[0, P.tf3], pool[0, P.tf4]),
                    s[S.relative_fall_power], s[S.drive_tau_min],
                )
            else:
                tau = rc.lumped_drive_tau_from_rate(
                    u, effective_drive[i], m[M.t_rise], m[M.t_fall], m[M.t_rise_rate]
                )
            ueff = act.lag_step(effective_drive[i], u, tau, dt)
        elif scheme == CONTINUOUS:
            tau = rc.continuous_drive_tau_song2008(
                u, effective_drive[i], s[S.continuous_tau_rise], s[S.continuous_tau_fall]
            )
            ueff = act.lag_step(effective_drive[i], u, tau, dt)
        else:
            ueff = u
        effective_drive[i] = ueff
        weight_s = weight_f = 0.0
        if scheme != NATURAL:
            weight_s, weight_f = _type_weights(
                scheme, ueff, m, thresholds[i, 0], thresholds[i, 1], w_slow_poly, s
            )
        # every pool: its activation path, then its share of the type's activation
        activity = out_activity[i]
        stimulation = out_stimulation[i]
        for t in range(2):
            activity[t] = stimulation[t] = 0.0
        for j in range(n_pools):
            p = pool[j]
            # Phase 2, FIRING: rise/fall cascade, sag and yield of the pool
            l_pool = clip(l, s[S.l_activation_min], p[P.l_max])
            f_env = act.firing_envelope(u, thresholds[i, j], s[S.fmin], s[S.fmax])
            fe_old = f_eff[i, j]
            # Af at the old state enters the time constant only while falling
            af_now = 0.0
            if f_int[i, j] < fe_old:
                af_now = curves.activation_frequency_brown1999(
                    fe_old, l_pool, yield_factor[i, j], sag[i, j], p[P.af], p[P.nf0], p[P.nf1]
                )
            tf = act.rise_fall_time_constant(
                f_env, f_int[i, j], fe_old, l_pool, af_now, p[P.tf1], p[P.tf2], p[P.tf3], p[P.tf4]
            )
            fi_new, fe_new = act.cascade_step(f_int[i, j], fe_old, f_env, tf, dt)
            sag_new = act.lag_step_decayed(
                sag[i, j],
                act.sag_target(fe_old, p[P.as1], p[P.as2], p[P.sag_rate_threshold]),
                pool_decay[j, 0],
            )
            yield_new = act.lag_step_decayed(
                yield_factor[i, j], act.yield_target(v, p[P.cy], p[P.vy]), pool_decay[j, 1]
            )
            f_int[i, j], f_eff[i, j], sag[i, j], yield_factor[i, j] = (
                fi_new, fe_new, sag_new, yield_new,
            )
            # Phase 3, ACTIVATION: the pool's share of Acteff and stimulation of its type
            t = pool_type[j]
            weight = pool_pcsa[i, j] if scheme == NATURAL else (weight_s if t == 0 else weight_f)
            af = curves.activation_frequency_brown1999(
                fe_new, l_pool, yield_new, sag_new, p[P.af], p[P.nf0], p[P.nf1]
            )
            af_l0 = curves.activation_frequency_brown1999(
                fe_new, 1.0, 1.0, sag_new, p[P.af], p[P.nf0], p[P.nf1]
            )
            activity[t] += weight * af
            stimulation[t] += weight * af_l0
        # Phase 4, MECHANICS (ROS2, activation held over the step, analytic Jacobian). The
        # curves' terms and slopes depend on (x, xdot) only: those of the last step's end state are
        # kept in terms_end and reused while (x, xdot) are bit-for-bit the same.
        l0 = m[M.l0]
        base = terms_end[i]
        if not (xv_end[i, 0] == x and xv_end[i, 1] == xdot):
            _fibre_terms(l, v, m, fibre_type, s, base, True)
        f_se, d_se_dx = _tendon_force_and_slope(x, lp, m, s)
        f_ce, d_ce_dx, d_ce_dv = _contractile_force_and_slopes(activity, base, m, s)
        accel, a_x, a_v, a_p = mech.ros2_jacobian(f_se, f_ce, d_se_dx, d_ce_dx, d_ce_dv, m[M.m_eff])
        k1_x, k1_v, x2, v2 = mech.ros2_stage1(x, xdot, vp, dt, accel, a_x, a_v, a_p)
        _fibre_terms(x2 / l0, v2 / l0, m, fibre_type, s, terms_tmp, False)
        accel2 = (
            _tendon_force(x2, lp + dt * vp, m, s) - _contractile_force(activity, terms_tmp, m)
        ) / m[M.m_eff]
        x_new, xdot_new = mech.ros2_stage2(x, xdot, vp, dt, a_x, a_v, a_p, k1_x, k1_v, v2, accel2)
        floor = s[S.l_activation_min] * l0
        if x_new < floor:
            x_new = floor
            xdot_new = max(xdot_new, 0.0)
        x_state[i], xdot_state[i] = x_new, xdot_new
        # Phase 5, INITIAL_ENERGY: forces, E_a and E_xb at the step's end state (STEPs 1-5)
        l_new, v_new = x_new / l0, xdot_new / l0
        _fibre_terms(l_new, v_new, m, fibre_type, s, base, True)
        xv_end[i, 0], xv_end[i, 1] = x_new, xdot_new
        f_se = _tendon_force(x_new, lp + dt * vp, m, s)
        f_ce = _contractile_force(activity, base, m)
        out_f_se[i], out_f_ce[i] = f_se, f_ce
        power = -f_ce * xdot_new
        out_power[i] = power
        rates = out_rates[i]
        rates[0] = rates[1] = rates[2] = 0.0
        for t in range(2):
            ft = fibre_type[t]
            e_act, e_xb = en.initial_energy_rates_tsianos2012(
                stimulation[t], activity[t], base[FL_SLOW + t], v_new, m[M.dry_mass],
                ft[T.e1], ft[T.e2], ft[T.e3], ft[T.e4], s[S.activation_fraction], ft[T.vmax],
            )
            initial = e_act + e_xb
            # Phase 6, RECOVERY: STEP 6 (static) or the Appendix B filter (dynamic)
            if dynamic_recovery:
                z_decay = en.recovery_state_step_decayed(
                    recovery_filter[i, t, 0], initial, s[S.recovery_tau_decay], recovery_decay
                )
                z_rise = en.recovery_state_step_decayed(
                    recovery_filter[i, t, 1], initial, s[S.recovery_tau_rise], recovery_rise
                )
                recovery_filter[i, t, 0], recovery_filter[i, t, 1] = z_decay, z_rise
                recovery = en.recovery_rate_from_filter(
                    z_decay,
                    z_rise,
                    ft[T.recovery_ratio],
                    s[S.recovery_tau_rise],
                    s[S.recovery_tau_decay],
                )
            else:
                recovery = en.static_recovery_rate(initial, ft[T.recovery_ratio])
            # Phase 7, TOTALS: rates summed (STEP 7), energies and work integrated
            out_components[i, t, 0] = e_act
            out_components[i, t, 1] = e_xb
            out_components[i, t, 2] = recovery
            energy[i, t, 0] += dt * e_act
            energy[i, t, 1] += dt * e_xb
            energy[i, t, 2] += dt * recovery
            rates[0] += e_act
            rates[1] += e_xb
            rates[2] += recovery
        rates[3] = rates[0] + rates[1] + rates[2]
        work[i] += dt * power
    return 0


@jitable
def _copy(destination, source):
    """destination[...] = source for C-ordered arrays of one shape, as a flat loop (Numba
    compiles an array assignment into a broadcasting function of its own, which took most of
    the series' compile time)."""
    flat_destination, flat_source = destination.reshape(-1), source.reshape(-1)
    for i in range(flat_source.shape[0]):
        flat_destination[i] = flat_source[i]


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
    """:func:`_advance` for k steps: inputs and outputs carry a leading step axis (k, n, ...);
    the state arrays end at the last step, and with ``snapshot_every`` m > 0 the ``snap_``
    arrays (k // m, ...) take the state at the end of steps m, 2m, ... Returns 0, or 1 + the
    flat index step * n + muscle of the first bad input (the caller discards the state
    arrays).

    Each step runs over blocks of ``chunk`` muscles (0: one block), in parallel where this is
    compiled with ``parallel`` (advance_series_parallel: ``prange``), in turn otherwise; every
    muscle takes the same arithmetic either way. A step is a series of one (CompiledStep.step),
    so the model is compiled once for both."""
    n = excitation.shape[1]
    size = chunk if chunk > 0 else max(n, 1)
    blocks = (n + size - 1) // size
    status = np.zeros(blocks, dtype=np.int64)
    for k in range(excitation.shape[0]):
        for b in prange(blocks):
            i, j = b * size, min(n, (b + 1) * size)
            first_bad = _advance_step(
                dt, excitation[k, i:j], path_length[k, i:j], path_velocity[k, i:j], scheme,
                dynamic_recovery, muscle[i:j], pool, pool_type, thresholds[i:j],
                pool_pcsa[i:j], fibre_type, shared, w_slow_poly, effective_drive[i:j],
                f_int[i:j], f_eff[i:j], sag[i:j], yield_factor[i:j], x_state[i:j],
                xdot_state[i:j], recovery_filter[i:j], energy[i:j], work[i:j], terms_end[i:j],
                xv_end[i:j], out_excitation[k, i:j], out_f_se[k, i:j], out_f_ce[k, i:j],
                out_activity[k, i:j], out_stimulation[k, i:j], out_components[k, i:j],
                out_rates[k, i:j], out_power[k, i:j],
            )
            status[b] = i + first_bad if first_bad != 0 else 0
        for b in range(blocks):
            if status[b] != 0:
                return k * n + status[b]
        _copy(out_length[k], x_state)
        _copy(out_velocity[k], xdot_state)
        if snapshot_every > 0 and (k + 1) % snapshot_every == 0:
            j = (k + 1) // snapshot_every - 1
            _copy(snap_effective_drive[j], effective_drive)
            _copy(snap_f_int[j], f_int)
            _copy(snap_f_eff[j], f_eff)
            _copy(snap_sag[j], sag)
            _copy(snap_yield_factor[j], yield_factor)
            _copy(snap_x_state[j], x_state)
            _copy(snap_xdot_state[j], xdot_state)
            _copy(snap_recovery_filter[j], recovery_filter)
            _copy(snap_energy[j], energy)
            _copy(snap_work[j], work)
    return 0


def _renamed(function, name: str):
    """A copy of ``function`` under another name (Numba caches each compiled copy by name)."""
    code = function.__code__.replace(co_name=name, co_qualname=name)
    copy = types.FunctionType(code, function.__globals__, name, function.__defaults__,
                              function.__closure__)
    copy.__qualname__, copy.__module__, copy.__doc__ = name, function.__module__, function.__doc__
    return copy


# LLVM may contract a*b + c into fused multiply-adds, reassociate and use reciprocals; NaN and
# infinity keep their IEEE meaning (the input checks rely on them). Results differ from the NumPy
# step by rounding, which the stiff fascicle dynamics carry on (test_kernel: measured at most 4e-6
# of the largest velocity, 7e-9 of force; held to 1e-5 of each field's scale).
FASTMATH = {"nsz", "arcp", "contract", "afn", "reassoc"}
_advance_step = jitable(_advance)
prange = range
advance_series = advance_series_parallel = None
if HAVE_NUMBA:
    prange = numba.prange
    with model_cache_directory():
        _options = {"cache": True, "nogil": True, "error_model": "numpy", "fastmath": FASTMATH}
        advance_series = numba.njit(**_options)(_advance_series)
        advance_series_parallel = numba.njit(parallel=True, **_options)(
            _renamed(_advance_series, "_advance_series_parallel"))
AVAILABLE = advance_series is not None

# The parallel switch (CompiledStep(parallel=...), or this environment variable) and the bank
# size below which the step stays serial even when it is on. Measured on 2 idle cores (step,
# serial / parallel): 1.06x at 16 muscles, 1.43x at 64, 1.6x at 128-256, 1.8-2.0x at 1000-10000;
# with the other core busy it loses (0.4-0.8x), hence off by default.
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


def warm_up(parallel: bool = False) -> None:
    """Compile the kernel (step and run share it) or load it from Numba's disk cache now rather
    than in the first step: about 5 s the first time on a machine, 0.3 s after; with
    ``parallel`` its parallel build too."""
    if not AVAILABLE:
        return
    for wanted, function in ((True, advance_series), (parallel, advance_series_parallel)):
        if wanted and not function.signatures:
            function(*layout.dummy_arguments(LUMPED))


__all__ = [
    "AVAILABLE",
    "PARALLEL_ENV",
    "PARALLEL_MIN_MUSCLES",
    "advance_series",
    "advance_series_parallel",
    "parallel_chunk",
    "parallel_wanted",
    "warm_up",
]
