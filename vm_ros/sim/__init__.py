"""Simulators that close the loop with muscle_node over ROS 2 (optional extras).

- ``mujoco_node``: a MuJoCo model stepped in (scaled) real time, publishing ``joint_states`` and
  applying ``joint_effort_commands`` as generalized forces, MuJoCo's own actuation off (extras
  ``mujoco`` and ``ros``; console script and ``ros2 run vm_ros mujoco_sim_node``).
- ``loop_log``: such a loop as muscle_node's MCAP recorded it: motion, joint torques, forces and
  energy as arrays, a summary and a plot (no rclpy, no MuJoCo; used by ``vm-ros demo
  --closed-loop``).
"""


def mujoco_sim_main(args=None) -> int:
    """The mujoco_sim_node entry point: SIGINT/SIGTERM handlers before rclpy's import, as
    muscle_node's (vm_ros.node.signals)."""
    from vm_ros.node.signals import main_after_signals

    def import_main():
        from vm_ros.sim.mujoco_node import main as node_main

        return node_main

    return main_after_signals(import_main, args)
