"""Small OpenSim models for the importer tests, built with the OpenSim Python API (planar, 2-4
muscles, quick to sample). Importing this module skips the importing test when opensim is not
installed, so import it inside fixtures (``osim_models.osim`` is the opensim module).

- ``build_knee(path)``: one knee (pin joint, ``knee_angle`` -2.0..0.1 rad, flexion negative) with
  a patella body on its own pin (``patella_angle``) driven from the knee angle by a
  CoordinateCouplerConstraint with a smooth quadratic (PATELLA_COUPLING); ``vas_pat`` runs over a
  via point on the patella; ``ext_wrap`` wraps over a WrapCylinder on the femur in part of the
  range only (from about -0.2 rad of flexion on); ``flex`` is a straight posterior line;
  ``cond`` has a ConditionalPathPoint active for knee_angle > COND_SWITCH only, off the straight
  line, so its length jumps by about 5 mm there (a discontinuous path, for the flag).
- ``build_hip_knee(path)``: hip (``hip_flexion`` -0.5..1.6) and knee (``knee_angle`` -2.0..0.1):
  biarticular ``rf`` (anterior, via a point on the distal femur) and ``ham`` (posterior),
  monoarticular ``vas`` (knee) and ``ilio`` (hip).
"""

from __future__ import annotations

from pathlib import Path

import pytest

from vm_ros.errors import VmRosError
from vm_ros.importers.osim import load_opensim

try:  # load_opensim, not a plain import: it keeps this process's LD_LIBRARY_PATH and PATH intact
    osim = load_opensim()
except VmRosError:
    pytest.skip('the OpenSim tests need the opensim extra (pip install ".[opensim]")',
                allow_module_level=True)

# patella_angle = a2 q^2 + a1 q + a0 (q = knee_angle), PolynomialFunction order: highest first
PATELLA_COUPLING = (0.02, 0.55, 0.0)
KNEE_RANGE = (-2.0, 0.1)
COND_SWITCH = -1.0
HIP_RANGE = (-0.5, 1.6)


def _body(name: str, mass: float = 2.0) -> osim.Body:
    return osim.Body(name, mass, osim.Vec3(0), osim.Inertia(0.01, 0.01, 0.01))


def _pin(name, parent, parent_offset, child, coordinate, value_range, default=0.0):
    joint = osim.PinJoint(name, parent, osim.Vec3(*parent_offset), osim.Vec3(0),
                          child, osim.Vec3(0), osim.Vec3(0))
    c = joint.upd_coordinates(0)
    c.setName(coordinate)
    c.setRangeMin(value_range[0])
    c.setRangeMax(value_range[1])
    c.setDefaultValue(default)
    return joint


def _muscle(model, name, f0, l0, slack, pennation, points):
    """A Millard muscle; l0 and slack chosen so that the longest path puts the fibre near 1.3 l0
    (tendon at slack), as in real models."""
    muscle = osim.Millard2012EquilibriumMuscle(name, f0, l0, slack, pennation)
    for i, (body, xyz) in enumerate(points):
        muscle.addNewPathPoint(f"{name}_p{i}", body, osim.Vec3(*xyz))
    model.addForce(muscle)
    return muscle


def _write(model: osim.Model, path) -> Path:
    model.finalizeConnections()
    model.initSystem()
    path = Path(path)
    model.printToXML(str(path))
    return path


def _model(name: str, bodies: dict):
    """A model with the given bodies (name: mass); the first is welded to the ground 1 m up."""
    model = osim.Model()
    model.setName(name)
    made = [_body(n, m) for n, m in bodies.items()]
    for body in made:
        model.addBody(body)
    model.addJoint(osim.WeldJoint(f"{made[0].getName()}_weld", model.getGround(),
                                  osim.Vec3(0, 1.0, 0), osim.Vec3(0), made[0], osim.Vec3(0),
                                  osim.Vec3(0)))
    return model, made


