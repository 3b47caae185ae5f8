"""`vm-ros recompute`: a log's recorded inputs reproduce its outputs; changed parameters change
them."""

from __future__ import annotations

import numpy as np
import pytest

from vm_ros import telemetry as tm
from vm_ros.cli import main
from vm_ros.recording.run_log import read_run

OUTPUTS = (tm.TOPIC_FORCE, tm.TOPIC_ENERGY_RATE, tm.TOPIC_ENERGY_RATE_TOTAL, tm.TOPIC_ENERGY_TOTAL,
           "muscle_telemetry")


@pytest.fixture(scope="module")
def knee_log(tmp_path_factory):
    out = tmp_path_factory.mktemp("recompute") / "knee.mcap"
    assert main(["simulate", "--scenario", "knee_extension", "--duration", "0.4", "--out",
                 str(out), "--chunk-size", "16384"]) == 0
    return out


def _values(run, topic):
    series = run.get(topic)
    return series.time_ns, {k: v for k, v in series.fields.items()}


def test_recompute_reproduces_the_run(knee_log, tmp_path, capsys):
    out = tmp_path / "again.mcap"
    assert main(["recompute", str(knee_log), "--out", str(out)]) == 0
    assert "max |difference| 0 N over 40 samples" in capsys.readouterr().out
    original, again = read_run(knee_log), read_run(out)
    assert again.info.source == "recompute"
    assert again.info.extra["recomputed_from"] == str(knee_log)
    assert again.info.extra["scenario"] == "knee_extension"  # the report's bins
    assert again.info.timing.start_time_ns == original.info.timing.start_time_ns > 0
    assert again.info.config.muscles == original.info.config.muscles
    assert again.info.config.recovery_mode == "dynamic"
    assert set(again.topic_types) == set(original.topic_types)
    for topic in OUTPUTS + ("excitation", "muscle_kinematics"):
        times, fields = _values(original, topic)
        times_again, fields_again = _values(again, topic)
        np.testing.assert_array_equal(times_again, times)
        for key, value in fields.items():
            np.testing.assert_allclose(fields_again[key], value, rtol=1e-12, atol=0,
                                       err_msg=f"{topic}.{key}")


def test_changed_parameters_change_the_outputs(knee_log, tmp_path, capsys):
    out = tmp_path / "changed.mcap"
    assert main(["recompute", str(knee_log), "--out", str(out), "--override",
                 "vasti.fpcsa_slow=0.9", "--recovery-mode", "static", "--telemetry-rate",
                 "0"]) == 0
    original, changed = read_run(knee_log), read_run(out)
    assert changed.info.config.overrides == {"vasti": {"fpcsa_slow": 0.9}}
    assert changed.info.config.recovery_mode == "static"
    assert changed.get("muscle_telemetry") is None
    force, force_changed = (r.get("muscle_force").fields["effort"] for r in (original, changed))
    np.testing.assert_allclose(force_changed[:, 0], force[:, 0], rtol=1e-12)  # rectus femoris
    assert np.max(np.abs(force_changed[:, 1] - force[:, 1])) > 1.0  # vasti
    np.testing.assert_array_equal(changed.get("excitation").fields["position"],
                                  original.get("excitation").fields["position"])


def test_other_model_file_is_attached(knee_log, tmp_path):
    run = read_run(knee_log, topics=())
    model = tmp_path / "model.yaml"
    model.write_bytes(run.attachments["model.yaml"] + b"\n# edited copy\n")
    out = tmp_path / "params.mcap"
    assert main(["recompute", str(knee_log), "--out", str(out), "--params", str(model)]) == 0
    assert read_run(out, topics=()).attachments["model.yaml"] == model.read_bytes()


