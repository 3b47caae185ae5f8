"""The bad-parameter campaign: 60 bad start-ups of muscle_node, each an exit status 2 and exactly
one stderr line naming the parameter and its value, never a traceback.

Cases marked ``process`` run the installed node (``python -P -m vm_ros.node --ros-args ...``,
under scripts/netns-run), all at once in a few parallel processes: what only ROS can get wrong
(rcl's argument and params-file parsing, rclpy's typed declarations such as use_sim_time, QoS
overrides, the MCAP file) and a sample of the rest. The other cases take the node's own start-up
path without ROS (vm_ros.node.startup.check_parameters: NodeConfig, the bank, the geometry, the
initial lengths) and the line the node prints (error_line), as run_node does.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor

import pytest

from vm_ros.errors import VmRosError
from vm_ros.node.startup import EXIT_BAD_PARAMETER, LINE_MAX_CHARS, check_parameters, error_line

PROCESS_TIMEOUT_S = 60
PARALLEL_PROCESSES = 4
MUSCLES_10K = [f"m{i}" for i in range(10_000)]


def P(*args):  # noqa: N802 - a marker: these arguments go to a real node process
    return ("process", args)


# (id, parameters: a dict of values for the start-up path or P(ROS arguments), parameter named,
#  text of the value that the line must show). {tmp} is the case folder.
CASES = [
    # use_sim_time (rclpy declares it before the node's own parameters)
    ("use_sim_time-maybe", P("-p", "use_sim_time:=maybe"), "use_sim_time", "'maybe'"),
    ("use_sim_time-integer", P("-p", "use_sim_time:=1"), "use_sim_time", "1"),
    ("use_sim_time-list", P("-p", "use_sim_time:=[true, false]"), "use_sim_time",
     "[True, False]"),
    # wrong types
    ("recruitment-integer", P("-p", "recruitment:=3"), "recruitment", "3"),
    ("muscles-integer", P("-p", "muscles:=5"), "muscles", "5"),
    ("model_rate_hz-text", P("-p", "model_rate_hz:=fast"), "model_rate_hz", "'fast'"),
    ("qos_depth-double", P("-p", "qos_depth:=2.5"), "qos_depth", "2.5"),
    ("model_rate_hz-bool", {"model_rate_hz": True}, "model_rate_hz", "True"),
    ("units_per_type-double", {"units_per_type": 2.5}, "units_per_type", "2.5"),
    ("mcap.enabled-text", {"mcap.enabled": "yes"}, "mcap.enabled", "'yes'"),
    ("muscles-numbers", {"muscles": [1, 2]}, "muscles", "[1, 2]"),
    ("initial_path_length_m-text", {"initial_path_length_m": ["a", "b"]},
     "initial_path_length_m", "['a', 'b']"),
    ("stale_input_policy-list", {"stale_input_policy": [1, 2]}, "stale_input_policy", "[1, 2]"),
    ("executor-integer", {"executor": 3}, "executor", "3"),
    ("joints-text", {"joints": "knee"}, "joints", "'knee'"),
    # out of range, negative rates, not finite
    ("model_rate_hz-low", {"model_rate_hz": 5.0}, "model_rate_hz", "5.0"),
    ("model_rate_hz-high", {"model_rate_hz": 1e6}, "model_rate_hz", "1000000.0"),
    ("model_rate_hz-negative", {"model_rate_hz": -1000.0}, "model_rate_hz", "-1000.0"),
    ("model_rate_hz-nan", {"model_rate_hz": float("nan")}, "model_rate_hz", "nan"),
    ("publish_rate_hz-zero", {"publish_rate_hz": 0.0}, "publish_rate_hz", "0.0"),
    ("publish_rate_hz-negative", {"publish_rate_hz": -3.0}, "publish_rate_hz", "-3.0"),
    ("max_catch_up_steps-zero", {"max_catch_up_steps": 0}, "max_catch_up_steps", "0"),
    ("qos_depth-zero", {"qos_depth": 0}, "qos_depth", "0"),
    ("qos_depth-high", {"qos_depth": 100_000}, "qos_depth", "100000"),
    ("units_per_type-negative", {"units_per_type": -1}, "units_per_type", "-1"),
    ("input_timeout_s-zero", {"input_timeout_s": 0.0}, "input_timeout_s", "0.0"),
    ("diagnostics_period_s-zero", {"diagnostics_period_s": 0.0}, "diagnostics_period_s", "0.0"),
    ("path_speed_max-negative", {"path_speed_max_m_per_s": -1.0}, "path_speed_max_m_per_s",
     "-1.0"),
    ("extrapolation_max_s-negative", {"extrapolation_max_s": -0.1}, "extrapolation_max_s",
     "-0.1"),
    ("path_length_margin_l0-negative", {"path_length_margin_l0": -1.0},
     "path_length_margin_l0", "-1.0"),
    # choices
    ("recruitment-unknown", {"recruitment": "nope"}, "recruitment", "'nope'"),
    ("recovery_mode-unknown", {"recovery_mode": "fast"}, "recovery_mode", "'fast'"),
    ("stale_input_policy-unknown", {"stale_input_policy": "ignore"}, "stale_input_policy",
     "'ignore'"),
    ("executor-unknown", {"executor": "multi"}, "executor", "'multi'"),
    # publish rate above the model rate
    ("publish-above-model", {"publish_rate_hz": 2000.0}, "publish_rate_hz", "2000.0"),
    # muscles: unknown, empty, repeated, 10,000
    ("muscles-unknown", P("-p", "muscles:=[vasti, quadriceps]"), "muscles", "'quadriceps'"),
    ("muscles-empty", P("-p", "muscles:=[]"), "muscles", "[]"),
    ("muscles-repeated", {"muscles": ["vasti", "vasti"]}, "muscles", "vasti"),
    ("muscles-10000-repeated", P("--params-file", "{tmp}/repeated.yaml"), "muscles", "vasti"),
    ("muscles-10000-unknown", {"muscles": MUSCLES_10K}, "muscles", "'m0'"),
    # initial path lengths
    ("initial-count", {"initial_path_length_m": [0.3]}, "initial_path_length_m", "[0.3]"),
    ("initial-negative", {"initial_path_length_m": [0.3, -0.1]}, "initial_path_length_m",
     "-0.1"),
    ("initial-inf", {"initial_path_length_m": [0.3, float("inf")]}, "initial_path_length_m",
     "inf"),
    ("initial-outside", {"initial_path_length_m": [10.0, 0.3]}, "initial_path_length_m",
     "[10.0, 0.3]"),
    # missing files and malformed YAML
    ("library-missing", {"library": "{tmp}/none.yaml"}, "library", "none.yaml"),
    ("model-missing", {"model": "{tmp}/none.yaml"}, "model", "none.yaml"),
    ("geometry-missing", {"geometry": "{tmp}/none.yaml"}, "geometry", "none.yaml"),
    ("library-malformed", {"library": "{tmp}/malformed.yaml"}, "library", "malformed.yaml"),
    ("model-malformed", {"model": "{tmp}/malformed.yaml"}, "model", "malformed.yaml"),
    ("geometry-malformed", {"geometry": "{tmp}/malformed.yaml"}, "geometry", "malformed.yaml"),
    ("params-file-missing", P("--params-file", "{tmp}/none.yaml"), "params-file", "none.yaml"),
    ("params-file-malformed", P("--params-file", "{tmp}/malformed.yaml"), "params-file",
     "malformed.yaml"),
    ("overrides-not-nested", {"overrides": "{vasti: 3}"}, "overrides", "'{vasti: 3}'"),
    ("overrides-malformed", {"overrides": "{vasti: [unclosed"}, "overrides", "[unclosed"),
    ("overrides-unknown-field", {"overrides": "{vasti: {no_field: 1}}"}, "overrides",
     "no_field"),
    ("joint_map-without-geometry", {"joint_map": "{knee: knee_angle_r}"}, "joint_map",
     "knee_angle_r"),
    # names only ROS checks: unknown parameter, QoS overrides, the MCAP file
    ("unknown-parameter", P("-p", "model_rate:=500.0"), "model_rate", "500.0"),
    ("qos-reliability", P("-p", "qos_overrides./muscle_force.publisher.reliability:=sometimes"),
     "qos_overrides./muscle_force.publisher.reliability", "'sometimes'"),
    ("qos-depth-negative", P("-p", "qos_overrides./muscle_force.publisher.depth:=-1"),
     "qos_overrides./muscle_force.publisher.depth", "-1"),
    ("mcap-path-unwritable", P("-p", "mcap.enabled:=true", "-p", "mcap.path:={tmp}/file/x.mcap"),
     "mcap", "file/x.mcap"),
]
PROCESS_CASES = [c for c in CASES if isinstance(c[1], tuple)]


def test_the_campaign_has_sixty_cases_and_a_process_sample():
    assert len(CASES) == 60 and len({c[0] for c in CASES}) == 60
    assert any(c[2] == "use_sim_time" for c in PROCESS_CASES) and len(PROCESS_CASES) >= 15


@pytest.fixture(scope="module")
def case_dir(tmp_path_factory):
    folder = tmp_path_factory.mktemp("bad_params")
    (folder / "malformed.yaml").write_text("a: [unclosed\n  b: {\n")
    (folder / "file").write_text("")  # a regular file where the MCAP folder should be
    names = ", ".join(["vasti"] * 10_000)
    (folder / "repeated.yaml").write_text(f"/**:\n  ros__parameters:\n    muscles: [{names}]\n")
    return folder


def _filled(value, folder):
    if isinstance(value, str):
        return value.replace("{tmp}", str(folder))
    if isinstance(value, list):
        return [_filled(v, folder) for v in value]
    if isinstance(value, dict):
        return {k: _filled(v, folder) for k, v in value.items()}
    return value


@pytest.fixture(scope="module")
def process_results(case_dir):
    """case id -> (exit status, stderr, seconds) of the node process, run a few at a time."""
    from conftest import require_ros

    require_ros()
    env = {**os.environ, "PYTHONWARNINGS": "ignore"}

    def run(case):
        args = [_filled(a, case_dir) for a in case[1][1]]
        start = time.monotonic()
        proc = subprocess.run([sys.executable, "-P", "-m", "vm_ros.node", "--ros-args", *args],
                              capture_output=True, text=True, timeout=PROCESS_TIMEOUT_S, env=env,
                              cwd=case_dir)
        return case[0], (proc.returncode, proc.stderr, time.monotonic() - start)

    with ThreadPoolExecutor(PARALLEL_PROCESSES) as pool:
        return dict(pool.map(run, PROCESS_CASES))


def _start_up(values) -> tuple[int, str]:
    """(exit status, stderr) that run_node gives for an error on the start-up path."""
    try:
        check_parameters(values)
    except VmRosError as exc:
        return EXIT_BAD_PARAMETER, error_line("muscle_node", exc) + "\n"
    return 0, ""


@pytest.mark.parametrize(("case_id", "params", "name", "value"), CASES,
                         ids=[c[0] for c in CASES])
def test_bad_parameter_is_one_line_and_exit_2(case_id, params, name, value, case_dir, request):
    if isinstance(params, tuple):
        status, stderr, _ = request.getfixturevalue("process_results")[case_id]
    else:
        status, stderr = _start_up(_filled(params, case_dir))
    lines = stderr.splitlines()
    assert status == 2, stderr
    assert "Traceback" not in stderr, stderr
    assert len(lines) == 1, stderr
    line = lines[0]
    assert line.startswith("muscle_node: error: "), line
    assert name in line and _filled(value, case_dir) in line, line
    assert len(line) <= LINE_MAX_CHARS, len(line)
    assert "np.float64" not in line and "= None" not in line, line
