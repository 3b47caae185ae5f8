"""Topic names and message type names of vm_ros (vm_ros.telemetry describes them and their array
layouts). Declared here, in a module that imports nothing of the model or ROS, so that a
program's --help (the topic table of muscle_node) loads neither.

INPUT_TOPICS is the one table of input topics: muscle_node's subscriptions and its --help, the
node-log replay (vm_ros.node.replay), the offline runner (vm_ros.offline.runner) and the run log's
channels all read it, and dispatch a message by its row's ``role`` (input_topic: an unknown topic
is an UnknownInputTopicError, never a fall-through). A new input topic is one row here.
"""

from dataclasses import dataclass

from vm_ros.errors import VmRosError

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
# live coordination (muscle_node with coordination.enabled; vm_ros.node.effort_targets)
TOPIC_JOINT_EFFORT_TRAJECTORY = "joint_effort_trajectory"
TOPIC_JOINT_EFFORT_TARGETS = "joint_effort_targets"
TOPIC_JOINT_EFFORT_TARGETS_ARRAY = "joint_effort_targets_array"
TOPIC_MUSCLE_DRIVE = "muscle_drive"
TOPIC_JOINT_RESERVES = "joint_reserves"
# the joint-driven muscles' drives of a publish period, stamped and logged at its start: what
# the coordinator applied, so that a run log of live coordination can be recomputed
TOPIC_COORDINATION_DRIVE = "coordination_drive"

TYPE_JOINT_STATE = "sensor_msgs/msg/JointState"
TYPE_FLOAT64_MULTI_ARRAY = "std_msgs/msg/Float64MultiArray"
TYPE_FLOAT64 = "std_msgs/msg/Float64"
TYPE_DIAGNOSTIC_ARRAY = "diagnostic_msgs/msg/DiagnosticArray"
TYPE_JOINT_TRAJECTORY = "trajectory_msgs/msg/JointTrajectory"

# the roles of an input topic: what its values are and where they go
DRIVE = "drive"  # drive U per muscle, in [0, 1] (NodeInputs.on_drive)
PATH = "path"  # muscle path length (m) and lengthening velocity (m/s) (NodeInputs.on_path)
JOINTS = "joints"  # joint coordinates and velocities through a geometry (JointInputs)
ROLE_FIELDS = {DRIVE: 1, PATH: 2, JOINTS: 2}  # how many value fields a role's message gives


@dataclass(frozen=True)
class InputTopic:
    """| field | meaning |
    | name | topic (relative name) |
    | type_name | ROS message type name |
    | role | DRIVE, PATH or JOINTS (ROLE_FIELDS) |
    | by_name | the message names its entries (JointState ``name[]``; empty: all, in order);
      False: one value per muscle in the ``muscles`` order |
    | fields | the message fields holding the role's values, in the role's order: (drive,) or
      (length or position, velocity) |
    | text | what muscle_node's --help says of it |
    """

    name: str
    type_name: str
    role: str
    by_name: bool
    fields: tuple
    text: str

    def __post_init__(self):
        if len(self.fields) != ROLE_FIELDS.get(self.role, -1):
            raise ValueError(f"input topic {self.name}: role {self.role!r} with fields "
                             f"{self.fields} (roles and their field counts: {ROLE_FIELDS})")


INPUT_TOPICS = (
    InputTopic(TOPIC_EXCITATION, TYPE_JOINT_STATE, DRIVE, True, ("position",),
               "drive per muscle by name: name[], position[] in [0, 1]"),
    InputTopic(TOPIC_EXCITATION_ARRAY, TYPE_FLOAT64_MULTI_ARRAY, DRIVE, False, ("data",),
               "drive, one per muscle in muscles order"),
    InputTopic(TOPIC_KINEMATICS, TYPE_JOINT_STATE, PATH, True, ("position", "velocity"),
               "muscle path length (position[], m) and velocity (velocity[], m/s) by name"),
    InputTopic(TOPIC_JOINT_STATES, TYPE_JOINT_STATE, JOINTS, True, ("position", "velocity"),
               "robot joint positions and velocities (with geometry)"),
)


class UnknownInputTopicError(VmRosError, KeyError):
    """A topic that is not in INPUT_TOPICS was handed to an input path."""

    def __str__(self) -> str:
        return str(self.args[0])


def input_topic(name: str) -> InputTopic:
    """The row of INPUT_TOPICS for ``name``; UnknownInputTopicError when there is none."""
    for row in INPUT_TOPICS:
        if row.name == name:
            return row
    raise UnknownInputTopicError(f"{name!r} is not an input topic (input topics: "
                                 f"{', '.join(row.name for row in INPUT_TOPICS)})")


