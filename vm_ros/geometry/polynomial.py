"""Multivariate polynomials of joint coordinates: the basis and its evaluation (pure NumPy).

A muscle's path length is a polynomial of the k coordinates it crosses, in scaled coordinates

    x_j = (q_j - offset_j) / scale_j,      L(q) = sum_t c_t * prod_j x_j ** e_tj,

with integer exponents e_t (one row per term). Its gradient is exact,

    dL/dq_j = (1 / scale_j) * sum_t c_t * e_tj * x_j ** (e_tj - 1) * prod_{i != j} x_i ** e_ti,

so the moment arm r = -dL/dq is the derivative of the evaluated polynomial itself, not a second fit.
The terms of every muscle are stacked into flat arrays (``PackedPolynomials``) so that one call
evaluates all muscles; the compiled loop in ``vm_ros.geometry.kernel`` reads the same arrays.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from itertools import combinations_with_replacement
from typing import NamedTuple

import numpy as np


def total_degree_exponents(n_coordinates: int, degree: int) -> np.ndarray:
    """Exponents of every monomial of total degree <= ``degree`` in ``n_coordinates`` variables.

    Shape (n_terms, n_coordinates), int; ordered by total degree, then lexicographically (the
    constant term first). n_terms = C(degree + n_coordinates, n_coordinates).
    """
    if n_coordinates < 1 or degree < 0:
        raise ValueError(f"need n_coordinates >= 1 and degree >= 0, got {n_coordinates}, {degree}")
    rows = []
    for total in range(degree + 1):
        for combo in combinations_with_replacement(range(n_coordinates), total):
            row = [0] * n_coordinates
            for j in combo:
                row[j] += 1
            rows.append(row)
    return np.array(rows, dtype=np.int64).reshape(-1, n_coordinates)


def monomials(x: np.ndarray, exponents: np.ndarray) -> np.ndarray:
    """Design matrix: each monomial at each point. x (P, k), exponents (T, k) -> (P, T)."""
    x = np.asarray(x, dtype=float)
    return np.prod(x[:, None, :] ** exponents[None, :, :], axis=2)


def monomial_gradients(x: np.ndarray, exponents: np.ndarray) -> np.ndarray:
    """d(monomial)/dx_j: x (P, k), exponents (T, k) -> (P, T, k).

    x_j ** (e - 1) is taken as 0 where e = 0 (the factor e makes the term 0 anyway), so points
    with x_j = 0 need no special case.
    """
    x = np.asarray(x, dtype=float)
    powers = x[:, None, :] ** exponents[None, :, :]                       # (P, T, k)
    lowered = np.where(exponents > 0, x[:, None, :] ** np.maximum(exponents - 1, 0), 0.0)
    out = np.empty(powers.shape)
    for j in range(exponents.shape[1]):
        others = np.delete(powers, j, axis=2).prod(axis=2) if exponents.shape[1] > 1 else 1.0
        out[:, :, j] = exponents[None, :, j] * lowered[:, :, j] * others
    return out


class _Lookup(NamedTuple):
    term_power: np.ndarray      # (K, T) index into powers (n, K, degree + 1), raveled
    first_term: np.ndarray      # (n,) index of each muscle's first term
    slot_cell: np.ndarray       # (n * K,) index into the gradient (n, n_q + 1), raveled


@dataclass(frozen=True)
class PackedPolynomials:
    """Every muscle's polynomial in flat arrays (built once; read by both evaluators).

    | field | shape | meaning |
    | --- | --- | --- |
    | slot_coordinate | (n_muscles, K) int | coordinate of each muscle's j-th variable (n_q: pad) |
    | slot_offset, slot_scale | (n_muscles, K) | x = (q - offset) / scale (padding: 0, 1) |
    | term_muscle | (T,) int | muscle of each term |
    | term_exponent | (T, K) int | exponents of the term over its muscle's slots |
    | term_coefficient | (T,) | coefficient (m per unit of the monomial) |

    K is the largest number of coordinates one muscle crosses; n_q the number of coordinates.
    """

    n_coordinates: int
    slot_coordinate: np.ndarray
    slot_offset: np.ndarray
    slot_scale: np.ndarray
    term_muscle: np.ndarray
    term_exponent: np.ndarray
    term_coefficient: np.ndarray

    @property
    def n_muscles(self) -> int:
        return self.slot_coordinate.shape[0]

    @cached_property
    def max_degree(self) -> int:
        return int(self.term_exponent.max(initial=0))

    @cached_property
    def lookup(self) -> _Lookup:
        """Flat indices that evaluate_packed gathers and scatters with (computed once)."""
        n, width = self.slot_coordinate.shape
        slots = self.term_muscle[None, :] * width + np.arange(width)[:, None]        # (K, T)
        counts = np.bincount(self.term_muscle, minlength=n)
        if np.any(counts == 0) or np.any(np.diff(self.term_muscle) < 0):
            raise ValueError("every muscle needs at least one term, terms grouped by muscle")
        return _Lookup(term_power=slots * (self.max_degree + 1) + self.term_exponent.T,
                       first_term=np.concatenate([[0], np.cumsum(counts)[:-1]]),
                       slot_cell=(np.arange(n)[:, None] * (self.n_coordinates + 1)
                                  + self.slot_coordinate).ravel())

    @classmethod
    def pack(cls, n_coordinates: int, muscles) -> PackedPolynomials:
        """muscles: iterable of (coordinate_indices, offset, scale, exponents, coefficients)."""
        muscles = list(muscles)
        width = max([len(m[0]) for m in muscles] + [1])
        n = len(muscles)
        slot_coordinate = np.full((n, width), n_coordinates, dtype=np.int64)
        slot_offset = np.zeros((n, width))
        slot_scale = np.ones((n, width))
        term_muscle, term_exponent, term_coefficient = [], [], []
        for i, (coords, offset, scale, exponents, coefficients) in enumerate(muscles):
            k = len(coords)
            slot_coordinate[i, :k] = coords
            slot_offset[i, :k] = offset
            slot_scale[i, :k] = scale
            exponents = np.asarray(exponents, dtype=np.int64).reshape(-1, k)
            padded = np.zeros((exponents.shape[0], width), dtype=np.int64)
            padded[:, :k] = exponents
            term_exponent.append(padded)
            term_coefficient.append(np.asarray(coefficients, dtype=float))
            term_muscle.append(np.full(exponents.shape[0], i, dtype=np.int64))
        return cls(n_coordinates, slot_coordinate, slot_offset, slot_scale,
                   np.concatenate(term_muscle) if term_muscle else np.zeros(0, np.int64),
                   np.concatenate(term_exponent) if term_exponent
                   else np.zeros((0, width), np.int64),
                   np.concatenate(term_coefficient) if term_coefficient else np.zeros(0))


def evaluate_packed(packed: PackedPolynomials, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Path lengths and their gradients for every muscle at coordinates q (n_q,).

    Returns (length (n_muscles,), dL/dq (n_muscles, n_q)). Vectorised over terms; the compiled
    evaluator (vm_ros.geometry.kernel) computes the same sums in a loop.
    """
    n, width = packed.slot_coordinate.shape
    degree = packed.max_degree
    index = packed.lookup
    q_padded = np.append(np.asarray(q, dtype=float), 0.0)
    x = (q_padded[packed.slot_coordinate] - packed.slot_offset) / packed.slot_scale   # (n, K)
    powers = np.ones((n, width, degree + 1))                                          # x ** p
    for p in range(1, degree + 1):
        powers[:, :, p] = powers[:, :, p - 1] * x
    slopes = np.zeros_like(powers)                                # d(x ** p)/dx = p x ** (p-1)
    slopes[:, :, 1:] = np.arange(1, degree + 1) * powers[:, :, :-1]
    factors = powers.ravel()[index.term_power]                                    # (K, T)
    # products of the other slots' factors: prefix times suffix products (no division)
    others = np.ones_like(factors)
    for j in range(1, width):
        others[j] = others[j - 1] * factors[j - 1]
    suffix = np.ones(factors.shape[1])
    for j in range(width - 2, -1, -1):
        suffix = suffix * factors[j + 1]
        others[j] *= suffix
    weighted = packed.term_coefficient * others                                       # (K, T)
    # sums over each muscle's terms (contiguous runs: one reduceat per sum)
    length = np.add.reduceat(weighted[0] * factors[0], index.first_term)
    dl_dx = np.add.reduceat(weighted * slopes.ravel()[index.term_power], index.first_term,
                            axis=1).T                                                  # (n, K)
    gradient = np.bincount(index.slot_cell, weights=(dl_dx / packed.slot_scale).ravel(),
                           minlength=n * (packed.n_coordinates + 1))
    return length, gradient.reshape(n, packed.n_coordinates + 1)[:, :packed.n_coordinates]


__all__ = ["PackedPolynomials", "evaluate_packed", "monomial_gradients", "monomials",
           "total_degree_exponents"]
