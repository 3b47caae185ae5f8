"""joint_states -> the joint-driven muscles' path kinematics, as muscle_node conditions them
(no rclpy here; the node and the offline tools use this one implementation, so that a recompute
conditions joint_states exactly as the node did). Joint maps, joint spaces and torques:
vm_ros.joint_space.

- :class:`JointInputs`: joint_states messages -> coordinates -> ``geometry.evaluate(q, q')`` ->
  the joint-driven muscles' path lengths and velocities, handed to
  :class:`~vm_ros.node.inputs.NodeInputs` as kinematics received at that time (so extrapolation,
  staleness, the stale-input policy and the path-length checks are those of muscle_kinematics);
  the moment arms of that joint sample are held (zero-order hold) for the torques.

joint_states rules (every bad message is reported as an Issue; nothing is stored from a dropped
message):

- name[] robot joints (empty: one position per joint of ``joints``, in that order), position[]
  (rad or m), velocity[] optional: empty means 0 for every named joint, as muscle_kinematics
  treats missing velocities; otherwise one per position.
- sizes that do not match, a joint named twice, NaN or inf in a named joint's position or
  velocity, or a coordinate that overflows to inf with joint_map's offset or moved on by its
  velocity: message dropped. Names not in the map: those entries ignored, counted per entry.
- A message may name some joints only: the others are taken where their latest position and
  velocity put them now (moved on for at most extrapolation_max_s, then held with velocity 0),
  as the path lengths of muscle_kinematics are; so muscles sharing a joint agree.
- Coordinates outside the geometry's box: clamped to it, velocity taken as 0 (GeometryOutput), the
  message used and the clamping counted.
- The path lengths from the geometry go through the range and speed checks of
  muscle_kinematics, the range widened to the geometry's own range over its box
  (geometry_length_range); a message giving a length outside both, or a velocity beyond
  path_speed_max_m_per_s, is dropped whole.
- Waiting: no joint sample exists (and the joint-driven muscles have no path length, so the model
  does not start) until every *needed* coordinate has a position: those a joint-driven muscle
  crosses and those listed in ``joints``. Other coordinates, until received, are evaluated at 0
  clamped into their box (they change no joint-driven path).
- muscle_kinematics entries for joint-driven muscles are ignored and counted (NodeInputs): their
  lengths must stay consistent with the moment arms used for the torques. Other muscles keep using
  muscle_kinematics. Their ``initial_path_length_m`` entries are not used either.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from vm_ros.geometry import JointGeometry, generalized_forces
from vm_ros.geometry.checks import box_poses
from vm_ros.joint_space import JointEfforts, JointSpace
from vm_ros.node.health import Issue

TOPIC = "joint_states"
_SHOWN_NAMES = 5  # unknown joint names quoted in one issue text


@dataclass(frozen=True)
class JointSample:
    """One accepted joint_states message, evaluated: the model steps after it use its moment
    arms, and its positions and velocities are what joint_efforts reports.

    | field | shape | unit |
    | --- | --- | --- |
    | time_ns | - | ns, when it was applied (the time NodeInputs got its path kinematics) |
    | q | (n_coordinates,) | rad or m, model convention, after clamping |
    | qdot | (n_coordinates,) | rad/s or m/s, 0 where clamped |
    | moment_arm | (n_driven, n_coordinates) | m (m/m): r = -dL/dq of the joint-driven muscles |
    """

    time_ns: int
    q: np.ndarray
    qdot: np.ndarray
    moment_arm: np.ndarray


@dataclass(frozen=True)
class JointSamples:
    """k JointSample stacked (read-only arrays): ``time_ns`` (k,) int64, ``q``, ``qdot``
    (k, n_coordinates), ``moment_arm`` (k, n_driven, n_coordinates); ``row(i)`` is sample i."""

    time_ns: np.ndarray
    q: np.ndarray
    qdot: np.ndarray
    moment_arm: np.ndarray

    def __post_init__(self):
        for array in (self.time_ns, self.q, self.qdot, self.moment_arm):
            array.flags.writeable = False

    def __len__(self) -> int:
        return len(self.time_ns)

    def row(self, i: int) -> JointSample:
        return JointSample(int(self.time_ns[i]), self.q[i], self.qdot[i], self.moment_arm[i])

    @classmethod
    def stack(cls, samples: Sequence[JointSample]) -> JointSamples:
        return cls(np.array([s.time_ns for s in samples], dtype=np.int64),
                   *(np.array([getattr(s, key) for s in samples])
                     for key in ("q", "qdot", "moment_arm")))

    def take(self, index, before: JointSample | None = None) -> JointSamples:
        """The samples at ``index`` (k,), in that order (these arrays when it is 0 ... k - 1);
        ``before`` where ``index`` is -1 (the sample before these)."""
        index = np.asarray(index, dtype=int)
        if np.array_equal(index, np.arange(len(self))):
            return self
        earlier = index < 0
        taken = [np.take(getattr(self, key), np.maximum(index, 0), axis=0)
                 for key in ("time_ns", "q", "qdot", "moment_arm")]
        if earlier.any():
            for array, key in zip(taken, ("time_ns", "q", "qdot", "moment_arm"), strict=True):
                array[earlier] = getattr(before, key)
        return JointSamples(*taken)


@dataclass(frozen=True)
class JointBlock:
    """k joint_states messages as JointInputs.on_joint_states_many conditioned them, none stored
    yet (JointInputs.keep stores the last). Per message (row): ``samples`` (JointSamples),
    ``q``, ``qdot``, ``q_time_ns`` (k, n_coordinates) the coordinates held after it (model
    convention, as received: JointInputs.q), ``seen`` (n_coordinates,) after the first;
    ``path`` (updated (k, n) bool, lengths m, velocities m/s (k, n)) per node muscle, the path
    kinematics each stored (NodeInputs.hold_rows); ``issues`` their issues, each kind once with
    the first message's text and the count over all."""

    samples: JointSamples
    q: np.ndarray
    qdot: np.ndarray
    q_time_ns: np.ndarray
    seen: np.ndarray
    path: tuple
    issues: list


