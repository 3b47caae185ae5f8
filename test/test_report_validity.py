"""`vm-ros report` of a muscle_node log says whether its inputs kept up (the demos' check,
vm_ros.report.validity.node_log_validity), over the time the node had inputs; a log without the
fibres' work says why W mech is n/a."""

from __future__ import annotations

import json
from types import SimpleNamespace

import numpy as np
import pytest

from vm_ros.recording.run_log import INPUT_TIME_KEY, INPUT_TIME_STAMPED, NODE_PARAMETERS_KEY
from vm_ros.report.summary import WORK_NOT_LOGGED, summarize, summary_table
from vm_ros.report.validity import node_input_losses, node_log_validity

MS = 1_000_000


class _Series(SimpleNamespace):
    def __len__(self) -> int:
        return len(self.time_ns)


def _series(time_ns, stamp_ns=None):
    fields = {} if stamp_ns is None else {"stamp_ns": np.asarray(stamp_ns, dtype=np.int64)}
    return _Series(time_ns=np.asarray(time_ns, dtype=np.int64), fields=fields)


def _node_log(outputs_ns, inputs: dict, parameters: dict | None = None,
              source: str = "muscle_node", input_time: str | None = None):
    """A stand-in for a RunLog: muscle_force at ``outputs_ns``; each input topic -> (log times,
    header stamps); muscle_node's parameters unless ``parameters`` is None; written by
    ``source`` (RunInfo.source); its input_time key unless None."""
    channels = {"muscle_force": _series(outputs_ns)}
    channels.update({topic: _series(*times) for topic, times in inputs.items()})
    extra = {} if parameters is None else {NODE_PARAMETERS_KEY: json.dumps(parameters)}
    if input_time is not None:
        extra[INPUT_TIME_KEY] = input_time
    return SimpleNamespace(path="node.mcap", info=SimpleNamespace(extra=extra, source=source),
                           get=channels.get)


def _replayed(start_ms: int, end_ms: int, delay_ms: int = 3):
    """Inputs at 1 kHz stamped on their own time and applied ``delay_ms`` later."""
    stamps = MS * np.arange(start_ms, end_ms)
    return stamps + delay_ms * MS, stamps


def test_a_node_log_whose_inputs_kept_up_is_valid_and_the_stale_tail_is_named():
    outputs = 10 * MS * np.arange(1, 301)  # 3 s of outputs; the inputs end at 2 s
    run = _node_log(outputs, {"excitation": _replayed(0, 2000),
                              "muscle_kinematics": _replayed(0, 2000)}, {})
    validity, stale_s = node_log_validity(run)
    assert validity.valid
    assert [t.topic for t in validity.inputs] == ["excitation", "muscle_kinematics"]
    assert stale_s == pytest.approx(1.0, abs=0.011)  # outputs after the last input (2.002 s)
    assert not any("NOT VALID" in line for line in validity.lines(None))


def test_a_late_burst_of_inputs_makes_the_report_say_not_valid_without_an_exit_status():
    outputs = 10 * MS * np.arange(1, 201)
    applied, stamps = _replayed(0, 2000)
    applied[1000:1040] = applied[1040]  # 40 samples applied together, up to 40 ms late
    run = _node_log(outputs, {"muscle_kinematics": (applied, stamps)},
                    {"extrapolation_max_s": 0.05})
    validity, _ = node_log_validity(run)
    assert not validity.valid
    lines = validity.lines(None)
    assert "muscle_kinematics applied up to 40 ms off its time" in lines[1]
    assert "exit status" not in lines[1] and "accept" not in lines[1]


def test_the_gap_bound_is_the_node_logs_own_extrapolation_max_s():
    outputs = 10 * MS * np.arange(1, 201)
    applied, stamps = _replayed(0, 2000)
    keep = np.r_[0:1000, 1080:2000]  # 80 ms without kinematics
    inputs = {"muscle_kinematics": (applied[keep], stamps[keep])}
    assert not node_log_validity(_node_log(outputs, inputs, {}))[0].valid  # default 0.05 s
    assert node_log_validity(_node_log(outputs, inputs, {"extrapolation_max_s": 0.1}))[0].valid


