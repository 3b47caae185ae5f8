"""Compiled polynomial evaluator (Numba, optional): the sums of
``vm_ros.geometry.polynomial.evaluate_packed``, on the same packed arrays.

Muscles that cross at most SLOTS coordinates (every muscle of the myo-sim and OpenSim models
imported so far) are evaluated with the slots written out: a muscle at a time, the table of
x_j ** p of its slots, then one loop over its terms with the factors, the products of the other
factors (by prefix and suffix) and the sums over the terms in registers. Wider geometries take
the loop over slots (``evaluate_wide``). Both take every product and sum in the same order (the
slots of a narrower muscle padded with x ** 0 = 1, its terms in order), so they give the same
bits; test_geometry holds them equal.

Without Numba (not installed, or VM_ROS_NUMBA=0) ``available()`` is False and PolynomialGeometry
uses the NumPy evaluator; test_geometry holds the two equal to rounding.
"""

from __future__ import annotations

import numpy as np

from vm_ros.model.jit import HAVE_NUMBA, model_cache_directory, numba

SLOTS = 4  # coordinates per muscle written out in the compiled loop (docs/performance.md)
# poses evaluate_many takes together (docs/performance.md): passed as an argument, since with a
# trip count known when compiling LLVM unrolls the loop over them instead of vectorising it
POSE_BLOCK = 64

_evaluate = None
# the compiled one-pose evaluator, which evaluate_inside calls, and the terms of a muscle crossing
# 4 and at most 3 coordinates, which both evaluators call: module globals, not closure
# variables, since Numba keys a cached function by its closure's pickled contents, and a
# dispatcher pickles differently in every process (each would compile them again)
_evaluate_pose = _term4 = _term3 = None


def available() -> bool:
    return HAVE_NUMBA


