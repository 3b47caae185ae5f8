"""Joint space to muscle space and back: path lengths, velocities, moment arms, joint torques.

Sign conventions (they bite):

- q: independent joint coordinates (rad for rotational, m for translational), in the model's own
  convention (a robot's convention is mapped by the node's ``joint_map``).
- L: musculotendon path length (m); Ldot = dL/dt (m/s), positive when lengthening.
- r = -dL/dq, the geometric moment arm (m for rotational coordinates, m/m = dimensionless for
  translational ones): positive when a tension F > 0 drives q positive.
- tau = r^T F: generalized forces (N m or N) of muscle tensions F (N, positive in tension). Then
  sum(tau * qdot) = -sum(F * Ldot): joint power equals the power the muscles deliver.

Every coordinate has a valid box [lower, upper] (the range the path was fitted over). Coordinates
outside it are clamped to it, never extrapolated; a clamped coordinate's velocity is taken as 0,
so that L, Ldot and r stay consistent (L does not change while the coordinate is held at the
box) and the power identity above still holds with the velocities used. ``GeometryOutput.clamped``
says which coordinates were clamped; callers count and report them.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from vm_ros.errors import InputError
from vm_ros.geometry.polynomial import PackedPolynomials, evaluate_packed

UNITS = {"rad": "rotational", "m": "translational"}


@dataclass(frozen=True)
class Coordinate:
    """An independent joint coordinate: name, unit ('rad' or 'm') and valid box."""

    name: str
    unit: str
    lower: float
    upper: float

    def __post_init__(self):
        if self.unit not in UNITS:
            raise ValueError(f"coordinate {self.name!r}: unit {self.unit!r} is not one of "
                             f"{', '.join(UNITS)}")
        if not (np.isfinite(self.lower) and np.isfinite(self.upper) and self.lower < self.upper):
            raise ValueError(f"coordinate {self.name!r}: box [{self.lower}, {self.upper}] "
                             "is not a finite interval")


COUPLING_POINTS = 201   # samples of a coupling function over its driver's box (importers)


@dataclass(frozen=True)
class CoupledCoordinate:
    """A dependent coordinate of the source model (OpenSim coordinate coupler, MuJoCo joint
    equality): not an input. Its effect on every path is inside the fitted polynomials, which
    are functions of the independent coordinates only. ``follows`` names them; ``note`` says how
    the source model couples them.

    The coupling function, when the importer could store it (one driver): ``values`` (in
    ``unit``, rad or m) at ``follows_values`` (increasing, the driver's unit, over its box),
    linear in between (``value``); all three None when it is not stored."""

    name: str
    follows: tuple[str, ...]
    note: str = ""
    unit: str | None = None
    follows_values: tuple[float, ...] | None = None
    values: tuple[float, ...] | None = None

    def __post_init__(self):
        table = (self.unit, self.follows_values, self.values)
        if all(v is None for v in table):
            return
        x = np.asarray(self.follows_values if self.follows_values is not None else [], float)
        y = np.asarray(self.values if self.values is not None else [], float)
        if self.unit not in UNITS:
            raise ValueError(f"coupled coordinate {self.name!r}: unit {self.unit!r} is not one "
                             f"of {', '.join(UNITS)}")
        if len(self.follows) != 1:
            raise ValueError(f"coupled coordinate {self.name!r}: a coupling table needs one "
                             f"driver, it follows {len(self.follows)}")
        if not (x.ndim == 1 and x.shape == y.shape and len(x) >= 2 and np.all(np.isfinite(x))
                and np.all(np.isfinite(y)) and np.all(np.diff(x) > 0)):
            raise ValueError(f"coupled coordinate {self.name!r}: follows_values and values must "
                             "be equally long lists (at least 2) of finite numbers, "
                             "follows_values increasing")
        object.__setattr__(self, "follows_values", tuple(float(v) for v in x))
        object.__setattr__(self, "values", tuple(float(v) for v in y))

    @property
    def has_function(self) -> bool:
        return self.values is not None

    def value(self, driver) -> np.ndarray:
        """The coupling function at driver values (the driver's unit): linear between the
        table's points, NaN outside its range (the driver's box)."""
        driver = np.asarray(driver, dtype=float)
        x = self.follows_values
        inside = (driver >= x[0]) & (driver <= x[-1])
        return np.where(inside, np.interp(driver, x, self.values), np.nan)


@dataclass(frozen=True)
class FitReport:
    """How well one muscle's polynomial reproduces the source model's path (from the importer).

    Lengths in m, moment arms in m (m/m for translational coordinates); ``poses_*`` count the
    sampled poses used for fitting and held out for checking; ``flags`` lists problems found
    (for example ``discontinuous``: the source path jumps, finite differences at two step sizes
    disagree).
    """

    length_rms_m: float
    length_max_m: float
    moment_arm_rms_m: float
    moment_arm_max_m: float
    poses_fit: int
    poses_held_out: int
    flags: tuple[str, ...] = ()


@dataclass(frozen=True)
class MusclePath:
    """One muscle's path length as a polynomial of the coordinates it crosses.

    x_j = (q_j - offset_j) / scale_j; L = sum_t coefficients[t] * prod_j x_j ** exponents[t, j].
    """

    name: str
    coordinates: tuple[str, ...]
    offset: tuple[float, ...]
    scale: tuple[float, ...]
    exponents: np.ndarray          # (n_terms, len(coordinates)) int
    coefficients: np.ndarray       # (n_terms,) m
    fit: FitReport | None = None
    basis: str = "monomial"

    def __post_init__(self):
        k = len(self.coordinates)
        exponents = np.asarray(self.exponents, dtype=np.int64)
        if exponents.ndim != 2 or exponents.shape[1] != k or np.any(exponents < 0):
            raise ValueError(f"muscle {self.name!r}: exponents must be (n_terms, {k}) "
                             "non-negative integers")
        coefficients = np.asarray(self.coefficients, dtype=float)
        if coefficients.shape != (exponents.shape[0],) or not np.all(np.isfinite(coefficients)):
            raise ValueError(f"muscle {self.name!r}: need {exponents.shape[0]} finite "
                             "coefficients")
        if len(self.offset) != k or len(self.scale) != k or not all(
                s > 0 and np.isfinite(s) for s in self.scale) or not all(
                np.isfinite(v) for v in self.offset):
            raise ValueError(f"muscle {self.name!r}: offset and scale need {k} finite values, "
                             "scale > 0")
        object.__setattr__(self, "name", str(self.name))
        object.__setattr__(self, "coordinates", tuple(str(c) for c in self.coordinates))
        object.__setattr__(self, "offset", tuple(float(v) for v in self.offset))
        object.__setattr__(self, "scale", tuple(float(v) for v in self.scale))
        object.__setattr__(self, "exponents", exponents)
        object.__setattr__(self, "coefficients", coefficients)


@dataclass
class GeometryOutput:
    """Muscle-space kinematics at one pose (``evaluate_many``: at k poses, every field with a
    leading axis of k; ``row(i)`` is pose i's).

    | field | shape | unit |
    | --- | --- | --- |
    | length_m | (n_muscles,) | m |
    | velocity_m_per_s | (n_muscles,) | m/s, positive when lengthening |
    | moment_arm | (n_muscles, n_coordinates) | m (m/m for translational coordinates) |
    | q | (n_coordinates,) | rad or m: the coordinates used (after clamping) |
    | qdot | (n_coordinates,) | rad/s or m/s: the velocities used (0 where clamped) |
    | clamped | (n_coordinates,) | bool: outside the box, clamped |
    """

    length_m: np.ndarray
    velocity_m_per_s: np.ndarray
    moment_arm: np.ndarray
    q: np.ndarray
    qdot: np.ndarray
    clamped: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))

    def row(self, i: int) -> GeometryOutput:
        """Pose ``i`` of an ``evaluate_many`` output (views of its arrays)."""
        return GeometryOutput(self.length_m[i], self.velocity_m_per_s[i], self.moment_arm[i],
                              self.q[i], self.qdot[i], self.clamped[i])


def generalized_forces(moment_arm: np.ndarray, force: np.ndarray) -> np.ndarray:
    """tau = r^T F: (n_muscles, n_q) moment arms and (n_muscles,) tensions (N) -> (n_q,)
    generalized forces (N m for rotational coordinates, N for translational ones)."""
    return np.asarray(moment_arm, dtype=float).T @ np.asarray(force, dtype=float)


def clamp_to_box(q, qdot, lower, upper) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(q clamped to [lower, upper], qdot with clamped coordinates' velocity 0, clamped mask)."""
    q_used = np.minimum(np.maximum(q, lower), upper)
    clamped = q_used != q
    return q_used, np.where(clamped, 0.0, qdot), clamped


class JointGeometry:
    """Interface of a geometry back end (polynomial from a file, or MuJoCo's exact tendons).

    Attributes: ``coordinates`` (tuple of Coordinate), ``coupled`` (tuple of CoupledCoordinate),
    ``muscle_names``. ``evaluate(q, qdot=None) -> GeometryOutput``.
    """

    coordinates: tuple[Coordinate, ...] = ()
    coupled: tuple[CoupledCoordinate, ...] = ()
    muscle_names: tuple[str, ...] = ()
    # a back end's compiled conditioning and evaluation of a message in one call
    # (vm_ros.geometry.kernel.compiled_mapped_evaluator), or None
    mapped_evaluator = None

    @property
    def coordinate_names(self) -> tuple[str, ...]:
        return tuple(c.name for c in self.coordinates)

    @property
    def lower(self) -> np.ndarray:
        return np.array([c.lower for c in self.coordinates])

    @property
    def upper(self) -> np.ndarray:
        return np.array([c.upper for c in self.coordinates])

    def coordinate_index(self, name: str) -> int:
        return self.coordinate_names.index(name)

    def check_pose(self, q, qdot) -> tuple[np.ndarray, np.ndarray]:
        """q, qdot as float arrays of shape (n_q,); InputError for a wrong shape or non-finite
        values (qdot None -> zeros)."""
        n = len(self.coordinates)
        q = np.asarray(q, dtype=float)
        qdot = np.zeros(n) if qdot is None else np.asarray(qdot, dtype=float)
        for name, value in (("q", q), ("qdot", qdot)):
            if value.shape != (n,):
                raise InputError(name, value.shape, f"need shape ({n},): one per coordinate "
                                 f"({', '.join(self.coordinate_names)})")
            if not np.all(np.isfinite(value)):
                raise InputError(name, value.tolist(), "values must be finite")
        return q, qdot

    def evaluate(self, q, qdot=None) -> GeometryOutput:  # pragma: no cover - interface
        raise NotImplementedError

    def evaluate_many(self, q, qdot) -> GeometryOutput:
        """``evaluate`` at each pose of q, qdot (k, n_q), stacked (GeometryOutput.row)."""
        n, n_q = len(self.muscle_names), len(self.coordinates)
        outputs = [self.evaluate(pose, speed) for pose, speed in zip(q, qdot, strict=True)]
        shapes = {"length_m": (n,), "velocity_m_per_s": (n,), "moment_arm": (n, n_q),
                  "q": (n_q,), "qdot": (n_q,), "clamped": (n_q,)}
        return GeometryOutput(**{key: np.array([getattr(out, key) for out in outputs]).reshape(
            len(outputs), *shape) for key, shape in shapes.items()})


class PolynomialGeometry(JointGeometry):
    """Path lengths and moment arms of many muscles from fitted polynomials (NumPy only; the
    compiled evaluator in vm_ros.geometry.kernel is used when Numba is available, unless
    ``backend='numpy'``).

    ``source`` and ``options`` are what the geometry file records about the model the paths came
    from and how they were fitted (free-form mappings).
    """

    def __init__(self, coordinates, muscles, coupled=(), source=None, options=None,
                 backend: str = "auto"):
        self.coordinates = tuple(coordinates)
        self.coupled = tuple(coupled)
        self.muscles = tuple(muscles)
        self.muscle_names = tuple(m.name for m in self.muscles)
        self.source = dict(source or {})
        self.options = dict(options or {})
        names = self.coordinate_names
        for label, values in (("coordinate", names), ("muscle", self.muscle_names),
                              ("coupled coordinate", [c.name for c in self.coupled])):
            seen = set()
            for value in values:
                if value in seen:
                    raise ValueError(f"{label} {value!r} is listed twice")
                seen.add(value)
        for c in self.coupled:
            if c.name in names:
                raise ValueError(f"coupled coordinate {c.name!r} is also an independent "
                                 "coordinate")
            unknown = [f for f in c.follows if f not in names]
            if unknown:
                raise ValueError(f"coupled coordinate {c.name!r} follows unknown coordinates "
                                 f"{unknown}")
        for muscle in self.muscles:
            unknown = [c for c in muscle.coordinates if c not in names]
            if unknown:
                raise ValueError(f"muscle {muscle.name!r} crosses unknown coordinates {unknown}")
        self.packed = PackedPolynomials.pack(len(names), (
            ([names.index(c) for c in m.coordinates], m.offset, m.scale, m.exponents,
             m.coefficients) for m in self.muscles))
        self._lower, self._upper = self.lower, self.upper
        self._compiled = self._compiled_inside = None
        if backend not in ("auto", "numpy", "compiled"):
            raise ValueError(f"backend {backend!r}: one of auto, numpy, compiled")
        if backend != "numpy":
            from vm_ros.geometry import kernel

            if kernel.available():
                self._compiled = kernel.compiled_evaluator(self.packed)
                self._compiled_many = kernel.compiled_evaluator(self.packed, many=True)
                self._compiled_inside = kernel.compiled_inside_evaluator(
                    self.packed, self._lower, self._upper)
                self.mapped_evaluator = kernel.compiled_mapped_evaluator(
                    self.packed, self._lower, self._upper)
            elif backend == "compiled":
                raise ValueError("backend 'compiled' needs Numba (pip install '.[fast]')")
        self.backend = "compiled" if self._compiled is not None else "numpy"

    def lengths_and_gradients(self, q) -> tuple[np.ndarray, np.ndarray]:
        """(L (n_muscles,), dL/dq (n_muscles, n_q)) at q, with no clamping (for fitting and
        tests; use ``evaluate`` for inputs)."""
        q = np.asarray(q, dtype=float)
        if self._compiled is not None:
            return self._compiled(q)
        return evaluate_packed(self.packed, q)

    def lengths_many(self, poses) -> np.ndarray:
        """L (k, n_muscles) at each pose of ``poses`` (k, n_q), with no clamping: the lengths of
        ``lengths_and_gradients`` pose by pose (compiled: the poses in one call)."""
        poses = np.asarray(poses, dtype=float)
        if self._compiled is not None and len(poses):
            return self._compiled_many(poses)[0]
        return np.array([self.lengths_and_gradients(q)[0] for q in poses]).reshape(
            len(poses), len(self.muscles))

    def evaluate(self, q, qdot=None) -> GeometryOutput:
        if self._compiled_inside is not None:  # a pose inside the box: the checks, the
            # polynomials
            # and r = -dL/dq in one compiled call (on the box, outside it or bad: as below)
            q_in = np.ascontiguousarray(q, dtype=float)
            qdot_in = (np.zeros(q_in.shape) if qdot is None
                       else np.ascontiguousarray(qdot, dtype=float))
            if q_in.shape == qdot_in.shape == self._lower.shape:
                inside, length, gradient, arm, q_used, qdot_used = self._compiled_inside(
                    q_in, qdot_in)
                if inside:
                    return GeometryOutput(length, gradient @ qdot_used, arm, q_used, qdot_used,
                                          np.zeros(q_used.shape, dtype=bool))
        q, qdot = self.check_pose(q, qdot)
        q_used, qdot_used, clamped = clamp_to_box(q, qdot, self._lower, self._upper)
        length, gradient = self.lengths_and_gradients(q_used)
        return GeometryOutput(length, gradient @ qdot_used, -gradient, q_used, qdot_used,
                              clamped)

    def evaluate_many(self, q, qdot) -> GeometryOutput:
        """``evaluate`` at each pose of q, qdot (k, n_q), stacked (GeometryOutput.row), the
        polynomials of every pose in one compiled call (the NumPy evaluator: pose by pose); the
        same numbers as k calls."""
        q, qdot = np.asarray(q, dtype=float), np.asarray(qdot, dtype=float)
        shape = (len(q), len(self.coordinates))
        if (self._compiled is None or not len(q) or q.shape != shape or qdot.shape != shape
                or not (np.isfinite(q).all() and np.isfinite(qdot).all())):
            return super().evaluate_many(q, qdot)  # check_pose's errors, pose by pose
        q_used, qdot_used, clamped = clamp_to_box(q, qdot, self._lower, self._upper)
        lengths, gradients = self._compiled_many(q_used)
        # each velocity as evaluate computes it, gradient @ qdot: a stacked matrix-vector
        # matmul calls BLAS's gemv once per pose with the same arguments but the pointers
        velocity = np.matmul(gradients, qdot_used[:, :, None])[:, :, 0]
        moment_arm = np.negative(gradients, out=gradients)  # r = -dL/dq, in place (k n n_q)
        return GeometryOutput(lengths, velocity, moment_arm, q_used, qdot_used, clamped)


__all__ = ["COUPLING_POINTS", "Coordinate", "CoupledCoordinate", "FitReport", "GeometryOutput",
           "JointGeometry", "MusclePath", "PolynomialGeometry", "UNITS", "clamp_to_box",
           "generalized_forces"]
