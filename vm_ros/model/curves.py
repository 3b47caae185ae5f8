"""Virtual Muscle's static curves: pure functions over NumPy arrays (any broadcastable shapes).

Units: L = fascicle length / L0; V = dL/dt in L0/s, **negative when shortening**; forces in F0;
firing rates in f0.5; L_SE = tendon length / L0T. Parameters are passed explicitly (arrays over
the fibre-type or unit axis broadcast against the state). Nothing here raises mid-step: divisions
are guarded and inputs clipped inside the arithmetic.

References: Brown, Cheng & Loeb 1999 (J Muscle Res Cell Motil 20:627); Cheng, Brown & Loeb 2000
(J Neurosci Methods 101:117); Tsianos, Rustin & Loeb 2012 (IEEE TNSRE 20:117).
"""

from __future__ import annotations

import numpy as np

from vm_ros.model.jit import exp, expm1, jitable, log1p, maximum, minimum, power, where
from vm_ros.model.layout import T


@jitable
def force_length_base(l_beta, omega):
    """z = (L^beta - 1) / omega of :func:`force_length_cheng2000`, from L^beta."""
    return (l_beta - 1.0) / omega


@jitable
def _force_length_parts(l, omega, beta, rho):
    """(L clipped at 0, L^beta, z, |z|^rho, FL) of :func:`force_length_cheng2000`."""
    l = np.maximum(l, 0.0)
    l_beta = power(l, beta)
    z = force_length_base(l_beta, omega)
    z_rho = power(np.abs(z), rho)
    return l, l_beta, z, z_rho, exp(-z_rho)


@jitable
def force_length_cheng2000(l, omega, beta, rho):
    """Active force-length relation.

    FL(L) = exp(-|(L^beta - 1) / omega|^rho)

    omega, beta, rho per fibre type (docs/model.md section 8). FL(1) = 1. L is clipped at 0.
    """
    return _force_length_parts(l, omega, beta, rho)[4]


@jitable
def force_length_and_slope_cheng2000(l, omega, beta, rho):
    """FL(L) (:func:`force_length_cheng2000`) and its slope dFL/dL, sharing the powers:

    z = (L^beta - 1) / omega,  FL = exp(-|z|^rho),
    dFL/dL = -FL rho (|z|^rho / z) beta L^beta / (L omega)      (0 at z = 0 and at L <= 0)
    """
    l, l_beta, z, z_rho, fl = _force_length_parts(l, omega, beta, rho)
    defined = (z != 0.0) & (l > 0.0)
    ratio = where(defined, z_rho / where(defined, z * l, 1.0), 0.0)
    return fl, -fl * rho * ratio * beta * l_beta / omega


@jitable
def force_velocity_cheng2000(v, l, vmax, cv0, cv1, av0, av1, av2, bv, denominator_min):
    """Active force-velocity relation (shortening V <= 0, lengthening V > 0).

    FV = (Vmax - V) / (Vmax + (cV0 + cV1 L) V)                    V <= 0
       = (bV - (aV0 + aV1 L + aV2 L^2) V) / (bV + V)               V > 0

    FV(0, L) = 1. The shortening denominator is negative for physiological states; for fast
    fibres below L = 0.621 it can reach zero at high shortening speed, so it is held at or below
    ``-denominator_min * |Vmax|``.
    """
    v_short = np.minimum(v, 0.0)
    v_long = np.maximum(v, 0.0)
    denominator = np.minimum(vmax + (cv0 + cv1 * l) * v_short, -denominator_min * np.abs(vmax))
    shortening = (vmax - v_short) / denominator
    lengthening = (bv - (av0 + av1 * l + av2 * l * l) * v_long) / (bv + v_long)
    return where(v <= 0.0, shortening, lengthening)


