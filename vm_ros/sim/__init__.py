"""Simulators that close the loop with muscle_node over ROS 2 (optional extras).

- ``mujoco_node``: a MuJoCo model stepped in (scaled) real time, publishing ``joint_states`` and
  applying ``joint_effort_commands`` as generalized forces, MuJoCo's own actuation off (extras
  ``mujoco`` and ``ros``).
"""
