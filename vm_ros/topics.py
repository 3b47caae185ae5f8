"""Topic names and message type names of vm_ros (vm_ros.telemetry describes them and their array
layouts). Declared here, in a module that imports nothing, so that a program's --help (the topic
table of muscle_node) loads neither the model nor ROS."""

TOPIC_EXCITATION = "excitation"
TOPIC_EXCITATION_ARRAY = "excitation_array"
TOPIC_KINEMATICS = "muscle_kinematics"
TOPIC_FORCE = "muscle_force"
TOPIC_ENERGY_RATE = "energy_rate"
TOPIC_ENERGY_RATE_TOTAL = "energy_rate_total"
TOPIC_ENERGY_TOTAL = "energy_total"
TOPIC_ENERGY_RATE_MODELS = "energy_rate_models"
TOPIC_DIAGNOSTICS = "/diagnostics"
TOPIC_JOINT_STATES = "joint_states"
TOPIC_JOINT_EFFORTS = "joint_efforts"
TOPIC_JOINT_EFFORT_COMMANDS = "joint_effort_commands"
TOPIC_JOINT_WORK = "joint_work"  # logged by offline runs only (vm_ros.offline.runner)

TYPE_JOINT_STATE = "sensor_msgs/msg/JointState"
TYPE_FLOAT64_MULTI_ARRAY = "std_msgs/msg/Float64MultiArray"
TYPE_FLOAT64 = "std_msgs/msg/Float64"
TYPE_DIAGNOSTIC_ARRAY = "diagnostic_msgs/msg/DiagnosticArray"

TOPIC_TYPES = {
    TOPIC_EXCITATION: TYPE_JOINT_STATE,
    TOPIC_EXCITATION_ARRAY: TYPE_FLOAT64_MULTI_ARRAY,
    TOPIC_KINEMATICS: TYPE_JOINT_STATE,
    TOPIC_FORCE: TYPE_JOINT_STATE,
    TOPIC_ENERGY_RATE: TYPE_FLOAT64_MULTI_ARRAY,
    TOPIC_ENERGY_RATE_TOTAL: TYPE_FLOAT64,
    TOPIC_ENERGY_TOTAL: TYPE_FLOAT64,
    TOPIC_ENERGY_RATE_MODELS: TYPE_FLOAT64_MULTI_ARRAY,
    TOPIC_DIAGNOSTICS: TYPE_DIAGNOSTIC_ARRAY,
    TOPIC_JOINT_STATES: TYPE_JOINT_STATE,
    TOPIC_JOINT_EFFORTS: TYPE_JOINT_STATE,
    TOPIC_JOINT_EFFORT_COMMANDS: TYPE_FLOAT64_MULTI_ARRAY,
    TOPIC_JOINT_WORK: TYPE_FLOAT64_MULTI_ARRAY,
}

__all__ = [
    "TOPIC_DIAGNOSTICS",
    "TOPIC_ENERGY_RATE",
    "TOPIC_ENERGY_RATE_MODELS",
    "TOPIC_ENERGY_RATE_TOTAL",
    "TOPIC_ENERGY_TOTAL",
    "TOPIC_EXCITATION",
    "TOPIC_EXCITATION_ARRAY",
    "TOPIC_FORCE",
    "TOPIC_JOINT_EFFORTS",
    "TOPIC_JOINT_EFFORT_COMMANDS",
    "TOPIC_JOINT_STATES",
    "TOPIC_JOINT_WORK",
    "TOPIC_KINEMATICS",
    "TOPIC_TYPES",
    "TYPE_DIAGNOSTIC_ARRAY",
    "TYPE_FLOAT64",
    "TYPE_FLOAT64_MULTI_ARRAY",
    "TYPE_JOINT_STATE",
]
