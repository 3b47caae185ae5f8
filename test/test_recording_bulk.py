"""Bulk message building (vm_ros.recording.bulk) and the offline run by blocks: the same bytes as
the per-message serialiser, the same log as the step-by-step loop, and decoded values equal to
the bank's own outputs."""

from __future__ import annotations

import numpy as np
import pytest
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory

from vm_ros import telemetry as tm
from vm_ros.model.run_config import RunConfig
from vm_ros.offline.runner import OfflineRun, RecordedInputs, SampledInputs
from vm_ros.offline.scenarios import load_scenario
from vm_ros.recording import bulk
from vm_ros.recording import messages as msgs
from vm_ros.recording.cdr import serialize
from vm_ros.recording.run_log import RunInfo, RunTiming, open_run_log, read_run

NAMES = ("rectus_femoris", "vasti")
LIBRARY_12 = ("biceps_long_head", "biceps_short_head", "triceps_long_head", "brachialis",
              "first_dorsal_interosseous", "soleus", "gastrocnemius_medialis",
              "tibialis_anterior", "vastus_lateralis", "rectus_femoris", "vasti",
              "gluteus_maximus")
# stamps at 0, just below and at a second boundary, and past 2^32 ns
STAMPS = np.array([0, 999_999_999, 1_000_000_000, 4_294_967_297_123], dtype=np.int64)


@pytest.fixture(scope="module")
def steps():
    """Four step outputs of a knee-extension bank (changing drive and path)."""
    scenario = load_scenario("knee_extension")
    bank = scenario.make_bank()
    inputs = scenario.inputs(bank)
    bank.reset(inputs.path_length(0.0))
    outs, held = [], []
    for k in range(400):
        t = k * 1e-3
        u, lp, vp = inputs.excitation(t), inputs.path_length(t), inputs.path_velocity(t)
        out = bank.step(1e-3, u, lp, vp)
        if k % 100 == 99:
            outs.append(out)
            held.append((u, lp, vp))
    return bank.names, outs, held


def test_input_messages_equal_the_serializer_byte_for_byte():
    rng = np.random.default_rng(1)
    u, lp, vp = rng.random((3, len(STAMPS), 2))
    excitation = bulk.joint_state_layout(NAMES, position=2).encode(STAMPS, position=u)
    kinematics = bulk.joint_state_layout(NAMES, position=2, velocity=2).encode(
        STAMPS, position=lp, velocity=vp)
    for i, stamp in enumerate(STAMPS.tolist()):
        assert excitation[i] == serialize(tm.TYPE_JOINT_STATE,
                                          msgs.excitation_fields(NAMES, u[i], stamp))
        assert kinematics[i] == serialize(tm.TYPE_JOINT_STATE,
                                          msgs.kinematics_fields(NAMES, lp[i], vp[i], stamp))


@pytest.mark.parametrize("names", [("a",), ("ab", "abc", "abcd"), ("muscle_é",)])
def test_names_of_any_length_pad_as_the_serializer(names):
    values = np.arange(2 * len(names), dtype=float).reshape(2, len(names)) - 0.5
    encoded = bulk.joint_state_layout(names, position=len(names)).encode(STAMPS[:2],
                                                                         position=values)
    for i in range(2):
        assert encoded[i] == serialize(tm.TYPE_JOINT_STATE, msgs.excitation_fields(
            names, values[i], int(STAMPS[i])))


def test_output_messages_equal_the_serializer_byte_for_byte(steps):
    names, outs, held = steps
    n = len(names)
    stamps = STAMPS[:len(outs)]
    force = bulk.joint_state_layout(names, n, n, n).encode(
        stamps, position=[o.fascicle_length for o in outs],
        velocity=[o.fascicle_velocity for o in outs], effort=[o.force for o in outs])
    rate = bulk.multi_array_layout(tm.energy_rate_layout(n), 12 * n).encode(
        data=[tm.energy_rate_array(o) for o in outs])
    totals = bulk.float64_layout().encode(data=[o.total_energy for o in outs])
    for i, (out, stamp) in enumerate(zip(outs, stamps.tolist(), strict=True)):
        assert force[i] == serialize(tm.TYPE_JOINT_STATE, tm.force_fields(out, names, stamp))
        assert rate[i] == serialize(tm.TYPE_FLOAT64_MULTI_ARRAY, tm.energy_rate_fields(out))
        assert totals[i] == serialize(tm.TYPE_FLOAT64, msgs.float64_fields(out.total_energy))


