"""Cross-check for item 10 of test/validation/REPORT.md (joint torque): the same sweep with the
source models' own Hill-type muscles in OpenSim, and the OpenSim path lengths written into
config/joint_validation.yaml (`reference_paths`).

    .venv/bin/python test/validation/joint_torque_opensim.py MODELS_DIR

MODELS_DIR holds Rajagopal2016.osim and arm26.osim from github:opensim-org/opensim-models (no
licence file: used here, not committed). Needs the opensim extra (OpenSim 4.6). For each angle:
the posture of config/joint_validation.yaml, agonists at activation 1 and every other muscle at 0
(Millard muscles' minimum activation set to 0), muscles equilibrated, torque = sign * sum of
tendon force x computeMomentArm. Prints path lengths (m) and torque / peak.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import opensim as osim

SWEEPS = {
    # file, posture (deg), coordinate, agonists, angles (deg), torque sign (positive = published)
    "knee": ("Rajagopal2016.osim", {"hip_flexion_r": 80.0}, "knee_angle_r",
             ("vaslat_r", "vasint_r", "vasmed_r", "recfem_r"), range(0, 121, 10), -1.0),
    "elbow": ("arm26.osim", {"r_shoulder_elev": 0.0}, "r_elbow_flex",
              ("BIClong", "BICshort", "BRA"), range(0, 131, 10), 1.0),
}


def sweep(path: Path, posture, coordinate, agonists, angles, sign):
    model = osim.Model(str(path))
    muscles = model.getMuscles()
    for i in range(muscles.getSize()):
        millard = osim.Millard2012EquilibriumMuscle.safeDownCast(muscles.get(i))
        if millard:
            millard.set_minimum_activation(0.0)
    state = model.initSystem()
    coords = model.getCoordinateSet()
    for name, value in posture.items():
        coords.get(name).setValue(state, np.radians(value), False)
    joint = coords.get(coordinate)
    rows = []
    for angle in angles:
        joint.setValue(state, np.radians(angle), True)
        for i in range(muscles.getSize()):
            muscles.get(i).setActivation(state, 1.0 if muscles.get(i).getName() in agonists
                                         else 0.0)
        model.equilibrateMuscles(state)
        model.realizeDynamics(state)
        net = active = 0.0
        for i in range(muscles.getSize()):
            muscle = muscles.get(i)
            torque = sign * muscle.computeMomentArm(state, joint) * muscle.getTendonForce(state)
            net += torque
            active += torque if muscle.getName() in agonists else 0.0
        lengths = [muscles.get(name).getLength(state) for name in agonists]
        rows.append((angle, net, active, lengths))
    return rows


def main(models_dir: str) -> None:
    for key, (file, posture, coordinate, agonists, angles, sign) in SWEEPS.items():
        rows = sweep(Path(models_dir) / file, posture, coordinate, agonists, angles, sign)
        angle = np.array([r[0] for r in rows], dtype=float)
        net, active = (np.array([r[k] for r in rows]) for k in (1, 2))
        print(f"{key} ({file}, {posture}): angles {angle.astype(int).tolist()}")
        for j, name in enumerate(agonists):
            print(f"  path {name}: {[round(r[3][j], 5) for r in rows]}")
        for label, torque in (("net", net), ("agonists", active)):
            print(f"  {label}: peak {torque.max():.1f} N m at {angle[np.argmax(torque)]:.0f} deg;"
                  f" torque/peak {np.round(torque / torque.max(), 2).tolist()}")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else ".")
