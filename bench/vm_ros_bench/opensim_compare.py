"""OpenSim's side of ``vm-ros bench --compare`` (the comparison: vm_ros_bench.peer_compare)."""

from __future__ import annotations

import numpy as np

from vm_ros.errors import VmRosError
from vm_ros.importers.osim import load_opensim
from vm_ros_bench.model_bench import DT
from vm_ros_bench.peers import PeerStepper, bench_inputs

TENDON_SLACK_OVER_L0T = 0.964  # config/muscles.yaml conversion rule 3: L0T = Ls / 0.964


def opensim_missing() -> str | None:
    """None when OpenSim can be imported, else the reason."""
    try:
        load_opensim()
    except VmRosError as exc:
        return str(exc)
    return None


def opensim_version() -> str:
    return load_opensim().__version__


class OpensimMuscles(PeerStepper):
    """``n`` Millard 2012 muscles with Umberger 2010 probe entries (module docstring)."""

    def __init__(self, n: int):
        osim = load_opensim()
        _, _, _, bank = bench_inputs(n)
        model = osim.Model()
        model.setName("vm_ros_bench")
        controller = osim.PrescribedController()
        probe = osim.Umberger2010MuscleMetabolicsProbe(True, True, True, True)
        probe.setName("umberger")
        probe.set_report_total_metabolics_only(False)
        # one prescribed slider: coordinate q moves +-2 % of the first muscle's rest length at
        # 1 Hz; muscle i runs from a ground point at q_rest - rest_i to the slider's body
        rest = bank.l0_m + bank.l0t_m
        q_rest = float(rest[0])
        body = osim.Body("insertion", 1.0, osim.Vec3(0), osim.Inertia(0.01))
        model.addBody(body)
        joint = osim.SliderJoint("path", model.getGround(), osim.Vec3(0), osim.Vec3(0), body,
                                 osim.Vec3(0), osim.Vec3(0))
        coordinate = joint.updCoordinate()
        coordinate.setName("path_length")
        coordinate.setPrescribedFunction(osim.Sine(0.02 * q_rest, 2 * np.pi, 0.0, q_rest))
        coordinate.setDefaultIsPrescribed(True)
        coordinate.setDefaultValue(q_rest)
        coordinate.setRangeMin(0.5 * q_rest)
        coordinate.setRangeMax(1.5 * q_rest)
        model.addJoint(joint)
        for i in range(n):
            muscle = osim.Millard2012EquilibriumMuscle(
                f"m{i}", float(bank.f0[i]), float(bank.l0_m[i]),
                float(bank.l0t_m[i] * TENDON_SLACK_OVER_L0T), 0.0)
            muscle.addNewPathPoint("origin", model.getGround(),
                                   osim.Vec3(q_rest - float(rest[i]), 0, 0))
            muscle.addNewPathPoint("insertion", body, osim.Vec3(0))
            model.addForce(muscle)
            controller.addActuator(muscle)
            controller.prescribeControlForActuator(f"m{i}",
                                                   osim.Sine(0.45, 2 * np.pi * 2.0, float(i), 0.5))
        model.addController(controller)
        model.addProbe(probe)
        for i, spec in enumerate(bank.specs):
            probe.addMuscle(f"m{i}", float(spec.fpcsa_slow))
        state = model.initSystem()
        model.equilibrateMuscles(state)
        self.model, self.probe, self.state = model, probe, state
        self.muscles = [osim.Millard2012EquilibriumMuscle.safeDownCast(
            model.getMuscles().get(f"m{i}")) for i in range(n)]
        self.manager = osim.Manager(model)
        # no record of past states: kept, it makes every step dearer as the run goes on
        # (docs/performance.md)
        self.manager.setWriteToStorage(False)
        self.manager.setRecordStatesTrajectory(False)
        self.manager.initialize(state)
        self.k = 0
        self.force, self.rate = [0.0] * n, np.zeros(n)

    def advance(self, steps: int) -> None:
        model, manager, probe, muscles = self.model, self.manager, self.probe, self.muscles
        k = self.k
        for _ in range(steps):
            state = manager.integrate((k + 1) * DT)
            model.realizeReport(state)
            self.force = [muscle.getTendonForce(state) for muscle in muscles]
            self.rate = probe.getProbeOutputs(state).to_numpy()
            k += 1
        self.k = k

    def reading(self) -> dict:
        # the probe's outputs: the total, the basal rate, then each muscle's rate
        return {"total_force_n": float(np.sum(self.force)),
                "total_energy_rate_w": float(self.rate[0])}
