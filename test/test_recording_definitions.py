"""Bundled message definitions: equal to the installed ROS packages' files, and concatenated as
rosbag2's MCAP storage does (rosbag2_storage_mcap message_definition_cache.cpp)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from vm_ros.recording import cdr
from vm_ros.recording.definitions import MSG_TEXTS, TYPE_HASHES
from vm_ros.recording.message_types import UnknownMessageTypeError, schema_text, type_hash
from vm_ros.recording.schema import DELIMITER, concatenated_definition, msg_dependencies

REPO = Path(__file__).resolve().parents[1]
SHARE = Path(sys.prefix) / "share"
STRICT = os.environ.get("VM_ROS_NETNS") == "1" or os.environ.get("CI", "").lower() not in (
    "", "0", "false")
STANDARD = sorted(t for t in MSG_TEXTS if not t.startswith("vm_ros/"))


def _share_file(type_name: str, suffix: str) -> Path:
    package, _, name = type_name.split("/")
    path = SHARE / package / "msg" / f"{name}{suffix}"
    if not path.is_file():
        reason = f"{path} missing: install the [ros] extra to compare with the ROS packages"
        if STRICT:
            pytest.fail(f"{reason} (not skipped: CI or VM_ROS_NETNS=1 is set)")
        pytest.skip(reason)
    return path


@pytest.mark.parametrize("type_name", STANDARD)
def test_bundled_text_and_hash_equal_the_installed_package(type_name):
    assert MSG_TEXTS[type_name] == _share_file(type_name, ".msg").read_text(encoding="utf-8")
    hashes = json.loads(_share_file(type_name, ".json").read_text(encoding="utf-8"))
    expected = {h["type_name"]: h["hash_string"] for h in hashes["type_hashes"]}[type_name]
    assert TYPE_HASHES[type_name] == expected


def test_own_definition_is_msg_defs_file():
    assert MSG_TEXTS["vm_ros/msg/MuscleTelemetry"] == (
        REPO / "msg_defs" / "MuscleTelemetry.msg").read_text(encoding="utf-8")
    assert sorted(p.stem for p in (REPO / "msg_defs").glob("*.msg")) == sorted(
        t.split("/")[-1] for t in MSG_TEXTS if t.startswith("vm_ros/"))


def test_generated_module_is_current_including_rosidl_hash_of_own_type():
    """The generator recomputes vm_ros's RIHS01 with rosidl's own tooling and diffs the file."""
    _share_file("std_msgs/msg/Header", ".json")
    proc = subprocess.run([sys.executable, str(REPO / "scripts" / "gen-msg-definitions"),
                           "--check"], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stdout + proc.stderr


def test_dependencies_parsed_like_rosbag2():
    text = ("# comment Foo/Bar baz\nstd_msgs/Header header\nKeyValue[] values\n"
            "byte OK=0\nstring name  # builtin_interfaces/Time not a field\nuint8[4] raw\n")
    assert msg_dependencies(text, "diagnostic_msgs") == [
        "diagnostic_msgs/msg/KeyValue", "std_msgs/msg/Header"]


def test_joint_state_schema_is_rosbag2_concatenation():
    def section(type_name):
        return _share_file(type_name, ".msg").read_text(encoding="utf-8")

    expected = (section("sensor_msgs/msg/JointState")
                + "\n" + "=" * 80 + "\nMSG: std_msgs/Header\n" + section("std_msgs/msg/Header")
                + "\n" + "=" * 80 + "\nMSG: builtin_interfaces/Time\n"
                + section("builtin_interfaces/msg/Time"))
    assert schema_text("sensor_msgs/msg/JointState") == expected


def test_dependencies_depth_first_sorted_each_once():
    texts = {"p/msg/A": "p/C c\np/B b\n", "p/msg/B": "p/C c\nq/D d\n", "p/msg/C": "int8 x\n",
             "q/msg/D": "int8 y\n"}
    text = concatenated_definition("p/msg/A", texts)
    headers = [line for line in text.splitlines() if line.startswith("MSG: ")]
    # B first (sorted), then its deps C and D depth first; C is not repeated for A
    assert headers == ["MSG: p/B", "MSG: p/C", "MSG: q/D"]
    assert text.count(DELIMITER) == 3


def test_diagnostic_array_schema_order():
    headers = [line for line in schema_text("diagnostic_msgs/msg/DiagnosticArray").splitlines()
               if line.startswith("MSG: ")]
    assert headers == ["MSG: diagnostic_msgs/DiagnosticStatus", "MSG: diagnostic_msgs/KeyValue",
                       "MSG: std_msgs/Header", "MSG: builtin_interfaces/Time"]


def test_unknown_type_is_a_clear_error():
    with pytest.raises(UnknownMessageTypeError, match="geometry_msgs/msg/Twist"):
        schema_text("geometry_msgs/msg/Twist")
    with pytest.raises(UnknownMessageTypeError):
        type_hash("not a type")


def test_telemetry_cdr_round_trip():
    fields = {"header": {"stamp": {"sec": 3, "nanosec": 5}, "frame_id": ""},
              "name": ["a", "b"], "energy": [float(i) for i in range(24)],
              "firing_rate": [0.5, 1.5, 2.5, 3.5], "total_energy": 12.25}
    msg = cdr.deserialize("vm_ros/msg/MuscleTelemetry",
                          cdr.serialize("vm_ros/msg/MuscleTelemetry", fields))
    assert msg.name == ["a", "b"] and msg.header.stamp.nanosec == 5
    assert msg.energy == fields["energy"] and msg.firing_rate == fields["firing_rate"]
    assert msg.total_energy == 12.25 and msg.force == []
