"""The one-process loop: MuJoCo (actuation off) driven by MuscleBank forces on myoelbow.

Checks: time-step convergence (1 ms vs 0.5 ms), the energy balance with MuJoCo's own kinetic and
potential energy, muscle work against the recorded path lengths, MuJoCo's actuators silent, and
the CLI (files written, a bad model name is one line and exit 2).
"""

from __future__ import annotations

import signal
import sys

import numpy as np
import pytest

pytest.importorskip("mujoco", reason="the mujoco extra is not installed")

from vm_ros.cli import main  # noqa: E402
from vm_ros.closed_loop import (  # noqa: E402
    ClosedLoop,
    constant_excitation,
    pulse_excitation,
)
from vm_ros.errors import VmRosError  # noqa: E402
from vm_ros.geometry.mujoco_backend import MujocoGeometry  # noqa: E402
from vm_ros.importers import common, mjcf  # noqa: E402
from vm_ros.model import MuscleBank  # noqa: E402


@pytest.fixture(scope="module")
def elbow():
    return MujocoGeometry("myoelbow")


@pytest.fixture(scope="module")
def library(elbow, tmp_path_factory):
    choices = common.ImportChoices(common.specific_tension_option("rajagopal"))
    derived = mjcf.derive_library(elbow, choices, *mjcf.path_extremes(elbow, 200))
    assert derived.excluded == () and derived.flagged == ()
    return common.write_library(tmp_path_factory.mktemp("lib") / "muscles.yaml",
                                derived.entries, "test")


def run_loop(elbow, library, dt, duration=2.0):
    bank = MuscleBank.from_config(list(elbow.muscle_names), library=library)
    q0 = np.array([1.0])
    r = elbow.evaluate(q0).moment_arm[:, 0]
    excitation = pulse_excitation(r, "r_elbow_flex")
    loop = ClosedLoop(elbow, bank, dt)
    loop.reset(q0, excitation(0.0))
    loop.data.ctrl[:] = 1.0  # MuJoCo's own muscles would pull hard: actuation must be off
    return loop, loop.run(duration, excitation)


@pytest.fixture(scope="module")
def runs(elbow, library):
    return {dt: run_loop(elbow, library, dt) for dt in (0.001, 0.0005)}


def test_time_steps_agree(runs):
    (_, coarse), (_, fine) = runs[0.001], runs[0.0005]
    assert coarse.q.shape == (2001, 1) and fine.q.shape == (4001, 1)
    moved = np.ptp(coarse.q[:, 0])
    assert moved > np.radians(40), "the default pulses move the elbow visibly"
    gap = np.abs(coarse.q[:, 0] - fine.q[::2, 0]).max()
    assert np.degrees(gap) < 0.5


def test_energy_balance(runs):
    loop, result = runs[0.001]
    e = result.ledger
    assert result.limit_steps == 0 and e.constraint_work_j == 0.0  # joint limits never reached
    assert e.muscle_work_j > 0.5 and e.damping_loss_j > 0.5
    # MuJoCo's own energies, read independently at the end of the run
    assert e.kinetic_j == pytest.approx(loop.data.energy[1], abs=1e-12)
    assert e.potential_j == pytest.approx(loop.data.energy[0], abs=1e-12)
    assert abs(e.relative_residual) < 0.01
    # muscle work against the recorded path lengths: -sum F (L(t + dt) - L(t))
    length = result.path_length
    from_paths = -np.sum(result.force[:-1] * np.diff(length, axis=0))
    assert from_paths == pytest.approx(e.muscle_work_j, rel=0.01)
    # the loop's torques are r^T F with MuJoCo's moment arms
    assert np.all(loop.data.actuator_force == 0)
    r = loop.moment_arms()
    np.testing.assert_allclose(r, -loop._jacobian.jacobian(loop.data), atol=1e-15)


def test_finer_step_smaller_residual(runs):
    coarse, fine = runs[0.001][1].ledger, runs[0.0005][1].ledger
    assert abs(fine.residual_j) < abs(coarse.residual_j)


def test_excitation_sources(elbow, tmp_path):
    from vm_ros.cli.closed_loop import file_excitation

    names = elbow.muscle_names
    path = tmp_path / "u.csv"
    path.write_text("time_s,BRA,TRIlong.excitation\n0,0,0.2\n1,0.6,0.4\n")
    u = file_excitation(path, names)
    np.testing.assert_allclose(u(0.5), [0.3, 0, 0, 0, 0, 0.3])
    np.testing.assert_allclose(u(5.0), [0.4, 0, 0, 0, 0, 0.6])
    assert u.coverage(0.0, 1.0) == []
    np.testing.assert_allclose(constant_excitation(6, 0.1)(3.0), np.full(6, 0.1))
    path.write_text("time_s,deltoid\n0,0\n")
    with pytest.raises(VmRosError, match="deltoid"):
        file_excitation(path, names)


