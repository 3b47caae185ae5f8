"""Compiled polynomial evaluator (Numba, optional): the sums of
``vm_ros.geometry.polynomial.evaluate_packed``, on the same packed arrays.

Muscles that cross at most SLOTS coordinates (every muscle of the myo-sim and OpenSim models
imported so far) are evaluated with the slots written out: the table of x_j ** p of a muscle's
slots, then one pass over its terms with the factors, the products of the other factors (by
prefix and suffix) and the sums over the terms (``term4``, ``term3``). One pose (``evaluate``)
takes the muscles with the same exponent rows side by side (a group: the imports' polynomials
are total-degree bases, so myolegs' 80 muscles make 9 groups), every term of the group for
each of its muscles in an inner loop that LLVM vectorises; many poses (``evaluate_many``) take
a muscle at a time with the poses side by side. Wider geometries take the loop over slots
(``evaluate_wide``). All take every product and sum of a muscle in the same order (the slots of
a narrower muscle padded with x ** 0 = 1, its terms in order), so they give the same bits;
test_geometry holds them equal.

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
# evaluate's groups (docs/performance.md): muscles with the same table of exponents, up to LANES
# side by side, their tables of powers in stack buffers for polynomials of degree <= GROUP_DEGREE
# (higher degrees: evaluate_many at the one pose, the same numbers)
LANES = 64
GROUP_DEGREE = 8

_evaluate = None
# the compiled one-pose evaluator, which evaluate_inside calls, and the terms of a muscle crossing
# 4 and at most 3 coordinates, which both evaluators call: module globals, not closure
# variables, since Numba keys a cached function by its closure's pickled contents, and a
# dispatcher pickles differently in every process (each would compile them again)
_evaluate_pose = _term4 = _term3 = None


def available() -> bool:
    return HAVE_NUMBA


def _stack_buffer(size: int):
    """A compiled function () -> a pointer to ``size`` float64 on the caller's stack (an
    alloca: LLVM knows it overlaps no argument and no other buffer)."""
    from numba.core import cgutils, types
    from numba.extending import intrinsic

    @intrinsic
    def buffer(typingctx):
        def codegen(context, builder, signature, args):
            return cgutils.alloca_once(builder, context.get_value_type(types.float64), size=size)

        return types.CPointer(types.float64)(), codegen

    return buffer


if HAVE_NUMBA:
    _powers_buffer = _stack_buffer(SLOTS * (GROUP_DEGREE + 1) * LANES)
    _sums_buffer = _stack_buffer((SLOTS + 1) * LANES)


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

        @numba.njit(cache=True, fastmath=False, error_model="numpy", boundscheck=False,
                    inline="always")
        def term4(sums, k, powers, c, a0, a1, a2, a3, e0, e1, e2, e3, b0, b1, b2, b3):
            """Adds a term c x0^e0 x1^e1 x2^e2 x3^e3 of a muscle crossing 4 coordinates to
            column k of ``sums`` (its value, then its derivative by each x_j without the slot's
            scale; 0 where e_j = 0), from its factors f_j = x_j^e_j = powers[a_j, k] and
            slopes p_j = x_j^(e_j - 1) = powers[b_j, k]."""
            f0, f1, f2, f3 = powers[a0, k], powers[a1, k], powers[a2, k], powers[a3, k]
            p0, p1, p2, p3 = powers[b0, k], powers[b1, k], powers[b2, k], powers[b3, k]
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
            sums[0, k] += o3 * f3
            sums[1, k] += v0 if e0 > 0.0 else 0.0
            sums[2, k] += v1 if e1 > 0.0 else 0.0
            sums[3, k] += v2 if e2 > 0.0 else 0.0
            sums[4, k] += v3 if e3 > 0.0 else 0.0

        @numba.njit(cache=True, fastmath=False, error_model="numpy", boundscheck=False,
                    inline="always")
        def term3(sums, k, powers, c, a0, a1, a2, e0, e1, e2, b0, b1, b2):
            """term4 of a muscle crossing at most 3 coordinates (slot 3 padding: f3 = 1,
            e3 = 0), with the products by f3 = 1 and s2 = 1 left out: the same bits."""
            f0, f1, f2 = powers[a0, k], powers[a1, k], powers[a2, k]
            p0, p1, p2 = powers[b0, k], powers[b1, k], powers[b2, k]
            o0 = c
            o1 = o0 * f0
            o2 = o1 * f1
            o3 = o2 * f2
            s1 = f2
            s0 = s1 * f1
            v2 = o2 * e2 * p2
            v1 = o1 * s1 * e1 * p1
            v0 = o0 * s0 * e0 * p0
            sums[0, k] += o3
            sums[1, k] += v0 if e0 > 0.0 else 0.0
            sums[2, k] += v1 if e1 > 0.0 else 0.0
            sums[3, k] += v2 if e2 > 0.0 else 0.0

        _term4, _term3 = term4, term3

        @numba.njit(cache=True, fastmath=False, error_model="numpy", boundscheck=False)
        def evaluate(q, slot_coordinate, slot_offset, slot_scale, member, group, factor_index,
                     slope_index, exponent, coefficient, max_degree):
            """L and dL/dq at q, from _slot_arrays' tables: a group's muscles (up to LANES)
            side by side, their tables of powers (row: a power, column: a muscle) and sums,
            each of the group's terms for every muscle of the group in an inner loop over the
            muscles (vectorised: the same operations per muscle, in the same order). The
            tables and sums are stack buffers, which LLVM knows overlap no argument (with
            heap arrays it tests the term's rows against the sums before every term)."""
            n = slot_coordinate.shape[0]
            n_q = q.shape[0]
            row = max_degree + 1
            length = np.zeros(n)
            gradient = np.zeros((n, n_q))
            powers = numba.carray(_powers_buffer(), (SLOTS * (GROUP_DEGREE + 1), LANES))
            sums = numba.carray(_sums_buffer(), (SLOTS + 1, LANES))  # L, then dL/dx_j
            base = 0  # the group's first coefficient (term by term, a muscle at a time)
            for g in range(group.shape[0] - 1):
                first, lanes = group[g, 0], group[g + 1, 0] - group[g, 0]
                for j in range(SLOTS):
                    for k in range(lanes):
                        m = member[first + k]
                        c = slot_coordinate[m, j]
                        x = 0.0 if c >= n_q else (q[c] - slot_offset[m, j]) / slot_scale[m, j]
                        powers[j * row, k] = 1.0
                        for p in range(1, row):
                            powers[j * row + p, k] = powers[j * row + p - 1, k] * x
                sums[:, :lanes] = 0.0
                if slot_coordinate[member[first], SLOTS - 1] < n_q:  # crosses 4 coordinates
                    for t in range(group[g, 1], group[g + 1, 1]):
                        a0, a1, a2, a3 = factor_index[t]
                        b0, b1, b2, b3 = slope_index[t]
                        e0, e1, e2, e3 = exponent[t]
                        for k in range(lanes):
                            _term4(sums, k, powers, coefficient[base + k], a0, a1, a2, a3, e0,
                                   e1, e2, e3, b0, b1, b2, b3)
                        base += lanes
                else:
                    for t in range(group[g, 1], group[g + 1, 1]):
                        a0, a1, a2 = factor_index[t, 0], factor_index[t, 1], factor_index[t, 2]
                        b0, b1, b2 = slope_index[t, 0], slope_index[t, 1], slope_index[t, 2]
                        e0, e1, e2 = exponent[t, 0], exponent[t, 1], exponent[t, 2]
                        for k in range(lanes):
                            _term3(sums, k, powers, coefficient[base + k], a0, a1, a2, e0, e1,
                                   e2, b0, b1, b2)
                        base += lanes
                for k in range(lanes):
                    m = member[first + k]
                    length[m] = sums[0, k]
                    for j in range(SLOTS):
                        c = slot_coordinate[m, j]
                        if c < n_q:
                            gradient[m, c] += sums[j + 1, k] / slot_scale[m, j]
            return length, gradient

        _evaluate_pose = evaluate

        @numba.njit(cache=True, fastmath=False, error_model="numpy", boundscheck=False)
        def evaluate_many(poses, slot_coordinate, slot_offset, slot_scale, member, group,
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
                base = 0
                for g in range(group.shape[0] - 1):
                    first, lanes = group[g, 0], group[g + 1, 0] - group[g, 0]
                    for lane in range(lanes):
                        m = member[first + lane]
                        for j in range(SLOTS):
                            c = slot_coordinate[m, j]
                            for k in range(width):
                                x = 0.0 if c >= n_q else (
                                    poses[start + k, c] - slot_offset[m, j]) / slot_scale[m, j]
                                powers[j * row, k] = 1.0
                                for p in range(1, row):
                                    powers[j * row + p, k] = powers[j * row + p - 1, k] * x
                        sums[:, :width] = 0.0
                        at = base + lane  # the muscle's coefficient of the group's first term
                        if slot_coordinate[m, SLOTS - 1] < n_q:  # crosses 4 coordinates
                            for t in range(group[g, 1], group[g + 1, 1]):
                                # the term's numbers read before the loop over poses (in it,
                                # LLVM would read them again after every store to the sums)
                                c = coefficient[at]
                                at += lanes
                                a0, a1, a2, a3 = factor_index[t]
                                b0, b1, b2, b3 = slope_index[t]
                                e0, e1, e2, e3 = exponent[t]
                                for k in range(width):
                                    _term4(sums, k, powers, c, a0, a1, a2, a3, e0, e1, e2, e3,
                                           b0, b1, b2, b3)
                        else:
                            for t in range(group[g, 1], group[g + 1, 1]):
                                c = coefficient[at]
                                at += lanes
                                a0, a1, a2 = (factor_index[t, 0], factor_index[t, 1],
                                              factor_index[t, 2])
                                b0, b1, b2 = slope_index[t, 0], slope_index[t, 1], slope_index[t, 2]
                                e0, e1, e2 = exponent[t, 0], exponent[t, 1], exponent[t, 2]
                                for k in range(width):
                                    _term3(sums, k, powers, c, a0, a1, a2, e0, e1, e2, b0, b1,
                                           b2)
                        for k in range(width):
                            lengths[start + k, m] = sums[0, k]
                            for j in range(SLOTS):
                                c = slot_coordinate[m, j]
                                if c < n_q:
                                    gradients[start + k, m, c] += sums[j + 1, k] / slot_scale[m, j]
                    base += lanes * (group[g + 1, 1] - group[g, 1])
            return lengths, gradients

        @numba.njit(cache=True, fastmath=False, error_model="numpy")
        def evaluate_inside(q, qdot, lower, upper, slot_coordinate, slot_offset, slot_scale,
                            member, group, factor_index, slope_index, exponent, coefficient,
                            max_degree):
            for j in range(q.shape[0]):
                if not (lower[j] < q[j] < upper[j] and np.isfinite(qdot[j])):
                    return False, q[:0], np.empty((0, 0)), np.empty((0, 0)), q[:0], q[:0]
            length, gradient = _evaluate_pose(
                q, slot_coordinate, slot_offset, slot_scale, member, group, factor_index,
                slope_index, exponent, coefficient, max_degree)
            return True, length, gradient, -gradient, q.copy(), qdot.copy()

        @numba.njit(cache=True, fastmath=False, error_model="numpy")
        def evaluate_mapped(values, speeds, entries, sign, offset, moving, rows, lower, upper,
                            slot_coordinate, slot_offset, slot_scale, member, group,
                            factor_index, slope_index, exponent, coefficient, max_degree):
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
                q_used, slot_coordinate, slot_offset, slot_scale, member, group,
                factor_index, slope_index, exponent, coefficient, max_degree)
            arm = np.empty((rows.shape[0], n_q))
            for i in range(rows.shape[0]):
                for j in range(n_q):
                    arm[i, j] = -gradient[rows[i], j]
            return True, q, qdot, q_used, qdot_used, length, gradient, arm
    _evaluate = evaluate, evaluate_many, evaluate_inside, evaluate_wide, evaluate_mapped
    return _evaluate


def _slot_arrays(packed) -> tuple:
    """The arrays the compiled evaluators read, from ``packed`` (at most SLOTS slots; terms
    grouped by muscle, as PackedPolynomials.pack makes them), slots padded to SLOTS (coordinate
    n_q, x = 0, exponent 0): the slots' coordinates, offsets and scales; the muscles by group
    (muscles with the same exponent rows and padding, at most LANES to a group) and each
    group's first member and first term (and the ends); each of a group's terms' factor
    x_j ** e and slope x_j ** (e - 1) as indices into a muscle's table of powers (row j:
    x_j ** 0 ... x_j ** max_degree) and e as a float; the coefficients of a group term by term,
    its muscles side by side."""
    n, width = packed.slot_coordinate.shape
    pad = SLOTS - width
    row = packed.max_degree + 1
    if SLOTS * row > np.iinfo(np.uint16).max:
        raise ValueError(f"polynomial degree {packed.max_degree}: at most "
                         f"{np.iinfo(np.uint16).max // SLOTS - 1}")
    exponent = np.pad(packed.term_exponent, ((0, 0), (0, pad)))                      # (T, S)
    slot_coordinate = np.pad(packed.slot_coordinate, ((0, 0), (0, pad)),
                             constant_values=packed.n_coordinates).astype(np.int64)
    first = np.concatenate([[0], np.cumsum(np.bincount(packed.term_muscle, minlength=n))])
    groups: dict = {}
    for m in range(n):
        key = (exponent[first[m]:first[m + 1]].tobytes(), first[m + 1] - first[m],
               bool(slot_coordinate[m, -1] < packed.n_coordinates))
        groups.setdefault(key, []).append(m)
    chunks = [ms[i:i + LANES] for ms in groups.values() for i in range(0, len(ms), LANES)]
    terms = [np.arange(first[ms[0]], first[ms[0] + 1]) for ms in chunks]
    group = np.cumsum([[0, 0]] + [[len(ms), len(t)] for ms, t in zip(chunks, terms, strict=True)],
                      axis=0)
    rows = exponent[np.concatenate(terms)] if terms else exponent[:0]
    slot = np.arange(SLOTS) * row
    coefficient = [packed.term_coefficient[np.add.outer(first[ms], np.arange(len(t)))].T.ravel()
                   for ms, t in zip(chunks, terms, strict=True)]
    return (slot_coordinate,
            np.pad(packed.slot_offset, ((0, 0), (0, pad))).astype(np.float64),
            np.pad(packed.slot_scale, ((0, 0), (0, pad)), constant_values=1.0).astype(
                np.float64),
            np.array([m for ms in chunks for m in ms], dtype=np.int64),
            np.ascontiguousarray(group, dtype=np.int64),
            np.ascontiguousarray(slot + rows, dtype=np.uint16),  # unsigned: indexing
            np.ascontiguousarray(slot + np.maximum(rows - 1, 0), dtype=np.uint16),  # with
            # no test for negative indices (a third of the loop's instructions with int64)
            np.ascontiguousarray(rows, dtype=np.float64),
            np.ascontiguousarray(np.concatenate(coefficient) if coefficient else np.zeros(0),
                                 dtype=np.float64))


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

    if degree > GROUP_DEGREE:  # evaluate's stack buffers are too small: evaluate_many's numbers
        def run_one(q):
            lengths, gradients = evaluate_many(np.ascontiguousarray(q, dtype=np.float64)[None],
                                               *arrays, degree, POSE_BLOCK)
            return lengths[0], gradients[0]

        return run_one

    def run(q):
        return evaluate(np.ascontiguousarray(q, dtype=np.float64), *arrays, degree)

    return run


def _box_and_tables(packed, lower, upper) -> tuple | None:
    """The arguments the box-checking evaluators take after their own: the box (lower,
    upper), the slot tables and the degree; None for a geometry wider than SLOTS or of a degree
    above GROUP_DEGREE."""
    if packed.slot_coordinate.shape[1] > SLOTS or packed.max_degree > GROUP_DEGREE:
        return None
    return (np.array(lower, dtype=np.float64), np.array(upper, dtype=np.float64),
            *_slot_arrays(packed), packed.max_degree)


def compiled_inside_evaluator(packed, lower, upper):
    """A function (q, qdot) -> (inside, L, dL/dq, -dL/dq, copies of q and qdot) for float
    arrays of shape (n_q,): ``inside`` is False (and the rest placeholders) unless every
    coordinate lies strictly inside (lower, upper) and every velocity is finite, where clamping
    changes nothing; the numbers of ``compiled_evaluator``'s function, with the checks in one
    call. None for a geometry wider than SLOTS or of a degree above GROUP_DEGREE."""
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
    sums in its own order). One call for all of it. None for a geometry wider than SLOTS or of
    a degree above GROUP_DEGREE."""
    tail = _box_and_tables(packed, lower, upper)
    if tail is None:
        return None
    evaluate = _compile()[4]

    def run(values, speeds, entries, sign, offset, moving, rows):
        return evaluate(values, speeds, entries, sign, offset, moving, rows, *tail)

    return run


__all__ = ["SLOTS", "available", "compiled_evaluator", "compiled_inside_evaluator",
           "compiled_mapped_evaluator"]
