"""Joint-space inputs of `vm-ros simulate --motion`: joint_states sampled from an OpenSim motion,
drives from an ExcitationSeries, conditioned as muscle_node conditions them.

    motion = JointMotion.from_motion(read_motion(path), geometry, needed, hold)
    inputs = MotionInputs(bank.names, excitations, motion, joint_map, conditioning,
                          period_ns, sink)
    u, lp, vp = inputs.advance_to(t_ns)      # offline.OfflineRun's input interface
    inputs.joint_efforts(force)              # joint_efforts of the step's forces

Coordinates come from the motion's columns by name (vm_ros.importers.motion: degrees converted
when its header says ``inDegrees=yes``, rotational columns being the geometry's ``rad``
coordinates); ``hold`` gives a constant value (rad or m, from ``parse_hold``'s text with a unit)
to a coordinate instead (for one the motion lacks, or to freeze one). A coordinate the run needs
(crossed by a muscle of the run) that is neither is an error. Velocities at the frames are the
motion's own speed columns where it has them (an OpenSim states file's ``.../speed``), else the
derivative of a smoothing spline of the positions (``velocity_from_positions``). Between frames
positions and velocities are interpolated linearly; both are held outside the motion. The
motion's first frame is at log time ``start_ns`` (the run's start, vm_ros.recording.run_log);
the excitation files share the motion's time axis. ``box_warnings`` names the frames outside the
geometry's box.

Every ``period_ns`` from ``start_ns`` an excitation message (the drives) and a joint_states
message (every geometry coordinate the motion or ``hold`` gives, under its robot name, robot
convention through the joint map) are logged and handed to a replay.NodeConditioning at that
time, in the order a recompute replays them (excitation first), so that `vm-ros recompute`
reproduces the run.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from vm_ros import telemetry as tm
from vm_ros.errors import VmRosError
from vm_ros.importers.motion import Motion, velocity_from_positions
from vm_ros.joint_space import JointMap
from vm_ros.model.units import UNITS, units_for
from vm_ros.node.joint_inputs import JointSamples
from vm_ros.node.replay import NodeConditioning
from vm_ros.offline.excitations import ExcitationSeries, interpolate_rows
from vm_ros.offline.runner import INPUT_RANK
from vm_ros.recording import bulk
from vm_ros.recording import messages as msgs


@dataclass(frozen=True)
class JointMotion:
    """Model coordinates over time: ``coordinates`` (geometry names), ``time_s`` (k,) from the
    motion's first frame, ``q`` and ``qdot`` (k, m) in rad or m (per s), model convention;
    ``start_s``: the motion's first time (s, on its own axis)."""

    source: str
    coordinates: tuple
    time_s: np.ndarray
    q: np.ndarray
    qdot: np.ndarray
    start_s: float = 0.0

    @property
    def duration_s(self) -> float:
        return float(self.time_s[-1] - self.time_s[0])

    @classmethod
    def from_motion(cls, motion: Motion, geometry, needed, hold: Mapping[str, float]
                    ) -> JointMotion:
        """The geometry's coordinates found in ``motion`` or ``hold`` (``parse_hold``'s, rad or
        m); VmRosError for a ``needed`` coordinate that is in neither."""
        names = geometry.coordinate_names
        missing = [name for name in needed if name not in motion.names and name not in hold]
        if missing:
            raise VmRosError(f"motion {motion.path}: no column for coordinate(s) "
                             f"{', '.join(missing)} (columns: {', '.join(motion.names)}); give "
                             "them with --hold NAME=VALUE (with a unit: 0deg, 0.9m)")
        rotational = rotational_names(geometry)
        values = motion.to_si(rotational)
        speeds = motion.speeds_to_si(rotational)
        time = motion.time - motion.time[0]
        used = [name for name in names if name in motion.names or name in hold]
        q = np.empty((len(time), len(used)))
        qdot = np.zeros_like(q)
        for j, name in enumerate(used):
            if name in hold:
                q[:, j] = float(hold[name])
                continue
            q[:, j] = values[:, motion.names.index(name)]
            qdot[:, j] = speeds[name] if name in speeds else velocity_from_positions(time,
                                                                                      q[:, j])
        return cls(motion.path, tuple(used), time, q, qdot, float(motion.time[0]))

    def at(self, t_s: float) -> tuple[np.ndarray, np.ndarray]:
        """(q, qdot) at ``t_s`` from the first frame (linear between frames, held outside)."""
        q, qdot = self.at_many(np.array([t_s]))
        return q[0], qdot[0]

    def at_many(self, times_s) -> tuple[np.ndarray, np.ndarray]:
        """(q, qdot) (k, m) at each of ``times_s`` (``at`` at each, element for element)."""
        return (interpolate_rows(self.time_s, self.q, times_s),
                interpolate_rows(self.time_s, self.qdot, times_s))


