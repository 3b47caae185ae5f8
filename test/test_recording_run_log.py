"""Run logs: what an offline run writes, read back by the mcap library and by read_run, and
their robustness to a file cut short."""

from __future__ import annotations

import numpy as np
import pytest
import yaml
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory

from vm_ros import telemetry as tm
from vm_ros.model.run_config import RunConfig, parse_override
from vm_ros.offline.runner import LogSink, OfflineRun, RecordedInputs, SampledInputs
from vm_ros.offline.scenarios import load_scenario
from vm_ros.recording import cdr
from vm_ros.recording.messages import TOPIC_TELEMETRY, energy_partition
from vm_ros.recording.run_log import (
    ATTACHMENT_LIBRARY,
    ATTACHMENT_MODEL,
    ATTACHMENT_OVERRIDES,
    METADATA_NAME,
    RunInfo,
    RunTiming,
    open_run_log,
    read_run,
)
from vm_ros.recording.writer import McapRecorder

STEPS = 300  # 0.3 s at 1 kHz


@pytest.fixture(scope="module")
def sine_run(tmp_path_factory):
    """A 0.3 s sinusoidal-drive run on two muscles, logged, and the bank outputs it logged."""
    scenario = load_scenario("sinusoidal_drive")
    config = RunConfig(("vastus_lateralis", "soleus"), recovery_mode="dynamic",
                       overrides={"soleus": {"fpcsa_slow": 0.7}}, drive_law="tsianos2012")
    timing = RunTiming(dt_s=0.001, publish_rate_hz=100.0, telemetry_rate_hz=50.0)
    path = tmp_path_factory.mktemp("runlog") / "sine.mcap"
    bank = config.make_bank()
    inputs = scenario.inputs(bank)
    info = RunInfo(config, timing, "simulate", extra={"scenario": scenario.name})
    with open_run_log(path, info, bank, chunk_size=4096) as recorder:
        offline = OfflineRun(bank, timing, recorder)
        sampled = SampledInputs(bank.names, inputs.excitation, inputs.path_length,
                                inputs.path_velocity, timing.dt_ns, 0, offline.sink)
        result = offline.run(sampled, STEPS)
    reference = config.make_bank()  # the same run, not logged
    reference.reset(path_length=inputs.path_length(0.0))
    outputs = [reference.step(0.001, inputs.excitation(k * 1e-3), inputs.path_length(k * 1e-3),
                              inputs.path_velocity(k * 1e-3)) for k in range(STEPS)]
    return path, config, result, outputs


def test_outputs_decoded_by_mcap_ros2_equal_the_bank(sine_run):
    path, _, _, outputs = sine_run
    with open(path, "rb") as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        decoded = {}
        for _, channel, message, msg in reader.iter_decoded_messages():
            decoded.setdefault(channel.topic, []).append((message.log_time, msg))
    published = outputs[9::10]  # every 10th step, stamped at the step's end
    forces = decoded["/muscle_force"]
    assert len(forces) == len(published) == STEPS // 10
    for (log_time, msg), out in zip(forces, published, strict=True):
        stamp = msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec
        assert log_time == stamp == round(out.time_s * 1e9)
        assert msg.name == ["vastus_lateralis", "soleus"]
        np.testing.assert_allclose(msg.effort, out.force, rtol=1e-12)
        np.testing.assert_allclose(msg.position, out.fascicle_length, rtol=1e-12)
    rates = [m for _, m in decoded["/energy_rate"]]
    np.testing.assert_allclose(rates[-1].data, tm.energy_rate_array(published[-1]).ravel())
    assert [d.label for d in rates[-1].layout.dim] == ["muscle", "fibre", "component"]
    totals = [m.data for _, m in decoded["/energy_total"]]
    np.testing.assert_allclose(totals, [o.total_energy for o in published])
    # inputs: one sample per step start
    assert len(decoded["/excitation"]) == len(decoded["/muscle_kinematics"]) == STEPS
    telemetry = [m for _, m in decoded["/" + TOPIC_TELEMETRY]]
    assert len(telemetry) == STEPS // 20
    np.testing.assert_allclose(telemetry[-1].energy, energy_partition(
        outputs[-1].energy_by_fibre, outputs[-1].energy).ravel())
    np.testing.assert_allclose(telemetry[-1].firing_rate, outputs[-1].firing_rate_f05.ravel())


