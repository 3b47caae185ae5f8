"""MuJoCo's own muscle as a peer in ``vm-ros bench --compare`` (when the ``mujoco`` wheel is
installed): ``n`` muscle actuators stepped by ``mj_step`` from Python at 1 ms, beside the same
number of vm_ros muscles.

The model, built in code as MJCF (the layout of the OpenSim peer in
vm_ros_bench.opensim_compare): one body (1 kg) on a slide joint (axis x) and per muscle a
spatial tendon from its own site on the world to a site on the body, the sites placed so that the
tendon's length is its muscle's rest length (L0 + L0T) when the joint is at the first muscle's;
on each tendon a ``<muscle>`` actuator (MuJoCo's muscle dynamics, gain and bias: rigid tendon,
one activation state, no recruitment, no energetics) with the vm_ros muscle's F0 and an optimal
length equal to its L0 (``lengthrange`` spans ``range`` = 0.75..1.05 L0 with the rest length at
1 L0). One joint for all, as a model with many muscles per joint has (a slide joint per muscle
adds cost: docs/performance.md). Each step sets the
slider's position and velocity (the path of the other systems) and the excitations as ``ctrl``,
calls ``mj_step`` and reads ``actuator_force``: what a user of MuJoCo from Python does per control
step. This compares cost, not physiology (different models; MuJoCo reports no energy).
"""

from __future__ import annotations

import numpy as np

from vm_ros_bench.model_bench import DT
from vm_ros_bench.peers import PeerStepper, bench_inputs

MUSCLE_RANGE_L0 = (0.75, 1.05)  # MuJoCo's default <muscle range> (normalised length)
NEEDS_MUJOCO = "the mujoco package is not installed (pip install '.[mujoco]')"


def missing() -> str | None:
    """None when MuJoCo can be imported, else the reason."""
    try:
        import mujoco  # noqa: F401
    except ImportError:
        return NEEDS_MUJOCO
    return None


def version() -> str:
    import mujoco

    return mujoco.__version__


def muscles_mjcf(f0_n, l0_m, rest_m) -> str:
    """MJCF of one slide-joint body pulled by ``len(f0_n)`` ``<muscle>`` actuators on spatial
    tendons, tendon i of length q - rest_0 + rest_i at joint position q (module docstring)."""
    lo, hi = MUSCLE_RANGE_L0
    q_rest = float(rest_m[0])
    sites, tendons, actuators = [], [], []
    for i, (f0, l0, rest) in enumerate(zip(f0_n, l0_m, rest_m, strict=True)):
        length_min = rest - (1.0 - lo) * l0
        length_max = length_min + (hi - lo) * l0
        sites.append(f'<site name="origin{i}" pos="{q_rest - rest:.17g} 0 0"/>')
        tendons.append(f'<spatial name="path{i}"><site site="origin{i}"/>'
                       '<site site="insertion"/></spatial>')
        actuators.append(f'<muscle name="m{i}" tendon="path{i}" force="{f0:.17g}" '
                         f'range="{lo:g} {hi:g}" lengthrange="{length_min:.17g} '
                         f'{length_max:.17g}"/>')
    body = ('<body name="insertion"><joint name="path" type="slide" axis="1 0 0" '
            f'range="{0.5 * q_rest:.17g} {1.5 * q_rest:.17g}"/>'
            '<geom type="sphere" size="0.01" mass="1" contype="0" conaffinity="0"/>'
            '<site name="insertion"/></body>')
    return ("<mujoco><compiler autolimits=\"true\"/>"
            f"<option timestep=\"{DT:g}\" gravity=\"0 0 0\"/>"
            "<worldbody>" + "".join(sites) + body + "</worldbody><tendon>" +
            "".join(tendons) + "</tendon><actuator>" + "".join(actuators) +
            "</actuator></mujoco>")


class MujocoMuscles(PeerStepper):
    """``n`` MuJoCo muscles driven like the vm_ros bank of :func:`bench_inputs`."""

    def __init__(self, n: int):
        import mujoco

        self._mujoco = mujoco
        self.u, lp, vp, bank = bench_inputs(n)
        self.q, self.qdot = lp[:, 0].copy(), vp[:, 0].copy()
        rest = bank.l0_m + bank.l0t_m
        self.model = mujoco.MjModel.from_xml_string(muscles_mjcf(bank.f0, bank.l0_m, rest))
        self.data = mujoco.MjData(self.model)
        self.data.qpos[0] = self.q[0]
        self.k = 0
        self.force = np.zeros(n)

    def advance(self, steps: int) -> None:
        mujoco, model, data = self._mujoco, self.model, self.data
        u, q, qdot, period = self.u, self.q, self.qdot, len(self.u)
        k = self.k
        for _ in range(steps):
            j = k % period
            data.qpos[0] = q[j]
            data.qvel[0] = qdot[j]
            data.ctrl[:] = u[j]
            mujoco.mj_step(model, data)
            self.force = data.actuator_force.copy()
            k += 1
        self.k = k

    def reading(self) -> dict:
        # MuJoCo's actuator force is signed along the tendon (pulling is negative)
        return {"total_force_n": float(-self.force.sum()), "total_energy_rate_w": None}
