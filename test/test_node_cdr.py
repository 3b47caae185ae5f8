"""How muscle_node decodes its inputs (vm_ros.recording.cdr.input_decoder, which a recompute uses
too; and the general mcap_ros2-based decoder): what rclpy serialises decodes to the same values;
a payload that claims more elements than it holds, a truncated or corrupted one, is refused
(raises) without a stderr line. The input decoder gives mcap_ros2's values on every message that
decodes, and reuses a stream's repeated names."""

from __future__ import annotations

import random
import struct

import pytest

serialization = pytest.importorskip("rclpy.serialization", exc_type=ImportError)
msgs = pytest.importorskip("sensor_msgs.msg", exc_type=ImportError)
std = pytest.importorskip("std_msgs.msg", exc_type=ImportError)

from vm_ros.recording.cdr import decoder, input_decoder  # noqa: E402

DECODERS = {"input_decoder": input_decoder, "mcap_ros2": decoder}


def samples():
    joint = msgs.JointState(name=["vasti", "rectus_femoris"], position=[0.3, 0.4],
                            velocity=[0.01], effort=[])
    joint.header.frame_id = "base"
    array = std.Float64MultiArray(data=[0.1, 0.2, 0.3])
    array.layout.dim = [std.MultiArrayDimension(label="muscle", size=3, stride=3)]
    return [joint, array, msgs.JointState(), std.Float64MultiArray()]


def _type(msg_type) -> str:
    return f"{msg_type.__module__.split('.')[0]}/msg/{msg_type.__name__}"


def _decode(msg_type, data, kind="input_decoder"):
    return DECODERS[kind](_type(msg_type))(data)


@pytest.mark.parametrize("kind", DECODERS)
@pytest.mark.parametrize("msg", samples(), ids=lambda m: type(m).__name__)
def test_what_rclpy_serialises_decodes_to_the_same_values(msg, kind):
    decoded = _decode(type(msg), serialization.serialize_message(msg), kind)
    if isinstance(msg, msgs.JointState):
        assert list(decoded.name) == list(msg.name)
        assert list(decoded.position) == list(msg.position)
        assert list(decoded.velocity) == list(msg.velocity)
        assert decoded.header.frame_id == msg.header.frame_id
    else:
        assert list(decoded.data) == list(msg.data)
        assert [d.label for d in decoded.layout.dim] == [d.label for d in msg.layout.dim]


@pytest.mark.parametrize("kind", DECODERS)
def test_oversized_claims_are_refused_without_a_stderr_line(capfd, kind):
    data = bytearray(serialization.serialize_message(samples()[0]))
    data[4 + 8: 4 + 12] = struct.pack("<I", 10**9)  # the frame_id length, after the stamp
    for payload in (bytes(data), bytes(data[:20]), b"\x00\x01"):
        with pytest.raises(Exception):  # noqa: B017 - any decoding error: counted as undecodable
            _decode(msgs.JointState, payload, kind)
    assert capfd.readouterr().err == ""


@pytest.mark.parametrize("kind", DECODERS)
@pytest.mark.parametrize("msg", samples()[:2], ids=lambda m: type(m).__name__)
def test_truncations_and_corruptions_decode_or_raise_quietly(msg, capfd, kind):
    data = serialization.serialize_message(msg)
    rng = random.Random(7)
    refused = 0
    for trial in range(1500):
        payload = bytearray(data[: trial] if trial < len(data) else data)
        if trial >= len(data):
            for _ in range(3):
                payload[rng.randrange(4, len(payload))] = rng.randrange(256)
        try:
            _decode(type(msg), bytes(payload), kind)
        except Exception:
            refused += 1
    assert refused >= len(data) - 8  # every truncation past the header at least
    assert capfd.readouterr().err == ""


def _values(msg):
    if hasattr(msg, "name"):
        return (msg.header.stamp.sec, msg.header.stamp.nanosec, msg.header.frame_id,
                list(msg.name), list(msg.position), list(msg.velocity), list(msg.effort))
    return ([(d.label, d.size, d.stride) for d in msg.layout.dim], msg.layout.data_offset,
            list(msg.data))


def _many_names(n=1000):
    rng = random.Random(3)
    joint = msgs.JointState(name=[f"m{i}_{'é' * (i % 3)}" for i in range(n)],
                            position=[rng.random() for _ in range(n)],
                            velocity=[rng.uniform(-1, 1) for _ in range(n)])
    joint.header.stamp.sec, joint.header.stamp.nanosec = -3, 999
    joint.header.frame_id = "odd"
    return joint


