"""OpenSim's exact musculotendon paths for sampling (the ``opensim`` extra), the counterpart of
vm_ros.geometry.mujoco_backend for MuJoCo models.

``OsimPaths`` opens an .osim model and gives every muscle's path length and dL/dq (central
differences, step STEP) at poses of chosen independent coordinates, with the dependent coordinates
of CoordinateCouplerConstraints set from their coupling functions at every pose and held
coordinates (locked, or range min == max) kept at one value. This is the only module of
vm_ros.geometry that imports OpenSim, and it does so inside ``load_opensim``.
"""

from __future__ import annotations

import xml.etree.ElementTree as ElementTree
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from vm_ros.child_process import environment_kept
from vm_ros.errors import VmRosError
from vm_ros.geometry.paths import COUPLING_POINTS, CoupledCoordinate

NEEDS_OPENSIM = 'needs the opensim extra: pip install ".[opensim]"'
STEP = 1e-5                     # central-difference step (rad or m); stable from 1e-3 to 1e-7

_ENVIRONMENT_KEPT = ("LD_LIBRARY_PATH", "PATH", "SIMBODY_HOME")


def load_opensim():
    """The opensim module, or VmRosError with the one line saying how to install it."""
    # Importing opensim rewrites this process's LD_LIBRARY_PATH and PATH (and sets SIMBODY_HOME);
    # child processes (muscle_node, other ROS programs) would then fail to load their libraries.
    # Its own libraries are loaded by then: the environment is put back as it was.
    with environment_kept(_ENVIRONMENT_KEPT):
        try:
            import opensim
        except ImportError as exc:
            raise VmRosError(NEEDS_OPENSIM) from exc
    opensim.Logger.setLevelString("error")
    opensim.Logger.removeFileSink()  # else OpenSim writes opensim.log into the working directory
    return opensim


def check_model_file(path) -> Path:
    """An existing .osim file whose XML root is an OpenSimDocument holding a Model."""
    path = Path(path)
    if not path.is_file():
        raise VmRosError(f"{path}: no such file")
    if path.suffix.lower() != ".osim":
        raise VmRosError(f"{path}: not an .osim file (OpenSim model files end in .osim)")
    try:
        root = ElementTree.parse(path).getroot()
    except (ElementTree.ParseError, OSError) as exc:
        raise VmRosError(f"{path}: not an OpenSim model (not valid XML: {exc})") from None
    if root.tag != "OpenSimDocument" or root.find("Model") is None:
        raise VmRosError(f"{path}: not an OpenSim model (no <OpenSimDocument><Model>)")
    return path


@dataclass
class _Coupler:
    name: str
    dependent: object           # opensim Coordinate
    independent: list           # opensim Coordinates, the function's argument order
    function: object
    scale: float


