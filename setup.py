"""Build definition for vm_ros (ament_python: colcon needs a real setup.py).

The data_files lay out an ament prefix, so that `pip install .` and `colcon build` both give
`ros2 run vm_ros muscle_node` (and `mujoco_sim_node`) what it looks for:

    share/ament_index/resource_index/packages/vm_ros   package marker
    share/vm_ros/package.xml, config/*.yaml, msg/*.msg
    lib/vm_ros/muscle_node                             sh shim that execs <prefix>/bin/muscle_node
    lib/vm_ros/mujoco_sim_node                         the same for <prefix>/bin/mujoco_sim_node

`colcon build` (without --symlink-install) runs `setup.py install`; InstallAndWarm then compiles
the model step into Numba's cache, as `make venv` does, so that the node's first start does not.
"""

import os
import subprocess
import sys
from glob import glob

from setuptools import find_packages, setup
from setuptools.command.install import install

PACKAGE = "vm_ros"
WARM_UP = "from vm_ros.model import kernel; kernel.warm_up()"


class InstallAndWarm(install):
    """`setup.py install`, then the model step compiled (or loaded) into Numba's cache by the
    installed copy in a child process (vm_ros.model.kernel.warm_up: one cache per machine and
    Python, not per install location). Skipped where Numba is not importable, and for a wheel
    (pip builds one into a staging root, and `make venv` warms after installing); a failed
    warm-up is one line, not a failed install: the first start then compiles."""

    def run(self):
        super().run()
        if self.root is not None:  # a staging tree (bdist_wheel): not where it will run
            return
        env = dict(os.environ, PYTHONPATH=os.pathsep.join(
            p for p in (self.install_lib, os.environ.get("PYTHONPATH")) if p))
        if subprocess.run([sys.executable, "-c", "import numba"], env=env,
                          capture_output=True).returncode != 0:
            return
        if subprocess.run([sys.executable, "-c", WARM_UP], env=env).returncode != 0:
            print(f"vm_ros: the model step was not compiled now (python3 -c '{WARM_UP}' "
                  "does it; else the first start does)", file=sys.stderr)

setup(
    name=PACKAGE,
    version="0.1.0",
    description="Virtual Muscle model (force and partitioned energetics) with a ROS 2 node",
    license="Apache-2.0",
    cmdclass={"install": InstallAndWarm},
    python_requires=">=3.10",
    packages=find_packages(exclude=["test", "test.*", "tests", "tests.*"]),
    include_package_data=False,
    zip_safe=False,
    install_requires=[
        "numpy>=1.24",
        "scipy>=1.10",  # test_roots.py: every name used exists in SciPy 1.10 (Debian 12)
        "pyyaml>=6.0",
        # coordination: the QP steps (live receding horizon, offline Gauss-Newton)
        "osqp>=1.0",
        "mcap>=1.1",
        "mcap-ros2-support>=0.5",
        "zstandard>=0.21",
    ],
    extras_require={
        # ROS 2 Jazzy wheels from PyPI (third-party build): exact pins, see docs/node.md section 1.
        "ros": [
            "ros-rclpy[fastrtps]==7.1.6",
            "ros-std-msgs==5.3.6",
            "ros-sensor-msgs==5.3.6",
            "ros-geometry-msgs==5.3.6",
            "ros-diagnostic-msgs==5.3.6",
            "ros-trajectory-msgs==5.3.6",
        ],
        "plot": ["matplotlib>=3.6"],
        # the compiled model step (vm_ros.model.kernel); without it the NumPy step is used
        "fast": ["numba>=0.60"],
        # build-time importers of musculoskeletal geometry (vm-ros import-osim / import-mjcf), the
        # exact MuJoCo geometry back end and the closed-loop simulator; the run time needs neither
        "opensim": ["opensim==4.6"],
        "mujoco": ["mujoco==4.0.0", "myo-sim==0.2.3"],
        # vm-ros study: runs on Dask distributed, results table in Parquet
        "study": ["dask[distributed]>=2024.1", "pyarrow>=14"],
        # rosbags: test_recording_bag's independent rosbag2 reader; pytest-xdist: `make test` runs
        # the suite on two workers (9.2 against 21.1 min from a fresh clone, docs/development.md)
        "dev": ["pytest>=7.4", "pytest-xdist>=3.5", "ruff>=0.5", "hypothesis>=6.80",
                "matplotlib>=3.6", "rosbags>=0.11"],
    },
    entry_points={
        "console_scripts": [
            "muscle_node = vm_ros.node:main",
            # extras ros and mujoco (without mujoco it says so and exits 2)
            "mujoco_sim_node = vm_ros.sim:mujoco_sim_main",
            "vm-ros = vm_ros.cli:main",
        ],
    },
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{PACKAGE}"]),
        (f"share/{PACKAGE}", ["package.xml"]),
        # sorted globs: new files are picked up, and an empty folder gives an empty (harmless) entry
        (f"share/{PACKAGE}/config", sorted(glob("config/*.yaml"))),
        (f"share/{PACKAGE}/config/studies", sorted(glob("config/studies/*.yaml"))),
        (f"share/{PACKAGE}/msg", sorted(glob("msg_defs/*.msg"))),
        (f"lib/{PACKAGE}", ["resource/muscle_node", "resource/mujoco_sim_node"]),
    ],
)
