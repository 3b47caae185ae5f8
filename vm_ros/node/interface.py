"""muscle_node's interface as its --help shows it: the topics (names and message type names) and
the parameter table, without rclpy or the model, so that ``muscle_node --help`` answers before
either is imported (vm_ros.node.main). vm_ros.node.shell subscribes and publishes these topics."""

from __future__ import annotations

import argparse

from vm_ros import topics as tp
from vm_ros.node.params import PARAMS

# (topic, message type name, description); joint topics only with a geometry. The input topics
# are vm_ros.topics.INPUT_TOPICS, those of role JOINTS only with a geometry.
OUTPUT_TOPICS = (
    (tp.TOPIC_FORCE, tp.TYPE_JOINT_STATE,
     "tendon force (effort[], N), fascicle length and velocity"),
    (tp.TOPIC_ENERGY_RATE, tp.TYPE_FLOAT64_MULTI_ARRAY,
     "energy rate (W) by muscle x fibre (slow, fast, all) x component"),
    (tp.TOPIC_ENERGY_RATE_TOTAL, tp.TYPE_FLOAT64, "energy rate of all muscles (W)"),
    (tp.TOPIC_ENERGY_TOTAL, tp.TYPE_FLOAT64, "energy since the start (J)"),
    (tp.TOPIC_DIAGNOSTICS, tp.TYPE_DIAGNOSTIC_ARRAY, "node health and counters (steady clock)"),
)
MODEL_OUTPUT_TOPICS = (
    (tp.TOPIC_ENERGY_RATE_MODELS, tp.TYPE_FLOAT64_MULTI_ARRAY,
     "published energetics models' rates (W) by muscle x model x component (with "
     "energetics_models)"),
)
JOINT_OUTPUT_TOPICS = (
    (tp.TOPIC_JOINT_EFFORTS, tp.TYPE_JOINT_STATE,
     "joint efforts (N m or N) by joint (with geometry)"),
    (tp.TOPIC_JOINT_EFFORT_COMMANDS, tp.TYPE_FLOAT64_MULTI_ARRAY,
     "joint efforts in joints order (with geometry)"),
)

# with coordination.enabled (vm_ros.node.effort_targets); not in vm_ros.topics.INPUT_TOPICS: a
# run log keeps them as data, and its recompute applies the drives logged on coordination_drive
COORDINATION_INPUT_TOPICS = (
    (tp.TOPIC_JOINT_EFFORT_TRAJECTORY, tp.TYPE_JOINT_TRAJECTORY,
     "planned joint efforts (N m or N): joint_names, points' time_from_start, effort[] and "
     "optionally positions[] (the planned motion) (with coordination.enabled)"),
    (tp.TOPIC_JOINT_EFFORT_TARGETS, tp.TYPE_JOINT_STATE,
     "target joint efforts as a stream: name[], effort[] (with coordination.enabled)"),
    (tp.TOPIC_JOINT_EFFORT_TARGETS_ARRAY, tp.TYPE_FLOAT64_MULTI_ARRAY,
     "target joint efforts as a stream, one per joint in joints order (with "
     "coordination.enabled)"),
)
COORDINATION_OUTPUT_TOPICS = (
    (tp.TOPIC_MUSCLE_DRIVE, tp.TYPE_JOINT_STATE,
     "drive per muscle as used by the last step (position[]) (with coordination.enabled)"),
    (tp.TOPIC_JOINT_RESERVES, tp.TYPE_JOINT_STATE,
     "target minus joint effort (effort[], N m or N) by joint; 0 where untracked (with "
     "coordination.enabled)"),
    (tp.TOPIC_COORDINATION_DRIVE, tp.TYPE_JOINT_STATE,
     "the joint-driven muscles' drives (position[]) over the publish period that starts at the "
     "stamp (with coordination.enabled)"),
)

ROS_ARGS, ROS_ARGS_END = "--ros-args", "--"


def user_arguments(argv) -> list[str]:
    """``argv`` without its program name and its ROS arguments (each ``--ros-args ...`` up to a
    ``--`` or the end), as rclpy's remove_ros_args leaves them."""
    kept, in_ros = [], False
    for arg in list(argv)[1:]:
        if arg == ROS_ARGS:
            in_ros = True
        elif in_ros and arg == ROS_ARGS_END:
            in_ros = False
        elif not in_ros:
            kept.append(arg)
    return kept


def _topic_lines(topics) -> list[str]:
    return [f"  {topic} ({type_name}): {text}" for topic, type_name, text in topics]


def input_topics(geometry: bool) -> tuple:
    """(topic, message type name, description) of the input topics: those of role JOINTS only
    with a ``geometry``."""
    return tuple((row.name, row.type_name, row.text) for row in tp.INPUT_TOPICS
                 if geometry or row.role != tp.JOINTS)


def argument_parser() -> argparse.ArgumentParser:
    """muscle_node's parser: no options of its own but --help, which lists topics and
    parameters."""
    lines = [f"  {p.name} ({p.kind}, default {p.default!r}): {p.describe()}" for p in PARAMS]
    epilog = ["inputs (reliable, keep last qos_depth; relative names):",
              *_topic_lines(input_topics(geometry=True) + COORDINATION_INPUT_TOPICS),
              "outputs (reliable, keep last qos_depth):",
              *_topic_lines(OUTPUT_TOPICS + JOINT_OUTPUT_TOPICS + COORDINATION_OUTPUT_TOPICS),
              "parameters:", *lines,
              "The node interface (layouts, bad inputs, diagnostics) is described in "
              "docs/node.md and the README."]
    return argparse.ArgumentParser(
        prog="muscle_node", formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Virtual Muscle force and fibre-type energetics as a ROS 2 node. Set "
                    "parameters with --ros-args -p NAME:=VALUE or --params-file FILE.",
        epilog="\n".join(epilog))


__all__ = ["COORDINATION_INPUT_TOPICS", "COORDINATION_OUTPUT_TOPICS", "JOINT_OUTPUT_TOPICS",
           "MODEL_OUTPUT_TOPICS", "OUTPUT_TOPICS", "argument_parser", "input_topics",
           "user_arguments"]