_HOLD_VALUE = re.compile(r"\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*(\S*)\s*")


def parse_hold(texts, geometry, option: str = "--hold") -> dict[str, float]:
    """``["knee_angle_r=30deg", "pelvis_ty=0.9m"]`` -> ``{"knee_angle_r": 0.5236, ...}`` in rad
    or m. The unit is required (deg or rad for a rotational coordinate, m, cm or mm for a
    translational one) and the value must lie in the geometry's box; VmRosError otherwise,
    naming ``option`` (the command-line option the texts come from: --hold, closed-loop's
    --q0)."""
    hold, given = {}, {}
    names = geometry.coordinate_names
    for text in texts or ():
        name, sep, value = (part.strip() for part in text.partition("="))
        match = _HOLD_VALUE.fullmatch(value)
        if not sep or not name or match is None:
            raise VmRosError(f"{option} {text!r}: expected COORDINATE=VALUE with a unit, e.g. "
                             "knee_angle_r=30deg or pelvis_ty=0.9m")
        if name in given:
            raise VmRosError(f"{option} {name}: given twice ({given[name]!r} and {text!r}); "
                             "give each coordinate once")
        given[name] = text
        if name not in names:
            raise VmRosError(f"{option} {name}: not a coordinate of the geometry (it has: "
                             f"{', '.join(names)})")
        coordinate = geometry.coordinates[names.index(name)]
        accepted = units_for(coordinate.unit)
        number, symbol = float(match.group(1)), match.group(2)
        if symbol not in accepted:
            given = f"{symbol!r} is not" if symbol else "no unit is given:"
            raise VmRosError(f"{option} {text!r}: {given} a unit of {name} ({coordinate.unit}); "
                             f"write it with one of {', '.join(accepted)}, e.g. "
                             f"{name}={match.group(1)}{accepted[-1]}")
        si = number * UNITS[symbol].factor
        if not coordinate.lower <= si <= coordinate.upper:
            raise VmRosError(f"{option} {text!r}: outside the geometry's range of {name}, "
                             f"{shown_range(coordinate, symbol)}")
        hold[name] = si
    return hold


def rotational_names(geometry) -> set[str]:
    """The geometry's rotational coordinates, independent and coupled (unit rad): the motion
    columns that ``inDegrees=yes`` puts in degrees."""
    return {c.name for c in (*geometry.coordinates, *geometry.coupled) if c.unit == "rad"}


def shown_unit(unit: str, in_degrees: bool) -> str:
    """The unit a coordinate of ``unit`` (rad or m) is shown in for a motion: deg for a rotational
    one when the motion is in degrees."""
    return "deg" if in_degrees and unit == "rad" else unit


def shown_range(coordinate, symbol: str) -> str:
    """A coordinate's box in the unit ``symbol`` (e.g. '-10 to 120 deg')."""
    factor = UNITS[symbol].factor
    return f"{coordinate.lower / factor:.6g} to {coordinate.upper / factor:.6g} {symbol}"


# |column - coupling| (rad, m) above which a dependent coordinate's motion column warns: an
# IK solution that enforces the coupler matches it to solver precision (far below), a column
# from another model or a wrong unit is off by degrees; 1 deg / 1 mm is also far above the
# coupling table's own interpolation error (linear between COUPLING_POINTS points)
COUPLER_TOLERANCE = {"rad": np.radians(1.0), "m": 1e-3}