@dataclass
class OsimPaths:
    """An OpenSim model opened for sampling: independent coordinates, couplers, muscles, and
    path lengths (with gradients by central differences) at poses of chosen coordinates."""

    osim: object
    path: Path
    model: object = field(init=False)
    state: object = field(init=False)

    def __post_init__(self):
        osim = self.osim
        try:
            self.model = osim.Model(str(self.path))
            self.state = self.model.initSystem()
        except Exception as exc:  # noqa: BLE001 - OpenSim raises RuntimeError with C++ text
            first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
            raise VmRosError(f"{self.path}: OpenSim cannot load the model: {first}") from None
        model, state = self.model, self.state
        coordinates = model.getCoordinateSet()
        all_coords = [coordinates.get(i) for i in range(coordinates.getSize())]
        self.coordinate_names = tuple(c.getName() for c in all_coords)
        self.couplers: list[_Coupler] = []
        self.other_constraints: list[str] = []
        constraints = model.getConstraintSet()
        for i in range(constraints.getSize()):
            constraint = constraints.get(i)
            if not constraint.isEnforced(state):
                continue
            coupler = osim.CoordinateCouplerConstraint.safeDownCast(constraint)
            if coupler is None:
                self.other_constraints.append(
                    f"{constraint.getName()} ({constraint.getConcreteClassName()})")
                continue
            names = coupler.getIndependentCoordinateNames()
            scale = float(coupler.getPropertyByName("scale_factor").toString())
            self.couplers.append(_Coupler(
                coupler.getName(), coordinates.get(coupler.getDependentCoordinateName()),
                [coordinates.get(names.get(j)) for j in range(names.getSize())],
                coupler.getFunction(), scale))
        self._order_couplers()
        dependent = {c.dependent.getName() for c in self.couplers}
        self.locked = tuple(c.getName() for c in all_coords if c.getDefaultLocked())
        self.held = self._held(all_coords, dependent)
        self.independent = [c for c in all_coords
                            if c.getName() not in dependent and c.getName() not in self.held]
        if not self.independent:
            raise VmRosError(f"{self.path}: every coordinate is held, none is left to sample: "
                             f"{self.held_text()}")
        self.units = [self._unit(c) for c in self.independent]
        self.defaults = np.array([c.getDefaultValue() for c in self.independent])
        self.ranges = np.array([[c.getRangeMin(), c.getRangeMax()] for c in self.independent])
        muscles = model.getMuscles()
        self.muscles = [muscles.get(i) for i in range(muscles.getSize())]
        self.muscle_names = tuple(m.getName() for m in self.muscles)
        self.evaluations = 0

    def _held(self, all_coords, dependent) -> dict:
        """{name: why} of the coordinates that are no inputs and stay at one value: locked
        (at its default value, as OpenSim holds it), range min == max (set to that value), and
        coupler dependents whose independent coordinates are all held. Each reason says what to
        change in the model to make the coordinate an input."""
        held = {}
        for c in all_coords:
            name, unit = c.getName(), self._unit(c)
            if name in dependent:
                continue
            if c.getDefaultLocked():
                held[name] = (f"locked at {c.getDefaultValue():g} {unit}, unlock it "
                              "(<locked>false</locked>)")
            elif c.getRangeMin() == c.getRangeMax():
                c.setValue(self.state, c.getRangeMin(), False)
                held[name] = (f"range [{c.getRangeMin():g}, {c.getRangeMax():g}] {unit}, held "
                              "there, give it a range (<range>min max</range>)")
        for c in self.couplers:  # in order: a chain's dependents after their drivers
            drivers = [a.getName() for a in c.independent]
            if all(d in held for d in drivers):
                held[c.dependent.getName()] = (f"follows the held {', '.join(drivers)} through "
                                               f"CoordinateCouplerConstraint {c.name}, free "
                                               f"{' or '.join(drivers)}")
        return held

    def held_text(self) -> str:
        """The held coordinates and why, in one line ('' when none)."""
        return "; ".join(f"{name}: {why}" for name, why in self.held.items())

    def _unit(self, coordinate) -> str:
        translational = int(coordinate.getMotionType()) == int(self.osim.Coordinate.Translational)
        return "m" if translational else "rad"

    def _order_couplers(self) -> None:
        """Couplers ordered so that one whose argument is another's dependent comes after it."""
        ordered, pending = [], list(self.couplers)
        while pending:
            done = {c.dependent.getName() for c in pending}
            ready = [c for c in pending
                     if not any(a.getName() in done for a in c.independent)]
            if not ready:
                raise VmRosError(f"{self.path}: coordinate couplers form a cycle: "
                                 f"{', '.join(c.name for c in pending)}")
            ordered += ready
            pending = [c for c in pending if c not in ready]
        self.couplers = ordered

    def coupled_coordinates(self, coordinates=()) -> list[CoupledCoordinate]:
        """The couplers' dependents; for one whose single argument is among ``coordinates``
        (the geometry's, with their boxes) the coupling function sampled at COUPLING_POINTS
        points over that box, through OpenSim's function."""
        boxes = {c.name: c for c in coordinates}
        out = []
        for c in self.couplers:
            follows = tuple(a.getName() for a in c.independent)
            table = {}
            if len(follows) == 1 and follows[0] in boxes:
                box = boxes[follows[0]]
                grid = np.linspace(box.lower, box.upper, COUPLING_POINTS)
                table = {"unit": self._unit(c.dependent), "follows_values": tuple(grid),
                         "values": tuple(self._coupled_value(c, [x]) for x in grid)}
            out.append(CoupledCoordinate(
                c.dependent.getName(), follows,
                f"OpenSim CoordinateCouplerConstraint {c.name}: {c.dependent.getName()} = "
                f"{c.scale:g} * {c.function.getConcreteClassName()}({', '.join(follows)}); set "
                "from the coupling at every sample, so the fitted paths include its effect",
                **table))
        return out

    def _coupled_value(self, coupler: _Coupler, args) -> float:
        """The dependent's value (rad or m) at its arguments' values: scale * f(args)."""
        return coupler.scale * coupler.function.calcValue(self.osim.Vector(
            [float(a) for a in args]))

    def lengths(self, columns, q) -> np.ndarray:
        """Path lengths (n_muscles,) with independent coordinates ``columns`` (indices into
        ``independent``) at values q; the other coordinates keep their defaults."""
        state = self.state
        for j, value in zip(columns, q, strict=True):
            self.independent[j].setValue(state, float(value), False)
        for c in self.couplers:
            c.dependent.setValue(state, self._coupled_value(
                c, [a.getValue(state) for a in c.independent]), False)
        self.model.realizePosition(state)
        self.evaluations += 1
        return np.array([m.getLength(state) for m in self.muscles])

    def lengths_and_gradients(self, columns, q, wrt=None, step: float = STEP):
        """(L (n_muscles,), dL/dq (n_muscles, len(wrt))) at q by central differences; ``wrt``:
        positions within ``columns`` to differentiate (default all)."""
        q = np.asarray(q, dtype=float)
        wrt = range(len(columns)) if wrt is None else wrt
        base = self.lengths(columns, q)
        gradient = np.empty((len(base), len(wrt)))
        for k, j in enumerate(wrt):
            q_plus, q_minus = q.copy(), q.copy()
            q_plus[j] += step
            q_minus[j] -= step
            gradient[:, k] = (self.lengths(columns, q_plus)
                              - self.lengths(columns, q_minus)) / (2.0 * step)
        self.lengths(columns, q)
        return base, gradient


__all__ = ["NEEDS_OPENSIM", "OsimPaths", "STEP", "check_model_file", "load_opensim"]
