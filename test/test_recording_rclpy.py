"""Run logs decode with rclpy's own deserializer, message by message, to the same values as the
independent mcap_ros2 decoder (docs/log_format.md section 1: readable with and without ROS)."""

from __future__ import annotations

import importlib

import numpy as np
from conftest import require_ros
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory

from vm_ros.cli import main


def _message_class(schema_name: str):
    package, _, name = schema_name.split("/")
    return getattr(importlib.import_module(f"{package}.msg"), name)


def test_simulate_log_decodes_with_rclpy_like_mcap_ros2(tmp_path):
    require_ros()
    from rclpy.serialization import deserialize_message

    path = tmp_path / "run.mcap"
    assert main(["simulate", "--scenario", "sinusoidal_drive", "--duration", "0.3",
                 "--out", str(path)]) == 0
    checked = {}
    with open(path, "rb") as handle:
        reader = make_reader(handle, decoder_factories=[DecoderFactory()])
        for schema, channel, message, decoded in reader.iter_decoded_messages():
            if schema.name.startswith("vm_ros/"):
                continue  # the package's own offline type has no Python typesupport on pip
            via_rclpy = deserialize_message(message.data, _message_class(schema.name))
            for field in ("effort", "position", "velocity", "data"):
                if hasattr(decoded, field):
                    assert np.array_equal(np.asarray(getattr(via_rclpy, field)),
                                          np.asarray(getattr(decoded, field))), (channel.topic,
                                                                                 field)
            checked[channel.topic] = checked.get(channel.topic, 0) + 1
    for topic in ("muscle_force", "energy_rate", "energy_rate_total", "excitation",
                  "muscle_kinematics"):
        assert any(t.endswith(topic) and n > 10 for t, n in checked.items()), (topic, checked)
