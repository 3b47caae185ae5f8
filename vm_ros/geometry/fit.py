"""Fitting path-length polynomials to sampled lengths and gradients (used by the importers).

Least squares on stacked rows [L; dL/dq] (lengths and their gradients in scaled coordinates, so
that both kinds of row weigh alike): the polynomial then reproduces the source model's moment
arms (r = -dL/dq) as well as its lengths. Errors are reported on held-out poses.
"""

from __future__ import annotations

import numpy as np

from vm_ros.errors import VmRosError
from vm_ros.geometry.paths import FitReport, MusclePath
from vm_ros.geometry.polynomial import monomial_gradients, monomials, total_degree_exponents


def scaling(lower, upper) -> tuple[np.ndarray, np.ndarray]:
    """offset and scale that map the box [lower, upper] onto [-1, 1]."""
    lower, upper = np.asarray(lower, dtype=float), np.asarray(upper, dtype=float)
    return (upper + lower) / 2.0, (upper - lower) / 2.0


def solve_coefficients(q, length, gradient, exponents, offset, scale) -> np.ndarray:
    """Coefficients minimising sum (L - L_fit)^2 + sum (scale_j * (dL/dq_j - dL_fit/dq_j))^2.

    q (P, k), length (P,), gradient (P, k) dL/dq; returns (n_terms,) coefficients.
    """
    x = (np.asarray(q, dtype=float) - offset) / scale
    rows_length = monomials(x, exponents)                                  # (P, T)
    rows_gradient = monomial_gradients(x, exponents)                       # (P, T, k) d/dx
    k = exponents.shape[1]
    a = np.vstack([rows_length] + [rows_gradient[:, :, j] for j in range(k)])
    b = np.concatenate([np.asarray(length, float)]
                       + [np.asarray(gradient, float)[:, j] * scale[j] for j in range(k)])
    column_norm = np.linalg.norm(a, axis=0)
    column_norm[column_norm == 0] = 1.0
    solution, *_ = np.linalg.lstsq(a / column_norm, b, rcond=None)
    return solution / column_norm


def evaluate_path(path: MusclePath, q) -> tuple[np.ndarray, np.ndarray]:
    """(L (P,), dL/dq (P, k)) of one path at poses q (P, k) of its own coordinates."""
    scale = np.asarray(path.scale, dtype=float)
    x = (np.asarray(q, dtype=float) - np.asarray(path.offset, dtype=float)) / scale
    length = monomials(x, path.exponents) @ path.coefficients
    gradient = np.einsum("ptk,t->pk", monomial_gradients(x, path.exponents),
                         path.coefficients) / scale
    return length, gradient


def errors(path: MusclePath, q, length, gradient) -> tuple[float, float, float, float]:
    """(length RMS, length max, moment-arm RMS, moment-arm max) of a path against samples (m)."""
    fitted_length, fitted_gradient = evaluate_path(path, q)
    dl = fitted_length - np.asarray(length, float)
    dr = (fitted_gradient - np.asarray(gradient, float)).ravel()
    return (float(np.sqrt(np.mean(dl ** 2))), float(np.max(np.abs(dl))),
            float(np.sqrt(np.mean(dr ** 2))), float(np.max(np.abs(dr))))


def fit_path(name: str, coordinates, lower, upper, q_fit, length_fit, gradient_fit,
             q_test, length_test, gradient_test, degrees=(2, 3, 4, 5, 6),
             length_tolerance_m: float = 2e-5, flags=()) -> MusclePath:
    """Fit one muscle: the lowest degree in ``degrees`` whose held-out length RMS is within
    ``length_tolerance_m`` (else the degree with the smallest held-out length RMS). The fit report
    gives the held-out errors of the chosen polynomial."""
    if len(q_fit) == 0 or len(q_test) == 0:
        raise VmRosError(f"muscle {name!r}: no valid poses to fit ({len(q_fit)}) or to check "
                         f"the fit ({len(q_test)}): the source model's path could not be "
                         "evaluated there")
    offset, scale = scaling(lower, upper)
    k = len(coordinates)
    best = None
    for degree in degrees:
        exponents = total_degree_exponents(k, degree)
        if exponents.shape[0] > len(q_fit) * (k + 1):
            break  # more terms than equations
        coefficients = solve_coefficients(q_fit, length_fit, gradient_fit, exponents,
                                          offset, scale)
        path = MusclePath(name, tuple(coordinates), tuple(offset), tuple(scale), exponents,
                          coefficients)
        err = errors(path, q_test, length_test, gradient_test)
        if best is None or err[0] < best[1][0]:
            best = (path, err)
        if err[0] <= length_tolerance_m:
            best = (path, err)
            break
    path, err = best
    report = FitReport(*err, poses_fit=len(q_fit), poses_held_out=len(q_test),
                       flags=tuple(flags))
    return MusclePath(path.name, path.coordinates, path.offset, path.scale, path.exponents,
                      path.coefficients, report)


__all__ = ["errors", "evaluate_path", "fit_path", "scaling", "solve_coefficients"]
