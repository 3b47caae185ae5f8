"""muscle_node's input decoding (``vm-ros bench --only decode``): sensor_msgs/JointState messages
of ``JOINTS`` joints (names, positions and velocities, no efforts), decoded in one process.

Cases, each timed on the same messages:
- ``stream``: vm_ros.recording.cdr.input_decoder as the node uses it on a topic, one decoder for
  a publisher that keeps its names and sends new values in every message (the node's steady
  state: the message is read at the previous one's layout);
- ``stream, padding varies``: the same stream with the alignment padding after each name set to
  other bytes in every message (not every serialiser initialises it);
- ``new names``: the same decoder given two name sets in turn (every message's names decoded);
- ``mcap_ros2``: the general decoder (vm_ros.recording.cdr.decoder: lists, not arrays);
- ``rclpy``: rclpy.serialization.deserialize_message (needs the ros extra): the reference the
  node used before; it does not check a count against the message's length.

Thread CPU time per message (``time.thread_time``, so that other processes on a busy machine
count less than in wall time), median, min and max over interleaved rounds, and the 1-minute
load average at the start and the end.
"""

from __future__ import annotations

import os
import statistics
import time

import numpy as np

JOINTS = 80
MESSAGES = 64  # distinct messages of a stream (values differ), cycled through
TYPE = "sensor_msgs/msg/JointState"
TARGET_US = 20.0  # the stream case, 80 joints


def joint_states(joints: int, count: int, suffix: str = "", seed: int = 0) -> list[bytes]:
    """``count`` serialised JointState messages of ``joints`` named joints (the same names,
    other values and stamps in each)."""
    from vm_ros.recording.cdr import serialize

    rng = np.random.default_rng(seed)
    names = [f"joint_{k}{suffix}" for k in range(joints)]
    return [serialize(TYPE, {"header": {"stamp": {"sec": 1 + k // 1000,
                                                  "nanosec": (k % 1000) * 1000000},
                                        "frame_id": ""},
                             "name": names, "position": rng.uniform(-1, 1, joints).tolist(),
                             "velocity": rng.uniform(-2, 2, joints).tolist()})
            for k in range(count)]


def with_random_padding(message: bytes, names: int, seed: int) -> bytes:
    """``message`` (a JointState of ``names`` names and an empty frame_id) with the 0-3
    alignment bytes after each name but the last set to random values. The name block starts at
    byte 20: the 4-byte encapsulation, the 8-byte stamp, frame_id's length and its NUL, aligned
    to 4 from byte 4."""
    rng = np.random.default_rng(seed)
    data, offset = bytearray(message), 24  # the first name's length word
    for k in range(names):
        end = offset + 4 + int.from_bytes(data[offset:offset + 4], "little")
        padding = -end % 4
        if k < names - 1 and padding:
            data[end:end + padding] = rng.integers(1, 256, padding, dtype=np.uint8).tobytes()
        offset = end + padding
    return bytes(data)


def _cases(joints: int) -> dict:
    """name -> a function that decodes the next message (or the reason it cannot run)."""
    from vm_ros.recording.cdr import decoder, input_decoder

    stream = joint_states(joints, MESSAGES)
    renamed = joint_states(joints, MESSAGES, suffix="_b", seed=1)
    alternate = [m for pair in zip(stream, renamed, strict=True) for m in pair]

    def cycling(decode, messages):
        position = [0]

        def step():
            position[0] = (position[0] + 1) % len(messages)
            return decode(messages[position[0]])
        return step

    padded = [with_random_padding(m, joints, seed) for seed, m in enumerate(stream)]
    cases = {"stream": cycling(input_decoder(TYPE), stream),
             "stream, padding varies": cycling(input_decoder(TYPE), padded),
             "new names": cycling(input_decoder(TYPE), alternate),
             "mcap_ros2": cycling(decoder(TYPE), stream)}
    try:
        from rclpy.serialization import deserialize_message
        from sensor_msgs.msg import JointState
    except ImportError as exc:
        cases["rclpy"] = f"needs the ros extra ({exc})"
    else:
        cases["rclpy"] = cycling(lambda data: deserialize_message(data, JointState), stream)
    return cases


def bench_joint_state_decode(repeats: int = 7, min_seconds: float = 0.2,
                             joints: int = JOINTS, progress=None) -> dict:
    """Per-message thread CPU time of each case (module docstring), in interleaved rounds."""
    cases = _cases(joints)
    runnable = {name: step for name, step in cases.items() if callable(step)}
    for step in runnable.values():  # warm-up, and the calls per round (~min_seconds each)
        for _ in range(2 * MESSAGES):
            step()
    calls = {}
    for name, step in runnable.items():
        start, count = time.thread_time(), 0
        while time.thread_time() - start < 0.05:
            step()
            count += 1
        calls[name] = max(100, int(min_seconds * count / (time.thread_time() - start)))
    load_start = os.getloadavg()[0]
    samples: dict = {name: [] for name in runnable}
    for _ in range(repeats):
        for name, step in runnable.items():
            start = time.thread_time()
            for _ in range(calls[name]):
                step()
            samples[name].append(1e6 * (time.thread_time() - start) / calls[name])
    rows = []
    for name, reason in cases.items():
        if name not in runnable:
            rows.append({"case": name, "skipped": reason})
            continue
        rows.append({"case": name, "us": statistics.median(samples[name]),
                     "us_min": min(samples[name]), "us_max": max(samples[name]),
                     "calls_per_round": calls[name]})
        if progress:
            progress(f"decode {name}: {rows[-1]['us']:.2f} us per message")
    return {"joints": joints, "message_bytes": len(joint_states(joints, 1)[0]),
            "repeats": repeats, "clock": "thread CPU", "target_us": TARGET_US,
            "load_1min_start": load_start, "load_1min_end": os.getloadavg()[0], "rows": rows}


__all__ = ["JOINTS", "TARGET_US", "bench_joint_state_decode", "joint_states"]
