"""Roots of many scalar equations at once, each bracketed: Chandrupatla's method over arrays.

Each element keeps a bracket [x1, x2] with a sign change of f and a third point x3; the next
point is x1 + t (x2 - x1), with t from inverse quadratic interpolation through the three points
where it is safe (Chandrupatla's criterion: 1 - sqrt(1 - xi) < phi < sqrt(xi) with
xi = (x1 - x2)/(x3 - x2), phi = (f1 - f2)/(f3 - f2)), else 1/2 (bisection), and at least tol/2
away from the bracket's ends. An element stops when |x2 - x1| < xrtol |x| + xatol, at the end
with the smaller |f| (or at once where f is 0 or below the smallest normal float). ``func`` is
called on the elements still iterating only.

It is the algorithm of SciPy's ``scipy.optimize.elementwise.find_root`` (SciPy 1.15 and later),
with its convergence test, written here so that the model needs no more than SciPy 1.10 (Debian
12's python3-scipy is 1.10.1): test_roots.py holds it to ``scipy.optimize.brentq`` element by
element. The same problems give the same roots to the bit as SciPy 1.17's find_root (bank
equilibrium at 1 to 1000 muscles).

Reference: Chandrupatla, T. R. (1997) A new hybrid quadratic/bisection algorithm for finding the
zero of a nonlinear function without using derivatives. Adv Eng Softw 28:145-149.
"""

from __future__ import annotations

import numpy as np

# |f| at or below this is a root (SciPy's default fatol: the smallest normal float64)
F_TINY = np.finfo(float).smallest_normal
# Bisection alone halves the bracket each time: 1100 halvings span float64's whole range
MAX_ITERATIONS = 1100


def find_root(func, lower, upper, *, xatol: float, xrtol: float) -> np.ndarray:
    """The root of ``func(x, index)`` in [lower, upper] per element of the 1-d arrays ``lower``
    and ``upper``: ``func`` takes the points ``x`` (k,) of elements ``index`` (k,) (positions in
    ``lower``) and returns f (k,). NaN where f has the same sign at both ends, or where x or
    both f are not finite."""
    x1 = np.array(lower, dtype=float)
    x2 = np.array(upper, dtype=float)
    result = np.full(x1.shape, np.nan)
    index = np.arange(x1.size)
    f1, f2 = func(x1, index), func(x2, index)
    x3 = f3 = None  # the third point: none before the first step
    t = np.full(x1.shape, 0.5)
    for _ in range(MAX_ITERATIONS):
        nearer = np.abs(f1) < np.abs(f2)
        x_best = np.where(nearer, x1, x2)
        f_best = np.where(nearer, f1, f2)
        dx = np.abs(x2 - x1)
        tol = np.abs(x_best) * xrtol + xatol
        solved = np.abs(f_best) <= F_TINY
        failed = ~solved & ((np.sign(f1) == np.sign(f2)) | ~np.isfinite(x1 + x2)
                            | (np.isnan(f1) & np.isnan(f2)))
        solved |= ~failed & (dx < tol)
        result[index[solved]] = x_best[solved]
        going = ~(solved | failed)
        if not going.any():
            break
        x1, f1, x2, f2, dx, tol, t, index = (a[going] for a in (x1, f1, x2, f2, dx, tol, t,
                                                                 index))
        if x3 is not None:
            x3, f3 = x3[going], f3[going]
            t = _interpolation_step(x1, f1, x2, f2, x3, f3)
        limit = 0.5 * tol / dx
        t = np.clip(t, limit, 1.0 - limit)
        x = x1 + t * (x2 - x1)
        f = func(x, index)
        same = np.sign(f) == np.sign(f1)
        x3, f3 = np.where(same, x1, x2), np.where(same, f1, f2)
        x2, f2 = np.where(same, x2, x1), np.where(same, f2, f1)
        x1, f1 = x, f
    return result


def _interpolation_step(x1, f1, x2, f2, x3, f3):
    """t of the inverse quadratic through the three points where Chandrupatla's criterion holds,
    else 1/2."""
    with np.errstate(divide="ignore", invalid="ignore"):
        xi = (x1 - x2) / (x3 - x2)
        phi = (f1 - f2) / (f3 - f2)
        alpha = (x3 - x1) / (x2 - x1)
        quadratic = (1.0 - np.sqrt(1.0 - xi) < phi) & (phi < np.sqrt(xi))
        t = (f1 / (f1 - f2) * f3 / (f3 - f2) - alpha * f1 / (f3 - f1) * f2 / (f2 - f3))
    return np.where(quadratic, t, 0.5)


__all__ = ["F_TINY", "MAX_ITERATIONS", "find_root"]
