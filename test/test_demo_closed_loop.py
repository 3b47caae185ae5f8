"""`vm-ros demo --closed-loop`: muscle_node driving mujoco_sim_node over ROS 2, logged and plotted.

The demo runs as a process, as a user runs it; its MCAP is checked against numbers computed here
from the geometry file: the joint torques muscle_node published are r(q)^T F at the joint
positions it logged, with the forces it logged, and the elbow moved. Also: the geometry cache,
the command line the demo re-runs itself with inside a namespace, the sim node holding its
pose until the first command, and the nodes' environment keeping Fast DDS off shared memory.
"""

from __future__ import annotations

import subprocess
import sys
import time

import numpy as np
import pytest
import yaml
from conftest import require_ros

pytest.importorskip("mujoco", reason="the mujoco extra is not installed")

from vm_ros import telemetry as tm  # noqa: E402
from vm_ros.child_process import module_environment, node_environment  # noqa: E402
from vm_ros.cli import build_parser, demo  # noqa: E402
from vm_ros.geometry import load_geometry  # noqa: E402
from vm_ros.recording import read_run  # noqa: E402
from vm_ros.recording.run_log import ATTACHMENT_GEOMETRY  # noqa: E402


@pytest.mark.ros
@pytest.mark.slow
def test_closed_loop_demo_logs_moves_and_plots(tmp_path):
    require_ros()
    start = time.monotonic()
    proc = subprocess.run([sys.executable, "-P", "-m", "vm_ros.cli", "demo", "--closed-loop",
                           "--duration", "2", "--out", str(tmp_path), "--accept-skips"],
                          capture_output=True, text=True, timeout=240)
    wall = time.monotonic() - start
    assert proc.returncode == 0, proc.stderr[-3000:]
    out = proc.stdout
    # whether this run is valid depends on the load (test_demo_validity.py forces a skip); the
    # summary says which, and --accept-skips exits 0 either way
    assert "validity: skipped model time" in out and "r_elbow_flex jitter" not in out
    assert "joint_states jitter" in out
    mcap, png = tmp_path / demo.LOOP_MCAP, tmp_path / demo.LOOP_PNG
    assert "range of motion" in out and f"MCAP log: {mcap}" in out and f"plot: {png}" in out
    assert png.stat().st_size > 20_000

    run = read_run(mcap)
    assert run.complete and run.info.source == "muscle_node"
    geometry_file = tmp_path / "geometry.yaml"
    assert run.attachments[ATTACHMENT_GEOMETRY] == geometry_file.read_bytes()
    geometry = load_geometry(geometry_file)
    states, efforts = run.get(tm.TOPIC_JOINT_STATES), run.get(tm.TOPIC_JOINT_EFFORTS)
    forces, commands = run.get(tm.TOPIC_FORCE), run.get(tm.TOPIC_JOINT_EFFORT_COMMANDS)
    assert states.names == efforts.names == ("r_elbow_flex",)
    # enough samples for the checks below; how many arrive in 2 s is pace (the bench measures it:
    # with both cores busy, 239 joint_states and 692 joint_efforts were seen)
    assert len(states) > 50 and len(efforts) > 100

    # the elbow moved: the flexor pulses lift it, gravity and the triceps bring it back
    q = states.fields["position"][:, 0]
    assert np.all(np.isfinite(q))
    assert np.degrees(np.ptp(q)) > 5.0
    assert np.all((q >= geometry.lower[0] - 0.05) & (q <= geometry.upper[0] + 0.05))

    # joint_efforts = r^T F: r from the geometry file at the joint position that step used,
    # F the forces of the same step (muscle_force at the same model time)
    assert np.array_equal(forces.time_ns, efforts.time_ns)
    columns = [list(forces.names).index(m) for m in geometry.muscle_names]
    received = set(q.tolist())
    scale_max = 0.0
    for k in range(len(efforts)):
        qk = efforts.fields["position"][k]
        assert qk[0] in received, "a joint position muscle_node never received"
        r = geometry.evaluate(qk).moment_arm                 # (muscles, coordinates)
        force = forces.fields["effort"][k, columns]
        expected = r.T @ force
        scale = np.abs(r).T @ np.abs(force)                  # sum of |r_i F_i|
        assert abs(efforts.fields["effort"][k, 0] - expected[0]) <= 1e-9 * scale[0] + 1e-300
        scale_max = max(scale_max, scale[0])
    assert scale_max > 0.5  # the muscles pulled (N m)
    np.testing.assert_array_equal(commands.fields["data"], efforts.fields["effort"])
    print(f"closed-loop demo test: {wall:.1f} s wall, {len(efforts)} joint_efforts checked")