def build_knee(path) -> Path:
    model, (femur, tibia, patella) = _model("knee_wrap_patella",
                                            {"femur": 5.0, "tibia": 3.0, "patella": 0.1})
    knee = _pin("knee", femur, (0, 0, 0), tibia, "knee_angle", KNEE_RANGE)
    model.addJoint(knee)
    model.addJoint(_pin("patellofemoral", femur, (0, 0, 0), patella, "patella_angle", (-3.0, 3.0)))

    coupler = osim.CoordinateCouplerConstraint()
    coupler.setName("patella_coupler")
    names = osim.ArrayStr()
    names.append("knee_angle")
    coupler.setIndependentCoordinateNames(names)
    coupler.setDependentCoordinateName("patella_angle")
    function = osim.PolynomialFunction(osim.Vector(list(PATELLA_COUPLING)))
    coupler.setFunction(function)
    function.thisown = False  # the constraint may own it (see the OpenSim notes on setFunction)
    model.addConstraint(coupler)

    cylinder = osim.WrapCylinder()
    cylinder.setName("knee_cylinder")
    cylinder.set_radius(0.025)
    cylinder.set_length(0.1)
    cylinder.set_quadrant("+x")
    femur.addWrapObject(cylinder)

    _muscle(model, "vas_pat", 3000.0, 0.12, 0.23, 0.08,
            [(femur, (0.03, 0.22, 0)), (patella, (0.05, 0.0, 0)), (tibia, (0.04, -0.08, 0))])
    wrap = _muscle(model, "ext_wrap", 800.0, 0.08, 0.245, 0.0,
                   [(femur, (0.02, 0.2, 0)), (tibia, (0.03, -0.1, 0))])
    wrap.updGeometryPath().addPathWrap(cylinder)
    _muscle(model, "flex", 1200.0, 0.14, 0.08, 0.15,
            [(femur, (-0.02, 0.2, 0)), (tibia, (-0.02, -0.06, 0))])
    cond = _muscle(model, "cond", 500.0, 0.2, 0.047, 0.0,
                   [(femur, (-0.03, 0.2, 0)), (tibia, (-0.03, -0.1, 0))])
    point = osim.ConditionalPathPoint()
    point.setName("cond_via")
    point.setParentFrame(femur)
    point.set_location(osim.Vec3(-0.05, 0.05, 0))
    point.setCoordinate(knee.upd_coordinates(0))
    point.setRangeMin(COND_SWITCH)
    point.setRangeMax(0.5)
    cond.updGeometryPath().updPathPointSet().insert(1, point)
    point.thisown = False  # the path point set owns it now
    return _write(model, path)


def build_hip_knee(path) -> Path:
    model, (pelvis, femur, tibia) = _model("hip_knee",
                                           {"pelvis": 10.0, "femur": 5.0, "tibia": 3.0})
    model.addJoint(_pin("hip", pelvis, (0, 0, 0), femur, "hip_flexion", HIP_RANGE))
    model.addJoint(_pin("knee", femur, (0, -0.4, 0), tibia, "knee_angle", KNEE_RANGE))

    _muscle(model, "rf", 1200.0, 0.1, 0.36, 0.09,
            [(pelvis, (0.03, -0.05, 0)), (femur, (0.035, -0.38, 0)), (tibia, (0.04, -0.08, 0))])
    _muscle(model, "vas", 5000.0, 0.09, 0.193, 0.05,
            [(femur, (0.03, -0.2, 0)), (femur, (0.035, -0.38, 0)), (tibia, (0.04, -0.08, 0))])
    _muscle(model, "ham", 2500.0, 0.2, 0.25, 0.2,
            [(pelvis, (-0.05, -0.05, 0)), (tibia, (-0.03, -0.06, 0))])
    _muscle(model, "ilio", 1500.0, 0.08, 0.035, 0.14,
            [(pelvis, (0.03, 0.05, 0)), (femur, (0.01, -0.08, 0))])
    return _write(model, path)


def set_pose(model, state, values: dict) -> None:
    """Set coordinates by name and let OpenSim satisfy the constraints (couplers) itself: each
    coordinate is set with enforceConstraints, which holds it while OpenSim assembles the rest."""
    coordinates = model.getCoordinateSet()
    for name, value in values.items():
        coordinates.get(name).setValue(state, float(value), True)
    model.realizePosition(state)


def lengths(model, state, names) -> list[float]:
    muscles = model.getMuscles()
    return [muscles.get(n).getLength(state) for n in names]
