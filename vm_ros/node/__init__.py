"""muscle_node: the ROS 2 program around MuscleBank, and its conditioning without ROS.

shell (the rclpy node and the program's main), params (the parameter table), inputs (messages to
step arrays, every bad input counted), health (issue kinds, diagnostics values), timing (fixed
steps by elapsed ROS time), recording (the node's run log), replay (the node's conditioning
replayed from a log without rclpy) and motion_inputs (an OpenSim motion conditioned as the node
would). Only shell imports rclpy; ``main`` imports it when called.
"""


def main(args=None) -> int:
    """The muscle_node entry point (console script ``muscle_node``, ``python -m vm_ros.node``)."""
    from vm_ros.node.shell import main as shell_main

    return shell_main(args)
