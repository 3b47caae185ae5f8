"""Field dicts of the run-log messages not built by vm_ros.telemetry: the inputs, the Float64
totals and the offline-only vm_ros/msg/MuscleTelemetry record (msg_defs/MuscleTelemetry.msg).

Each function returns the nested dict that vm_ros.recording.cdr.serialize encodes.
"""

from __future__ import annotations

import numpy as np

from vm_ros.model import StepOutput
from vm_ros.telemetry import energy_partition, stamp_fields

TOPIC_TELEMETRY = "muscle_telemetry"
TYPE_MUSCLE_TELEMETRY = "vm_ros/msg/MuscleTelemetry"


def _header(time_ns: int, frame_id: str = "") -> dict:
    return {"stamp": stamp_fields(time_ns), "frame_id": frame_id}


def excitation_fields(names, excitation, time_ns: int) -> dict:
    """sensor_msgs/JointState of the excitation input: position[] = drive U."""
    return {"header": _header(time_ns), "name": list(names),
            "position": np.asarray(excitation, dtype=float).tolist()}


def kinematics_fields(names, path_length, path_velocity, time_ns: int) -> dict:
    """sensor_msgs/JointState of the muscle_kinematics input: position[] path length (m),
    velocity[] path lengthening velocity (m/s; None leaves it empty)."""
    fields = {"header": _header(time_ns), "name": list(names),
              "position": np.asarray(path_length, dtype=float).tolist()}
    if path_velocity is not None:
        fields["velocity"] = np.asarray(path_velocity, dtype=float).tolist()
    return fields


def float64_fields(value: float) -> dict:
    """std_msgs/Float64."""
    return {"data": float(value)}


def telemetry_fields(out: StepOutput, names, time_ns: int, path_length, path_velocity) -> dict:
    """vm_ros/msg/MuscleTelemetry of one step (layouts in msg_defs/MuscleTelemetry.msg)."""

    def flat(array) -> list:
        return np.asarray(array, dtype=float).ravel().tolist()

    return {
        "header": _header(time_ns),
        "name": list(names),
        "excitation": flat(out.excitation),
        "path_length": flat(path_length),
        "path_velocity": flat(path_velocity),
        "effective_drive": flat(out.effective_drive),
        "force": flat(out.force),
        "contractile_force": flat(out.contractile_force),
        "fascicle_length": flat(out.fascicle_length),
        "fascicle_velocity": flat(out.fascicle_velocity),
        "mechanical_power": flat(out.mechanical_power),
        "mechanical_work": flat(out.mechanical_work),
        "firing_rate": flat(out.firing_rate_f05),
        "recruited_fraction": flat(out.recruited_fraction),
        "effective_activation": flat(out.effective_activation),
        "energy_rate": flat(energy_partition(out.energy_rate_by_fibre, out.energy_rate)),
        "energy": flat(energy_partition(out.energy_by_fibre, out.energy)),
        "total_energy_rate": float(out.total_energy_rate),
        "total_energy": float(out.total_energy),
    }
