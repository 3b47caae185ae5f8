"""The installed muscle_node as a process: found as `ros2 run vm_ros muscle_node` finds it
(ament_index_python on AMENT_PREFIX_PATH = this venv, then the lib/vm_ros/muscle_node shim),
stopped by SIGINT or SIGTERM with its MCAP file finished, and its start-up errors."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import STRICT, early_signal_stop, require_ros, stamp_ns

from vm_ros import telemetry as tm
from vm_ros.model import MuscleBank
from vm_ros.node.inputs import physical_path_length_range

pytestmark = pytest.mark.ros

MUSCLES = ["vasti", "rectus_femoris"]
START_TIMEOUT_S = 30


def _fail_or_skip(reason: str):
    if STRICT:
        pytest.fail(f"{reason} (not skipped: CI or VM_ROS_NETNS=1 is set)")
    pytest.skip(reason)


@pytest.fixture(scope="module")
def installed():
    """(shim path, environment) of the installed package, as ros2run would find it."""
    require_ros()  # every test here starts rclpy in a child process
    try:
        from ament_index_python import get_package_prefix
    except ImportError:
        _fail_or_skip("ament_index_python is missing: install the [ros] extra")
    env = {**os.environ, "AMENT_PREFIX_PATH": sys.prefix}
    saved = os.environ.get("AMENT_PREFIX_PATH")
    os.environ["AMENT_PREFIX_PATH"] = sys.prefix
    try:
        prefix = Path(get_package_prefix("vm_ros"))
    except Exception as exc:  # PackageNotFoundError: an editable or missing install
        _fail_or_skip(f"vm_ros is not an ament package in {sys.prefix} ({exc}): `make venv`")
    finally:
        if saved is None:
            os.environ.pop("AMENT_PREFIX_PATH")
        else:
            os.environ["AMENT_PREFIX_PATH"] = saved
    shim = prefix / "lib" / "vm_ros" / "muscle_node"
    if not os.access(shim, os.X_OK):
        _fail_or_skip(f"{shim} is missing or not executable: `make venv`")
    return shim, env


@pytest.fixture(scope="module")
def lengths():
    lo, hi = physical_path_length_range(MuscleBank.from_config(MUSCLES), 0.0)
    return 0.5 * (lo + hi)


def ros_args(**params) -> list:
    args = ["--ros-args"]
    for name, value in params.items():
        args += ["-p", f"{name.replace('__', '.')}:={value}"]
    return args


@pytest.mark.parametrize(("sig", "executor"), [(signal.SIGINT, "events"),
                                               (signal.SIGTERM, "events"),
                                               (signal.SIGINT, "single_threaded")],
                         ids=["SIGINT-events", "SIGTERM-events", "SIGINT-single_threaded"])
def test_signal_stops_the_node_and_finishes_the_log(ros, installed, lengths, tmp_path, sig,
                                                    executor):
    from vm_ros.recording import read_run

    shim, env = installed
    path = tmp_path / "run.mcap"
    command = [str(shim), *ros_args(
        muscles="[" + ", ".join(MUSCLES) + "]",
        initial_path_length_m="[" + ", ".join(f"{x:.6f}" for x in lengths) + "]",
        executor=executor, mcap__enabled="true", mcap__path=str(path))]
    probe = ros.probe()
    process = subprocess.Popen(command, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                               text=True)
    try:
        assert ros.spin_until(lambda: len(probe.forces) >= 5 or process.poll() is not None,
                              timeout_s=START_TIMEOUT_S)
        assert process.poll() is None, process.communicate()[1]
        assert ros.spin_until(lambda: probe.excitation_array.get_subscription_count() > 0,
                              timeout_s=START_TIMEOUT_S)  # matched: the message cannot be lost
        probe.send_excitation_array([0.5, 0.5])
        n = len(probe.forces)
        assert ros.spin_until(lambda: len(probe.forces) >= n + 10)
        process.send_signal(sig)
        _, stderr = process.communicate(timeout=15)
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
    assert process.returncode == 0, stderr
    assert "Traceback" not in stderr, stderr
    run = read_run(path)
    assert run.complete, run.stop_reason
    assert run.info.source == "muscle_node" and list(run.info.config.muscles) == MUSCLES
    forces = run.get(tm.TOPIC_FORCE)
    assert len(forces) >= 15 and np.all(np.isfinite(forces.fields["effort"]))
    assert run.get(tm.TOPIC_EXCITATION_ARRAY).fields["data"][0].tolist() == [0.5, 0.5]
    received = {stamp_ns(m) for m in probe.forces}
    assert received <= set(forces.time_ns.tolist())  # logged as published, at the stamp


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("/**:\n  ros__parameters:\n    model_rate: 500.0\n", "model_rate"),
        ("/**:\n  ros__parameters:\n    publish_rate_hz: -3.0\n", "publish_rate_hz"),
        ("/**:\n  ros__parameters:\n    muscles: [vasti, quadriceps]\n", "quadriceps"),
        ("/**:\n  ros__parameters:\n    stale_input_policy: [1, 2]\n", "stale_input_policy"),
        ("/**:\n  ros__parameters:\n    model_rate_hz: [unclosed\n", "params.yaml"),
    ],
    ids=["unknown-name", "out-of-range", "unknown-muscle", "wrong-type", "bad-yaml"],
)
def test_bad_params_file_is_a_clear_start_up_error(installed, tmp_path, text, expected):
    shim, env = installed
    params = tmp_path / "params.yaml"
    params.write_text(text)
    proc = subprocess.run([str(shim), "--ros-args", "--params-file", str(params)], env=env,
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2, proc.stderr
    assert "Traceback" not in proc.stderr, proc.stderr
    assert expected in proc.stderr, proc.stderr


def test_help_lists_the_parameters(installed):
    shim, env = installed
    proc = subprocess.run([str(shim), "--help"], env=env, capture_output=True, text=True,
                          timeout=60)
    assert proc.returncode == 0
    for name in ("muscles", "model_rate_hz", "stale_input_policy", "mcap.path"):
        assert name in proc.stdout


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
# Delays counted from the moment the handlers are in (conftest.early_signal_stop): at once, while
# rclpy is imported, and while the node is built.
@pytest.mark.parametrize("delay_s", [0.0, 0.15, 0.65])
def test_a_signal_soon_after_launch_is_a_clean_stop(sig, delay_s, tmp_path):
    """A signal while Python imports rclpy (the first second) or builds the node: exit 0, no
    traceback; the MCAP file, if the node got far enough to open it, is finished."""
    require_ros()
    path = tmp_path / "early.mcap"
    status, stderr = early_signal_stop(
        [sys.executable, "-P", "-m", "vm_ros.node", *ros_args(mcap__enabled="true",
                                                            mcap__path=str(path))],
        sig, delay_s, tmp_path)
    assert status == 0, stderr
    assert "Traceback" not in stderr and "KeyboardInterrupt" not in stderr, stderr
    if path.exists():
        from vm_ros.recording import read_run

        assert read_run(path).complete


def test_help_lists_the_topics_with_their_types(installed):
    shim, env = installed
    proc = subprocess.run([str(shim), "--help"], env=env, capture_output=True, text=True,
                          timeout=60)
    assert proc.returncode == 0
    for topic, msg_type in ((tm.TOPIC_EXCITATION, "sensor_msgs/msg/JointState"),
                            (tm.TOPIC_EXCITATION_ARRAY, "std_msgs/msg/Float64MultiArray"),
                            (tm.TOPIC_KINEMATICS, "sensor_msgs/msg/JointState"),
                            (tm.TOPIC_FORCE, "sensor_msgs/msg/JointState"),
                            (tm.TOPIC_ENERGY_TOTAL, "std_msgs/msg/Float64"),
                            (tm.TOPIC_DIAGNOSTICS, "diagnostic_msgs/msg/DiagnosticArray")):
        assert f"  {topic} ({msg_type})" in proc.stdout, topic
    assert "docs/node.md" in proc.stdout
