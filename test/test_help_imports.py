"""``vm-ros --help`` and ``muscle_node --help`` answer without importing Numba, SciPy or rclpy
(they took 3-4 s when they did; now about 0.1-0.2 s of CPU: not timed here, the modules loaded are
checked). Fresh processes: the modules loaded are those of the help alone."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

HEAVY = ("numba", "scipy", "rclpy", "vm_ros.model.bank", "vm_ros.model.kernel")

_LOADED = """
import json, sys
{call}
try:
    main({args})
except SystemExit as exc:
    code = exc.code
print(json.dumps([code, [name for name in {heavy!r} if name in sys.modules]]))
"""


def _help(call: str, args: str):
    code = _LOADED.format(call=call, args=args, heavy=HEAVY)
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 0, done.stderr
    *text, last = done.stdout.strip().splitlines()
    return "\n".join(text), *json.loads(last)


def test_vm_ros_help_imports_no_verb_implementation():
    from vm_ros.cli import VERBS

    text, code, loaded = _help("from vm_ros.cli import main", "['--help']")
    assert code == 0 and loaded == []
    for verb, (_, help_line) in VERBS.items():
        assert verb in text and help_line.split()[0] in text


def test_a_verb_still_gets_its_own_arguments_and_description():
    text, code, _ = _help("from vm_ros.cli import main", "['params', '--help']")
    assert code == 0
    assert "--muscle" in text and "--list-muscles" in text
    assert "usage: vm-ros params" in text


@pytest.mark.parametrize("verb", ["import-osim", "import-mjcf"])
def test_an_importers_help_states_units_and_the_moment_arm_sign(verb):
    """A user reading --help learns the written geometry's units and r's sign before importing."""
    text, code, _ = _help("from vm_ros.cli import main", f"[{verb!r}, '--help']")
    assert code == 0
    words = " ".join(text.split())  # the description as one line, whatever the wrapping
    assert "coordinates in rad" in words and "path lengths L in m" in words, words
    assert "the moment arm is r = -dL/dq" in words and "the joint torque is r * F" in words


def test_muscle_node_help_imports_neither_rclpy_nor_the_model():
    from vm_ros.node.params import PARAMS
    from vm_ros.topics import TOPIC_TYPES

    text, code, loaded = _help(
        "from vm_ros.node import main",
        "['muscle_node', '--ros-args', '-p', 'muscles:=[vasti]', '--', '--help']")
    assert code == 0 and loaded == []
    for param in PARAMS:
        assert f"  {param.name} ({param.kind}" in text
    for topic, type_name in TOPIC_TYPES.items():
        # energy_rate_models: listed with energetics_models only; joint_work: offline runs only
        if topic not in ("energy_rate_models", "joint_work"):
            assert f"  {topic} ({type_name})" in text


def test_muscle_node_rejects_an_unknown_argument_before_starting():
    _, code, loaded = _help("from vm_ros.node import main", "['muscle_node', '--bogus']")
    assert code == 2 and loaded == []