@jitable
def force_velocity_slopes_cheng2000(v, l, vmax, cv0, cv1, av0, av1, av2, bv, denominator_min):
    """(dFV/dV, dFV/dL) of :func:`force_velocity_cheng2000` (the shortening branch at V = 0).

    shortening: D = Vmax + (cV0 + cV1 L) V,  dFV/dV = -(D + (Vmax - V)(cV0 + cV1 L)) / D^2,
                dFV/dL = -(Vmax - V) cV1 V / D^2   (D held at its bound: only -1/D in dFV/dV)
    lengthening: a = aV0 + aV1 L + aV2 L^2,  dFV/dV = -bV (a + 1) / (bV + V)^2,
                 dFV/dL = -(aV1 + 2 aV2 L) V / (bV + V)
    """
    v_short = np.minimum(v, 0.0)
    v_long = np.maximum(v, 0.0)
    slope_short = cv0 + cv1 * l
    free = vmax + slope_short * v_short
    bound = -denominator_min * np.abs(vmax)
    held = free > bound
    denominator = np.minimum(free, bound)
    dv_short = -(denominator + where(held, 0.0, (vmax - v_short) * slope_short)) / (
        denominator * denominator
    )
    dl_short = where(held, 0.0, -(vmax - v_short) * cv1 * v_short / (denominator * denominator))
    a = av0 + av1 * l + av2 * l * l
    dv_long = -bv * (a + 1.0) / ((bv + v_long) * (bv + v_long))
    dl_long = -(av1 + 2.0 * av2 * l) * v_long / (bv + v_long)
    lengthening = v > 0.0
    return where(lengthening, dv_long, dv_short), where(lengthening, dl_long, dl_short)


@jitable
def fibre_type_curves(l, v, ft, denominator_min):
    """(FL, FV) of a fibre type at (L, V): the Cheng 2000 relations above, their parameters read
    from ``ft`` by the fibre-type columns of vm_ros.model.layout.T.

    The one (L, V) -> per-type curve values mapping: the NumPy step, the compiled kernel, the
    published models' inputs and validation all call it (or
    :func:`fibre_type_curves_and_slopes`). ``ft``: the kernel's row of one type (a tuple of
    scalars), or vm_ros.model.layout.type_columns of FibreTypeParams (arrays over the fibre-type
    axis, broadcast against L and V). A new curve parameter is a column of T, a field of
    FibreTypeParams and its use here.
    """
    fl = force_length_cheng2000(l, ft[T.omega], ft[T.beta], ft[T.rho])
    fv = force_velocity_cheng2000(v, l, ft[T.vmax], ft[T.cv0], ft[T.cv1], ft[T.av0], ft[T.av1],
                                  ft[T.av2], ft[T.bv], denominator_min)
    return fl, fv


@jitable
def fibre_type_curves_and_slopes(l, v, ft, denominator_min):
    """:func:`fibre_type_curves` with the slopes: (FL, dFL/dL, FV, dFV/dV, dFV/dL)."""
    fl, dfl = force_length_and_slope_cheng2000(l, ft[T.omega], ft[T.beta], ft[T.rho])
    fv_args = (ft[T.vmax], ft[T.cv0], ft[T.cv1], ft[T.av0], ft[T.av1], ft[T.av2], ft[T.bv],
               denominator_min)
    fv = force_velocity_cheng2000(v, l, *fv_args)
    dfv_dv, dfv_dl = force_velocity_slopes_cheng2000(v, l, *fv_args)
    return fl, dfl, fv, dfv_dv, dfv_dl


@jitable
def logistic_from_exp(x, e):
    """1 / (1 + exp(-x)) given e = exp(-|x|), without overflow for large |x|."""
    return where(x >= 0.0, 1.0 / (1.0 + e), e / (1.0 + e))


@jitable
def softplus_from_exp(x, e):
    """ln(exp(x) + 1) = max(x, 0) + ln(1 + exp(-|x|)) given e = exp(-|x|), without overflow; its
    slope is :func:`logistic_from_exp` (x, e), so a force and its slope share one exp."""
    return np.maximum(x, 0.0) + log1p(e)


@jitable
def passive_parallel_elastic_argument(l, lmax, k1, lr1):
    """x = (L/Lmax - Lr1) / k1, the argument of FPE1's softplus."""
    return (l / lmax - lr1) / k1


@jitable
def passive_parallel_elastic_from_log(x, log_term, v, c1, k1, eta):
    """FPE1 (:func:`passive_parallel_elastic_cheng2000`) from its argument x and
    log_term = ln(1 + exp(-|x|)): c1 k1 (max(x, 0) + log_term) + eta V."""
    return c1 * k1 * (maximum(x, 0.0) + log_term) + eta * v


@jitable
def passive_parallel_elastic_cheng2000(l, v, lmax, c1, k1, lr1, eta):
    """PE1, the parallel elastic element with its viscosity (F0).

    FPE1(L, V) = c1 k1 ln(exp((L/Lmax - Lr1)/k1) + 1) + eta V

    Lmax: fascicle length (L0) at the maximum anatomical path length.
    """
    x = passive_parallel_elastic_argument(l, lmax, k1, lr1)
    return passive_parallel_elastic_from_log(x, log1p(exp(-np.abs(x))), v, c1, k1, eta)