class EveryCoordinate(NamedTuple):
    """A stream's selection that names every coordinate once (JointInputs.on_joint_states'
    shorter way), in coordinate order: ``entries`` the message entry of each coordinate (None
    when entry j is coordinate j; ``entry_of`` the same as an array either way), its joint_map
    ``sign`` and ``offset``, ``index`` the coordinates in message order (for the clamping
    issue's text), and the joint-driven muscles such a message updates once a joint sample
    exists: ``update`` (node indices) and ``rows`` (geometry rows)."""

    entries: np.ndarray | None
    entry_of: np.ndarray
    sign: np.ndarray
    offset: np.ndarray
    index: np.ndarray
    update: np.ndarray
    rows: np.ndarray


RANGE_MARGIN = 0.1       # of the sampled length range, added on each side (poses miss extremes)


def geometry_length_range(geometry: JointGeometry, rows) -> tuple[np.ndarray, np.ndarray]:
    """(lo, hi) path length (m) of the geometry's muscles ``rows`` over its box: sampled at
    vm_ros.geometry.checks.box_poses (the poses the loader checked: fixed seed, so the node and a
    recompute agree), widened by RANGE_MARGIN of the range. NodeInputs floors lo at
    MIN_PATH_LENGTH_M."""
    poses = box_poses(geometry.lower, geometry.upper)
    lengths = geometry.evaluate_many(poses, np.zeros_like(poses)).length_m[:, rows]
    lo, hi = lengths.min(axis=0), lengths.max(axis=0)
    return lo - RANGE_MARGIN * (hi - lo), hi + RANGE_MARGIN * (hi - lo)


def _overflow(how: str) -> Issue:
    return Issue("joint_non_finite", f"{TOPIC}: a coordinate is not finite {how} (overflow)")