@pytest.mark.parametrize("msg", samples() + [_many_names()], ids=lambda m: type(m).__name__)
def test_the_input_decoder_agrees_with_mcap_ros2_on_everything_both_decode(msg):
    """On the message, its truncations and 600 corruptions (3 random bytes each): wherever
    mcap_ros2's decoder and the input decoder both decode, every value is the same; every
    truncation past the encapsulation header that mcap_ros2 refuses, the input decoder refuses."""
    data = serialization.serialize_message(msg)
    reference = DECODERS["mcap_ros2"](_type(type(msg)))
    assert _values(_decode(type(msg), data)) == _values(reference(data))
    rng = random.Random(11)
    payloads = [data[:cut] for cut in range(4, len(data), max(1, len(data) // 300))]
    for _ in range(600):
        corrupt = bytearray(data)
        for _ in range(3):
            corrupt[rng.randrange(4, len(corrupt))] = rng.randrange(256)
        payloads.append(bytes(corrupt))
    both = 0
    for payload in payloads:
        try:
            expected = _values(reference(payload))
        except Exception:
            expected = None
        try:
            got = _values(_decode(type(msg), payload))
        except (ValueError, UnicodeDecodeError):
            got = None
        if expected is not None and got is not None:
            both += 1
            assert got == expected
        elif len(payload) < len(data) and expected is None:
            assert got is None
    assert both > 0


def test_a_stream_with_repeated_names_decodes_them_once():
    decode = input_decoder("sensor_msgs/msg/JointState")
    first = _many_names(50)
    second = _many_names(50)
    second.position = [0.5] * 50
    other = _many_names(50)
    other.name = list(other.name[::-1])
    a, b, c = (decode(serialization.serialize_message(m)) for m in (first, second, other))
    assert b.name is a.name and list(b.position) == [0.5] * 50
    assert c.name is not a.name and list(c.name) == list(other.name)
    longer = msgs.JointState(name=list(first.name) + ["extra"], position=[0.0] * 51)
    longer.header.frame_id = "odd"  # the same name block start, a longer block
    d = decode(serialization.serialize_message(longer))
    assert list(d.name) == list(first.name) + ["extra"]


@pytest.mark.parametrize("msg", [samples()[0], _many_names(80)], ids=["2 joints", "80 joints"])
def test_a_stream_decoder_reading_at_the_last_layout_is_as_safe(msg):
    """A decoder that has just read the message (its layout kept) reads each truncation and 600
    corruptions as a fresh one does: mcap_ros2's values wherever both decode, refused wherever
    a fresh input decoder refuses; an oversized claim raises."""
    data = serialization.serialize_message(msg)
    rng = random.Random(5)
    payloads = [data[:cut] for cut in range(len(data))]
    for _ in range(600):
        corrupt = bytearray(data)
        for _ in range(3):
            corrupt[rng.randrange(4, len(corrupt))] = rng.randrange(256)
        payloads.append(bytes(corrupt))
    oversized = bytearray(data)
    effort_at = data.rindex(struct.pack("<d", msg.velocity[-1])) + 8  # after the velocities
    oversized[effort_at:effort_at + 4] = struct.pack("<I", 10**6)
    stream = input_decoder("sensor_msgs/msg/JointState")
    fast = 0
    for payload in [*payloads, bytes(oversized)]:
        assert _values(stream(data)) == _values(_decode(msgs.JointState, data))
        try:
            expected = _values(_decode(msgs.JointState, payload))
        except (ValueError, UnicodeDecodeError):
            expected = None
        try:
            got = _values(stream(payload))
        except (ValueError, UnicodeDecodeError):
            got = None
        assert got == expected
        fast += got is not None and len(payload) == len(data)
    assert fast > 0 and expected is None  # the oversized count, last


def test_a_stream_decoder_keeps_the_names_when_only_the_padding_differs():
    """The alignment padding between names is not initialised by every serialiser: two messages
    with the same names and different padding bytes share the names tuple."""
    msg = msgs.JointState(name=["a", "bb", "ccc", "dddd"], position=[1.0, 2.0, 3.0, 4.0])
    data = serialization.serialize_message(msg)
    decode = input_decoder("sensor_msgs/msg/JointState")
    first = decode(data)
    # encapsulation 4 bytes, stamp 8, frame_id "" as length 4 + NUL 1: the count at 20; "a" as
    # length at 24, "a\0" at 28-29, padding 30-31; "bb" as length at 32, "bb\0" at 36-38,
    # padding 39
    padded = bytearray(data)
    for at in (30, 31, 39):
        padded[at] = 0xAB
    assert bytes(padded) != data
    second = decode(bytes(padded))
    assert second.name is first.name and list(second.position) == [1.0, 2.0, 3.0, 4.0]
    renamed = bytearray(padded)
    renamed[28] = ord("z")  # "a" -> "z": a new names tuple
    assert decode(bytes(renamed)).name == ("z", "bb", "ccc", "dddd")
