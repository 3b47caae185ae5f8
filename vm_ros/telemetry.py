"""What the node publishes and the logs record: topic names, message types and array layouts.

Topic and type names are declared in vm_ros.topics (and re-exported here), layouts once here; the
node (rclpy messages) and the offline recorder (CDR from dicts, no ROS) both build their messages
from these functions, so live and offline logs have the same channels.

Topics (relative names, so namespaces and remapping apply):

| topic | type | content |
| excitation | sensor_msgs/msg/JointState | in: name[] muscles, position[] drive U in [0, 1] |
| excitation_array | std_msgs/msg/Float64MultiArray | in: drive U ordered as the muscles parameter |
| muscle_kinematics | sensor_msgs/msg/JointState | in: position[] path length (m), velocity[]
  path lengthening velocity (m/s, optional) |
| muscle_force | sensor_msgs/msg/JointState | out: effort[] tendon force (N), position[] fascicle
  length (m), velocity[] fascicle velocity (m/s), stamped with model time |
| energy_rate | std_msgs/msg/Float64MultiArray | out: W, layout (muscle, fibre, component) below |
| energy_rate_total | std_msgs/msg/Float64 | out: whole-body energy rate (W) |
| energy_total | std_msgs/msg/Float64 | out: whole-body energy since start (J) |
| energy_rate_models | std_msgs/msg/Float64MultiArray | out (with energetics models): W, layout
  (muscle, model, component) below |
| /diagnostics | diagnostic_msgs/msg/DiagnosticArray | out: node health at about 1 Hz |

With a geometry (vm_ros.joint_space):

| joint_states | sensor_msgs/msg/JointState | in: name[] robot joints, position[] (rad or m),
  velocity[] (rad/s or m/s, optional) |
| joint_efforts | sensor_msgs/msg/JointState | out: name[] the joints parameter, position[] and
  velocity[] the coordinates used (robot convention, after clamping), effort[] generalized force
  tau = r^T F (N m or N, robot convention), stamped with model time |
| joint_effort_commands | std_msgs/msg/Float64MultiArray | out: tau ordered by the joints
  parameter (ros2_control forward_command_controller effort convention); layout.dim[0] "joint" |
| joint_work | std_msgs/msg/Float64MultiArray | logged by offline runs only (simulate,
  recompute), not published by muscle_node: per joint of joint_efforts, the work of the joint
  torques since the start, sum over the model steps of tau qdot dt (J); layout.dim[0] "joint" |

energy_rate layout: ``data[i*12 + j*4 + k]`` = muscle i (order of the ``muscles`` parameter),
fibre j in FIBRE_LABELS = (slow, fast, all), component k in COMPONENT_LABELS = (activation,
cross_bridge, recovery, total). layout.dim[0..2] carry the labels "muscle", "fibre", "component"
with sizes and strides; layout.data_offset = 0.

energy_rate_models layout (the published energetics models the run selected,
vm_ros.model.energetics_models): ``data[i*M*C + j*C + k]`` = muscle i (order of the ``muscles``
parameter), model j (the run's models, in the order of the registry MODEL_NAMES), component k in
MODEL_COMPONENT_LABELS = (activation_maintenance, shortening_lengthening, basal,
mechanical_work, total), C = 5; NaN where a model has no such component. Each layout.dim's
label is the axis name, a colon and its entries separated by commas, so that a subscriber needs
nothing else to read it: ``muscle:vasti,rectus_femoris``, ``model:umberger2010,bhargava2004``,
``component:activation_maintenance,...,total`` (split_dim_label); sizes and strides as above,
layout.data_offset = 0.
"""

from __future__ import annotations

import numpy as np

from vm_ros.model.energetics_models.in_bank import COMPONENTS as MODEL_COMPONENTS
from vm_ros.model.records import ENERGY_COMPONENTS, StepOutput
from vm_ros.topics import *  # noqa: F403 - the topic and type names, declared there

FIBRE_LABELS = ("slow", "fast", "all")
COMPONENT_LABELS = ENERGY_COMPONENTS  # activation, cross_bridge, recovery, total
MODEL_COMPONENT_LABELS = MODEL_COMPONENTS  # of the published models (energy_rate_models)


def energy_partition(by_fibre, total) -> np.ndarray:
    """(n, 3, 4): fibre (slow, fast, all) x component, from EnergyRates per fibre (n, 2) and per
    muscle (n,); rates (W) or energies (J)."""
    return np.concatenate([by_fibre.as_array(), total.as_array()[:, None, :]], axis=1)


def energy_rate_rows(components, rates) -> np.ndarray:
    """Energy rates (W) as (..., n_muscles, 3 fibre labels, 4 components) from a step record's
    energy components (..., n, 2, 3) and rates (..., n, 4), one step or many: per fibre type
    the three components and their sum, then the muscle's rates."""
    by_fibre = np.concatenate([components, components.sum(axis=-1)[..., None]], axis=-1)
    return np.concatenate([by_fibre, rates[..., None, :]], axis=-2)


