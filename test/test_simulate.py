"""`vm-ros simulate`: scenarios and CSV inputs into a run log, a summary, clear errors."""

from __future__ import annotations

import subprocess
import sys
import time

import numpy as np
import pytest

from vm_ros import telemetry as tm
from vm_ros.cli import main
from vm_ros.recording.messages import TOPIC_TELEMETRY
from vm_ros.recording.run_log import read_run
from vm_ros.report.tables import run_summary

LOG_TOPICS = {"/excitation", "/excitation_array", "/muscle_kinematics", "/muscle_force",
              "/energy_rate", "/energy_rate_total", "/energy_total", "/muscle_telemetry"}


def test_scenario_run_writes_the_node_channels_on_model_time(tmp_path, capsys):
    out = tmp_path / "ramp.mcap"
    before = time.time_ns()
    code = main(["simulate", "--scenario", "isometric_ramp", "--duration", "0.2", "--out",
                 str(out), "--telemetry-rate", "50", "--muscles", "vastus_lateralis,soleus"])
    printed = capsys.readouterr().out
    assert code == 0
    run = read_run(out)
    assert run.complete and set(run.topic_types) == LOG_TOPICS
    assert run.info.source == "simulate" and run.info.extra["scenario"] == "isometric_ramp"
    assert run.info.config.muscles == ("vastus_lateralis", "soleus")
    assert run.info.config.recovery_mode == "static"  # the scenario's
    force = run.get("muscle_force")
    assert len(force) == 20 and len(run.get("excitation")) == 200
    assert len(run.get(TOPIC_TELEMETRY)) == 10 and run.get("excitation_array") is None
    np.testing.assert_array_equal(force.time_ns, force.fields["stamp_ns"])  # log time = stamp
    start = run.info.timing.start_time_ns
    assert before <= start <= time.time_ns()  # the wall clock when the run started
    np.testing.assert_array_equal(force.time_ns - start, np.arange(1, 21) * 10_000_000)
    np.testing.assert_array_equal(run.model_time_ns(force.time_ns), np.arange(1, 21) * 10_000_000)
    for name in ("vastus_lateralis", "soleus"):
        assert name in printed
    rows = run_summary(run)
    assert f"{rows[0].peak_force:.1f}" in printed
    assert f"{rows[1].energy[-1, -1]:.2f}" in printed


def test_csv_inputs_are_sampled_and_recorded(tmp_path, capsys):
    csv = tmp_path / "inputs.csv"
    csv.write_text("time_s,vasti.excitation,vasti.path_length,rectus_femoris.excitation,"
                   "rectus_femoris.path_length\n"
                   "0.0,0.0,0.30,0.2,0.50\n0.1,1.0,0.30,0.2,0.51\n0.2,1.0,0.29,0.0,0.52\n")
    out = tmp_path / "csv.mcap"
    assert main(["simulate", "--inputs", str(csv), "--out", str(out), "--input-rate", "100",
                 "--telemetry-rate", "0", "--start-time", "1700000000123456789"]) == 0
    run = read_run(out)
    assert run.info.config.muscles == ("vasti", "rectus_femoris")
    assert TOPIC_TELEMETRY not in {t.strip("/") for t in run.topic_types}
    excitation, kinematics = run.get("excitation"), run.get("muscle_kinematics")
    np.testing.assert_array_equal(excitation.time_ns,
                                  1700000000123456789 + np.arange(20) * 10_000_000)
    t = run.model_time_ns(excitation.time_ns) * 1e-9  # the CSV's time axis
    np.testing.assert_allclose(excitation.fields["position"][:, 0], np.interp(t, [0, .1, .2],
                                                                              [0, 1, 1]))
    np.testing.assert_allclose(kinematics.fields["position"][:, 1],
                               np.interp(t, [0, .1, .2], [.5, .51, .52]))
    np.testing.assert_allclose(kinematics.fields["velocity"][:, 1], 0.1)  # d(path length)/dt


@pytest.mark.parametrize("text, field", [
    ("time_s,vasti.excitation\n0,0\n1,1\n", "vasti.path_length"),
    ("t,vasti.excitation,vasti.path_length\n0,0,0.3\n1,1,0.3\n", "time_s"),
    ("time_s,vasti.excitation,vasti.path_length\n0,0,0.3\n0,1,0.3\n", "time_s"),
    ("time_s,vasti.drive,vasti.path_length\n0,0,0.3\n1,1,0.3\n", "vasti.drive"),
])
def test_bad_csv_is_a_clear_error(tmp_path, capsys, text, field):
    csv = tmp_path / "bad.csv"
    csv.write_text(text)
    assert main(["simulate", "--inputs", str(csv), "--out", str(tmp_path / "x.mcap")]) == 2
    err = capsys.readouterr().err
    assert str(csv) in err and field in err
    assert not (tmp_path / "x.mcap").exists()


def test_unwritable_output_is_named_at_start(tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("")
    target = blocker / "run.mcap"
    assert main(["simulate", "--scenario", "knee_extension", "--out", str(target)]) == 2
    err = capsys.readouterr().err
    assert str(target) in err and "cannot create" in err


def test_model_options_reach_the_bank(tmp_path):
    out = tmp_path / "natural.mcap"
    assert main(["simulate", "--scenario", "isovelocity", "--duration", "0.05", "--out",
                 str(out), "--recruitment", "continuous", "--recovery-mode", "dynamic",
                 "--override", "biceps_long_head.fpcsa_slow=0.9", "--publish-rate", "200"]) == 0
    info = read_run(out, topics=()).info
    assert info.config.recruitment == "continuous" and info.config.recovery_mode == "dynamic"
    assert info.config.overrides == {"biceps_long_head": {"fpcsa_slow": 0.9}}
    assert info.timing.publish_rate_hz == 200.0
    assert len(read_run(out, topics=[tm.TOPIC_FORCE]).get("muscle_force")) == 10


def test_runs_and_logs_without_any_ros_package(tmp_path):
    """The no-ROS install: rclpy and the ROS message packages cannot be imported."""
    out = tmp_path / "noros.mcap"
    blocked = ["rclpy", "std_msgs", "sensor_msgs", "diagnostic_msgs", "builtin_interfaces",
               "rosidl_runtime_py", "rosidl_parser", "rosidl_adapter", "ament_index_python"]
    code = (f"import sys\nfor name in {blocked!r}: sys.modules[name] = None\n"
            "from vm_ros.cli import main\n"
            f"sys.exit(main(['simulate', '--scenario', 'isovelocity', '--duration', '0.05', "
            f"'--out', {str(out)!r}]))\n")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=60)
    assert proc.returncode == 0, proc.stderr
    run = read_run(out)
    assert run.complete and len(run.get("muscle_force")) == 5


def test_no_source_runs_the_default_scenario_and_says_which(tmp_path, capsys):
    from vm_ros.cli.simulate import DEFAULT_SCENARIO
    from vm_ros.offline.scenarios import load_scenario

    out = tmp_path / "default.mcap"
    assert main(["simulate", "--duration", "0.05", "--out", str(out)]) == 0
    captured = capsys.readouterr()
    assert f"running the default scenario, {DEFAULT_SCENARIO}" in captured.err
    run = read_run(out)
    assert run.info.extra["scenario"] == DEFAULT_SCENARIO
    assert run.info.config.muscles == load_scenario(DEFAULT_SCENARIO).muscles