def input_topic_names() -> tuple:
    """The names of INPUT_TOPICS, in their order."""
    return tuple(row.name for row in INPUT_TOPICS)


def lost_key(topic: str) -> str:
    """muscle_node's /diagnostics key of the messages lost on one input topic (publisher
    sequence gaps, vm_ros.node.health.SequenceGaps)."""
    return f"lost: {topic} (messages)"


def header_stamp_ns(message) -> int:
    """The header stamp of an input message (ns), 0 for a type without a header
    (Float64MultiArray)."""
    header = getattr(message, "header", None)
    if header is None:
        return 0
    return header.stamp.sec * 1_000_000_000 + header.stamp.nanosec


def apply_input(row: InputTopic, message, receivers, time_ns: int):
    """Hand the values of ``message`` (an object with the message's fields as attributes) on
    ``row``'s topic to ``receivers[row.role]`` as (topic, names or None, *values, time_ns);
    returns what the receiver returns. ``receivers`` maps every role to a callable."""
    names = message.name if row.by_name else None
    return receivers[row.role](row.name, names, *(getattr(message, f) for f in row.fields),
                               time_ns)


TOPIC_TYPES = {
    **{row.name: row.type_name for row in INPUT_TOPICS},
    TOPIC_FORCE: TYPE_JOINT_STATE,
    TOPIC_ENERGY_RATE: TYPE_FLOAT64_MULTI_ARRAY,
    TOPIC_ENERGY_RATE_TOTAL: TYPE_FLOAT64,
    TOPIC_ENERGY_TOTAL: TYPE_FLOAT64,
    TOPIC_ENERGY_RATE_MODELS: TYPE_FLOAT64_MULTI_ARRAY,
    TOPIC_DIAGNOSTICS: TYPE_DIAGNOSTIC_ARRAY,
    TOPIC_JOINT_EFFORTS: TYPE_JOINT_STATE,
    TOPIC_JOINT_EFFORT_COMMANDS: TYPE_FLOAT64_MULTI_ARRAY,
    TOPIC_JOINT_WORK: TYPE_FLOAT64_MULTI_ARRAY,
    TOPIC_JOINT_EFFORT_TRAJECTORY: TYPE_JOINT_TRAJECTORY,
    TOPIC_JOINT_EFFORT_TARGETS: TYPE_JOINT_STATE,
    TOPIC_JOINT_EFFORT_TARGETS_ARRAY: TYPE_FLOAT64_MULTI_ARRAY,
    TOPIC_MUSCLE_DRIVE: TYPE_JOINT_STATE,
    TOPIC_JOINT_RESERVES: TYPE_JOINT_STATE,
    TOPIC_COORDINATION_DRIVE: TYPE_JOINT_STATE,
}

__all__ = [
    "DRIVE",
    "INPUT_TOPICS",
    "JOINTS",
    "PATH",
    "ROLE_FIELDS",
    "InputTopic",
    "UnknownInputTopicError",
    "apply_input",
    "header_stamp_ns",
    "input_topic",
    "lost_key",
    "input_topic_names",
    "TOPIC_DIAGNOSTICS",
    "TOPIC_ENERGY_RATE",
    "TOPIC_ENERGY_RATE_MODELS",
    "TOPIC_ENERGY_RATE_TOTAL",
    "TOPIC_ENERGY_TOTAL",
    "TOPIC_COORDINATION_DRIVE",
    "TOPIC_EXCITATION",
    "TOPIC_EXCITATION_ARRAY",
    "TOPIC_FORCE",
    "TOPIC_JOINT_EFFORTS",
    "TOPIC_JOINT_EFFORT_COMMANDS",
    "TOPIC_JOINT_EFFORT_TARGETS",
    "TOPIC_JOINT_EFFORT_TARGETS_ARRAY",
    "TOPIC_JOINT_EFFORT_TRAJECTORY",
    "TOPIC_JOINT_RESERVES",
    "TOPIC_MUSCLE_DRIVE",
    "TOPIC_JOINT_STATES",
    "TOPIC_JOINT_WORK",
    "TOPIC_KINEMATICS",
    "TOPIC_TYPES",
    "TYPE_DIAGNOSTIC_ARRAY",
    "TYPE_FLOAT64",
    "TYPE_FLOAT64_MULTI_ARRAY",
    "TYPE_JOINT_STATE",
    "TYPE_JOINT_TRAJECTORY",
]
