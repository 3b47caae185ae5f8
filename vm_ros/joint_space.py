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
- vm_ros.node.joint_inputs.JointInputs: joint_states messages -> coordinates ->
  ``geometry.evaluate(q, q')`` -> the joint-driven muscles' path lengths and velocities, handed to
  :class:`~vm_ros.node.inputs.NodeInputs` as kinematics received at that time (so extrapolation,
  staleness, the stale-input policy and the path-length checks are those of muscle_kinematics);
  the moment arms of that joint sample are held (zero-order hold) for the torques.

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
from vm_ros.geometry import JointGeometry, load_geometry

_ENTRY_KEYS = ("coordinate", "sign", "offset")


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
class JointEfforts:
    """What joint_efforts and joint_effort_commands carry, robot convention, ordered by
    ``joints``: position (rad or m), velocity (rad/s or m/s), effort tau (N m or N)."""

    names: tuple[str, ...]
    position: np.ndarray
    velocity: np.ndarray
    effort: np.ndarray


__all__ = ["JointEfforts", "JointMap", "JointSpace", "parse_joint_map"]