def coupled_columns(motion: Motion, geometry) -> tuple[list[str], list[str]]:
    """(warnings, notes) for the motion columns that are dependent coordinates of the geometry:
    not inputs (the geometry's paths follow them from the coordinates they couple to), so their
    values are not used. Where the geometry holds the coupling function and the motion has the
    driver's column, the column is compared with the function of the driver's values (frames
    with the driver inside its box, in SI); a difference beyond COUPLER_TOLERANCE is a warning
    naming the worst frame's time and both values in the motion's unit, else a note."""
    values = motion.to_si(rotational_names(geometry))
    warnings, notes = [], []
    for c in geometry.coupled:
        if c.name not in motion.names:
            continue
        how = f"it follows {', '.join(c.follows)}" if c.follows else "held at one value"
        note = (f"motion {motion.path}: column {c.name} is a dependent coordinate of the "
                f"geometry ({how}): not an input, its values are not used")
        if not c.has_function or c.follows[0] not in motion.names:
            notes.append(note)
            continue
        column = values[:, motion.names.index(c.name)]
        coupled = c.value(values[:, motion.names.index(c.follows[0])])
        difference = np.abs(column - coupled)   # NaN where the driver is outside its box
        symbol = shown_unit(c.unit, motion.in_degrees)
        factor = UNITS[symbol].factor
        tolerance = COUPLER_TOLERANCE[c.unit]
        if not np.isfinite(difference).any():
            notes.append(f"{note} (not checked: {c.follows[0]} stays outside its box)")
        elif np.nanmax(difference) <= tolerance:
            notes.append(f"{note} (it agrees with the coupling within "
                         f"{tolerance / factor:.6g} {symbol})")
        else:
            i = int(np.nanargmax(difference))
            warnings.append(
                f"motion {motion.path}: column {c.name} disagrees with the geometry's coupling "
                f"to {c.follows[0]} by up to {difference[i] / factor:.6g} {symbol} (more than "
                f"{tolerance / factor:.6g} {symbol}): at {motion.time[i]:.6g} s it has "
                f"{column[i] / factor:.6g} {symbol}, the coupling {coupled[i] / factor:.6g} "
                f"{symbol}; the column is not used, the paths follow the coupling")
    return warnings, notes


def box_warnings(motion: JointMotion, geometry, in_degrees: bool) -> list[str]:
    """One warning per motion coordinate with frames outside the geometry's box (clamped to
    it as muscle_node clamps), in the motion's own unit, with both ends of the range."""
    warnings = []
    for j, name in enumerate(motion.coordinates):
        coordinate = geometry.coordinates[geometry.coordinate_names.index(name)]
        q = motion.q[:, j]
        excess = np.maximum(coordinate.lower - q, q - coordinate.upper)  # > 0 outside
        if not (excess > 0).any():
            continue
        symbol = shown_unit(coordinate.unit, in_degrees)
        extreme = q[np.argmax(excess)] / UNITS[symbol].factor
        warnings.append(f"motion {motion.source}: {name} outside the geometry's range "
                        f"{shown_range(coordinate, symbol)} in {int((excess > 0).sum())} of "
                        f"{len(q)} frames (at worst {extreme:.6g} {symbol}): clamped to it")
    return warnings


def motion_checks(motion: Motion, joint_motion: JointMotion, geometry
                  ) -> tuple[list[str], list[str]]:
    """Every check of a motion against a geometry, for the verbs that take a motion (`vm-ros
    simulate --motion`, `vm-ros coordinate`, which runs them before its solve): (warnings,
    notes) from ``Motion.unit_warnings`` of the rotational coordinates used (VmRosError where
    the values cannot be in the header's unit), ``box_warnings`` and ``coupled_columns``."""
    used = rotational_names(geometry) & set(joint_motion.coordinates)
    warnings = motion.unit_warnings(used) + box_warnings(joint_motion, geometry,
                                                         motion.in_degrees)
    coupler_warnings, notes = coupled_columns(motion, geometry)
    return warnings + coupler_warnings, notes