def test_cut_short_log_is_recomputed_as_far_as_it_goes(knee_log, tmp_path, capsys):
    cut = tmp_path / "cut.mcap"
    data = knee_log.read_bytes()
    cut.write_bytes(data[: len(data) * 2 // 3])
    out = tmp_path / "cut-again.mcap"
    assert main(["recompute", str(cut), "--out", str(out)]) == 0
    captured = capsys.readouterr()
    assert "cut short" in captured.err and "max |difference| 0 N" in captured.out
    original = read_run(cut).get("muscle_force")
    again = read_run(out).get("muscle_force")
    assert 0 < len(original) <= len(again) < 40
    np.testing.assert_allclose(again.fields["effort"][: len(original)],
                               original.fields["effort"], rtol=1e-12)


def test_not_a_run_log(tmp_path, capsys):
    bogus = tmp_path / "x.mcap"
    bogus.write_bytes(b"not mcap at all")
    assert main(["recompute", str(bogus)]) == 2
    assert "not an MCAP file" in capsys.readouterr().err
    empty = tmp_path / "empty.mcap"
    empty.write_bytes(b"")
    assert main(["recompute", str(empty)]) == 2
    assert "the file is empty" in capsys.readouterr().err


def test_recompute_writes_the_original_messages_byte_for_byte(knee_log, tmp_path, capsys):
    """Inputs copied and outputs recomputed by blocks: the same messages, in the same order,
    with the same times and bytes as the simulated log, whose times start at the wall clock of
    its run (header stamps included: the bytes hold them)."""
    from mcap.reader import make_reader

    out = tmp_path / "same.mcap"
    assert main(["recompute", str(knee_log), "--out", str(out)]) == 0
    assert "exact: the recomputed outputs equal the recorded ones" in capsys.readouterr().out

    def messages(path):
        with open(path, "rb") as stream:
            return [(c.topic, m.log_time, m.publish_time, m.sequence, m.data)
                    for _, c, m in make_reader(stream).iter_messages(log_time_order=False)]

    original, again = messages(knee_log), messages(out)
    assert len(original) == 400 * 2 + 40 * 5  # inputs every step, outputs every 10 steps
    start = read_run(knee_log, topics=()).info.timing.start_time_ns
    assert start > 1_600_000_000 * 10**9  # a wall-clock date (2020 or later), not 0
    assert min(m[1] for m in original) == start  # the first inputs, at model time 0
    assert again == original


def test_log_with_an_older_model_file_says_how_to_recompute(tmp_path, capsys):
    """A model file attached by an older vm_ros lacks fields added since (here the drive law):
    one line naming the log and the field, and the way out (--params with today's file)."""
    import yaml

    from vm_ros.cli.recompute import _bank_of
    from vm_ros.errors import ConfigError
    from vm_ros.model.run_config import RunConfig
    from vm_ros.resources import config_dir

    model = yaml.safe_load((config_dir() / "model.yaml").read_text(encoding="utf-8"))
    del model["recruitment"]["lumped"]["drive_law"]
    attached = tmp_path / "attached"
    attached.mkdir()
    (attached / "model.yaml").write_text(yaml.safe_dump(model), encoding="utf-8")
    config = RunConfig(("vasti",), params=attached / "model.yaml")
    with pytest.raises(ConfigError) as caught:
        _bank_of(config, tmp_path / "old.mcap", attached)
    message = str(caught.value)
    assert message.startswith(f"{tmp_path / 'old.mcap'}: field 'recruitment.lumped.drive_law'")
    assert "--params config/model.yaml" in message and "\n" not in message
    # today's file, as the message says, builds the bank
    assert _bank_of(RunConfig(("vasti",)), tmp_path / "old.mcap", attached).n == 1


# --- the verdict and the printed differences come from one comparison ----------------------


def _without_one_force_message(log, out):
    """A copy of ``log`` without the middle muscle_force message (a recorder that lost one)."""
    from vm_ros.recording import McapRecorder
    from vm_ros.recording.reader import LogReader

    reader = LogReader(log)
    messages = [(m.topic, m.data, m.log_time_ns) for m in reader.messages()]
    forces = [i for i, m in enumerate(messages) if m[0] == "/muscle_force"]
    del messages[forces[len(forces) // 2]]
    with McapRecorder(out, metadata=reader.metadata, attachments=reader.attachments) as rec:
        for topic, type_name in reader.topic_types().items():
            rec.add_channel(topic, type_name)
        for message in messages:
            assert rec.write(*message)
    return out


def test_verdict_agrees_with_the_printed_difference(tmp_path, capsys):
    """A node-conditioned log that lost one output message: its stamps show a gap in model time,
    so the recompute is approximate, but every common stamp is equal (0 N printed). The verdict
    used to say 'differ' there; it now says what the comparison found."""
    from test_simulate_joint_space import simulate_leg

    log, _ = simulate_leg(tmp_path, "--excitation", "0.3")
    gap = _without_one_force_message(log, tmp_path / "gap.mcap")
    capsys.readouterr()
    assert main(["recompute", str(gap), "--out", str(tmp_path / "again.mcap")]) == 0
    printed = capsys.readouterr().out
    assert "approximate: the node's model time left its step grid (1 gap(s)" in printed
    assert "tendon force vs recorded: max |difference| 0 N over 20 samples\n" in printed
    assert "joint effort vs recorded: max |difference| 0 (N m or N) over 21 samples" in printed
    assert printed.count("exact") == 1 and ("not exact: equal at every common stamp, but the "
                                            "recorded model time left the step grid") in printed
    assert "differ from" not in printed   # the old verdict: "... outputs differ from the ..."


class _Recorded:
    """A recorded effort series as RunLog.get returns it (stamp_ns, effort, names)."""

    def __init__(self, stamps, effort, names=None):
        self.fields = {"stamp_ns": np.asarray(stamps), "effort": np.asarray(effort, float)}
        self.names = names

    def __len__(self):
        return len(self.fields["stamp_ns"])


class _Run:
    def __init__(self, series):
        self.series = series

    def get(self, topic):
        return self.series


@pytest.mark.parametrize(("recorded", "recomputed", "max_abs", "verdict"), [
    ([[1.0, np.nan]], [[1.0, np.nan]], 0.0, "exact:"),           # equal NaNs (a model reset)
    ([[1.0, np.nan]], [[1.0, 2.0]], np.nan, "not exact: the tendon forces cannot be compared"),
    ([[1.0, 2.0]], [[1.0, 2.5]], 0.5, "not exact: the tendon forces differ by up to 0.5 N"),
])
def test_comparison_counts_nan_and_differences_once(recorded, recomputed, max_abs, verdict):
    from vm_ros.cli.recompute import _difference
    from vm_ros.cli.recompute import verdict as make_verdict

    found = _difference(_Run(_Recorded([7], recorded)), tm.TOPIC_FORCE, "tendon force", "N",
                        np.array([7]), np.array(recomputed))
    np.testing.assert_equal(found.max_abs, max_abs)
    assert (found.common, found.recorded) == (1, 1)
    assert make_verdict([found], []).startswith(verdict)
    assert f"max |difference| {max_abs:.3g} N over 1 samples" in found.line()


def test_comparison_names_recorded_stamps_left_out():
    from vm_ros.cli.recompute import _difference, verdict

    found = _difference(_Run(_Recorded([5, 7, 9], [[1.0], [2.0], [3.0]])), tm.TOPIC_FORCE,
                        "tendon force", "N", np.array([7, 9, 11]), np.array([[2.0], [3.0], [4.0]]))
    assert found.line() == ("tendon force vs recorded: max |difference| 0 N over 2 samples (of "
                            "3 recorded)")
    assert verdict([found], []).startswith("exact:")
    assert verdict([found], ["1 gap(s) in model time"]).startswith(
        "not exact: equal at every common stamp")
    apart = _difference(_Run(_Recorded([5], [[1.0]])), tm.TOPIC_FORCE, "tendon force", "N",
                        np.array([6]), np.array([[1.0]]))
    assert verdict([apart], []) == ("not exact: recorded and recomputed tendon forces share no "
                                    "model time")
