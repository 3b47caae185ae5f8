# ruff: noqa: E501  (verbatim .msg lines)
"""Bundled ROS 2 message definitions and RIHS01 type hashes (GENERATED, do not edit).

Regenerate with ``scripts/gen-msg-definitions``. Standard texts are verbatim copies of
``share/<pkg>/msg/<Type>.msg`` of the ROS 2 Jazzy packages (std_msgs 5.3.6, sensor_msgs
5.3.6, diagnostic_msgs 5.3.6, trajectory_msgs 5.3.6, builtin_interfaces 2.0.3), hashes
from the packages' ``.json`` files; vm_ros types come from msg_defs/, hashed with rosidl's
own generator.
test/test_recording_definitions.py checks that nothing has drifted.
"""

MSG_TEXTS = {
    'builtin_interfaces/msg/Duration': (
        '# Duration defines a period between two time points.\n'
        '# Messages of this datatype are of ROS Time following this design:\n'
        '# https://design.ros2.org/articles/clock_and_time.html\n'
        '\n'
        '# The seconds component, valid over all int32 values.\n'
        'int32 sec\n'
        '\n'
        '# The nanoseconds component, valid in the range [0, 1e9), to be added to the seconds component. \n'
        '# e.g.\n'
        '# The duration -1.7 seconds is represented as {sec: -2, nanosec: 3e8}\n'
        '# The duration 1.7 seconds is represented as {sec: 1, nanosec: 7e8}\n'
        'uint32 nanosec\n'
    ),
    'builtin_interfaces/msg/Time': (
        '# This message communicates ROS Time defined here:\n'
        '# https://design.ros2.org/articles/clock_and_time.html\n'
        '\n'
        '# The seconds component, valid over all int32 values.\n'
        'int32 sec\n'
        '\n'
        '# The nanoseconds component, valid in the range [0, 1e9), to be added to the seconds component. \n'
        '# e.g.\n'
        '# The time -1.7 seconds is represented as {sec: -2, nanosec: 3e8}\n'
        '# The time 1.7 seconds is represented as {sec: 1, nanosec: 7e8}\n'
        'uint32 nanosec\n'
    ),
    'diagnostic_msgs/msg/DiagnosticArray': (
        '# This message is used to send diagnostic information about the state of the robot.\n'
        'std_msgs/Header header # for timestamp\n'
        'DiagnosticStatus[] status # an array of components being reported on\n'
    ),
    'diagnostic_msgs/msg/DiagnosticStatus': (
        '# This message holds the status of an individual component of the robot.\n'
        '\n'
        '# Possible levels of operations.\n'
        'byte OK=0\n'
        'byte WARN=1\n'
        'byte ERROR=2\n'
        'byte STALE=3\n'
        '\n'
        '# Level of operation enumerated above.\n'
        'byte level\n'
        '# A description of the test/component reporting.\n'
        'string name\n'
        '# A description of the status.\n'
        'string message\n'
        '# A hardware unique string.\n'
        'string hardware_id\n'
        '# An array of values associated with the status.\n'
        'KeyValue[] values\n'
        '\n'
    ),
    'diagnostic_msgs/msg/KeyValue': (
        '# What to label this value when viewing.\n'
        'string key\n'
        '# A value to track over time.\n'
        'string value\n'
    ),
    'sensor_msgs/msg/JointState': (
        '# This is a message that holds data to describe the state of a set of torque controlled joints.\n'
        '#\n'
        '# The state of each joint (revolute or prismatic) is defined by:\n'
        '#  * the position of the joint (rad or m),\n'
        '#  * the velocity of the joint (rad/s or m/s) and\n'
        '#  * the effort that is applied in the joint (Nm or N).\n'
        '#\n'
        '# Each joint is uniquely identified by its name\n'
        '# The header specifies the time at which the joint states were recorded. All the joint states\n'
        '# in one message have to be recorded at the same time.\n'
        '#\n'
        '# This message consists of a multiple arrays, one for each part of the joint state.\n'
        '# The goal is to make each of the fields optional. When e.g. your joints have no\n'
        '# effort associated with them, you can leave the effort array empty.\n'
        '#\n'
        '# All arrays in this message should have the same size, or be empty.\n'
        '# This is the only way to uniquely associate the joint name with the correct\n'
        '# states.\n'
        '\n'
        'std_msgs/Header header\n'
        '\n'
        'string[] name\n'
        'float64[] position\n'
        'float64[] velocity\n'
        'float64[] effort\n'
    ),
    'std_msgs/msg/Float64': (
        '# This was originally provided as an example message.\n'
        '# It is deprecated as of Foxy\n'
        '# It is recommended to create your own semantically meaningful message.\n'
        '# However if you would like to continue using this please use the equivalent in example_msgs.\n'
        '\n'
        'float64 data\n'
    ),
    'std_msgs/msg/Float64MultiArray': (
        '# This was originally provided as an example message.\n'
        '# It is deprecated as of Foxy\n'
        '# It is recommended to create your own semantically meaningful message.\n'
        '# However if you would like to continue using this please use the equivalent in example_msgs.\n'
        '\n'
        '# Please look at the MultiArrayLayout message definition for\n'
        '# documentation on all multiarrays.\n'
        '\n'
        'MultiArrayLayout  layout        # specification of data layout\n'
        'float64[]         data          # array of data\n'
    ),
    'std_msgs/msg/Header': (
        '# Standard metadata for higher-level stamped data types.\n'
        '# This is generally used to communicate timestamped data\n'
        '# in a particular coordinate frame.\n'
        '\n'
        '# Two-integer timestamp that is expressed as seconds and nanoseconds.\n'
        'builtin_interfaces/Time stamp\n'
        '\n'
        '# Transform frame with which this data is associated.\n'
        'string frame_id\n'
    ),
    'std_msgs/msg/MultiArrayDimension': (
        '# This was originally provided as an example message.\n'
        '# It is deprecated as of Foxy\n'
        '# It is recommended to create your own semantically meaningful message.\n'
        '# However if you would like to continue using this please use the equivalent in example_msgs.\n'
        '\n'
        'string label   # label of given dimension\n'
        'uint32 size    # size of given dimension (in type units)\n'
        'uint32 stride  # stride of given dimension\n'
    ),
    'std_msgs/msg/MultiArrayLayout': (
        '# This was originally provided as an example message.\n'
        '# It is deprecated as of Foxy\n'
        '# It is recommended to create your own semantically meaningful message.\n'
        '# However if you would like to continue using this please use the equivalent in example_msgs.\n'
        '\n'
        '# The multiarray declares a generic multi-dimensional array of a\n'
        '# particular data type.  Dimensions are ordered from outer most\n'
        '# to inner most.\n'
        '#\n'
        '# Accessors should ALWAYS be written in terms of dimension stride\n'
        '# and specified outer-most dimension first.\n'
        '#\n'
        '# multiarray(i,j,k) = data[data_offset + dim_stride[1]*i + dim_stride[2]*j + k]\n'
        '#\n'
        '# A standard, 3-channel 640x480 image with interleaved color channels\n'
        '# would be specified as:\n'
        '#\n'
        '# dim[0].label  = "height"\n'
        '# dim[0].size   = 480\n'
        '# dim[0].stride = 3*640*480 = 921600  (note dim[0] stride is just size of image)\n'
        '# dim[1].label  = "width"\n'
        '# dim[1].size   = 640\n'
        '# dim[1].stride = 3*640 = 1920\n'
        '# dim[2].label  = "channel"\n'
        '# dim[2].size   = 3\n'
        '# dim[2].stride = 3\n'
        '#\n'
        '# multiarray(i,j,k) refers to the ith row, jth column, and kth channel.\n'
        '\n'
        'MultiArrayDimension[] dim # Array of dimension properties\n'
        'uint32 data_offset        # padding bytes at front of data\n'
    ),
    'trajectory_msgs/msg/JointTrajectory': (
        '# The header is used to specify the coordinate frame and the reference time for\n'
        '# the trajectory durations\n'
        'std_msgs/Header header\n'
        '\n'
        '# The names of the active joints in each trajectory point. These names are\n'
        '# ordered and must correspond to the values in each trajectory point.\n'
        'string[] joint_names\n'
        '\n'
        '# Array of trajectory points, which describe the positions, velocities,\n'
        '# accelerations and/or efforts of the joints at each time point.\n'
        'JointTrajectoryPoint[] points\n'
    ),
    'trajectory_msgs/msg/JointTrajectoryPoint': (
        '# Each trajectory point specifies either positions[, velocities[, accelerations]]\n'
        '# or positions[, effort] for the trajectory to be executed.\n'
        '# All specified values are in the same order as the joint names in JointTrajectory.msg.\n'
        '\n'
        '# Single DOF joint positions for each joint relative to their "0" position.\n'
        '# The units depend on the specific joint type: radians for revolute or\n'
        '# continuous joints, and meters for prismatic joints.\n'
        'float64[] positions\n'
        '\n'
        '# The rate of change in position of each joint. Units are joint type dependent.\n'
        '# Radians/second for revolute or continuous joints, and meters/second for\n'
        '# prismatic joints.\n'
        'float64[] velocities\n'
        '\n'
        '# Rate of change in velocity of each joint. Units are joint type dependent.\n'
        '# Radians/second^2 for revolute or continuous joints, and meters/second^2 for\n'
        '# prismatic joints.\n'
        'float64[] accelerations\n'
        '\n'
        '# The torque or the force to be applied at each joint. For revolute/continuous\n'
        '# joints effort denotes a torque in newton-meters. For prismatic joints, effort\n'
        '# denotes a force in newtons.\n'
        'float64[] effort\n'
        '\n'
        '# Desired time from the trajectory start to arrive at this trajectory point.\n'
        'builtin_interfaces/Duration time_from_start\n'
    ),
    'vm_ros/msg/MuscleTelemetry': (
        '# One model step of a vm_ros muscle bank, for offline analysis.\n'
        '#\n'
        '# Logged to MCAP by muscle_node and `vm-ros simulate`; never published on the wire (a custom\n'
        '# message type would need a colcon build), so `ros2 bag play` skips it.\n'
        '#\n'
        '# Units are SI. n = len(name). Array layouts (0-based indices):\n'
        '#   per muscle                      [i]                 length n\n'
        '#   per muscle and fibre type       [i*2 + j]           length 2n,  j: 0 slow, 1 fast\n'
        '#   energy, per muscle, fibre type  [i*12 + j*4 + k]    length 12n, j: 0 slow, 1 fast, 2 all;\n'
        '#   and component                                       k: 0 activation, 1 cross_bridge,\n'
        '#                                                          2 recovery, 3 total\n'
        '# The energy layout is the one of the energy_rate topic.\n'
        '\n'
        'std_msgs/Header header             # stamp: model time at the end of the step\n'
        '\n'
        'string[] name                      # muscle names, in bank order\n'
        '\n'
        '# inputs of the step, per muscle\n'
        'float64[] excitation               # drive U as used, clipped to [0, 1]\n'
        'float64[] path_length              # musculotendon path length at the start of the step (m)\n'
        'float64[] path_velocity            # path lengthening velocity over the step (m/s)\n'
        '\n'
        '# mechanics, per muscle\n'
        'float64[] effective_drive          # filtered drive Ueff (U for natural units)\n'
        'float64[] force                    # tendon force F_SE (N)\n'
        'float64[] contractile_force        # contractile force F_CE (N)\n'
        'float64[] fascicle_length          # fascicle length (m)\n'
        'float64[] fascicle_velocity        # fascicle velocity (m/s), negative when shortening\n'
        'float64[] mechanical_power         # -F_CE * fascicle velocity (W), positive when shortening\n'
        'float64[] mechanical_work          # mechanical power integrated since reset (J)\n'
        '\n'
        '# activation, per muscle and fibre type\n'
        'float64[] firing_rate              # effective firing rate f_eff (f0.5), PCSA-weighted mean\n'
        "float64[] recruited_fraction       # recruited fraction of the fibre type's PCSA\n"
        'float64[] effective_activation     # effective activation Acteff\n'
        '\n'
        '# energetics, per muscle, fibre type and component\n'
        'float64[] energy_rate              # energy rate (W)\n'
        'float64[] energy                   # energy since reset (J)\n'
        '\n'
        '# whole bank\n'
        'float64 total_energy_rate          # energy rate (W)\n'
        'float64 total_energy               # energy since reset (J)\n'
    ),
}