def test_offline_logs_and_logs_without_inputs_are_not_checked():
    outputs = 10 * MS * np.arange(1, 201)
    replayed = {"excitation": _replayed(0, 2000)}
    assert node_log_validity(_node_log(outputs, replayed, None, source="simulate")) is None
    assert node_log_validity(_node_log(outputs, {}, {})) is None
    # `simulate --motion` and `recompute` of a node log condition their inputs as the node
    # does and hold its parameters, but step every dt: not checked (their runs end with the
    # inputs, and a check would name a stale tail that is not there)
    for source in ("simulate", "recompute"):
        assert node_log_validity(_node_log(outputs, replayed, {}, source=source)) is None


def test_work_not_in_the_log_prints_na_and_says_why():
    rows = summarize(["a", "b"], np.ones((3, 2)), np.ones((2, 3, 4)), [np.nan, np.nan])
    text = summary_table(rows)
    assert "nan" not in text
    assert text.splitlines()[-1] == WORK_NOT_LOGGED
    assert text.splitlines()[-2].split()[-2:] == ["n/a", "n/a"]
    measured = summary_table(summarize(["a"], np.ones((3, 1)), np.ones((1, 3, 4)), [0.5]))
    assert WORK_NOT_LOGGED not in measured


def _diagnostics(*values: dict):
    """A /diagnostics series of muscle_node statuses with ``values`` (key -> text), in order."""
    def message(kv):
        return SimpleNamespace(status=[SimpleNamespace(hardware_id="vm_ros", values=[
            SimpleNamespace(key=k, value=v) for k, v in kv.items()])])
    return SimpleNamespace(messages=[message(kv) for kv in values])


def test_the_losses_the_node_counted_are_read_from_its_last_diagnostics():
    """The node counts messages lost before it took them per input topic (publisher sequence
    gaps, diagnostics key 'lost: TOPIC (messages)'); the report names the nonzero ones."""
    run = SimpleNamespace(get={"/diagnostics": _diagnostics(
        {"lost: excitation (messages)": "2"},
        {"lost: excitation (messages)": "6", "lost: muscle_kinematics (messages)": "7",
         "lost: excitation_array (messages)": "0"})}.get)
    assert node_input_losses(run) == {"excitation": 6, "muscle_kinematics": 7}
    assert node_input_losses(SimpleNamespace(get={}.get)) == {}


def test_inputs_placed_at_their_arrival_are_counted_and_named_not_failed():
    """Stamps an hour old (a replayed log's own) are not on the node's clock: every sample was
    placed at its arrival. The report counts them per input in a note, the run stays valid
    (its jitter is the delivery's); samples placed at their stamps (a few ms late or on time)
    are not counted; a log written before the stamps were used (no input_time key) is not
    counted either."""
    outputs = 10 * MS * np.arange(1, 201)
    applied, stamps = _replayed(0, 2000)
    old = stamps - 3600_000 * MS
    mixed = stamps.copy()
    mixed[:100] = 0  # not stamped: placed at arrival too
    parameters = {"input_timeout_s": 0.5}
    run = _node_log(outputs, {"excitation": (applied, old), "muscle_kinematics": (applied, mixed)},
                    parameters, input_time=INPUT_TIME_STAMPED)
    validity, _ = node_log_validity(run)
    assert validity.valid
    counts = {t.topic: (t.at_arrival, t.messages) for t in validity.inputs}
    window = (applied >= outputs[0]) & (applied <= outputs[-1])  # checked over the outputs
    inside, unstamped = int(np.count_nonzero(window)), int(np.count_nonzero(window[:100]))
    assert counts == {"excitation": (inside, inside), "muscle_kinematics": (unstamped, inside)}
    note = [line for line in validity.lines(None) if line.startswith("note: placed at")]
    assert len(note) == 1 and f"excitation {inside} of {inside}" in note[0]
    assert f"muscle_kinematics {unstamped} of {inside}" in note[0] and "--restamp" in note[0]

    late = stamps.copy()
    late[500] = applied[500] - 600 * MS  # older than input_timeout_s by 100 ms: at arrival
    on_clock = _node_log(outputs, {"excitation": (applied, late)}, parameters,
                         input_time=INPUT_TIME_STAMPED)
    validity, _ = node_log_validity(on_clock)
    assert [(t.at_arrival, t.messages) for t in validity.inputs] == [(1, inside)]
    assert node_log_validity(_node_log(outputs, {"excitation": (applied, stamps)}, parameters,
                                       input_time=INPUT_TIME_STAMPED))[0].inputs[0].at_arrival == 0
    before = _node_log(outputs, {"excitation": (applied, old)}, parameters)
    validity, _ = node_log_validity(before)
    assert validity.inputs[0].at_arrival == -1
    assert not any(line.startswith("note: placed at") for line in validity.lines(None))