class JointInputs:
    """joint_states -> the joint-driven muscles' path kinematics in ``inputs`` (a NodeInputs
    built with ``joint_driven=space.driven``), and the latest joint sample for the torques.

    Only the joint-driven muscles that cross a coordinate named in a message get new path
    kinematics from it (all of them at the first sample), so that a message carrying other joints
    (a gripper at its own rate) neither refreshes nor restarts their extrapolation.
    """

    def __init__(self, space: JointSpace, inputs):
        if tuple(inputs.joint_driven_names) != space.driven:
            raise ValueError("NodeInputs must be built with joint_driven = JointSpace.driven")
        self.space = space
        self.inputs = inputs
        n = space.n_coordinates
        self.q = np.full(n, np.nan)  # model convention, as received (before clamping)
        self.qdot = np.zeros(n)
        self.q_time_ns = np.zeros(n, dtype=np.int64)  # when each coordinate was received
        self.seen = np.zeros(n, dtype=bool)  # replaced, never written in place
        self._all_seen = np.ones(n, dtype=bool)  # seen after a message naming every coordinate
        self._all_seen.flags.writeable = False
        self.sample: JointSample | None = None
        self.last_message_ns: int | None = None
        geometry = space.geometry
        self._default_q = np.clip(0.0, geometry.lower, geometry.upper)
        lo, hi = geometry_length_range(geometry, space.rows)
        inputs.allow_path_range(space.driven_index, lo, hi)
        self._expected: dict = {}  # time_ns -> (pose q, pose qdot, GeometryOutput): expect()
        self._selected = None  # ((names, size), issues, index, entries) of the last _select
        self._every: EveryCoordinate | None = None  # of the last _select, when it names all
        self._mapped = geometry.mapped_evaluator  # the compiled shorter way, or None

    @property
    def ready(self) -> bool:
        """A joint sample exists (every needed coordinate has a position)."""
        return self.sample is not None

    def missing(self) -> list[str]:
        """Robot names of the needed coordinates without a position yet."""
        return [self.space.map.robot_names[j] for j in np.flatnonzero(
            self.space.needed & ~self.seen)]

    def rebase(self, now_ns: int) -> None:
        """After the clock went backwards (NodeInputs.rebase does the kinematics times)."""
        self.q_time_ns[self.seen] = now_ns
        if self.last_message_ns is not None:
            self.last_message_ns = now_ns

    def age_s(self, now_ns: int) -> float | None:
        """Age (s) of the newest accepted joint_states message; None if never received."""
        if self.last_message_ns is None:
            return None
        return max(now_ns - self.last_message_ns, 0) * 1e-9

    def _select(self, names, size: int) -> tuple[list[Issue], np.ndarray | None, list[int]]:
        """(issues, coordinate index or None when the message is dropped, message index); the
        previous message's answer when its names and size were the same (a stream keeps its
        names: 80 look-ups per message saved)."""
        key = (names if isinstance(names, tuple) else tuple(names), size)
        if self._selected is None or self._selected[0] != key:
            issues, index, entries = self._select_names(*key)
            if index is not None:
                index.flags.writeable = False
            self._selected = key, issues, index, entries
            self._every = None if issues else self._every_coordinate(index, entries)
        _, issues, index, entries = self._selected
        return list(issues), index, entries

    def _select_names(self, names, size: int):
        space = self.space
        if len(names) == 0:
            if size != len(space.output):
                text = (f"{TOPIC}: {size} positions without names, expected "
                        f"{len(space.output)} (one per joint of the joints parameter)")
                return [Issue("joint_wrong_size", text)], None, []
            return [], space.output.copy(), list(range(size))
        if len(names) != size:
            return [Issue("joint_wrong_size", f"{TOPIC}: {len(names)} names but {size} "
                          "positions")], None, []
        issues, coordinates, entries, unknown = [], [], [], []
        for entry, name in enumerate(names):
            j = space.map.index_of(name)
            if j is None:
                unknown.append(str(name))
            else:
                coordinates.append(j)
                entries.append(entry)
        if unknown:
            shown = sorted(set(unknown))
            more = f" (+{len(shown) - _SHOWN_NAMES} more)" if len(shown) > _SHOWN_NAMES else ""
            text = ", ".join(repr(u[:40]) for u in shown[:_SHOWN_NAMES]) + more
            issues.append(Issue("joint_unknown_name", f"{TOPIC}: joints not in the geometry or "
                                f"joint_map: {text}", count=len(unknown)))
        if len(set(coordinates)) != len(coordinates):
            repeated = next(j for j in coordinates if coordinates.count(j) > 1)
            issues.append(Issue("joint_duplicate_name", f"{TOPIC}: "
                                f"{space.map.robot_names[repeated]!r} named twice"))
            return issues, None, []
        return issues, np.array(coordinates, dtype=int), entries

    def _every_coordinate(self, index, entries) -> EveryCoordinate | None:
        """The EveryCoordinate of a selection (_select_names' index and entries), or None when
        it does not name every coordinate."""
        space = self.space
        n = space.n_coordinates
        if index is None or index.size != n or not np.array_equal(np.sort(index), np.arange(n)):
            return None
        by_coordinate = np.empty(n, dtype=np.intp)
        by_coordinate[index] = entries
        update = space.crosses[:, index].any(axis=1)
        arrays = EveryCoordinate(
            None if np.array_equal(by_coordinate, np.arange(n)) else by_coordinate,
            by_coordinate, space.map.sign[np.arange(n)], space.map.offset[np.arange(n)], index,
            space.driven_index[update], space.rows[update])
        for array in arrays:
            if array is not None:
                array.flags.writeable = False
        return arrays

    def on_joint_states(self, names: Sequence[str], position, velocity,
                        now_ns: int) -> list[Issue]:
        """A JointState on joint_states, applied at ``now_ns`` (module docstring)."""
        position = np.asarray(position, dtype=float).ravel()
        velocity = np.asarray(velocity, dtype=float).ravel()
        if velocity.size not in (0, position.size):
            return [Issue("joint_wrong_size", f"{TOPIC}: {velocity.size} velocities for "
                          f"{position.size} positions (give none or one per position)")]
        issues, index, entries = self._select(names, position.size)
        if index is None or index.size == 0:
            return issues
        if self._every is not None and velocity.size and self.sample is not None:
            done = self._on_every_coordinate(self._every, position, velocity, now_ns)
            if done is not None:
                return issues + done
        robot_q = position[entries]
        robot_qdot = velocity[entries] if velocity.size else np.zeros(index.size)
        if not (np.all(np.isfinite(robot_q)) and np.all(np.isfinite(robot_qdot))):
            return issues + [Issue("joint_non_finite",
                                   f"{TOPIC}: position or velocity is not finite")]
        q, qdot, seen = self.q.copy(), self.qdot.copy(), self.seen.copy()
        q_time = self.q_time_ns.copy()
        with np.errstate(over="ignore"):  # an overflow is reported as an issue below
            q[index], qdot[index] = self.space.map.to_model(index, robot_q, robot_qdot)
        seen[index] = True
        q_time[index] = now_ns
        if not np.isfinite(q[index]).all():  # a position near 1.8e308 plus joint_map's offset
            return issues + [_overflow("with joint_map's offset")]
        if np.all(seen[self.space.needed]):
            with np.errstate(over="ignore"):
                q_now, qdot_now = self._extrapolated(q, qdot, seen, q_time, now_ns)
            if not np.isfinite(q_now[seen]).all():  # the geometry would refuse it (check_pose)
                return issues + [_overflow("moved on by its velocity")]
            sample, more = self._evaluate(q_now, qdot_now, seen, index, now_ns)
            issues += more
            if sample is None:  # NodeInputs rejected the paths: nothing is stored
                return issues
            self.sample = sample
        self.q, self.qdot, self.seen, self.q_time_ns = q, qdot, seen, q_time
        self.last_message_ns = now_ns
        return issues

    def _on_every_coordinate(self, every: EveryCoordinate, position, velocity,
                             now_ns: int) -> list[Issue] | None:
        """on_joint_states of a message that names every coordinate, with velocities, after the
        first joint sample (a robot's usual stream), in fewer NumPy operations: each value is
        computed by the same operations as there (every coordinate received now, so none is
        moved on: q + q' * 0.0, and the pose is q itself), so the same bits. None (nothing
        stored) when a value is not finite, which on_joint_states then reports."""
        moving = self.inputs.limits.extrapolation_max_ns > 0
        if self._mapped is not None and not self._expected:
            done = self._on_every_coordinate_compiled(every, position, velocity, moving, now_ns)
            if done is not None:
                return done
        robot_q, robot_qdot = ((position, velocity) if every.entries is None else
                               (position[every.entries], velocity[every.entries]))
        with np.errstate(over="ignore", invalid="ignore"):  # not finite: on_joint_states
            q = every.sign * robot_q + every.offset
            qdot = every.sign * robot_qdot
            q_now = q + qdot * 0.0  # _extrapolated: received now, moved on for 0 s
            if not math.isfinite(q_now.sum() + qdot.sum()):
                return None
        out = self._geometry_at(q_now, qdot if moving else np.zeros(q.size), now_ns)
        sample, issues = self._stored(out, q_now, every.index, every.update, every.rows, now_ns)
        if sample is None:  # NodeInputs rejected the paths: nothing is stored
            return issues
        self._keep_every(sample, q, qdot, now_ns)
        return issues

    def _on_every_coordinate_compiled(self, every: EveryCoordinate, position, velocity,
                                      moving: bool, now_ns: int) -> list[Issue] | None:
        """_on_every_coordinate of a pose strictly inside the box, the geometry's
        mapped_evaluator doing the joint_map, the pose, the polynomials and the moment arms in
        one compiled call and NodeInputs.set_path_rows the paths' checks and stores in another,
        with the same operations per value (vm_ros.geometry.kernel.compiled_mapped_evaluator);
        the velocities dL/dq @ q' stay NumPy's, as in evaluate. None when the pose is not
        inside or a value not finite: the NumPy way then."""
        inside, q, qdot, q_used, qdot_used, length, gradient, arm = self._mapped(
            position, velocity, every.entry_of, every.sign, every.offset, moving,
            self.space.rows)
        if not inside:
            return None
        if every.update.size:
            issues, accepted = self.inputs.set_path_rows(
                TOPIC, every.update, length, gradient @ qdot_used, every.rows, now_ns)
            if not accepted:  # nothing is stored
                return issues
        sample = JointSample(int(now_ns), q_used, qdot_used, arm)
        for array in (q_used, qdot_used, arm):
            array.flags.writeable = False
        self._keep_every(sample, q, qdot, now_ns)
        return []

    def _keep_every(self, sample: JointSample, q, qdot, now_ns: int) -> None:
        """The state after an accepted message naming every coordinate: its sample, q and q'
        received now, every coordinate seen."""
        self.sample = sample
        self.q, self.qdot = q, qdot
        self.seen = self._all_seen
        self.q_time_ns = np.empty(q.size, dtype=np.int64)  # rebase writes into it
        self.q_time_ns.fill(now_ns)
        self.last_message_ns = now_ns

    def on_joint_states_many(self, names: tuple, positions, velocities,
                             times_ns) -> JointBlock | None:
        """on_joint_states of k messages naming ``names`` (rows of ``positions`` and
        ``velocities`` (k, m), at increasing ``times_ns``, no other joint_states in between),
        conditioned as arrays with the same operations element by element (the geometry at
        every pose in one call: geometry.evaluate_many), nothing stored (keep stores it). None
        when one of them would not be the usual accepted message: dropped (a name unknown or
        repeated, a value not finite, paths NodeInputs would refuse) or before every needed
        coordinate has a position; the caller then hands them over one by one. Coordinates
        outside the box are clamped and counted as on_joint_states does."""
        positions = np.asarray(positions, dtype=float)
        velocities = np.asarray(velocities, dtype=float)
        k = len(positions)
        if k == 0 or positions.ndim != 2 or velocities.shape != positions.shape:
            return None
        issues, index, entries = self._select(names, positions.shape[1])
        if issues or index is None or index.size == 0:
            return None
        robot_q, robot_qdot = positions[:, entries], velocities[:, entries]
        space = self.space
        seen = self.seen.copy()
        seen[index] = True
        if not (np.isfinite(robot_q).all() and np.isfinite(robot_qdot).all()
                and seen[space.needed].all()):
            return None
        times = np.asarray(times_ns, dtype=np.int64)[:, None]
        q, qdot = np.tile(self.q, (k, 1)), np.tile(self.qdot, (k, 1))
        q_time = np.tile(self.q_time_ns, (k, 1))
        with np.errstate(over="ignore", invalid="ignore"):
            q[:, index], qdot[:, index] = space.map.to_model(index, robot_q, robot_qdot)
            q_time[:, index] = times
            if not np.isfinite(q[:, index]).all():
                return None
            q_now, qdot_now = self._extrapolated(q, qdot, seen, q_time, times)
        if not np.isfinite(q_now[:, seen]).all():
            return None
        outputs = space.geometry.evaluate_many(*self._pose(q_now, qdot_now, seen))
        update = np.tile(space.crosses[:, index].any(axis=1), (k, 1))
        if self.sample is None:
            update[0] = True  # the first sample gives every joint-driven muscle its path
        lengths = outputs.length_m[:, space.rows]
        speeds = outputs.velocity_m_per_s[:, space.rows]
        lo, hi = (bound[space.driven_index] for bound in self.inputs.path_bounds())
        limit = self.inputs.limits.path_speed_max_m_per_s
        if not ((((lengths >= lo) & (lengths <= hi)) | ~update).all()
                and ((np.abs(speeds) <= limit) | ~update).all()):
            return None  # NodeInputs.set_path_kinematics would refuse one
        path = tuple(np.zeros((k, self.inputs.n), dtype=dtype) for dtype in (bool, float, float))
        for array, values in zip(path, (update, lengths, speeds), strict=True):
            array[:, space.driven_index] = values
        clamped = outputs.clamped[:, index]
        issues = []
        if clamped.any():  # one issue: the first message's text, the count over all
            first = int(np.argmax(clamped.any(axis=1)))
            issue = self._clamped_issue(q_now[first], outputs.row(first), index)
            issues.append(Issue(issue.kind, issue.text, count=int(clamped.sum())))
        samples = JointSamples(times[:, 0], outputs.q, outputs.qdot,  # take: C-contiguous
                               np.take(outputs.moment_arm, space.rows, axis=1))
        return JointBlock(samples, q, qdot, q_time, seen, path, issues)

    def keep(self, block: JointBlock) -> None:
        """Store what the last message of ``block`` left (on_joint_states_many)."""
        self.q, self.qdot, self.q_time_ns = (rows[-1].copy() for rows in (
            block.q, block.qdot, block.q_time_ns))
        self.seen = block.seen.copy()
        last = block.samples.row(-1)  # copied: the block's arrays need not stay alive
        self.sample = JointSample(last.time_ns, *(array.copy() for array in (
            last.q, last.qdot, last.moment_arm)))
        for array in (self.sample.q, self.sample.qdot, self.sample.moment_arm):
            array.flags.writeable = False
        self.last_message_ns = self.sample.time_ns
        self._expected = {}

    def expect(self, names: tuple, positions, velocities, times_ns) -> None:
        """joint_states messages about to come (rows of ``positions``, ``velocities`` (k, m), at
        ``times_ns``, all naming ``names`` and no other joint in between): the poses each will be
        evaluated at if the joints named by none of them stay as they are, evaluated now at once
        (geometry.evaluate_many). on_joint_states uses an expected output only when its pose is
        the expected one, bit for bit; otherwise it evaluates as usual."""
        positions = np.asarray(positions, dtype=float)
        issues, index, entries = self._select(names, positions.shape[1])
        self._expected = {}
        if index is None or index.size == 0 or issues:
            return
        times = np.asarray(times_ns, dtype=np.int64)[:, None]
        seen = self.seen.copy()
        seen[index] = True
        q, qdot = np.tile(self.q, (len(times), 1)), np.tile(self.qdot, (len(times), 1))
        q_time = np.tile(self.q_time_ns, (len(times), 1))
        with np.errstate(over="ignore", invalid="ignore"):
            q[:, index], qdot[:, index] = self.space.map.to_model(
                index, positions[:, entries], np.asarray(velocities, dtype=float)[:, entries])
            q_time[:, index] = times
            q_now, qdot_now = self._extrapolated(q, qdot, seen, q_time, times)
        pose_q, pose_qdot = self._pose(q_now, qdot_now, seen)
        usable = np.isfinite(pose_q).all(axis=1) & np.isfinite(pose_qdot).all(axis=1)
        rows = np.flatnonzero(usable)
        outputs = self.space.geometry.evaluate_many(pose_q[rows], pose_qdot[rows])
        self._expected = {int(times[k, 0]): (pose_q[k], pose_qdot[k], outputs.row(i))
                          for i, k in enumerate(rows.tolist())}

    def _pose(self, q, qdot, seen) -> tuple[np.ndarray, np.ndarray]:
        """The pose the geometry is evaluated at: coordinates never received at their default,
        velocity 0."""
        return np.where(seen, q, self._default_q), np.where(seen, qdot, 0.0)

    def _geometry_at(self, q, qdot, now_ns: int):
        """geometry.evaluate(q, qdot), or the output expect() computed for this pose."""
        expected = self._expected.pop(int(now_ns), None)
        if (expected is not None and expected[0].tobytes() == q.tobytes()
                and expected[1].tobytes() == qdot.tobytes()):
            return expected[2]
        return self.space.geometry.evaluate(q, qdot)

    def _extrapolated(self, q, qdot, seen, q_time, now_ns) -> tuple[np.ndarray, np.ndarray]:
        """Coordinates at ``now_ns``: each held one moved on by its velocity for at most
        extrapolation_max_s since it was received (velocity 0 beyond), as NodeInputs moves path
        lengths on. So a message naming some joints evaluates the muscles that also cross the
        others where the muscles crossing only those are (a joint group published on its own
        would otherwise pull their lengths back by r q' dt)."""
        since_ns = np.maximum(now_ns - q_time, 0)
        horizon_ns = self.inputs.limits.extrapolation_max_ns
        moving = seen & (since_ns < horizon_ns)
        return (q + np.where(seen, qdot * (np.minimum(since_ns, horizon_ns) * 1e-9), 0.0),
                np.where(moving, qdot, 0.0))

    def _evaluate(self, q, qdot, seen, index, now_ns) -> tuple[JointSample | None, list[Issue]]:
        """Evaluate the geometry at q, q'; hand the paths of the joint-driven muscles that cross
        a coordinate in ``index`` (all at the first sample) to NodeInputs. Returns (the sample, or
        None when NodeInputs rejected the paths; issues)."""
        space = self.space
        out = self._geometry_at(*self._pose(q, qdot, seen), now_ns)
        update = (np.ones(len(space.driven), dtype=bool) if self.sample is None
                  else space.crosses[:, index].any(axis=1))
        return self._stored(out, q, index, space.driven_index[update], space.rows[update],
                            now_ns)

    def _stored(self, out, q, index, driven, rows, now_ns) -> tuple[JointSample | None,
                                                                    list[Issue]]:
        """The geometry's output ``out`` at the pose ``q`` (before clamping) handed on: the
        clamping of the coordinates ``index`` counted, the paths of the joint-driven muscles
        ``driven`` (node indices; their geometry ``rows``) to NodeInputs. Returns (the sample,
        or None when NodeInputs rejected the paths; issues)."""
        issues = []
        if out.clamped[index].any():
            issues.append(self._clamped_issue(q, out, index))
        if driven.size:
            more, accepted = self.inputs.set_path_kinematics(
                TOPIC, driven, out.length_m[rows], out.velocity_m_per_s[rows], now_ns)
            issues += more
            if not accepted:
                return None, issues
        sample = JointSample(int(now_ns), out.q, out.qdot, out.moment_arm[self.space.rows])
        for array in (sample.q, sample.qdot, sample.moment_arm):
            array.flags.writeable = False
        return sample, issues

    def _clamped_issue(self, q, out, index) -> Issue:
        """joint_clamped for the coordinates of ``index`` that ``out`` clamped (q: the pose
        before clamping)."""
        space = self.space
        clamped = index[out.clamped[index]]
        shown = clamped[:3]
        before = space.map.to_robot(shown, q[shown], 0.0, 0.0)[0]
        after = space.map.to_robot(shown, out.q[shown], 0.0, 0.0)[0]
        details = ", ".join(f"{space.map.robot_names[k]} {a:.6g} -> {b:.6g}"
                            for k, a, b in zip(shown, before, after, strict=True))
        return Issue("joint_clamped", f"{TOPIC}: outside the geometry's box, clamped: {details}",
                     count=int(clamped.size))

    def efforts(self, sample: JointSample, force) -> JointEfforts:
        """joint_efforts of a step: ``force`` (N, every node muscle, the step's output) through
        the moment arms of ``sample`` (the joint sample that step used); robot convention,
        ordered by ``joints``."""
        tau = generalized_forces(sample.moment_arm,
                                 np.asarray(force, dtype=float)[self.space.driven_index])
        out = self.space.output
        position, velocity, effort = self.space.map.to_robot(out, sample.q[out],
                                                             sample.qdot[out], tau[out])
        return JointEfforts(self.space.output_names, position, velocity, effort)

    def efforts_many(self, samples: JointSamples, forces) -> JointEfforts:
        """``efforts`` of k steps: ``samples`` the joint sample of each step, ``forces`` (k, n)
        their outputs; JointEfforts with (k, n_joints) arrays. The same bits as ``efforts``
        step by step: r^T F as a stacked matrix-vector matmul, which calls BLAS's gemv once
        per step with the arguments generalized_forces gives it (the pointers aside; the forces
        C-contiguous, since OpenBLAS sums a strided vector in another order)."""
        force = np.take(np.asarray(forces, dtype=float), self.space.driven_index, axis=1)
        tau = np.matmul(samples.moment_arm.transpose(0, 2, 1), force[:, :, None])[:, :, 0]
        out = self.space.output
        position, velocity, effort = self.space.map.to_robot(
            out, samples.q[:, out], samples.qdot[:, out], tau[:, out])
        return JointEfforts(self.space.output_names, position, velocity, effort)


__all__ = ["JointBlock", "JointInputs", "JointSample", "JointSamples",
           "geometry_length_range"]
