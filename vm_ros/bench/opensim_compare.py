"""Side by side with OpenSim (when the ``opensim`` wheel is installed): one Millard 2012
equilibrium muscle with the Umberger 2010 metabolics probe, against one vm_ros muscle, both
driven by the same excitation and the same path length, advanced in 1 ms steps from Python.

The OpenSim model: a slider joint whose coordinate is the musculotendon path length (prescribed,
a 1 Hz sinusoid of +-2 % about rest), a Millard2012EquilibriumMuscle with the vm_ros muscle's
F0, L0 and tendon slack length (L0T x 0.964, the inverse of config/muscles.yaml's conversion),
no pennation, a PrescribedController with a sinusoidal excitation (0.5 +- 0.45, 2 Hz), and an
Umberger2010MuscleMetabolicsProbe (activation/maintenance, shortening, basal and work terms) with
the muscle's slow-twitch fraction. Each step is ``Manager.integrate(t + 1 ms)`` followed by
reading the tendon force and the probe's rate (state realized to Report): what a user of OpenSim
from Python does per control step. This compares cost, not physiology (different models).
"""

from __future__ import annotations

import statistics
import time

import numpy as np

from vm_ros.bench.model_bench import DT
from vm_ros.errors import VmRosError
from vm_ros.importers.osim import load_opensim

TENDON_SLACK_OVER_L0T = 0.964  # config/muscles.yaml conversion rule 3: L0T = Ls / 0.964


def available() -> bool:
    try:
        load_opensim()
    except VmRosError:
        return False
    return True


def _drive(t):
    return 0.5 + 0.45 * np.sin(2 * np.pi * 2.0 * t)


def _opensim_model(f0, l0, l0t, slow_fraction, rest_length):
    osim = load_opensim()

    model = osim.Model()
    model.setName("vm_ros_bench")
    body = osim.Body("insertion_body", 1.0, osim.Vec3(0), osim.Inertia(0.01))
    model.addBody(body)
    joint = osim.SliderJoint("path", model.getGround(), osim.Vec3(0), osim.Vec3(0), body,
                             osim.Vec3(0), osim.Vec3(0))
    coordinate = joint.updCoordinate()
    coordinate.setName("path_length")
    coordinate.setPrescribedFunction(
        osim.Sine(0.02 * rest_length, 2 * np.pi, 0.0, rest_length)
    )
    coordinate.setDefaultIsPrescribed(True)
    coordinate.setDefaultValue(rest_length)
    coordinate.setRangeMin(0.5 * rest_length)
    coordinate.setRangeMax(1.5 * rest_length)
    model.addJoint(joint)
    muscle = osim.Millard2012EquilibriumMuscle("muscle", float(f0), float(l0),
                                               float(l0t * TENDON_SLACK_OVER_L0T), 0.0)
    muscle.addNewPathPoint("origin", model.getGround(), osim.Vec3(0))
    muscle.addNewPathPoint("insertion", body, osim.Vec3(0))
    model.addForce(muscle)
    controller = osim.PrescribedController()
    controller.addActuator(muscle)
    controller.prescribeControlForActuator("muscle", osim.Sine(0.45, 2 * np.pi * 2.0, 0.0, 0.5))
    model.addController(controller)
    probe = osim.Umberger2010MuscleMetabolicsProbe(True, True, True, True)
    probe.setName("umberger")
    model.addProbe(probe)
    probe.addMuscle("muscle", float(slow_fraction))
    state = model.initSystem()
    model.equilibrateMuscles(state)
    return model, muscle, probe, state


def compare(muscle: str = "vastus_lateralis", seconds: float = 2.0, repeats: int = 5) -> dict:
    """Per-step wall time (median over ``repeats`` runs of ``seconds``) of OpenSim and vm_ros
    for one muscle, and the mean force and energy rate each reports over the last run."""
    from vm_ros.model import MuscleBank

    # its per-call integration summary would be timed too; no opensim.log in the working directory
    osim = load_opensim()
    bank = MuscleBank.from_config([muscle])
    spec = bank.specs[0]
    rest = float(bank.l0_m[0] + bank.l0t_m[0])
    steps = int(round(seconds / DT))
    t = DT * np.arange(steps)
    u = _drive(t)[:, None]
    lp = (rest + 0.02 * rest * np.sin(2 * np.pi * t))[:, None]
    vp = (0.02 * rest * 2 * np.pi * np.cos(2 * np.pi * t))[:, None]

    opensim_times, vm_times = [], []
    for _ in range(repeats):
        model, os_muscle, probe, state = _opensim_model(bank.f0[0], bank.l0_m[0], bank.l0t_m[0],
                                                        spec.fpcsa_slow, rest)
        manager = osim.Manager(model)
        manager.initialize(state)
        forces, rates = [], []
        start = time.perf_counter()
        for k in range(steps):
            state = manager.integrate((k + 1) * DT)
            model.realizeReport(state)
            forces.append(os_muscle.getTendonForce(state))
            rates.append(probe.getProbeOutputs(state).get(0))
        opensim_times.append((time.perf_counter() - start) / steps)
        bank.reset(lp[0], excitation=u[0])
        vm_forces, vm_rates = [], []
        start = time.perf_counter()
        for k in range(steps):
            out = bank.step(DT, u[k], lp[k], vp[k])
            vm_forces.append(out.force[0])
            vm_rates.append(out.energy_rate.total[0])
        vm_times.append((time.perf_counter() - start) / steps)
    opensim_step = statistics.median(opensim_times)
    vm_step = statistics.median(vm_times)
    return {
        "muscle": spec.name, "seconds": seconds, "repeats": repeats,
        "opensim_version": osim.__version__,
        "opensim_step_us": 1e6 * opensim_step, "vm_ros_step_us": 1e6 * vm_step,
        "opensim_over_vm_ros": opensim_step / vm_step,
        "opensim_mean_force_n": float(np.mean(forces)),
        "vm_ros_mean_force_n": float(np.mean(vm_forces)),
        "opensim_mean_energy_rate_w": float(np.mean(rates)),
        "vm_ros_mean_energy_rate_w": float(np.mean(vm_rates)),
        "vm_ros_backend": bank.backend,
    }