def _compile():
    global _evaluate, _evaluate_pose, _term4, _term3
    if _evaluate is not None:
        return _evaluate
    with model_cache_directory():  # vm_ros.model.jit.cache_root()/<hash>/geometry

        @numba.njit(cache=True, fastmath=False, error_model="numpy")
        def evaluate_wide(q, slot_coordinate, slot_offset, slot_scale, term_muscle,
                          term_exponent, term_coefficient, max_degree):
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

        @numba.njit(cache=True, fastmath=False, error_model="numpy", inline="always")
        def term4(c, f0, f1, f2, f3, e0, e1, e2, e3, p0, p1, p2, p3):
            """A term c x0^e0 x1^e1 x2^e2 x3^e3 of a muscle crossing 4 coordinates, from its
            factors f_j = x_j^e_j and slopes p_j = x_j^(e_j - 1): (its value, its derivative
            by each x_j without the slot's scale; 0 where e_j = 0)."""
            o0 = c        # o_j: the coefficient times the factors before j
            o1 = o0 * f0
            o2 = o1 * f1
            o3 = o2 * f2
            s2 = 1.0 * f3  # s_j: the product of the factors after j
            s1 = s2 * f2
            s0 = s1 * f1
            v3 = o3 * 1.0 * e3 * p3
            v2 = o2 * s2 * e2 * p2
            v1 = o1 * s1 * e1 * p1
            v0 = o0 * s0 * e0 * p0
            return (o3 * f3, v0 if e0 > 0.0 else 0.0, v1 if e1 > 0.0 else 0.0,
                    v2 if e2 > 0.0 else 0.0, v3 if e3 > 0.0 else 0.0)

        @numba.njit(cache=True, fastmath=False, error_model="numpy", inline="always")
        def term3(c, f0, f1, f2, e0, e1, e2, p0, p1, p2):
            """term4 of a muscle crossing at most 3 coordinates (slot 3 padding: f3 = 1,
            e3 = 0), with the products by f3 = 1 and s2 = 1 left out: the same bits."""
            o0 = c
            o1 = o0 * f0
            o2 = o1 * f1
            o3 = o2 * f2
            s1 = f2
            s0 = s1 * f1
            v2 = o2 * e2 * p2
            v1 = o1 * s1 * e1 * p1
            v0 = o0 * s0 * e0 * p0
            return (o3, v0 if e0 > 0.0 else 0.0, v1 if e1 > 0.0 else 0.0,
                    v2 if e2 > 0.0 else 0.0)

        _term4, _term3 = term4, term3

        @numba.njit(cache=True, fastmath=False, error_model="numpy", boundscheck=False)
        def evaluate(q, slot_coordinate, slot_offset, slot_scale, first_term, factor_index,
                     slope_index, exponent, coefficient, max_degree):
            """factor_index, slope_index, exponent: (T, SLOTS), see _slot_arrays."""
            n = slot_coordinate.shape[0]
            n_q = q.shape[0]
            row = max_degree + 1
            length = np.zeros(n)
            gradient = np.zeros((n, n_q))
            powers = np.empty(SLOTS * row)
            for m in range(n):
                for j in range(SLOTS):
                    c = slot_coordinate[m, j]
                    x = 0.0 if c >= n_q else (q[c] - slot_offset[m, j]) / slot_scale[m, j]
                    powers[j * row] = 1.0
                    for p in range(1, row):
                        powers[j * row + p] = powers[j * row + p - 1] * x
                total = d0 = d1 = d2 = d3 = 0.0
                if slot_coordinate[m, SLOTS - 1] < n_q:  # crosses 4 coordinates
                    for t in range(first_term[m], first_term[m + 1]):
                        a, b, e = factor_index[t], slope_index[t], exponent[t]
                        value, v0, v1, v2, v3 = _term4(
                            coefficient[t], powers[a[0]], powers[a[1]], powers[a[2]],
                            powers[a[3]], e[0], e[1], e[2], e[3], powers[b[0]], powers[b[1]],
                            powers[b[2]], powers[b[3]])
                        total += value
                        d0 += v0
                        d1 += v1
                        d2 += v2
                        d3 += v3
                else:
                    for t in range(first_term[m], first_term[m + 1]):
                        a, b, e = factor_index[t], slope_index[t], exponent[t]
                        value, v0, v1, v2 = _term3(
                            coefficient[t], powers[a[0]], powers[a[1]], powers[a[2]], e[0],
                            e[1], e[2], powers[b[0]], powers[b[1]], powers[b[2]])
                        total += value
                        d0 += v0
                        d1 += v1
                        d2 += v2
                length[m] = total
                for j, d in enumerate((d0, d1, d2, d3)):
                    c = slot_coordinate[m, j]
                    if c < n_q:
                        gradient[m, c] += d / slot_scale[m, j]
            return length, gradient

        _evaluate_pose = evaluate

        @numba.njit(cache=True, fastmath=False, error_model="numpy", boundscheck=False)
        def evaluate_many(poses, slot_coordinate, slot_offset, slot_scale, first_term,
                          factor_index, slope_index, exponent, coefficient, max_degree, block):
            """evaluate at each pose, ``block`` poses at a time: a muscle's tables of powers
            (row: a power, column: a pose) and sums for the block, and each term's factors,
            products and sums for every pose of the block in an inner loop over the poses
            (vectorised: the same operations per pose, in the same order)."""
            count, n_q = poses.shape
            n = slot_coordinate.shape[0]
            row = max_degree + 1
            lengths = np.zeros((count, n))
            gradients = np.zeros((count, n, n_q))
            powers = np.empty((SLOTS * row, block))
            sums = np.empty((SLOTS + 1, block))  # the length, then dL/dx_j
            for start in range(0, count, block):
                width = min(block, count - start)
                for m in range(n):
                    for j in range(SLOTS):
                        c = slot_coordinate[m, j]
                        for k in range(width):
                            x = 0.0 if c >= n_q else (
                                poses[start + k, c] - slot_offset[m, j]) / slot_scale[m, j]
                            powers[j * row, k] = 1.0
                            for p in range(1, row):
                                powers[j * row + p, k] = powers[j * row + p - 1, k] * x
                    sums[:, :width] = 0.0
                    if slot_coordinate[m, SLOTS - 1] < n_q:  # crosses 4 coordinates
                        for t in range(first_term[m], first_term[m + 1]):
                            # the term's numbers read before the loop over poses (in it, LLVM
                            # would read them again after every store to the sums)
                            c = coefficient[t]
                            a0, a1, a2, a3 = factor_index[t]
                            b0, b1, b2, b3 = slope_index[t]
                            e0, e1, e2, e3 = exponent[t]
                            for k in range(width):
                                value, v0, v1, v2, v3 = _term4(
                                    c, powers[a0, k], powers[a1, k], powers[a2, k],
                                    powers[a3, k], e0, e1, e2, e3, powers[b0, k], powers[b1, k],
                                    powers[b2, k], powers[b3, k])
                                sums[0, k] += value
                                sums[1, k] += v0
                                sums[2, k] += v1
                                sums[3, k] += v2
                                sums[4, k] += v3
                    else:
                        for t in range(first_term[m], first_term[m + 1]):
                            c = coefficient[t]
                            a0, a1, a2 = factor_index[t, 0], factor_index[t, 1], factor_index[t, 2]
                            b0, b1, b2 = slope_index[t, 0], slope_index[t, 1], slope_index[t, 2]
                            e0, e1, e2 = exponent[t, 0], exponent[t, 1], exponent[t, 2]
                            for k in range(width):
                                value, v0, v1, v2 = _term3(
                                    c, powers[a0, k], powers[a1, k], powers[a2, k], e0, e1, e2,
                                    powers[b0, k], powers[b1, k], powers[b2, k])
                                sums[0, k] += value
                                sums[1, k] += v0
                                sums[2, k] += v1
                                sums[3, k] += v2
                    for k in range(width):
                        lengths[start + k, m] = sums[0, k]
                        for j in range(SLOTS):
                            c = slot_coordinate[m, j]
                            if c < n_q:
                                gradients[start + k, m, c] += sums[j + 1, k] / slot_scale[m, j]
            return lengths, gradients

        @numba.njit(cache=True, fastmath=False, error_model="numpy")
        def evaluate_inside(q, qdot, lower, upper, slot_coordinate, slot_offset, slot_scale,
                            first_term, factor_index, slope_index, exponent, coefficient,
                            max_degree):
            for j in range(q.shape[0]):
                if not (lower[j] < q[j] < upper[j] and np.isfinite(qdot[j])):
                    return False, q[:0], np.empty((0, 0)), np.empty((0, 0)), q[:0], q[:0]
            length, gradient = _evaluate_pose(
                q, slot_coordinate, slot_offset, slot_scale, first_term, factor_index,
                slope_index, exponent, coefficient, max_degree)
            return True, length, gradient, -gradient, q.copy(), qdot.copy()

        @numba.njit(cache=True, fastmath=False, error_model="numpy")
        def evaluate_mapped(values, speeds, entries, sign, offset, moving, rows, lower, upper,
                            slot_coordinate, slot_offset, slot_scale, first_term, factor_index,
                            slope_index, exponent, coefficient, max_degree):
            """compiled_mapped_evaluator's function (its docstring), with the packed arrays."""
            n_q = sign.shape[0]
            q, qdot, q_used = np.empty(n_q), np.empty(n_q), np.empty(n_q)
            qdot_used = np.zeros(n_q)
            for j in range(n_q):
                q[j] = sign[j] * values[entries[j]] + offset[j]
                qdot[j] = sign[j] * speeds[entries[j]]
                q_used[j] = q[j] + qdot[j] * 0.0  # received now, moved on for 0 s
                if moving:
                    qdot_used[j] = qdot[j]
            for j in range(n_q):
                if not (lower[j] < q_used[j] < upper[j] and np.isfinite(qdot[j])):
                    return (False, q, qdot, q_used, qdot_used, q[:0], np.empty((0, 0)),
                            np.empty((0, 0)))
            length, gradient = _evaluate_pose(
                q_used, slot_coordinate, slot_offset, slot_scale, first_term, factor_index,
                slope_index, exponent, coefficient, max_degree)
            arm = np.empty((rows.shape[0], n_q))
            for i in range(rows.shape[0]):
                for j in range(n_q):
                    arm[i, j] = -gradient[rows[i], j]
            return True, q, qdot, q_used, qdot_used, length, gradient, arm
    _evaluate = evaluate, evaluate_many, evaluate_inside, evaluate_wide, evaluate_mapped
    return _evaluate


