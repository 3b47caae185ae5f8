"""What a polynomial geometry must satisfy over its coordinate box to be loaded (pure NumPy).

The model needs every path length finite and > 0 m (MuscleBank.check_inputs); a geometry that
gives less somewhere in its box would stop the model at the first joint sample there. So every
geometry file is checked when it is read (vm_ros.geometry.file), at the poses of
:func:`box_poses`, with these rules (the first muscle that breaks one is named, with the pose):

- every coefficient finite with abs(c) <= MAX_COEFFICIENT_M;
- every path length in [MIN_PATH_LENGTH_M, MAX_PATH_LENGTH_M] (so finite). Moment arms are
  not checked separately: a pose where they overflow makes the length's terms overflow too.

The node's input checks floor the path lengths they accept at MIN_PATH_LENGTH_M as well
(vm_ros.node.inputs), so a path length between the sampled poses below it is a rejected,
counted message, never a model error.
"""

from __future__ import annotations

import numpy as np

# Constants (m). `vm-ros import-mjcf` of myoelbow, myoarm_r and myolegs (149 muscles) writes
# paths of 0.0215-0.595 m over these poses with coefficients abs(c) <= 0.52 m (the fit maps
# the box onto x in [-1, 1]); these limits are far outside that.
MIN_PATH_LENGTH_M = 1e-3       # the margin kept above the model's L > 0: no muscle path is 1 mm
MAX_PATH_LENGTH_M = 100.0      # no muscle path is 100 m long: longer is a broken file
MAX_COEFFICIENT_M = 1e3        # per unit of a monomial; 10 x the longest path allowed
BOX_POSES = 512                # random poses (fixed seed) in box_poses, besides centre and ends


def box_poses(lower, upper) -> np.ndarray:
    """Poses (P, n_q) covering the box [lower, upper]: its centre, each coordinate's two ends
    (others at the centre) and BOX_POSES random poses (fixed seed, so that every reader of a
    geometry samples the same poses). P = 1 + 2 n_q + BOX_POSES."""
    lower, upper = np.asarray(lower, dtype=float), np.asarray(upper, dtype=float)
    centre = (lower + upper) / 2
    ends = np.repeat(centre[None, :], 2 * len(lower), axis=0)
    for j in range(len(lower)):
        ends[2 * j, j], ends[2 * j + 1, j] = lower[j], upper[j]
    rng = np.random.default_rng(0)
    return np.vstack([centre, ends, lower + (upper - lower) * rng.random((BOX_POSES, len(lower)))])


def sampled_lengths(geometry, poses) -> np.ndarray:
    """Path lengths (P, n_muscles) m of a PolynomialGeometry at ``poses`` (P, n_q), by its own
    evaluator (the one the node uses; no clamping); overflow gives inf or NaN, no warning."""
    with np.errstate(all="ignore"):
        return geometry.lengths_many(poses)


def path_problem(geometry) -> tuple[int, str] | None:
    """The first muscle of a PolynomialGeometry that breaks a rule of this module, as (its index,
    a one-line reason naming the muscle and the pose); None when every muscle keeps them."""
    for i, muscle in enumerate(geometry.muscles):
        c = muscle.coefficients
        if c.size and not np.max(np.abs(c)) <= MAX_COEFFICIENT_M:
            t = int(np.argmax(~np.isfinite(c) | (np.abs(c) > MAX_COEFFICIENT_M)))
            return i, (f"muscle {muscle.name}: coefficient {t} is {float(c[t])!r} m; each "
                       f"must be finite with abs(c) <= {MAX_COEFFICIENT_M:g} m")
    poses = box_poses(geometry.lower, geometry.upper)
    lengths = sampled_lengths(geometry, poses)
    for i, muscle in enumerate(geometry.muscles):
        length = lengths[:, i]
        if not ((length >= MIN_PATH_LENGTH_M) & (length <= MAX_PATH_LENGTH_M)).all():
            # the worst pose: a NaN, else the shortest if too short, else the longest
            order = np.where(np.isnan(length), -np.inf, length)
            p = int(np.argmin(order) if order.min() < MIN_PATH_LENGTH_M else np.argmax(order))
            return i, (f"muscle {muscle.name}: path length {length[p]:.6g} m at "
                       f"{_pose_text(geometry, muscle, poses[p])}; must be in "
                       f"[{MIN_PATH_LENGTH_M:g}, {MAX_PATH_LENGTH_M:g}] m over the coordinate "
                       f"box ({len(poses)} poses checked)")
    return None


def _pose_text(geometry, muscle, q) -> str:
    """The coordinates ``muscle`` crosses at pose ``q``: 'elbow_flexion=0.5 rad, ...'."""
    units = {c.name: c.unit for c in geometry.coordinates}
    index = {name: j for j, name in enumerate(geometry.coordinate_names)}
    return ", ".join(f"{name}={q[index[name]]:.6g} {units[name]}" for name in muscle.coordinates)


__all__ = ["BOX_POSES", "MAX_COEFFICIENT_M", "MAX_PATH_LENGTH_M", "MIN_PATH_LENGTH_M",
           "box_poses", "path_problem", "sampled_lengths"]