@jitable
def passive_parallel_elastic_and_slope_cheng2000(l, v, lmax, c1, k1, lr1, eta):
    """(FPE1, dFPE1/dL) of :func:`passive_parallel_elastic_cheng2000`, sharing one exp:
    dFPE1/dL = c1 logistic((L/Lmax - Lr1)/k1) / Lmax (dFPE1/dV is eta)."""
    x = passive_parallel_elastic_argument(l, lmax, k1, lr1)
    e = exp(-np.abs(x))
    return c1 * k1 * softplus_from_exp(x, e) + eta * v, c1 * logistic_from_exp(x, e) / lmax


@jitable
def thick_filament_compression_cheng2000(l, c2, k2, lr2):
    """PE2, compression of thick filaments at short lengths (F0, <= 0).

    FPE2(L) = min(0, c2 (exp(k2 (L - Lr2)) - 1))

    Human rescaling k2 = -21, Lr2 = 0.70 (Tsianos 2012); VM's cat set is -18.7, 0.79.
    """
    return thick_filament_compression_from_expm1(
        expm1(thick_filament_compression_exponent(l, k2, lr2)), c2)


@jitable
def thick_filament_compression_exponent(l, k2, lr2):
    """k2 (L - Lr2), capped at 50: the argument of FPE2's expm1."""
    return minimum(k2 * (l - lr2), 50.0)


@jitable
def thick_filament_compression_from_expm1(excess, c2):
    """FPE2 (:func:`thick_filament_compression_cheng2000`) from excess = expm1(k2 (L - Lr2))
    (capped): min(0, c2 excess)."""
    return minimum(0.0, c2 * excess)


@jitable
def thick_filament_compression_and_slope_cheng2000(l, c2, k2, lr2):
    """(FPE2, dFPE2/dL) of :func:`thick_filament_compression_cheng2000`, sharing one expm1
    (exp = expm1 + 1): dFPE2/dL = c2 k2 exp(k2 (L - Lr2)) where FPE2 < 0 and the exponent is
    below its cap; else 0."""
    exponent = k2 * (l - lr2)
    excess = expm1(np.minimum(exponent, 50.0))
    active = (c2 * excess < 0.0) & (exponent < 50.0)
    return np.minimum(0.0, c2 * excess), where(active, c2 * k2 * (excess + 1.0), 0.0)


@jitable
def tendon_force_cheng2000(l_se, ct, kt, lrt):
    """Series elastic element (tendon and aponeurosis) force (F0).

    F_SE(L_SE) = cT kT ln(exp((L_SE - LrT)/kT) + 1),   L_SE = tendon length / L0T

    cT = 27.8, kT = 0.0047, LrT = 0.964: F_SE(1.0) = 1.0 F0 (L0T is the length at F0).
    """
    x = (l_se - lrt) / kt
    return ct * kt * softplus_from_exp(x, exp(-np.abs(x)))


@jitable
def tendon_force_and_stiffness_cheng2000(l_se, ct, kt, lrt):
    """(F_SE, dF_SE/dL_SE) of :func:`tendon_force_cheng2000`, sharing one exp: the stiffness is
    cT logistic((L_SE - LrT)/kT)."""
    x = (l_se - lrt) / kt
    e = exp(-np.abs(x))
    return ct * kt * softplus_from_exp(x, e), ct * logistic_from_exp(x, e)


def tendon_length_at_force(force, ct, kt, lrt):
    """Inverse of :func:`tendon_force_cheng2000`: L_SE (L0T) at which the tendon carries ``force``.

    L_SE = kT ln(exp(F/(cT kT)) - 1) + LrT, for F > 0.
    """
    z = np.asarray(force) / (ct * kt)
    # ln(exp(z) - 1) = z + ln(1 - exp(-z)), stable for large z
    return kt * (z + np.log(-np.expm1(-z))) + lrt


@jitable
def activation_frequency_brown1999(f_eff, l, yield_factor, sag_factor, af, nf0, nf1):
    """Activation-frequency relation Af (fraction of tetanic force at that rate).

    nf = nf0 + nf1 (1/L - 1)
    Af = 1 - exp(-((Y S f_eff) / (af nf))^nf)

    Y = 1 for fast fibres, S = 1 for slow fibres (neutral parameters). Af(f_eff=1, L=1) = 0.509.
    The caller clamps L below nf1/(nf1 - nf0), where nf reaches 0.
    """
    nf = nf0 + nf1 * (1.0 / l - 1.0)
    drive = np.maximum(yield_factor * sag_factor * f_eff, 0.0) / (af * nf)
    return -expm1(-power(drive, nf))
