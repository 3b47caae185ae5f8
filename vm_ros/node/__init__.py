"""muscle_node: the ROS 2 program around MuscleBank, and its conditioning without ROS.

shell (the rclpy node and the program's main), params (the parameter table), startup (parameters
to the model and the start-up error line, without ROS), inputs (messages to step arrays, every
bad input counted), health (issue kinds, diagnostics values), timing (fixed steps by elapsed ROS
time), signals (SIGINT/SIGTERM as a flag), recording (the node's run log), replay (the node's
conditioning replayed from a log without rclpy) and motion_inputs (an OpenSim motion conditioned
as the node would), interface (its topics and --help). Only shell imports rclpy; ``main``
imports it when called, after the arguments are parsed.
"""


def main(args=None) -> int:
    """The muscle_node entry point (console script ``muscle_node``, ``python -m vm_ros.node``).

    SIGINT/SIGTERM handlers go in before rclpy is imported (about 0.5 s), so that a signal at
    any time after this point is a clean stop. The arguments (ROS arguments aside) are parsed
    before rclpy and the model are imported: ``--help`` (and a wrong argument) answers at once."""
    import sys

    from vm_ros.node.signals import ShutdownRequest, main_after_signals

    ShutdownRequest.install()
    from vm_ros.node.interface import argument_parser, user_arguments

    argument_parser().parse_args(user_arguments(sys.argv if args is None else args))

    def import_main():
        from vm_ros.node.shell import main as shell_main

        return shell_main

    return main_after_signals(import_main, args)