def _slot_arrays(packed) -> tuple:
    """The arrays ``evaluate`` reads, from ``packed`` (at most SLOTS slots; terms grouped by
    muscle, as PackedPolynomials.pack makes them), slots padded to SLOTS (coordinate n_q,
    x = 0, exponent 0): the slots' coordinates, offsets and scales, each muscle's first term
    (and the end), each term's factor x_j ** e and slope x_j ** (e - 1) as indices into a
    muscle's table of powers (row j: x_j ** 0 ... x_j ** max_degree), and e as a float."""
    n, width = packed.slot_coordinate.shape
    pad = SLOTS - width
    row = packed.max_degree + 1
    if SLOTS * row > np.iinfo(np.uint16).max:
        raise ValueError(f"polynomial degree {packed.max_degree}: at most "
                         f"{np.iinfo(np.uint16).max // SLOTS - 1}")
    exponent = np.pad(packed.term_exponent, ((0, 0), (0, pad)))                      # (T, S)
    slot = np.arange(SLOTS) * row
    return (np.pad(packed.slot_coordinate, ((0, 0), (0, pad)),
                   constant_values=packed.n_coordinates).astype(np.int64),
            np.pad(packed.slot_offset, ((0, 0), (0, pad))).astype(np.float64),
            np.pad(packed.slot_scale, ((0, 0), (0, pad)), constant_values=1.0).astype(
                np.float64),
            np.concatenate([[0], np.cumsum(np.bincount(packed.term_muscle, minlength=n))]
                           ).astype(np.int64),
            np.ascontiguousarray(slot + exponent, dtype=np.uint16),  # unsigned: indexing
            np.ascontiguousarray(slot + np.maximum(exponent - 1, 0), dtype=np.uint16),  # with
            # no test for negative indices (a third of the loop's instructions with int64)
            np.ascontiguousarray(exponent, dtype=np.float64),
            np.ascontiguousarray(packed.term_coefficient, dtype=np.float64))


