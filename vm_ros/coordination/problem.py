"""The coordination problem: a prescribed motion through a geometry, target joint moments at
frames, and what a forward run of the bank needs over that motion.

    problem = build_problem(geometry, motion, targets, muscles, dt_s=0.001)

Time axis: model time 0 is the motion's first frame (JointMotion.time_s); the targets' times
are on the motion's own axis and shifted by ``motion.start_s``. Model step k covers
[k dt, (k + 1) dt) with the path length and velocity of the motion at k dt (``JointMotion.at``,
linear between frames, as `vm-ros simulate --motion` samples it every step). Moment arms and
target moments are taken at the target frames that lie in [0, duration] (within
FRAME_TOLERANCE_S: ID rows may start a little before the motion's first frame).

Coordinates of the targets that no muscle of the problem crosses (pelvis, lumbar in a gait
model) cannot be reached by the muscles: they are kept apart in ``uncrossed`` and reported as
left to the reserves by design.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vm_ros.coordination.targets import JointMomentTargets
from vm_ros.errors import VmRosError

FRAME_TOLERANCE_S = 1e-3   # target frames this close outside the motion's span are kept (clipped)


@dataclass(frozen=True)
class CoordinationProblem:
    """What the solver works on (n muscles, k model steps, T frames, C coordinates).

    | field | shape | unit |
    | --- | --- | --- |
    | muscles | (n,) | names |
    | coordinates | (C,) | target coordinates crossed by a muscle |
    | units | (C,) | 'rad' or 'm' per coordinate (targets in N m or N) |
    | dt_s | () | s, model step |
    | path_length | (k, n) | m, at each step's start |
    | path_velocity | (k, n) | m/s, lengthening positive |
    | frame_times_s | (T,) | s, model time of each target frame |
    | moment_arm | (T, n, C) | m (m/m translational) at the frames |
    | target | (T, C) | N m or N |
    | uncrossed | tuple | target coordinates no muscle crosses |
    | source | str | the targets' source |
    """

    muscles: tuple
    coordinates: tuple
    units: tuple
    dt_s: float
    path_length: np.ndarray
    path_velocity: np.ndarray
    frame_times_s: np.ndarray
    moment_arm: np.ndarray
    target: np.ndarray
    uncrossed: tuple = ()
    source: str = ""

    @property
    def n_steps(self) -> int:
        return int(self.path_length.shape[0])

    @property
    def duration_s(self) -> float:
        return self.n_steps * self.dt_s

    @property
    def peak(self) -> np.ndarray:
        """(C,) peak |target| per coordinate (N m or N), at least 1e-9."""
        return np.maximum(np.abs(self.target).max(axis=0), 1e-9)

    def moments(self, force_frames: np.ndarray) -> np.ndarray:
        """(T, C) generalized forces of tendon forces (T, n) at the frames: tau = r^T F."""
        return np.einsum("tic,ti->tc", self.moment_arm, force_frames)


def _pose(geometry, motion, t_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Every geometry coordinate at model time ``t_s``: the motion's, the others at 0 clipped
    to their box (no muscle of the problem crosses them)."""
    q = np.clip(np.zeros(len(geometry.coordinates)), geometry.lower, geometry.upper)
    qdot = np.zeros_like(q)
    values, rates = motion.at(t_s)
    for j, name in enumerate(motion.coordinates):
        i = geometry.coordinate_index(name)
        q[i], qdot[i] = values[j], rates[j]
    return q, qdot


def build_problem(geometry, motion, targets: JointMomentTargets, muscles, dt_s: float = 0.001,
                  duration_s: float | None = None) -> CoordinationProblem:
    """The problem of ``muscles`` (each with a path in ``geometry``) following ``motion`` (a
    vm_ros.node.motion_inputs.JointMotion) to ``targets``; VmRosError when a muscle has no
    path, a crossed coordinate is not in the motion, or no target frame lies in the motion."""
    muscles = tuple(muscles)
    missing = [m for m in muscles if m not in geometry.muscle_names]
    if missing:
        raise VmRosError(f"muscle {missing[0]!r} has no path in the geometry")
    index = [geometry.muscle_names.index(m) for m in muscles]
    crossed = {c for m in geometry.muscles if m.name in muscles for c in m.coordinates}
    lacking = sorted(crossed - set(motion.coordinates))
    if lacking:
        raise VmRosError(f"motion {motion.source}: no values for crossed coordinate(s) "
                         f"{', '.join(lacking)}")
    duration = motion.duration_s if duration_s is None else float(duration_s)
    n_steps = max(1, round(duration / dt_s))
    lengths, velocities = [], []
    for k in range(n_steps):
        out = geometry.evaluate(*_pose(geometry, motion, k * dt_s))
        lengths.append(out.length_m[index])
        velocities.append(out.velocity_m_per_s[index])
    times = np.asarray(targets.times_s, dtype=float) - motion.start_s
    end = n_steps * dt_s
    keep = (times >= -FRAME_TOLERANCE_S) & (times <= end + FRAME_TOLERANCE_S)
    if not np.any(keep):
        raise VmRosError(f"targets {targets.source}: no frame within the motion's "
                         f"{end:.3f} s (from {motion.start_s:g} s on its axis)")
    times = np.clip(times[keep], 0.0, end)
    moments = np.asarray(targets.moments_nm, dtype=float)[keep]
    used = [j for j, c in enumerate(targets.coordinates) if c in crossed]
    uncrossed = tuple(c for c in targets.coordinates if c not in crossed)
    if not used:
        raise VmRosError(f"targets {targets.source}: none of the coordinates "
                         f"{', '.join(targets.coordinates)} is crossed by a muscle")
    coords = tuple(targets.coordinates[j] for j in used)
    columns = [geometry.coordinate_index(c) for c in coords]
    arms = np.array([geometry.evaluate(*_pose(geometry, motion, t)).moment_arm[index][:, columns]
                     for t in times])
    units = tuple(geometry.coordinates[i].unit for i in columns)
    return CoordinationProblem(muscles, coords, units, float(dt_s), np.array(lengths),
                               np.array(velocities), times, arms, moments[:, used], uncrossed,
                               targets.source)
