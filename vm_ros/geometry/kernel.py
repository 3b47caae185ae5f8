"""Compiled polynomial evaluator (Numba, optional): the sums of
``vm_ros.geometry.polynomial.evaluate_packed`` as one loop over terms, on the same packed arrays.

Without Numba (not installed, or VM_ROS_NUMBA=0) ``available()`` is False and PolynomialGeometry
uses the NumPy evaluator; test_geometry holds the two equal to rounding.
"""

from __future__ import annotations

import numpy as np

from vm_ros.model.jit import HAVE_NUMBA, model_cache_directory, numba

_evaluate = None


def available() -> bool:
    return HAVE_NUMBA


def _compile():
    global _evaluate
    if _evaluate is not None:
        return _evaluate
    with model_cache_directory():  # vm_ros.model.jit.cache_root()/<hash>/geometry

        @numba.njit(cache=True, fastmath=False, error_model="numpy")
        def evaluate(q, slot_coordinate, slot_offset, slot_scale, term_muscle, term_exponent,
                     term_coefficient, max_degree):
            n, width = slot_coordinate.shape
            n_q = q.shape[0]
            length = np.zeros(n)
            gradient = np.zeros((n, n_q))
            powers = np.ones((width, max_degree + 1))
            dl_dx = np.zeros(width)
            others = np.zeros(width)
            current = -1
            for t in range(term_muscle.shape[0]):
                m = term_muscle[t]
                if m != current:
                    if current >= 0:
                        for j in range(width):
                            c = slot_coordinate[current, j]
                            if c < n_q:
                                gradient[current, c] += dl_dx[j] / slot_scale[current, j]
                    current = m
                    for j in range(width):
                        dl_dx[j] = 0.0
                        c = slot_coordinate[m, j]
                        x = 0.0 if c >= n_q else (q[c] - slot_offset[m, j]) / slot_scale[m, j]
                        for p in range(1, max_degree + 1):
                            powers[j, p] = powers[j, p - 1] * x
                # factors of this term; products of the others by prefix and suffix
                prefix = term_coefficient[t]
                for j in range(width):
                    others[j] = prefix
                    prefix *= powers[j, term_exponent[t, j]]
                length[m] += prefix
                suffix = 1.0
                for j in range(width - 1, -1, -1):
                    e = term_exponent[t, j]
                    if e > 0:
                        dl_dx[j] += others[j] * suffix * e * powers[j, e - 1]
                    suffix *= powers[j, e]
            if current >= 0:
                for j in range(width):
                    c = slot_coordinate[current, j]
                    if c < n_q:
                        gradient[current, c] += dl_dx[j] / slot_scale[current, j]
            return length, gradient

        @numba.njit(cache=True, fastmath=False, error_model="numpy")
        def evaluate_many(poses, slot_coordinate, slot_offset, slot_scale, term_muscle,
                          term_exponent, term_coefficient, max_degree):
            lengths = np.zeros((poses.shape[0], slot_coordinate.shape[0]))
            gradients = np.zeros((poses.shape[0], slot_coordinate.shape[0], poses.shape[1]))
            for k in range(poses.shape[0]):
                lengths[k], gradients[k] = evaluate(
                    poses[k], slot_coordinate, slot_offset, slot_scale, term_muscle,
                    term_exponent, term_coefficient, max_degree)
            return lengths, gradients
    _evaluate = evaluate, evaluate_many
    return _evaluate


def compiled_evaluator(packed, many: bool = False):
    """A function q -> (L, dL/dq) over ``packed`` (terms must be grouped by muscle, as
    PackedPolynomials.pack makes them); with ``many``, poses (k, n_q) -> (L (k, n), dL/dq
    (k, n, n_q)), each pose's the same numbers as one call."""
    evaluate = _compile()[1 if many else 0]
    arrays = (np.ascontiguousarray(packed.slot_coordinate),
              np.ascontiguousarray(packed.slot_offset), np.ascontiguousarray(packed.slot_scale),
              np.ascontiguousarray(packed.term_muscle),
              np.ascontiguousarray(packed.term_exponent),
              np.ascontiguousarray(packed.term_coefficient))
    degree = packed.max_degree

    def run(q):
        return evaluate(np.ascontiguousarray(q, dtype=np.float64), *arrays, degree)

    return run


__all__ = ["available", "compiled_evaluator"]