class MotionInputs:
    """Samples, logs and conditions the inputs of a joint-space run (module docstring)."""

    def __init__(self, muscles, excitations: ExcitationSeries, motion: JointMotion,
                 joint_map: JointMap, conditioning: NodeConditioning, period_ns: int, sink,
                 start_ns: int = 0):
        self.muscles = tuple(muscles)
        self.excitations = excitations
        self.motion = motion
        self.conditioning = conditioning
        self.period_ns = int(period_ns)
        self._sink = sink
        index = [joint_map.coordinates.index(name) for name in motion.coordinates]
        self._index = np.array(index, dtype=int)
        self._map = joint_map
        self._robot_names = [joint_map.robot_names[j] for j in index]
        self._start_ns = int(start_ns)  # log time of the motion's first frame
        self._next_ns = self._start_ns

    def _log_and_apply(self, time_ns: int) -> None:
        t_s = (time_ns - self._start_ns) * 1e-9
        drive = self.excitations.at(self.motion.start_s + t_s)
        excitation = msgs.excitation_fields(self.muscles, drive, time_ns)
        q, qdot = self.motion.at(t_s)
        robot_q, robot_qdot, _ = self._map.to_robot(self._index, q, qdot, 0.0)
        joints = msgs.kinematics_fields(self._robot_names, robot_q, robot_qdot, time_ns)
        write = self._sink.write_fields
        write(tm.TOPIC_EXCITATION, tm.TYPE_JOINT_STATE, excitation, time_ns)
        write(tm.TOPIC_JOINT_STATES, tm.TYPE_JOINT_STATE, joints, time_ns)
        # the values as a recompute decodes them from the logged messages
        conditioning = self.conditioning
        conditioning.on_excitation(excitation["name"], excitation["position"], time_ns)
        conditioning.on_joint_states(joints["name"], joints["position"], joints["velocity"],
                                     time_ns)

    def advance_to(self, time_ns: int):
        """Log and apply the samples due at or before ``time_ns``; (U, path length, path
        velocity) for the step starting there."""
        while self._next_ns <= time_ns:
            self._log_and_apply(self._next_ns)
            self._next_ns += self.period_ns
        return self._sample(time_ns)

    def _sample(self, time_ns: int):
        if not self.conditioning.ready:
            raise VmRosError(f"motion {self.motion.source}: the joint_states at "
                             f"{time_ns * 1e-9:.6f} s give no usable path lengths "
                             f"({self.conditioning.issue_text() or 'no joint sample'})")
        return self.conditioning.sample(time_ns)

    def joint_efforts(self, force):
        return self.conditioning.joint_efforts(force)

    def block(self, step_starts_ns: np.ndarray, first_step: int, pending):
        """advance_to for every step start of ``step_starts_ns`` (increasing): the inputs of
        each step, (k, n) each. The samples due are taken at once (interpolated as arrays,
        their messages encoded in bulk into ``pending`` at the step that takes them,
        ``first_step`` + index, as SampledInputs.block does, the geometry evaluated at their
        poses at once), then conditioned as arrays (NodeConditioning.block: the same bits as
        advance_to's messages one by one), or, where that declines (a message not the usual
        accepted one), handed to the conditioning one by one as advance_to hands them (the
        poses evaluated at once beforehand: JointInputs.expect). ``block_samples`` then holds
        the joint sample each step used (JointSamples, a row per step: block_efforts)."""
        last = int(step_starts_ns[-1])
        count = max(0, (last - self._next_ns) // self.period_ns + 1)
        times = self._next_ns + self.period_ns * np.arange(count, dtype=np.int64)
        t_s = (times - self._start_ns) * 1e-9
        drive = self.excitations.at_many(self.motion.start_s + t_s)
        q, qdot = self.motion.at_many(t_s)
        robot_q, robot_qdot, _ = self._map.to_robot(self._index, q, qdot, 0.0)
        if count:
            slots = first_step + np.searchsorted(step_starts_ns, times, side="left")
            muscles = bulk.joint_state_layout(self.muscles, position=len(self.muscles))
            joints = bulk.joint_state_layout(self._robot_names, position=len(self._index),
                                             velocity=len(self._index))
            pending.add(slots * 16 + INPUT_RANK, tm.TOPIC_EXCITATION,
                        muscles.encode(times, position=drive), times)
            pending.add(slots * 16 + INPUT_RANK + 1, tm.TOPIC_JOINT_STATES,
                        joints.encode(times, position=robot_q, velocity=robot_qdot), times)
        conditioning, names = self.conditioning, tuple(self._robot_names)
        done = conditioning.block(self.muscles, drive, names, robot_q, robot_qdot, times,
                                  step_starts_ns)
        if done is not None:
            *inputs, self.block_samples = done
            self._next_ns += count * self.period_ns
            return tuple(inputs)
        if conditioning.joints is not None:
            conditioning.joints.expect(names, robot_q, robot_qdot, times)
        u, lp, vp, self.block_samples = [], [], [], []
        applied = np.searchsorted(times, step_starts_ns, side="right").tolist()
        done = 0
        for step, time_ns in enumerate(step_starts_ns.tolist()):
            for i in range(done, applied[step]):  # as _log_and_apply, values as decoded
                at = int(times[i])
                conditioning.on_excitation(self.muscles, drive[i], at)
                conditioning.on_joint_states(names, robot_q[i], robot_qdot[i], at)
            done = applied[step]
            sample = self._sample(time_ns)
            for rows, value in zip((u, lp, vp), sample, strict=True):
                rows.append(value)
            self.block_samples.append(conditioning.joints.sample
                                      if conditioning.joints is not None else None)
        if conditioning.joints is not None:
            self.block_samples = JointSamples.stack(self.block_samples)
        self._next_ns += count * self.period_ns
        return tuple(np.array(rows) for rows in (u, lp, vp))

    def block_efforts(self, forces):
        """The joint efforts of each step of the last block (``forces`` (k, n), the steps'
        outputs) through the joint sample it used: JointEfforts with (k, n_joints) arrays."""
        return self.conditioning.joints.efforts_many(self.block_samples, forces)


__all__ = ["COUPLER_TOLERANCE", "JointMotion", "MotionInputs", "box_warnings", "coupled_columns",
           "motion_checks", "parse_hold", "rotational_names", "shown_range", "shown_unit",
           "velocity_from_positions"]
