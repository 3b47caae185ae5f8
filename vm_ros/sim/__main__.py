import sys

from vm_ros.sim import mujoco_sim_main

sys.exit(mujoco_sim_main())
