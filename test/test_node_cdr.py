"""How muscle_node decodes its inputs (vm_ros.recording.cdr, the decoder a recompute uses): what
rclpy serialises decodes to the same values; a payload that claims more elements than it holds,
a truncated or corrupted one, is refused (raises) without a stderr line."""

from __future__ import annotations

import random
import struct

import pytest

serialization = pytest.importorskip("rclpy.serialization", exc_type=ImportError)
msgs = pytest.importorskip("sensor_msgs.msg", exc_type=ImportError)
std = pytest.importorskip("std_msgs.msg", exc_type=ImportError)

from vm_ros.recording.cdr import decoder  # noqa: E402


def samples():
    joint = msgs.JointState(name=["vasti", "rectus_femoris"], position=[0.3, 0.4],
                            velocity=[0.01], effort=[])
    joint.header.frame_id = "base"
    array = std.Float64MultiArray(data=[0.1, 0.2, 0.3])
    array.layout.dim = [std.MultiArrayDimension(label="muscle", size=3, stride=3)]
    return [joint, array, msgs.JointState(), std.Float64MultiArray()]


def _decode(msg_type, data):
    return decoder(f"{msg_type.__module__.split('.')[0]}/msg/{msg_type.__name__}")(data)


@pytest.mark.parametrize("msg", samples(), ids=lambda m: type(m).__name__)
def test_what_rclpy_serialises_decodes_to_the_same_values(msg):
    decoded = _decode(type(msg), serialization.serialize_message(msg))
    if isinstance(msg, msgs.JointState):
        assert list(decoded.name) == list(msg.name)
        assert list(decoded.position) == list(msg.position)
        assert list(decoded.velocity) == list(msg.velocity)
        assert decoded.header.frame_id == msg.header.frame_id
    else:
        assert list(decoded.data) == list(msg.data)
        assert [d.label for d in decoded.layout.dim] == [d.label for d in msg.layout.dim]


def test_oversized_claims_are_refused_without_a_stderr_line(capfd):
    data = bytearray(serialization.serialize_message(samples()[0]))
    data[4 + 8: 4 + 12] = struct.pack("<I", 10**9)  # the frame_id length, after the stamp
    for payload in (bytes(data), bytes(data[:20]), b"\x00\x01"):
        with pytest.raises(Exception):  # noqa: B017 - any decoding error: counted as undecodable
            _decode(msgs.JointState, payload)
    assert capfd.readouterr().err == ""


@pytest.mark.parametrize("msg", samples()[:2], ids=lambda m: type(m).__name__)
def test_truncations_and_corruptions_decode_or_raise_quietly(msg, capfd):
    data = serialization.serialize_message(msg)
    rng = random.Random(7)
    refused = 0
    for trial in range(1500):
        payload = bytearray(data[: trial] if trial < len(data) else data)
        if trial >= len(data):
            for _ in range(3):
                payload[rng.randrange(4, len(payload))] = rng.randrange(256)
        try:
            _decode(type(msg), bytes(payload))
        except Exception:
            refused += 1
    assert refused >= len(data) - 8  # every truncation past the header at least
    assert capfd.readouterr().err == ""