def test_command_line_round_trips():
    """The demo re-runs itself inside a namespace with _command_line(args): same arguments."""
    for argv in (["demo"],
                 ["demo", "--closed-loop", "--model", "my model.xml", "--duration", "0.25",
                  "--out", "a b", "--mcap", "x.mcap", "--executor", "single_threaded",
                  "--recruitment", "natural", "--model-rate-hz", "500"],
                 ["demo", "--no-mcap", "--startup-timeout", "7", "--accept-skips"]):
        parser = build_parser(argv)  # loads the verb's own arguments (cli.build_parser)
        args = parser.parse_args(argv)
        again = parser.parse_args(demo._command_line(args))
        assert {k: v for k, v in vars(again).items() if k != "_run"} == \
            {k: v for k, v in vars(args).items() if k != "_run"}


def test_model_without_closed_loop_is_a_one_line_error(capsys):
    """--model names the closed-loop demo's model: without --closed-loop it was ignored (the knee
    demo ran); now exit 2 with one line, before any namespace or node is started."""
    from vm_ros.cli import main

    assert main(["demo", "--model", "myolegs", "--duration", "1"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--closed-loop" in err[0] and "myolegs" in err[0]


def test_geometry_is_reused_only_for_the_same_model(tmp_path, monkeypatch):
    from vm_ros.geometry.mujoco_backend import load_model

    calls = []
    monkeypatch.setattr(demo.subprocess, "run",
                        lambda command, **kw: calls.append(command) or
                        subprocess.CompletedProcess(command, 0))
    source = load_model("myoelbow").as_dict()
    (tmp_path / "muscles.yaml").write_text("muscles: {}\n")
    (tmp_path / "geometry.yaml").write_text(yaml.safe_dump({"source": source}))
    assert demo.prepare_geometry("myoelbow", tmp_path) == (tmp_path / "geometry.yaml",
                                                          tmp_path / "muscles.yaml")
    assert calls == []
    (tmp_path / "geometry.yaml").write_text(yaml.safe_dump({"source": {**source,
                                                                       "sha256": "0" * 64}}))
    demo.prepare_geometry("myoelbow", tmp_path)
    assert calls and calls[0][-4:] == ["import-mjcf", "myoelbow", "--out", str(tmp_path)]


@pytest.mark.ros
def test_sim_node_waits_for_the_first_command(ros):
    """wait_for_command: the initial pose is published, unchanged and without stepping, until
    a command arrives; then the model steps."""
    from rclpy.node import Node
    from rclpy.parameter import Parameter
    from sensor_msgs.msg import JointState
    from std_msgs.msg import Float64MultiArray

    from vm_ros.sim.mujoco_node import MujocoSimNode, stream_qos

    sim = MujocoSimNode(context=ros.context, parameter_overrides=[
        Parameter("wait_for_command", value=True), Parameter("initial_positions", value=[1.0]),
        Parameter("tick_s", value=0.001)])
    probe = Node("wait_probe", context=ros.context)
    for node in (sim, probe):
        ros.executor.add_node(node)
        ros.nodes.append(node)
    states = []
    probe.create_subscription(JointState, "joint_states", states.append, stream_qos(100))
    commands = probe.create_publisher(Float64MultiArray, "joint_effort_commands", stream_qos())
    assert ros.spin_until(lambda: len(states) > 20)
    ros.spin_for(0.2)
    assert sim.sim.steps == 0 and sim.sim.time_s == 0.0
    assert {s.position[0] for s in states} == {1.0}
    commands.publish(Float64MultiArray(data=[0.0]))
    assert ros.spin_until(lambda: sim.sim.steps > 50)
    # gravity and no muscle: the forearm falls
    assert ros.spin_until(lambda: states[-1].position[0] < 1.0 - 1e-3)
    assert "0 dropped" in sim.run_summary()


_DDS_THREADS = """
import os
import rclpy
rclpy.init()
node = rclpy.create_node("transport_probe")
print(" ".join(open(f"/proc/self/task/{t}/comm").read().strip()
               for t in os.listdir("/proc/self/task")))
node.destroy_node()
rclpy.shutdown()
"""


@pytest.mark.ros
def test_nodes_environment_keeps_fast_dds_off_shared_memory():
    """The demos' nodes run with node_environment() (UDP_ONLY_ENVIRONMENT): a process started
    so has none of Fast DDS's shared-memory threads (`dds.shm.<port>` listeners,
    `dds.shm.wdog`), whose transport can stall a node for 333 ms at its first send to a peer
    (docs/closed_loop.md). The namespace's own environment
    (ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST) has them, whatever FASTDDS_BUILTIN_TRANSPORTS
    says: that is what the test tells apart."""
    require_ros()

    def dds_threads(env):
        proc = subprocess.run([sys.executable, "-c", _DDS_THREADS], env=env,
                              capture_output=True, text=True, timeout=60)
        assert proc.returncode == 0, proc.stderr
        return [name for name in proc.stdout.split() if name.startswith("dds.")]

    localhost = dds_threads(module_environment())
    udp_only = dds_threads(node_environment())
    assert any(name.startswith("dds.shm") for name in localhost), localhost
    assert udp_only and not any(name.startswith("dds.shm") for name in udp_only), udp_only