def test_joint_layouts_equal_the_serializer_one_step_at_a_time():
    """JointLayouts.encode (muscle_node's joint_efforts and joint_effort_commands, one step per
    publish) gives the serializer's bytes of telemetry's fields, message after message."""
    from vm_ros.joint_space import JointEfforts

    names = ("r_shoulder_elev", "r_elbow_flex")
    layouts = bulk.JointLayouts(names)
    rng = np.random.default_rng(2)
    for stamp in STAMPS.tolist():
        efforts = JointEfforts(names, *rng.normal(size=(3, 2)))
        (state_topic, state), (command_topic, command) = layouts.encode(efforts, stamp)
        assert (state_topic, command_topic) == (tm.TOPIC_JOINT_EFFORTS,
                                                tm.TOPIC_JOINT_EFFORT_COMMANDS)
        assert state == serialize(tm.TYPE_JOINT_STATE, tm.joint_efforts_fields(efforts, stamp))
        assert command == serialize(tm.TYPE_FLOAT64_MULTI_ARRAY,
                                    tm.joint_effort_commands_fields(efforts))


def test_one_message_at_a_time_equals_the_serializer(steps):
    """encode_one (muscle_node, one message per publish through a kept record) gives the
    serializer's bytes message after message: nothing of one message stays in the next."""
    names, outs, _ = steps
    n = len(names)
    force = bulk.joint_state_layout(names, n, n, n)
    rate = bulk.multi_array_layout(tm.energy_rate_layout(n), 12 * n)
    total = bulk.float64_layout()
    for out, stamp in zip(outs, STAMPS[:len(outs)].tolist(), strict=True):
        assert force.encode_one(stamp, position=out.fascicle_length,
                                velocity=out.fascicle_velocity, effort=out.force) == serialize(
            tm.TYPE_JOINT_STATE, tm.force_fields(out, names, stamp))
        assert rate.encode_one(data=tm.energy_rate_array(out)) == serialize(
            tm.TYPE_FLOAT64_MULTI_ARRAY, tm.energy_rate_fields(out))
        assert total.encode_one(data=out.total_energy) == serialize(
            tm.TYPE_FLOAT64, msgs.float64_fields(out.total_energy))


def test_telemetry_equals_the_serializer_byte_for_byte(steps):
    names, outs, held = steps
    reference = [msgs.telemetry_fields(o, names, int(s), h[1], h[2])
                 for o, s, h in zip(outs, STAMPS.tolist(), held, strict=True)]
    arrays = {name: [r[name] for r in reference] for name, _ in bulk.TELEMETRY_ARRAYS}
    arrays.update({key: [r[key] for r in reference]
                   for key in ("total_energy_rate", "total_energy")})
    encoded = bulk.telemetry_layout(names).encode(STAMPS[:len(outs)], **arrays)
    for data, fields in zip(encoded, reference, strict=True):
        assert data == serialize(msgs.TYPE_MUSCLE_TELEMETRY, fields)


def _simulate(path, block_steps, stop_after_s=None, telemetry_rate_hz=100.0,
              duration_s=2.0, recruitment="lumped", muscles=None):
    scenario = load_scenario("knee_extension")
    config = RunConfig(muscles or scenario.muscles, recovery_mode=scenario.recovery_mode,
                       recruitment=recruitment, units_per_type=5)
    timing = RunTiming(dt_s=0.001, publish_rate_hz=100.0, telemetry_rate_hz=telemetry_rate_hz)
    bank = config.make_bank()
    inputs = scenario.inputs(bank)
    stop = (lambda: False) if stop_after_s is None else (lambda: bank.time_s > stop_after_s)
    info = RunInfo(config, timing, "simulate", extra={"scenario": scenario.name})
    with open_run_log(path, info, bank, chunk_size=8192) as recorder:
        offline = OfflineRun(bank, timing, recorder)
        sampled = SampledInputs(bank.names, inputs.excitation, inputs.path_length,
                                inputs.path_velocity, timing.dt_ns, 0, offline.sink)
        result = offline.run(sampled, round(duration_s / timing.dt_s), should_stop=stop,
                             block_steps=block_steps)
    return result, recorder.status


def _messages(path):
    with open(path, "rb") as stream:
        return [(channel.topic, m.log_time, m.publish_time, m.sequence, m.data)
                for _, channel, m in make_reader(stream).iter_messages(log_time_order=False)]