TYPE_HASHES = {
    'builtin_interfaces/msg/Duration':
        'RIHS01_e8d009f659816f758b75334ee1a9ca5b5c0b859843261f14c7f937349599d93b',
    'builtin_interfaces/msg/Time':
        'RIHS01_b106235e25a4c5ed35098aa0a61a3ee9c9b18d197f398b0e4206cea9acf9c197',
    'diagnostic_msgs/msg/DiagnosticArray':
        'RIHS01_5a8a36efb05fb25070fa0fb3810290c0e6cd4862b54a8fb975a1ee8dc55a333e',
    'diagnostic_msgs/msg/DiagnosticStatus':
        'RIHS01_b0e3e692ea2d54a8af2f4ef1930e81556a2db55216b771f8a7d2724ed47bf0e4',
    'diagnostic_msgs/msg/KeyValue':
        'RIHS01_d68081eaa540288c5440753baecef0c4e16e81a5f78ad68902ded5100413bb42',
    'sensor_msgs/msg/JointState':
        'RIHS01_a13ee3a330e346c9d87b5aa18d24e11690752bd33a0350f11c5882bc9179260e',
    'std_msgs/msg/Float64':
        'RIHS01_705ba9c3d1a09df43737eb67095534de36fd426c0587779bda2bc51fe790182a',
    'std_msgs/msg/Float64MultiArray':
        'RIHS01_1025ddc6b9552d191f89ef1a8d2f60f3d373e28b283d8891ddcc974e8c55397f',
    'std_msgs/msg/Header':
        'RIHS01_f49fb3ae2cf070f793645ff749683ac6b06203e41c891e17701b1cb597ce6a01',
    'std_msgs/msg/MultiArrayDimension':
        'RIHS01_5e773a60a4c7fc8a54985f307c7837aa2994252a126c301957a24e31282c9cbe',
    'std_msgs/msg/MultiArrayLayout':
        'RIHS01_4c66e6f78e740ac103a94cf63259f968e48c617e7699e829b63c21a5cb50dac6',
    'trajectory_msgs/msg/JointTrajectory':
        'RIHS01_179b33eba59d676f6d967ac71fe35e7ca2f64b2f3928f4a018cec115e213796e',
    'trajectory_msgs/msg/JointTrajectoryPoint':
        'RIHS01_de8907036d8bd45aac6f30cc9044a3d4a329c42cbf719aff7d95a584cfa532d7',
    'vm_ros/msg/MuscleTelemetry':
        'RIHS01_924ec5d44c492ab80a18938b8df24f2c3444c97323fa422e3f0981a778bf2b28',
}
