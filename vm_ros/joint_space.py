"""Joint space for muscle_node: robot joints <-> geometry coordinates, conditioning of joint_states,
joint torques (no rclpy here; the node and the offline tools use this one implementation, so that
a recompute conditions joint_states exactly as the node did).

Pieces, each usable alone:

- :class:`JointMap`: the ``joint_map`` parameter. YAML ``{robot_joint: coordinate}`` or
  ``{robot_joint: {coordinate: NAME, sign: 1 or -1, offset: VALUE}}`` (``coordinate`` defaults to
  the robot joint's own name, ``sign`` to 1, ``offset`` to 0, in the coordinate's unit, rad or m).
  Model q = sign * robot q + offset; velocities q' = sign * robot q'; generalized forces go back as
  robot tau = sign * tau, so that power is the same in both conventions. A coordinate named by no
  entry is matched by its own name. Each coordinate has exactly one robot name.
- :class:`JointSpace`: a geometry, its joint map, the node's muscles and the ``joints`` parameter
  checked together. Node muscles that the geometry covers are *joint-driven*: their path length
  and velocity come from joint_states through the geometry; geometry muscles that are not node
  muscles are ignored. ``joints`` orders joint_efforts and joint_effort_commands (default: every
  coordinate, in the file's order, under its robot name).
- :class:`JointInputs`: joint_states messages -> coordinates -> ``geometry.evaluate(q, q')`` ->
  the joint-driven muscles' path lengths and velocities, handed to
  :class:`~vm_ros.node_inputs.NodeInputs` as kinematics received at that time (so extrapolation,
  staleness, the stale-input policy and the path-length checks are those of muscle_kinematics);
  the moment arms of that joint sample are held (zero-order hold) for the torques.

joint_states rules (every bad message is reported as an Issue; nothing is stored from a dropped
message):

- name[] robot joints (empty: one position per joint of ``joints``, in that order), position[]
  (rad or m), velocity[] optional: empty means 0 for every named joint, as muscle_kinematics
  treats missing velocities; otherwise one per position.
- sizes that do not match, a joint named twice, NaN or inf in a named joint's position or
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

Torques: tau = r^T F (N m or N) with r = -dL/dq of the joint sample a step used and F the tendon
forces of that step's output; power is invariant: sum(tau_robot * q'_robot) = -sum(F * L') over
the joint-driven muscles, with the (clamped) velocities used.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import yaml

from vm_ros.errors import ConfigError
from vm_ros.geometry import JointGeometry, generalized_forces, load_geometry
from vm_ros.node_health import Issue

TOPIC = "joint_states"
_ENTRY_KEYS = ("coordinate", "sign", "offset")
_SHOWN_NAMES = 5  # unknown joint names quoted in one issue text


def parse_joint_map(text: str, source: str) -> dict[str, tuple[str, float, float]]:
    """The ``joint_map`` YAML -> {robot joint: (coordinate, sign, offset)}, syntax checked only
    (the coordinates are checked against a geometry by :meth:`JointMap.build`). ConfigError
    (``source``, field ``joint_map``) on any problem."""

    def fail(value, reason):
        raise ConfigError(source, "joint_map", value, reason)

    if not text.strip():
        return {}
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        fail(text, f"not valid YAML: {exc}".splitlines()[0])
    if data is None:
        return {}
    if not isinstance(data, dict):
        fail(text, "must be a YAML mapping {robot_joint: coordinate} or {robot_joint: "
                   "{coordinate: NAME, sign: 1 or -1, offset: VALUE}}")
    entries = {}
    for robot, value in data.items():
        if not isinstance(robot, str) or not robot:
            fail(robot, "robot joint names must be non-empty strings (quote names such as '1')")
        if isinstance(value, str) and value:
            entries[robot] = (value, 1.0, 0.0)
            continue
        if not isinstance(value, dict):
            fail({robot: value}, "each entry maps a robot joint to a coordinate name or to "
                                 "{coordinate: NAME, sign: 1 or -1, offset: VALUE}")
        unknown = sorted(str(k) for k in value if k not in _ENTRY_KEYS)
        if unknown:
            fail({robot: value}, f"unknown key {unknown[0]!r} (known: {', '.join(_ENTRY_KEYS)})")
        coordinate = value.get("coordinate", robot)
        sign, offset = value.get("sign", 1), value.get("offset", 0.0)
        if not isinstance(coordinate, str) or not coordinate:
            fail({robot: value}, "coordinate must be a coordinate name")
        if isinstance(sign, bool) or not isinstance(sign, (int, float)) or sign not in (1, -1):
            fail({robot: value}, "sign must be 1 or -1")
        if isinstance(offset, bool) or not isinstance(offset, (int, float)) or not math.isfinite(
                offset):
            fail({robot: value}, "offset must be a finite number (rad or m)")
        entries[robot] = (coordinate, float(sign), float(offset))
    return entries


@dataclass(frozen=True)
class JointMap:
    """Robot joints <-> model coordinates, one robot name per coordinate (module docstring).

    Arrays are in the geometry's coordinate order: ``robot_names[j]`` is coordinate j's robot
    name; model q = sign * robot q + offset.
    """

    coordinates: tuple[str, ...]
    robot_names: tuple[str, ...]
    sign: np.ndarray
    offset: np.ndarray

    def __post_init__(self):
        object.__setattr__(self, "_index", {name: j for j, name in enumerate(self.robot_names)})

    @classmethod
    def build(cls, text: str, geometry: JointGeometry, source: str) -> JointMap:
        """The joint map of ``geometry`` from the ``joint_map`` YAML; ConfigError naming
        ``joint_map`` for an unknown or coupled coordinate, a coordinate mapped twice, or a robot
        name standing for two coordinates."""
        entries = parse_joint_map(text, source)
        names = geometry.coordinate_names
        coupled = {c.name: c for c in geometry.coupled}
        robot = list(names)
        sign, offset = np.ones(len(names)), np.zeros(len(names))
        mapped_by: dict[str, str] = {}
        for joint, (coordinate, s, o) in entries.items():
            if coordinate in coupled:
                fail_text = (f"{coordinate!r} is a coupled coordinate (follows "
                             f"{', '.join(coupled[coordinate].follows)}), not an input: map the "
                             "coordinate(s) it follows")
                raise ConfigError(source, "joint_map", {joint: coordinate}, fail_text)
            if coordinate not in names:
                raise ConfigError(source, "joint_map", {joint: coordinate},
                                  f"unknown coordinate {coordinate!r} (the geometry has: "
                                  f"{', '.join(names)})")
            if coordinate in mapped_by:
                raise ConfigError(source, "joint_map", {joint: coordinate},
                                  f"coordinate {coordinate!r} is already mapped from robot joint "
                                  f"{mapped_by[coordinate]!r}")
            mapped_by[coordinate] = joint
            j = names.index(coordinate)
            robot[j], sign[j], offset[j] = joint, s, o
        seen: dict[str, int] = {}
        for j, joint in enumerate(robot):
            if joint in seen:
                a, b = names[seen[joint]], names[j]
                own, other = (a, b) if joint == a else (b, a)
                raise ConfigError(source, "joint_map", joint,
                                  f"robot joint {joint!r} would stand for coordinate {other!r} "
                                  f"(mapped) and for coordinate {own!r} (its own name): map "
                                  f"{own!r} from another robot joint")
            seen[joint] = j
        sign.flags.writeable = offset.flags.writeable = False
        return cls(tuple(names), tuple(robot), sign, offset)

    def index_of(self, robot_joint: str) -> int | None:
        """Coordinate index of a robot joint name (None when not mapped)."""
        return self._index.get(robot_joint)

    def select(self, joints: Sequence[str], source: str) -> np.ndarray:
        """Coordinate indices of the ``joints`` parameter ([] = every coordinate, in order);
        ConfigError naming ``joints`` for an unmapped or repeated joint."""
        if not joints:
            return np.arange(len(self.coordinates))
        indices = []
        for joint in joints:
            j = self.index_of(joint)
            if j is None:
                raise ConfigError(source, "joints", list(joints),
                                  f"{joint!r} is not a robot joint of the geometry (known: "
                                  f"{', '.join(self.robot_names)}; see joint_map)")
            if j in indices:
                raise ConfigError(source, "joints", list(joints), f"{joint!r} is listed twice")
            indices.append(j)
        return np.array(indices, dtype=int)

    def to_model(self, index, position, velocity) -> tuple[np.ndarray, np.ndarray]:
        """Robot positions and velocities of coordinates ``index`` -> model q, q'."""
        s = self.sign[index]
        return s * np.asarray(position, float) + self.offset[index], s * np.asarray(velocity, float)

    def to_robot(self, index, q, qdot, tau) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Model q, q' and generalized forces of coordinates ``index`` -> the robot's (tau
        transforms like q', so that tau * q' is the same in both conventions)."""
        s = self.sign[index]
        return (s * (np.asarray(q, float) - self.offset[index]), s * np.asarray(qdot, float),
                s * np.asarray(tau, float))


class JointSpace:
    """A geometry, its joint map, the node's muscles and the output joints, checked together.

    Attributes: ``geometry``, ``map`` (JointMap), ``driven`` (joint-driven muscle names, node
    order), ``driven_index`` (their indices among the node's muscles), ``rows`` (their rows in
    the geometry), ``ignored`` (geometry muscles that are not node muscles), ``output`` (coordinate
    indices of ``joints``), ``output_names`` (their robot names), ``needed`` (bool per coordinate:
    a position is needed before the first joint sample).
    """

    def __init__(self, geometry: JointGeometry, joint_map: JointMap, muscles: Sequence[str],
                 joints: Sequence[str], source: str):
        self.geometry = geometry
        self.map = joint_map
        self.muscles = tuple(muscles)
        covered = set(geometry.muscle_names)
        self.driven = tuple(m for m in self.muscles if m in covered)
        if not self.driven:
            raise ConfigError(source, "geometry", list(geometry.muscle_names),
                              f"none of the geometry's muscles is among the muscles parameter "
                              f"({', '.join(self.muscles)})")
        self.driven_index = np.array([self.muscles.index(m) for m in self.driven], dtype=int)
        self.rows = np.array([geometry.muscle_names.index(m) for m in self.driven], dtype=int)
        self.ignored = tuple(m for m in geometry.muscle_names if m not in self.muscles)
        self.output = joint_map.select(joints, source)
        self.output_names = tuple(joint_map.robot_names[j] for j in self.output)
        self.crosses = _crosses(geometry, self.driven)
        self.needed = self.crosses.any(axis=0)
        self.needed[self.output] = True

    @classmethod
    def load(cls, path, joint_map: str, muscles: Sequence[str], joints: Sequence[str],
             source: str, backend: str = "auto") -> JointSpace:
        """Read the geometry file at ``path`` and check it with the other parameters; a bad file
        is a ConfigError naming the ``geometry`` parameter (and the file's field)."""
        try:
            geometry = load_geometry(path, backend=backend)
        except ConfigError as exc:
            raise ConfigError(source, "geometry", str(path), str(exc)) from exc
        return cls(geometry, JointMap.build(joint_map, geometry, source), muscles, joints, source)

    @property
    def n_coordinates(self) -> int:
        return len(self.map.coordinates)

    def summary(self) -> str:
        """One line for the node's log."""
        joints = ", ".join(self.output_names)
        return (f"geometry: {len(self.driven)} joint-driven muscles ({', '.join(self.driven)}) "
                f"over {self.n_coordinates} coordinates; joint_efforts for {joints}")


def _crosses(geometry: JointGeometry, muscles: Sequence[str]) -> np.ndarray:
    """(len(muscles), n_coordinates) bool: which coordinates each muscle's path crosses (every
    coordinate when the back end does not say)."""
    paths = {m.name: m for m in getattr(geometry, "muscles", ())}
    names = geometry.coordinate_names
    crosses = np.zeros((len(muscles), len(names)), dtype=bool)
    for i, muscle in enumerate(muscles):
        path = paths.get(muscle)
        if path is None:
            crosses[i] = True
        else:
            crosses[i, [names.index(c) for c in path.coordinates]] = True
    return crosses


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
class JointEfforts:
    """What joint_efforts and joint_effort_commands carry, robot convention, ordered by
    ``joints``: position (rad or m), velocity (rad/s or m/s), effort tau (N m or N)."""

    names: tuple[str, ...]
    position: np.ndarray
    velocity: np.ndarray
    effort: np.ndarray


RANGE_POSES = 512        # random poses (fixed seed) sampled for geometry_length_range
RANGE_MARGIN = 0.1       # of the sampled length range, added on each side (poses miss extremes)


def geometry_length_range(geometry: JointGeometry, rows) -> tuple[np.ndarray, np.ndarray]:
    """(lo, hi) path length (m) of the geometry's muscles ``rows`` over its box: sampled at the
    box's centre, each coordinate's two ends (others at the centre) and RANGE_POSES random poses
    (fixed seed, so the node and a recompute agree), widened by RANGE_MARGIN of the range."""
    lower, upper = geometry.lower, geometry.upper
    centre = (lower + upper) / 2
    poses = [centre]
    for j in range(len(lower)):
        for end in (lower[j], upper[j]):
            pose = centre.copy()
            pose[j] = end
            poses.append(pose)
    rng = np.random.default_rng(0)
    poses += list(lower + (upper - lower) * rng.random((RANGE_POSES, len(lower))))
    lengths = np.array([geometry.evaluate(pose).length_m[rows] for pose in poses])
    lo, hi = lengths.min(axis=0), lengths.max(axis=0)
    return lo - RANGE_MARGIN * (hi - lo), hi + RANGE_MARGIN * (hi - lo)


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
        self.seen = np.zeros(n, dtype=bool)
        self.sample: JointSample | None = None
        self.last_message_ns: int | None = None
        geometry = space.geometry
        self._default_q = np.clip(0.0, geometry.lower, geometry.upper)
        lo, hi = geometry_length_range(geometry, space.rows)
        inputs.allow_path_range(space.driven_index, lo, hi)

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
        """(issues, coordinate index or None when the message is dropped, message index)."""
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
        robot_q = position[entries]
        robot_qdot = velocity[entries] if velocity.size else np.zeros(index.size)
        if not (np.all(np.isfinite(robot_q)) and np.all(np.isfinite(robot_qdot))):
            return issues + [Issue("joint_non_finite",
                                   f"{TOPIC}: position or velocity is not finite")]
        q, qdot, seen = self.q.copy(), self.qdot.copy(), self.seen.copy()
        q_time = self.q_time_ns.copy()
        q[index], qdot[index] = self.space.map.to_model(index, robot_q, robot_qdot)
        seen[index] = True
        q_time[index] = now_ns
        if np.all(seen[self.space.needed]):
            q_now, qdot_now = self._extrapolated(q, qdot, seen, q_time, now_ns)
            sample, more = self._evaluate(q_now, qdot_now, seen, index, now_ns)
            issues += more
            if sample is None:  # NodeInputs rejected the paths: nothing is stored
                return issues
            self.sample = sample
        self.q, self.qdot, self.seen, self.q_time_ns = q, qdot, seen, q_time
        self.last_message_ns = now_ns
        return issues

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
        space, issues = self.space, []
        out = space.geometry.evaluate(np.where(seen, q, self._default_q),
                                      np.where(seen, qdot, 0.0))
        clamped = index[out.clamped[index]]
        if clamped.size:
            shown = clamped[:3]
            before = space.map.to_robot(shown, q[shown], 0.0, 0.0)[0]
            after = space.map.to_robot(shown, out.q[shown], 0.0, 0.0)[0]
            details = ", ".join(f"{space.map.robot_names[k]} {a:.6g} -> {b:.6g}"
                                for k, a, b in zip(shown, before, after, strict=True))
            issues.append(Issue("joint_clamped", f"{TOPIC}: outside the geometry's box, "
                                f"clamped: {details}", count=int(clamped.size)))
        update = (np.ones(len(space.driven), dtype=bool) if self.sample is None
                  else space.crosses[:, index].any(axis=1))
        if np.any(update):
            rows = space.rows[update]
            more, accepted = self.inputs.set_path_kinematics(
                TOPIC, space.driven_index[update], out.length_m[rows],
                out.velocity_m_per_s[rows], now_ns)
            issues += more
            if not accepted:
                return None, issues
        sample = JointSample(int(now_ns), out.q, out.qdot, out.moment_arm[space.rows])
        for array in (sample.q, sample.qdot, sample.moment_arm):
            array.flags.writeable = False
        return sample, issues

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


__all__ = ["JointEfforts", "JointInputs", "JointMap", "JointSample", "JointSpace",
           "geometry_length_range", "parse_joint_map"]
