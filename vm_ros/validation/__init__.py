"""Validation of the model against Tsianos, Rustin & Loeb 2012 (docs/validation.md): each item
as a check with explicit numeric criteria. ``vm-ros validate`` runs them all (vm_ros.cli.validate),
draws them (vm_ros.validation.plots) and tabulates them."""

from __future__ import annotations

from collections.abc import Callable

from vm_ros.validation.held_out import check_held_out
from vm_ros.validation.joint_torque import (
    JOINT_TORQUE_BANDS,
    JOINT_TORQUE_KNOWN_GAPS,
    CheckSkippedError,
    JointTorqueSweep,
    check_joint_torque,
    published_ratio,
)
from vm_ros.validation.knee_extension import FIG7_EXPERIMENT_BAND_J, check_fig7_knee_extension
from vm_ros.validation.lumped_steps import check_lumped_steps
from vm_ros.validation.paper import (
    check_fig2_energy_velocity,
    check_fig3_fibre_type_energy,
    check_fig4_biceps_velocity_sweep,
    check_fig5_fibre_composition,
    check_fig6_drive,
    check_fig9_lumped_steady,
    check_fig10_lumped_sinusoidal,
    check_lumped_cost,
)
from vm_ros.validation.results import CheckResult, Criterion
from vm_ros.validation.walk import check_walk

CHECKS: dict[str, Callable[..., CheckResult]] = {
    "fig2": check_fig2_energy_velocity,
    "fig3": check_fig3_fibre_type_energy,
    "fig4": check_fig4_biceps_velocity_sweep,
    "fig5": check_fig5_fibre_composition,
    "fig6": check_fig6_drive,
    "fig7": check_fig7_knee_extension,
    "fig9": check_fig9_lumped_steady,
    "fig10": check_fig10_lumped_sinusoidal,
    "steps": check_lumped_steps,
    "held_out": check_held_out,
    "cost": check_lumped_cost,
    "joint_torque": check_joint_torque,
    "walk": check_walk,
}


__all__ = ["CHECKS", "FIG7_EXPERIMENT_BAND_J", "JOINT_TORQUE_BANDS", "JOINT_TORQUE_KNOWN_GAPS",
           "CheckResult", "CheckSkippedError", "Criterion", "JointTorqueSweep", "published_ratio"]