def _wide_arrays(packed) -> tuple:
    return (np.ascontiguousarray(packed.slot_coordinate),
            np.ascontiguousarray(packed.slot_offset), np.ascontiguousarray(packed.slot_scale),
            np.ascontiguousarray(packed.term_muscle),
            np.ascontiguousarray(packed.term_exponent),
            np.ascontiguousarray(packed.term_coefficient))


def compiled_evaluator(packed, many: bool = False):
    """A function q -> (L, dL/dq) over ``packed`` (terms must be grouped by muscle, as
    PackedPolynomials.pack makes them); with ``many``, poses (k, n_q) -> (L (k, n), dL/dq
    (k, n, n_q)), each pose's the same numbers as one call."""
    evaluate, evaluate_many, _, evaluate_wide, _ = _compile()
    degree = packed.max_degree
    if packed.slot_coordinate.shape[1] > SLOTS:
        arrays = _wide_arrays(packed)

        def run_wide(q):
            q = np.ascontiguousarray(q, dtype=np.float64)
            if not many:
                return evaluate_wide(q, *arrays, degree)
            out = [evaluate_wide(pose, *arrays, degree) for pose in q]
            return (np.array([o[0] for o in out]).reshape(len(q), packed.n_muscles),
                    np.array([o[1] for o in out]).reshape(len(q), packed.n_muscles, q.shape[1]))

        return run_wide
    arrays = _slot_arrays(packed)
    if many:
        def run_many(q):
            return evaluate_many(np.ascontiguousarray(q, dtype=np.float64), *arrays, degree,
                                 POSE_BLOCK)

        return run_many

    def run(q):
        return evaluate(np.ascontiguousarray(q, dtype=np.float64), *arrays, degree)

    return run


def _box_and_tables(packed, lower, upper) -> tuple | None:
    """The arguments the box-checking evaluators take after their own: the box (lower,
    upper), the slot tables and the degree; None for a geometry wider than SLOTS."""
    if packed.slot_coordinate.shape[1] > SLOTS:
        return None
    return (np.array(lower, dtype=np.float64), np.array(upper, dtype=np.float64),
            *_slot_arrays(packed), packed.max_degree)


def compiled_inside_evaluator(packed, lower, upper):
    """A function (q, qdot) -> (inside, L, dL/dq, -dL/dq, copies of q and qdot) for float
    arrays of shape (n_q,): ``inside`` is False (and the rest placeholders) unless every
    coordinate lies strictly inside (lower, upper) and every velocity is finite, where clamping
    changes nothing; the numbers of ``compiled_evaluator``'s function, with the checks in one
    call. None for a geometry wider than SLOTS."""
    tail = _box_and_tables(packed, lower, upper)
    if tail is None:
        return None
    evaluate = _compile()[2]

    def run(q, qdot):
        return evaluate(q, qdot, *tail)

    return run


def compiled_mapped_evaluator(packed, lower, upper):
    """A function (values, speeds, entries, sign, offset, moving, rows) -> (inside, q, q',
    q_used, q'_used, L, dL/dq, r of ``rows``) for a message's values (n,) and speeds (n,):
    q = sign * values[entries] + offset and q' = sign * speeds[entries] (each (n_q,), as
    vm_ros.joint_space.JointMap.to_model computes them), the pose q_used = q + q' * 0.0 (moved
    on for 0 s) and q'_used = q' (``moving``) or 0; ``inside`` is False (L, dL/dq and r empty)
    unless every q_used lies strictly inside (lower, upper) and every q' is finite, where
    clamping changes nothing. L and dL/dq are ``compiled_evaluator``'s numbers at q_used, r of
    ``rows`` is -dL/dq of those rows; the velocities, dL/dq @ q'_used, are left to NumPy (BLAS
    sums in its own order). One call for all of it. None for a geometry wider than SLOTS."""
    tail = _box_and_tables(packed, lower, upper)
    if tail is None:
        return None
    evaluate = _compile()[4]

    def run(values, speeds, entries, sign, offset, moving, rows):
        return evaluate(values, speeds, entries, sign, offset, moving, rows, *tail)

    return run


__all__ = ["SLOTS", "available", "compiled_evaluator", "compiled_inside_evaluator",
           "compiled_mapped_evaluator"]
