"""vm_ros: Virtual Muscle model and ROS 2 node."""