@pytest.mark.parametrize("case", [
    {},  # publish and telemetry at 100 Hz
    {"telemetry_rate_hz": 40.0, "duration_s": 1.013},  # ticks every 10 and 25 steps, a rest
    {"stop_after_s": 1.2295},  # asked to stop inside the second block: stops at its end
    {"recruitment": "natural", "duration_s": 0.5},
    {"muscles": LIBRARY_12, "duration_s": 0.3},  # sums over more than 8 values
])
def test_blocks_write_the_stepwise_log_message_for_message(tmp_path, case):
    blocks, status_b = _simulate(tmp_path / "blocks.mcap", 700, **case)
    if "stop_after_s" in case:  # a stop is seen between blocks (of 700 steps)
        assert blocks.steps == 1400
        case = {**case, "stop_after_s": 1.3995}  # the stepwise loop stopped there
    stepwise, status_a = _simulate(tmp_path / "stepwise.mcap", 0, **case)
    assert blocks.steps == stepwise.steps
    assert blocks.interrupted == stepwise.interrupted == ("stop_after_s" in case)
    np.testing.assert_array_equal(blocks.force_samples, stepwise.force_samples)
    assert status_a.dropped == status_b.dropped == 0
    assert _messages(tmp_path / "blocks.mcap") == _messages(tmp_path / "stepwise.mcap")


def test_recompute_inputs_by_blocks_write_the_stepwise_log(tmp_path):
    _simulate(tmp_path / "run.mcap", 700, duration_s=0.5)
    recorded = read_run(tmp_path / "run.mcap", raw=(tm.TOPIC_EXCITATION, tm.TOPIC_KINEMATICS))
    for name, block_steps in (("stepwise", 0), ("blocks", 128)):
        bank = recorded.config(tmp_path).make_bank()
        with open_run_log(tmp_path / f"{name}.mcap", recorded.info, bank) as recorder:
            offline = OfflineRun(bank, recorded.info.timing, recorder)
            inputs = RecordedInputs(recorded, bank.n, offline.sink)
            offline.run(inputs, 500, block_steps=block_steps)
    assert _messages(tmp_path / "blocks.mcap") == _messages(tmp_path / "stepwise.mcap")