# Excitation mistakes as cases (issue 27): file name, its text, options, the exit code and the
# last line on stderr ({path}: the file). The run is [0, 0.2 s].
EXCITATION_CASES = {
    "a file on another time axis (5-7 s against a run from 0 s) is an error": (
        "late.csv", "time_s,BRA\n5,0.2\n7,0.4\n", [], 2,
        "vm-ros closed-loop: error: excitations {path} cover 5-7 s, the run 0-0.2 s: no "
        "overlap; they must be on the run's time axis (0 s at its start)"),
    "drives in percent are an error naming muscle, time and the fix": (
        "percent.csv", "time_s,BRA,TRIlong\n0,20,0\n1,50,10\n", [], 2,
        "vm-ros closed-loop: error: excitations {path}: drive 50 for BRA at 1 s: drives are "
        "fractions in [0, 1]; if the values are percent, divide them by 100"),
    "a file covering part of the run is an error with --strict": (
        "part.csv", "time_s,BRA\n0.1,0.2\n2,0.4\n", ["--strict"], 2,
        "vm-ros closed-loop: error: excitations {path} cover 0.1-2 s, the run 0-0.2 s: the "
        "drives hold their first row for the 0.1 s before 0.1 s (an error with --strict)"),
    "a constant in percent": (
        None, None, ["--excitation", "constant:50"], 2,
        "vm-ros closed-loop: error: --excitation constant:50: drive 50 for every muscle: drives "
        "are fractions in [0, 1]; if the values are percent, divide them by 100"),
    "an initial angle without its unit (90: degrees or radians?)": (
        None, None, ["--q0", "r_elbow_flex=90"], 2,
        "vm-ros closed-loop: error: --q0 'r_elbow_flex=90': no unit is given: a unit of "
        "r_elbow_flex (rad); write it with one of rad, deg, e.g. r_elbow_flex=90deg"),
    "an initial angle outside the joint's range (myoelbow: 0 to 130 deg)": (
        None, None, ["--q0", "r_elbow_flex=200deg"], 2,
        "vm-ros closed-loop: error: --q0 'r_elbow_flex=200deg': outside the geometry's range "
        "of r_elbow_flex, 0 to 130 deg"),
}


@pytest.mark.parametrize("case", EXCITATION_CASES)
def test_excitation_mistakes_are_one_line_errors(case, tmp_path, capsys):
    name, text, options, code, line = EXCITATION_CASES[case]
    args = list(options)
    if name:
        path = tmp_path / name
        path.write_text(text)
        args += ["--excitation", str(path)]
    out = tmp_path / "run"
    assert main(["closed-loop", "--duration", "0.2", "--no-plot", "--out", str(out),
                 *args]) == code
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1] == line.format(path=tmp_path / name if name else "")
    assert not out.exists(), "nothing is written when an input is refused"


def test_partial_excitation_file_is_a_warning_repeated_after_the_summary(tmp_path, capsys):
    """First row held for 0.1 s: the run goes on (exit 0), the warning is printed when found and
    again as the last lines of the output, and the drive before 0.1 s is the first row's."""
    path = tmp_path / "part.csv"
    path.write_text("time_s,BRA\n0.1,0.2\n2,0.4\n")
    out = tmp_path / "run"
    assert main(["closed-loop", "--duration", "0.2", "--no-plot", "--out", str(out),
                 "--excitation", str(path)]) == 0
    captured = capsys.readouterr()
    text = (f"excitations {path} cover 0.1-2 s, the run 0-0.2 s: the drives hold their first "
            "row for the 0.1 s before 0.1 s")
    assert f"vm-ros closed-loop: warning: {text}" in captured.err
    assert captured.out.strip().splitlines()[-2:] == [
        "1 input warning(s), the numbers above depend on them (--strict makes them errors):",
        f"  {text}"]
    header = (out / "closed_loop.csv").read_text().splitlines()[0].split(",")
    table = np.loadtxt(out / "closed_loop.csv", delimiter=",", skiprows=1)
    bra = table[:, header.index("excitation.BRA")]
    time_s = table[:, 0]
    np.testing.assert_allclose(bra[time_s < 0.1], 0.2)


def test_initial_angle_takes_its_unit(tmp_path, capsys):
    out = tmp_path / "run"
    assert main(["closed-loop", "--duration", "0.01", "--no-plot", "--out", str(out),
                 "--q0", "r_elbow_flex=90deg"]) == 0
    table = np.loadtxt(out / "closed_loop.csv", delimiter=",", skiprows=1)
    assert table[0, 1] == pytest.approx(np.pi / 2, abs=1e-12)   # q.r_elbow_flex at t = 0