def energy_rate_array(out: StepOutput) -> np.ndarray:
    """Energy rates (W) as (n_muscles, 3 fibre labels, 4 components)."""
    return energy_rate_rows(out.record.energy_components, out.record.energy_rates)


def energy_rate_layout(n_muscles: int) -> list[dict]:
    """MultiArrayDimension fields (label, size, stride) of energy_rate, outermost first."""
    f, c = len(FIBRE_LABELS), len(COMPONENT_LABELS)
    return [
        {"label": "muscle", "size": n_muscles, "stride": n_muscles * f * c},
        {"label": "fibre", "size": f, "stride": f * c},
        {"label": "component", "size": c, "stride": c},
    ]


def energy_rate_models_layout(muscles, models) -> list[dict]:
    """MultiArrayDimension fields of energy_rate_models, outermost first; each label is
    ``axis:entry,entry,...`` (module docstring)."""
    c, m = len(MODEL_COMPONENT_LABELS), len(models)
    return [
        {"label": "muscle:" + ",".join(muscles), "size": len(muscles),
         "stride": len(muscles) * m * c},
        {"label": "model:" + ",".join(models), "size": m, "stride": m * c},
        {"label": "component:" + ",".join(MODEL_COMPONENT_LABELS), "size": c, "stride": c},
    ]


def split_dim_label(label: str) -> tuple[str, tuple]:
    """``"model:a,b"`` -> ``("model", ("a", "b"))``; a label without a colon has no entries."""
    axis, _, entries = str(label).partition(":")
    return axis, tuple(entry for entry in entries.split(",") if entry)


def energy_rate_models_fields(out: StepOutput, muscles, models) -> dict:
    """std_msgs/Float64MultiArray fields of the energy_rate_models message (a StepOutput of a
    bank with ``energetics_models``)."""
    return {"layout": {"dim": energy_rate_models_layout(muscles, models), "data_offset": 0},
            "data": np.asarray(out.energy_rate_models, dtype=float).ravel().tolist()}


def stamp_fields(time_ns: int) -> dict:
    """builtin_interfaces/Time fields for an integer nanosecond time."""
    return {"sec": int(time_ns // 1_000_000_000), "nanosec": int(time_ns % 1_000_000_000)}


def force_fields(out: StepOutput, names, time_ns: int, frame_id: str = "") -> dict:
    """sensor_msgs/JointState fields of the muscle_force message."""
    return {
        "header": {"stamp": stamp_fields(time_ns), "frame_id": frame_id},
        "name": list(names),
        "position": out.fascicle_length.tolist(),
        "velocity": out.fascicle_velocity.tolist(),
        "effort": out.force.tolist(),
    }


def energy_rate_fields(out: StepOutput) -> dict:
    """std_msgs/Float64MultiArray fields of the energy_rate message."""
    array = energy_rate_array(out)
    return {"layout": {"dim": energy_rate_layout(array.shape[0]), "data_offset": 0},
            "data": array.ravel().tolist()}


def joint_efforts_fields(efforts, time_ns: int, frame_id: str = "") -> dict:
    """sensor_msgs/JointState fields of joint_efforts from a vm_ros.joint_space.JointEfforts."""
    return {
        "header": {"stamp": stamp_fields(time_ns), "frame_id": frame_id},
        "name": list(efforts.names),
        "position": efforts.position.tolist(),
        "velocity": efforts.velocity.tolist(),
        "effort": efforts.effort.tolist(),
    }


def muscle_drive_fields(names, drive, time_ns: int) -> dict:
    """sensor_msgs/JointState fields of muscle_drive: the drive U per muscle (position[])."""
    return {"header": {"stamp": stamp_fields(time_ns), "frame_id": ""}, "name": list(names),
            "position": np.asarray(drive, dtype=float).tolist(), "velocity": [], "effort": []}


def joint_effort_commands_fields(efforts) -> dict:
    """std_msgs/Float64MultiArray fields of joint_effort_commands: tau in ``joints`` order."""
    return _joint_array_fields(efforts.effort)


def joint_work_fields(work_j) -> dict:
    """std_msgs/Float64MultiArray fields of joint_work: per joint of joint_efforts (same order)
    the work of the joint torques since the start, sum over the model steps of tau qdot dt (J)."""
    return _joint_array_fields(work_j)


def joint_array_layout(n: int) -> list[dict]:
    """MultiArrayLayout dims of joint_effort_commands and joint_work: one value per joint."""
    return [{"label": "joint", "size": n, "stride": n}]


def _joint_array_fields(values) -> dict:
    return {"layout": {"dim": joint_array_layout(len(values)), "data_offset": 0},
            "data": np.asarray(values, dtype=float).tolist()}