def test_decoded_log_equals_the_banks_own_outputs(tmp_path):
    """Decoded with mcap_ros2: every logged field against MuscleBank.run over the whole run
    (inputs sampled at the same times)."""
    path = tmp_path / "run.mcap"
    result, _ = _simulate(path, 700, duration_s=1.0)
    scenario = load_scenario("knee_extension")
    bank = scenario.make_bank()
    inputs = scenario.inputs(bank)
    times = [k * 1_000_000 * 1e-9 for k in range(1000)]
    u, lp, vp = (np.array([np.asarray(f(t), dtype=float) * np.ones(bank.n) for t in times])
                 for f in (inputs.excitation, inputs.path_length, inputs.path_velocity))
    bank.reset(lp[0])
    run = bank.run(1e-3, u, lp, vp)
    ticks = np.arange(9, 1000, 10)  # steps whose end is published
    decoded: dict = {}
    with open(path, "rb") as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        for _, channel, message, msg in reader.iter_decoded_messages():
            decoded.setdefault(channel.topic, []).append((message.log_time, msg))
    stamp = [m.header.stamp.sec * 10**9 + m.header.stamp.nanosec
             for _, m in decoded["/muscle_force"]]
    assert stamp == ((ticks + 1) * 1_000_000).tolist()
    force = decoded["/muscle_force"]
    np.testing.assert_array_equal([m.effort for _, m in force], run.force[ticks])
    np.testing.assert_array_equal([m.position for _, m in force], run.fascicle_length[ticks])
    np.testing.assert_array_equal([m.velocity for _, m in force], run.fascicle_velocity[ticks])
    rates = np.array([m.data for _, m in decoded["/energy_rate"]]).reshape(-1, bank.n, 3, 4)
    np.testing.assert_array_equal(rates[:, :, :2, :], run.energy_rate_by_fibre.as_array()[ticks])
    np.testing.assert_allclose(rates[:, :, 2, :], run.energy_rate.as_array()[ticks],
                               rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose([m.data for _, m in decoded["/energy_rate_total"]],
                               run.energy_rate.total[ticks].sum(axis=1), rtol=1e-12)
    assert decoded["/energy_total"][-1][1].data == run.last.total_energy
    np.testing.assert_array_equal([m.position for _, m in decoded["/excitation"]], u)
    np.testing.assert_array_equal([m.position for _, m in decoded["/muscle_kinematics"]], lp)
    np.testing.assert_array_equal([m.velocity for _, m in decoded["/muscle_kinematics"]], vp)
    record = [m for _, m in decoded["/muscle_telemetry"]]
    assert len(record) == len(ticks)
    for field, series in (("excitation", run.excitation), ("force", run.force),
                          ("contractile_force", run.contractile_force),
                          ("fascicle_length", run.fascicle_length),
                          ("mechanical_power", run.mechanical_power),
                          ("path_length", lp), ("path_velocity", vp)):
        np.testing.assert_array_equal([getattr(m, field) for m in record], series[ticks])
    np.testing.assert_array_equal([m.effective_activation for m in record],
                                  run.effective_activation[ticks].reshape(len(ticks), -1))
    assert record[-1].total_energy == run.last.total_energy
    np.testing.assert_array_equal(record[-1].mechanical_work, run.last.mechanical_work)
    np.testing.assert_array_equal(result.force_samples, run.force[ticks])


def _read_both(path, monkeypatch, **kwargs):
    """read_run with JointState messages decoded at once, and one by one."""
    from vm_ros.recording import series

    fast = read_run(path, **kwargs)
    monkeypatch.setattr(series.SeriesBuilder, "_learn_fixed", lambda self, msg: None)
    slow = read_run(path, **kwargs)
    return fast, slow


def _assert_same_series(fast, slow):
    assert fast.series.keys() == slow.series.keys()
    for topic, a in fast.series.items():
        b = slow.series[topic]
        np.testing.assert_array_equal(a.time_ns, b.time_ns)
        assert a.names == b.names and a.raw == b.raw
        assert a.fields.keys() == b.fields.keys(), topic
        for key in a.fields:
            assert a.fields[key].dtype == b.fields[key].dtype, (topic, key)
            np.testing.assert_array_equal(a.fields[key], b.fields[key])
    assert {t: s.count for t, s in fast.skipped.items()} == \
        {t: s.count for t, s in slow.skipped.items()}


def test_joint_states_decoded_at_once_equal_one_by_one(tmp_path, monkeypatch):
    """Messages like the first and others (names reordered, a muscle missing, a frame_id, an
    empty velocity, malformed bytes) read the same either way."""
    config = RunConfig(NAMES)
    timing = RunTiming(dt_s=0.001, publish_rate_hz=100.0, telemetry_rate_hz=0.0)
    bank = config.make_bank()
    path = tmp_path / "mixed.mcap"
    first = msgs.kinematics_fields(NAMES, [0.4, 0.3], [0.0, -0.1], 0)
    odd = [
        msgs.kinematics_fields(NAMES[::-1], [0.5, 0.6], [0.1, 0.2], 3),
        msgs.kinematics_fields(NAMES[:1], [0.45], [0.01], 4),
        {**msgs.kinematics_fields(NAMES, [0.41, 0.31], [1.0, 2.0], 5),
         "header": {"stamp": tm.stamp_fields(5), "frame_id": "knee"}},
        msgs.kinematics_fields(NAMES, [0.42, 0.32], None, 6),
        msgs.kinematics_fields(("vasti", "other", "rectus_femoris"), [1.0, 2.0, 3.0],
                               [4.0, 5.0, 6.0], 7),
    ]
    with open_run_log(path, RunInfo(config, timing, "simulate"), bank) as recorder:
        topic = "/" + tm.TOPIC_KINEMATICS
        write = recorder.write
        write(topic, serialize(tm.TYPE_JOINT_STATE, first), 0)
        write(topic, serialize(tm.TYPE_JOINT_STATE, msgs.kinematics_fields(
            NAMES, [np.nan, -0.0], [np.inf, 1e300], 1)), 1)
        write(topic, b"\x00\x01\x00\x00\x01", 2)  # malformed
        for i, fields in enumerate(odd):
            write(topic, serialize(tm.TYPE_JOINT_STATE, fields), 3 + i)
        for k in range(8, 40):
            write(topic, serialize(tm.TYPE_JOINT_STATE, msgs.kinematics_fields(
                NAMES, [0.4 + k, 0.3], [k, -k], 1_000_000_000 * k + 7)), k)
    fast, slow = _read_both(path, monkeypatch, raw=(tm.TOPIC_KINEMATICS,))
    _assert_same_series(fast, slow)
    assert len(fast.get(tm.TOPIC_KINEMATICS)) == 39


def test_simulated_log_reads_the_same_decoded_at_once(tmp_path, monkeypatch):
    path = tmp_path / "run.mcap"
    _simulate(path, 700, duration_s=0.3)
    fast, slow = _read_both(path, monkeypatch)
    _assert_same_series(fast, slow)


def test_recorded_inputs_block_equals_advance_to_step_by_step(tmp_path):
    """Names mapped, non-finite or non-positive values ignored, excitation_array by position,
    a message that does not decode copied but not applied: the same held inputs and the same
    copied messages at the same steps either way."""
    from vm_ros.offline.runner import LogSink, _Pending
    from vm_ros.recording import cdr
    from vm_ros.recording.run_log import METADATA_NAME
    from vm_ros.recording.writer import McapRecorder

    nan, inf = float("nan"), float("inf")
    ex, arr, kin = tm.TOPIC_EXCITATION, tm.TOPIC_EXCITATION_ARRAY, tm.TOPIC_KINEMATICS
    sent = [  # (topic, fields or raw bytes, log time ns)
        (kin, {"name": ["b", "a"], "position": [0.2, 0.1], "velocity": [0.5, -0.5]}, 0),
        (ex, {"name": ["b"], "position": [0.7]}, 10),
        (ex, {"name": ["a", "b"], "position": [nan, 0.9]}, 20),
        (ex, b"\x00\x01\x00\x00\x07", 21),  # does not decode
        (arr, {"data": [0.3, 0.4]}, 30),
        (ex, {"name": ["a"], "position": [inf]}, 30),
        (kin, {"name": ["a", "x"], "position": [-1.0, 5.0]}, 40),
        (kin, {"name": ["a"], "position": [0.15], "velocity": [nan]}, 50),
        (kin, {"name": ["b"], "position": [0.25]}, 50),
        (arr, {"data": [0.1]}, 55),  # too short: ignored
        (ex, {"name": ["a", "b"], "position": [1.5, -0.0]}, 61),
    ]
    path = tmp_path / "inputs.mcap"
    info = RunInfo(RunConfig(("a", "b")), RunTiming(), "test")
    with McapRecorder(path, metadata={METADATA_NAME: info.to_metadata()}) as recorder:
        for topic in (ex, arr, kin):
            recorder.add_channel("/" + topic, tm.TOPIC_TYPES[topic])
        for topic, fields, t in sent:
            data = fields if isinstance(fields, bytes) else cdr.serialize(tm.TOPIC_TYPES[topic],
                                                                          fields)
            recorder.write("/" + topic, data, t)
    run = read_run(path, raw=(tm.TOPIC_EXCITATION, tm.TOPIC_EXCITATION_ARRAY,
                              tm.TOPIC_KINEMATICS))
    starts = np.array([0, 5, 10, 20, 21, 29, 30, 44, 50, 55, 60, 61, 62, 70], dtype=np.int64)

    stepwise_sink = LogSink(None)
    stepwise_sink.pending = _Pending()
    stepwise = RecordedInputs(run, 2, stepwise_sink)
    stepwise.advance_to(0)
    rows = []
    for j, t in enumerate(starts.tolist()):
        stepwise_sink.slot = j
        rows.append(stepwise.advance_to(t))
    expected = [np.array([r[i] for r in rows]) for i in range(3)]

    block_sink = LogSink(None)
    blocks = RecordedInputs(run, 2, block_sink)
    block_sink.pending = _Pending()
    blocks.advance_to(0)
    block_sink.pending = pending = _Pending()
    got = [np.concatenate(parts) for parts in zip(
        blocks.block(starts[:6], 0, pending), blocks.block(starts[6:], 6, pending),
        strict=True)]
    for a, b in zip(got, expected, strict=True):
        np.testing.assert_array_equal(a, b)
    step = stepwise_sink.pending
    first = len(step.keys) - len(pending.keys)  # the messages at time 0 went before the loop
    assert (pending.keys, pending.topics, pending.data, pending.times) == (
        step.keys[first:], step.topics[first:], step.data[first:], step.times[first:])