def test_cli_writes_files(tmp_path, capsys):
    out = tmp_path / "run"
    assert main(["closed-loop", "--duration", "0.2", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "energy residual" in text and "per simulated s" in text
    for name in ("closed_loop.csv", "closed_loop.png", "muscles.yaml"):
        assert (out / name).stat().st_size > 0
    header = (out / "closed_loop.csv").read_text().splitlines()[0].split(",")
    assert header[:2] == ["time_s", "q.r_elbow_flex"] and "force.BRA" in header


def test_cli_bad_model_is_one_line(tmp_path, capsys):
    code = main(["closed-loop", "--model", "no_such_model", "--out", str(tmp_path)])
    err = capsys.readouterr().err
    assert code == 2
    assert len(err.strip().splitlines()) == 1 and "no_such_model" in err
    assert "Traceback" not in err


# ---------------------------------------------------------------------------- over ROS


def sim_node(ros, **params):
    from rclpy.parameter import Parameter

    from vm_ros.sim.mujoco_node import MujocoSimNode

    node = MujocoSimNode(context=ros.context,
                         parameter_overrides=[Parameter(k, value=v) for k, v in params.items()])
    ros.executor.add_node(node)
    ros.nodes.append(node)
    return node


@pytest.mark.ros
def test_sim_node_round_trip(ros):
    """A probe publishes joint_effort_commands and receives joint_states: positive elbow torque
    flexes the arm, negative extends it; a command of the wrong length is dropped."""
    from rclpy.node import Node
    from sensor_msgs.msg import JointState
    from std_msgs.msg import Float64MultiArray

    from vm_ros.sim.mujoco_node import stream_qos

    sim = sim_node(ros, model="myoelbow", real_time_factor=0.0, max_steps_per_tick=20,
                   tick_s=0.001, initial_positions=[1.0])
    probe = Node("effort_probe", context=ros.context)
    ros.executor.add_node(probe)
    ros.nodes.append(probe)
    states = []
    probe.create_subscription(JointState, "joint_states", states.append, stream_qos())
    commands = probe.create_publisher(Float64MultiArray, "joint_effort_commands", stream_qos())
    assert ros.spin_until(lambda: len(states) > 5)
    assert list(states[-1].name) == ["r_elbow_flex"]

    def drive(torque, sim_seconds=0.3):
        commands.publish(Float64MultiArray(data=[torque]))
        assert ros.spin_until(lambda: sim.sim.effort[0] == torque)
        start = sim.sim.time_s
        assert ros.spin_until(lambda: sim.sim.time_s > start + sim_seconds, timeout_s=10)
        assert ros.spin_until(lambda: states[-1].effort[0] == torque)
        return states[-1]

    before = states[-1].position[0]
    flexed = drive(8.0)
    assert flexed.position[0] > before + 0.1 and flexed.velocity[0] > 0
    extended = drive(-8.0)
    assert extended.position[0] < flexed.position[0] - 0.1
    commands.publish(Float64MultiArray(data=[1.0, 2.0]))
    assert ros.spin_until(lambda: sim.dropped_commands == 1)
    commands.publish(b"\x00\x01\x00\x00\xff")  # bytes that are no Float64MultiArray
    assert ros.spin_until(lambda: sim.dropped_commands == 2)
    assert sim.sim.effort[0] == -8.0 and sim.commands == 2
    stamps = [s.header.stamp.sec * 10**9 + s.header.stamp.nanosec for s in states]
    assert all(b >= a for a, b in zip(stamps, stamps[1:], strict=False))


@pytest.mark.ros
@pytest.mark.slow
def test_muscle_node_drives_the_sim_node(ros, tmp_path, capsys):
    """The loop over ROS: import-mjcf myoelbow -> muscle_node (geometry, joint_states in,
    joint_effort_commands out) <-> mujoco_sim_node, in real time; flexor drive flexes the
    elbow, extensor drive lets it extend."""
    assert main(["import-mjcf", "myoelbow", "--out", str(tmp_path), "--samples", "200"]) == 0
    capsys.readouterr()
    names = ["TRIlong", "TRIlat", "TRImed", "BIClong", "BICshort", "BRA"]
    sim = sim_node(ros, model="myoelbow", initial_positions=[1.0], tick_s=0.001)
    ros.muscle_node(muscles=names, library=str(tmp_path / "muscles.yaml"),
                    geometry=str(tmp_path / "geometry.yaml"), publish_rate_hz=1000.0,
                    executor="single_threaded")
    probe = ros.probe()
    start = sim.sim.positions()[0]
    probe.send_excitation(names, [0.05, 0.05, 0.05, 0.6, 0.6, 0.6])
    assert ros.spin_until(lambda: sim.sim.positions()[0] > start + 0.3, timeout_s=10)
    # commands arrived and flex the elbow; how many in that time is pace, left to the bench
    assert sim.commands > 0 and sim.sim.effort[0] > 0
    top = sim.sim.positions()[0]
    probe.send_excitation(names, [0.6, 0.6, 0.6, 0.02, 0.02, 0.02])
    assert ros.spin_until(lambda: sim.sim.positions()[0] < top - 0.3, timeout_s=10)
    assert sim.sim.effort[0] < 0 and sim.dropped_commands == 0


@pytest.mark.ros
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_a_signal_soon_after_the_sim_node_starts_is_a_clean_stop(sig, tmp_path):
    """mujoco_sim_node (``python -m vm_ros.sim``, what the console script runs): a signal while
    rclpy and MuJoCo are imported is exit 0 without a traceback, as for muscle_node."""
    from conftest import early_signal_stop, require_ros

    require_ros()
    status, stderr = early_signal_stop([sys.executable, "-P", "-m", "vm_ros.sim"], sig, 0.3,
                                       tmp_path)
    assert status == 0, stderr
    assert "Traceback" not in stderr and "KeyboardInterrupt" not in stderr, stderr
