"""Joint space: musculoskeletal geometry that maps joint coordinates to musculotendon paths and
muscle forces back to joint torques (NumPy only at run time).

- ``paths``: the interface (JointGeometry, GeometryOutput), the polynomial back end and
  ``generalized_forces``; sign conventions.
- ``polynomial``: the basis and its vectorised evaluation; ``kernel``: the compiled evaluator.
- ``file``: the versioned geometry file (YAML); ``fit``: fitting polynomials to sampled paths.
- ``checks``: what a geometry must give over its coordinate box to be loaded (paths > 1 mm).
- exact paths of source models (optional extras, build time and MuJoCo co-simulation):
  ``mujoco_backend`` (MuJoCo), ``opensim_backend`` (OpenSim); vm_ros.importers samples them.
"""

from vm_ros.geometry.file import load_geometry, write_geometry
from vm_ros.geometry.paths import (
    Coordinate,
    CoupledCoordinate,
    FitReport,
    GeometryOutput,
    JointGeometry,
    MusclePath,
    PolynomialGeometry,
    generalized_forces,
)

__all__ = ["Coordinate", "CoupledCoordinate", "FitReport", "GeometryOutput", "JointGeometry",
           "MusclePath", "PolynomialGeometry", "generalized_forces", "load_geometry",
           "write_geometry"]