def test_metadata_and_attachments_rebuild_the_run(sine_run, tmp_path):
    path, config, _, _ = sine_run
    run = read_run(path)
    assert run.complete and run.stop_reason is None
    assert run.info.config.muscles == config.muscles
    assert run.info.config.overrides == {"soleus": {"fpcsa_slow": 0.7}}
    assert run.info.config.recovery_mode == "dynamic"
    assert run.info.config.drive_law == "tsianos2012"
    assert run.config(tmp_path).make_bank().params.lumped.drive_law == "tsianos2012"
    assert run.info.timing == RunTiming(0.001, 100.0, 50.0, 0)
    assert run.info.extra["scenario"] == "sinusoidal_drive"
    assert run.attachments[ATTACHMENT_MODEL] == config.params_path.read_bytes()
    assert run.attachments[ATTACHMENT_LIBRARY] == config.library_path.read_bytes()
    overrides = yaml.safe_load(run.attachments[ATTACHMENT_OVERRIDES])
    assert overrides == {"soleus": {"fpcsa_slow": 0.7}}
    rebuilt = run.config(tmp_path)
    assert rebuilt.params.read_bytes() == config.params_path.read_bytes()
    assert rebuilt.make_bank().specs == config.make_bank().specs


def test_read_run_arrays_follow_the_muscle_order(sine_run):
    path, _, result, _ = sine_run
    run = read_run(path)
    force = run.get("muscle_force")
    assert force.names == ("vastus_lateralis", "soleus")
    np.testing.assert_allclose(force.fields["effort"], result.force_samples)
    np.testing.assert_array_equal(force.time_ns, result.sample_times_ns)
    assert run.get(TOPIC_TELEMETRY).fields["energy"].shape == (STEPS // 20, 24)
    assert run.get("energy_rate").layout[0] == {"label": "muscle", "size": 2, "stride": 24}


def test_cut_short_file_reads_up_to_the_last_complete_chunk(sine_run, tmp_path):
    path, _, result, _ = sine_run
    data = path.read_bytes()
    whole = read_run(path)
    for fraction in (0.5, 0.8):
        cut = tmp_path / f"cut{fraction}.mcap"
        cut.write_bytes(data[: int(len(data) * fraction)])
        run = read_run(cut)
        assert not run.complete and run.stop_reason
        force = run.get("muscle_force")
        k = len(force)
        assert 0 < k < len(whole.get("muscle_force"))
        np.testing.assert_array_equal(force.fields["effort"], result.force_samples[:k])
        assert run.info == whole.info  # metadata and attachments come first


def test_metadata_parse_accepts_comma_separated_muscles():
    info = RunInfo.from_metadata({"muscles": "vasti, rectus_femoris", "dt_s": "0.002",
                                  "recruitment": "natural", "recovery_mode": "None"})
    assert info.config.muscles == ("vasti", "rectus_femoris")
    assert info.config.recovery_mode is None and info.timing.start_time_ns is None
    assert info.timing.dt_s == 0.002 and info.config.recruitment == "natural"


def test_parse_override():
    assert parse_override("vasti.fpcsa_slow=0.5") == {"vasti": {"fpcsa_slow": 0.5}}
    with pytest.raises(Exception, match="MUSCLE.FIELD=VALUE"):
        parse_override("vasti=0.5")


def test_recorded_inputs_hold_map_names_and_ignore_bad_values(tmp_path):
    """Zero-order hold by log time, by name; non-finite or non-positive values are ignored."""
    names = ("a", "b")
    path = tmp_path / "inputs.mcap"
    info = RunInfo(RunConfig(names), RunTiming(), "test")
    js, arr = tm.TYPE_JOINT_STATE, tm.TYPE_FLOAT64_MULTI_ARRAY
    with McapRecorder(path, metadata={METADATA_NAME: info.to_metadata()}) as rec:
        for topic, type_name in ((tm.TOPIC_EXCITATION, js), (tm.TOPIC_EXCITATION_ARRAY, arr),
                                 (tm.TOPIC_KINEMATICS, js)):
            rec.add_channel("/" + topic, type_name)

        def send(topic, type_name, fields, t):
            rec.write("/" + topic, cdr.serialize(type_name, fields), t)

        send(tm.TOPIC_KINEMATICS, js, {"name": ["b", "a"], "position": [0.2, 0.1],
                                       "velocity": [0.5, -0.5]}, 0)
        send(tm.TOPIC_EXCITATION, js, {"name": ["b"], "position": [0.7]}, 10)
        send(tm.TOPIC_EXCITATION, js, {"name": ["a", "b"], "position": [float("nan"), 0.9]}, 20)
        send(tm.TOPIC_EXCITATION_ARRAY, arr, {"data": [0.3, 0.4]}, 30)
        send(tm.TOPIC_KINEMATICS, js, {"name": ["a", "x"], "position": [-1.0, 5.0]}, 40)
        send(tm.TOPIC_KINEMATICS, js, {"name": ["a"], "position": [0.15]}, 50)
    run = read_run(path, raw=("excitation",))
    inputs = RecordedInputs(run, 2, LogSink(None))
    u, lp, vp = inputs.advance_to(0)
    assert u.tolist() == [0.0, 0.0] and lp.tolist() == [0.1, 0.2] and vp.tolist() == [-0.5, 0.5]
    assert inputs.advance_to(15)[0].tolist() == [0.0, 0.7]
    assert inputs.advance_to(20)[0].tolist() == [0.0, 0.9]
    assert inputs.advance_to(39)[0].tolist() == [0.3, 0.4]
    assert inputs.advance_to(45)[1].tolist() == [0.1, 0.2]  # -1 m and unknown name ignored
    u, lp, vp = inputs.advance_to(50)
    assert lp.tolist() == [0.15, 0.2] and vp.tolist() == [0.0, 0.5]  # no velocity: 0
    assert len(run.get("excitation").raw) == 2


def test_remapped_topics_are_found_by_base_name(tmp_path):
    """A node whose outputs were remapped records the mapping; get() follows it."""
    info = RunInfo(RunConfig(("vasti",)), RunTiming(), "muscle_node", namespace="/leg",
                   topics={"muscle_force": "/leg/knee_force"})
    assert info.log_topic("muscle_force") == "/leg/knee_force"
    assert info.log_topic("energy_rate") == "/leg/energy_rate"
    path = tmp_path / "remapped.mcap"
    with open_run_log(path, info, topics=("muscle_force", "energy_total")) as rec:
        rec.write("/leg/knee_force", cdr.serialize(tm.TYPE_JOINT_STATE, {
            "name": ["vasti"], "effort": [12.5]}), 7)
    run = read_run(path, topics=("muscle_force",))
    assert run.info.topics == {"muscle_force": "/leg/knee_force"}
    assert run.get("muscle_force").fields["effort"].tolist() == [[12.5]]
    assert set(run.topic_types) == {"/leg/knee_force", "/leg/energy_total"}


def test_header_stamps_read_back_exactly_at_todays_epoch(tmp_path):
    """Stamps of a node log (ROS time, ~1.8e18 ns) come back as the integers written: as float64
    they would be rounded to 256 ns, and recompute would call an exact run approximate."""
    info = RunInfo(RunConfig(("vasti",)), RunTiming(), "muscle_node")
    stamps = [1_795_984_190_123_776_595 + k * 1_000_001 for k in range(5)]
    path = tmp_path / "stamps.mcap"
    with open_run_log(path, info, topics=("muscle_force",)) as rec:
        for stamp in stamps:
            sec, nanosec = divmod(stamp, 1_000_000_000)
            rec.write("/muscle_force", cdr.serialize(tm.TYPE_JOINT_STATE, {
                "header": {"stamp": {"sec": sec, "nanosec": nanosec}},
                "name": ["vasti"], "effort": [1.0]}), stamp)
    read = read_run(path, topics=("muscle_force",)).get("muscle_force").fields["stamp_ns"]
    assert read.dtype == np.int64
    assert read.tolist() == stamps
