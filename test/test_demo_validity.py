"""A real-time run whose model time was skipped or whose inputs were applied off their time is
not valid: the demos say so and exit 3 unless --accept-skips (vm_ros.report.validity)."""

from __future__ import annotations

import os
import signal
import subprocess
import time
from pathlib import Path

import numpy as np
import pytest
from conftest import require_ros

from vm_ros.child_process import module_command
from vm_ros.cli.demo import CATCH_UP_S
from vm_ros.report.validity import (
    EXIT_NOT_VALID,
    INPUT_JITTER_BOUND_S,
    input_timing,
    run_validity,
    skipped_from_stamps,
)

MS = 1_000_000


def test_a_gap_between_output_stamps_is_skipped_model_time():
    stamps = 10 * MS * np.arange(100)
    assert skipped_from_stamps(stamps) == 0.0
    jumped = np.concatenate([stamps[:50], stamps[50:] + 730 * MS])  # 730 ms with no output
    assert skipped_from_stamps(jumped) == pytest.approx(0.730)
    late = stamps.copy()
    late[50:] += 4 * MS  # one sample 4 ms late (within 1.5 periods): not a skip
    assert skipped_from_stamps(late) == 0.0


def test_jitter_is_the_largest_departure_from_the_median_offset():
    stamps = 5 * MS * np.arange(1, 200)
    applied = stamps + 30 * MS  # a constant transport delay: no jitter
    timing = input_timing("muscle_kinematics", applied, stamps, 0, int(applied[-1]))
    assert timing.jitter_s == 0.0 and timing.gap_s == pytest.approx(0.035)
    burst = applied.copy()
    burst[100:106] = burst[99]  # six samples applied at the model time of an earlier one
    timing = input_timing("muscle_kinematics", burst, stamps, 0, int(burst[-1]))
    assert timing.jitter_s == pytest.approx(0.030)
    unstamped = input_timing("x", applied, np.zeros_like(stamps), 0, int(applied[-1]))
    assert np.isnan(unstamped.jitter_s)  # publishers that leave the stamp zero: not known


def test_verdict_lines_and_exit_status():
    stamps = 10 * MS * np.arange(1, 301)
    inputs = [("excitation", stamps + 2 * MS, stamps)]
    valid = run_validity(stamps, 0.0, inputs)
    assert valid.valid and valid.exit_status(False) == 0
    assert not any("NOT VALID" in line for line in valid.lines(False))
    skipped = run_validity(stamps, 0.25, inputs)
    text = "\n".join(skipped.lines(False))
    assert "NOT VALID" in text and "skipped 0.25 s" in text and f"exit status {EXIT_NOT_VALID}" \
        in text
    assert skipped.exit_status(False) == EXIT_NOT_VALID and skipped.exit_status(True) == 0
    assert "accepted (--accept-skips)" in "\n".join(skipped.lines(True))
    shifted = stamps.copy()
    shifted[150] += round(1e9 * INPUT_JITTER_BOUND_S) + 5 * MS
    late = run_validity(stamps, 0.0, [("excitation", shifted, stamps)])
    assert not late.valid and "excitation applied up to 25 ms off its time" in late.lines(False)[1]


def test_bounds_are_inclusive_and_the_verdict_names_the_input():
    """At its bound a quantity is valid, 1 ns beyond it is not: the jitter (20 ms), an input's
    gap (extrapolation_max_s, here 50 ms), an output gap (1.5 periods, not a skip); the closed
    loop's input is joint_states."""
    stamps = 10 * MS * np.arange(1, 101)
    bound_ns = round(1e9 * INPUT_JITTER_BOUND_S)

    def verdict(applied, received=None, output=stamps):
        received = stamps if received is None else received
        return run_validity(output, 0.0, [("joint_states", applied, received)], 0.05)

    for extra_ns, valid in ((bound_ns - 1, True), (bound_ns, True), (bound_ns + 1, False)):
        applied = stamps.copy()
        applied[40] += extra_ns  # one sample applied late, the others on time (median lag 0)
        result = verdict(applied)
        assert result.valid == valid and result.exit_status(False) == (0 if valid else 3)
        assert result.inputs[0].jitter_s == pytest.approx(extra_ns * 1e-9, abs=1e-15)
    assert "joint_states applied up to 20 ms off its time (bound 20 ms)" in \
        verdict(applied).lines(False)[1]
    # an input gap: the samples from the 51st on arrive 40 ms later (a 50 ms gap), on time
    for extra_ns, valid in ((40 * MS, True), (40 * MS + 1, False)):
        later = np.concatenate([stamps[:50], stamps[50:] + extra_ns])
        result = verdict(later, later, later)
        assert result.skipped_s == pytest.approx(extra_ns * 1e-9) and not result.valid
        gap_only = verdict(later, later, stamps)  # the outputs ran on: no model time skipped
        assert gap_only.skipped_s == 0.0 and gap_only.valid == valid
        assert gap_only.inputs[0].gap_s == pytest.approx(0.010 + extra_ns * 1e-9)
    assert "joint_states arrived 0.05 s apart (bound: muscle_node's extrapolation_max_s, " \
        "0.05 s)" in gap_only.lines(False)[1]
    # an output gap of 1.5 periods is not a skip, 1 ns more is (counted beyond one period)
    for extra_ns, skipped in ((5 * MS, 0.0), (5 * MS + 1, 0.005 + 1e-9)):
        output = np.concatenate([stamps[:50], stamps[50:] + extra_ns])
        assert skipped_from_stamps(output) == pytest.approx(skipped, abs=1e-15)


def _children(pid: int) -> list[int]:
    found = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                stat = (entry / "stat").read_text()
            except OSError:
                continue
            if int(stat.rsplit(")", 1)[1].split()[1]) == pid:
                found.append(int(entry.name))
    return found


def _log_peaks(path: Path, duration_s: float) -> dict:
    """Peak tendon force per muscle from the log's muscle_force on model time (header stamps),
    over the duration from the first: read with mcap_ros2 alone."""
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    stamps, forces, names = [], [], None
    with open(path, "rb") as handle:
        reader = make_reader(handle, decoder_factories=[DecoderFactory()])
        messages = [m for *_, m in reader.iter_decoded_messages(topics=["/muscle_force"])]
    for msg in messages:
        names = list(msg.name)
        stamps.append(msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec)
        forces.append(list(msg.effort))
    stamps, forces = np.array(stamps), np.array(forces)
    inside = stamps <= stamps.min() + round(duration_s * 1e9)
    return dict(zip(names, forces[inside].max(axis=0), strict=True))


def _stalled_run(folder: Path, demo_args, ready: str, stall_s: float):
    """`vm-ros demo DEMO_ARGS` with muscle_node stopped (SIGSTOP) for ``stall_s`` once stderr
    says ``ready`` (the model runs): the finished process, its stderr as text."""
    err_path = folder / "stderr.txt"
    with open(err_path, "w") as err:
        process = subprocess.Popen(module_command("vm_ros.cli", "demo", *demo_args),
                                   stdout=subprocess.PIPE, stderr=err, text=True, cwd=folder)
        deadline = time.monotonic() + 180
        while ready not in err_path.read_text():
            assert process.poll() is None and time.monotonic() < deadline, err_path.read_text()
            time.sleep(0.05)
        node = [pid for pid in _children(process.pid)
                if b"vm_ros.node" in Path(f"/proc/{pid}/cmdline").read_bytes()]
        assert len(node) == 1
        os.kill(node[0], signal.SIGSTOP)
        try:
            time.sleep(stall_s)  # the stall itself; nothing is timed
        finally:
            os.kill(node[0], signal.SIGCONT)
        out, _ = process.communicate(timeout=180)
    return subprocess.CompletedProcess(process.args, process.returncode, out,
                                       err_path.read_text())


def _stalled_demo(tmp_path: Path, *extra: str) -> tuple[subprocess.CompletedProcess, Path]:
    """The knee demo with muscle_node stopped for longer than it catches up on, once the model
    runs: it must skip model time."""
    path = tmp_path / "demo.mcap"
    proc = _stalled_run(tmp_path, ("--duration", "3", "--mcap", str(path), *extra),
                        "muscle_node is running", CATCH_UP_S + 0.8)
    return proc, path


def _printed_peaks(out: str) -> dict:
    peaks = {}
    for line in out.splitlines():
        words = line.split()
        if len(words) == 3 and words[0] in ("rectus_femoris", "vasti"):
            peaks[words[0]] = float(words[1])
    return peaks


@pytest.mark.ros
@pytest.mark.slow
def test_a_stalled_demo_is_not_valid_and_exits_3_unless_accepted(tmp_path):
    require_ros()
    for extra, status in (((), EXIT_NOT_VALID), (("--accept-skips",), 0)):
        folder = tmp_path / (extra[0].strip("-") if extra else "default")
        folder.mkdir()
        proc, path = _stalled_demo(folder, *extra)
        assert proc.returncode == status, proc.stdout + proc.stderr[-3000:]
        verdict = next(line for line in proc.stdout.splitlines() if line.startswith("NOT VALID"))
        assert "muscle_node skipped" in verdict
        assert ("accepted (--accept-skips)" in verdict) == bool(extra)
        # the table's peaks are the log's, on model time (printed to 0.1 N)
        printed, logged = _printed_peaks(proc.stdout), _log_peaks(path, 3.0)
        assert set(printed) == set(logged) == {"rectus_femoris", "vasti"}
        for name, peak in logged.items():
            assert printed[name] == pytest.approx(peak, abs=0.051)


@pytest.mark.ros
@pytest.mark.slow
def test_a_stalled_closed_loop_demo_is_not_valid_and_exits_3(tmp_path):
    """`vm-ros demo --closed-loop` with muscle_node stopped for 1.5 s once the loop is closed:
    it catches up on max_catch_up_steps (50 steps, 0.05 s) and skips the rest, so the summary
    ends with NOT VALID naming more than 1.2 s skipped, and the demo exits 3. SIGSTOP makes
    this so whatever the load."""
    pytest.importorskip("mujoco", reason="the mujoco extra is not installed")
    require_ros()
    stall_s = 1.5
    proc = _stalled_run(tmp_path, ("--closed-loop", "--duration", "3", "--out",
                                   str(tmp_path / "out")), "the loop is closed", stall_s)
    assert proc.returncode == EXIT_NOT_VALID, proc.stdout + proc.stderr[-3000:]
    last = proc.stdout.strip().splitlines()[-1]
    assert last.startswith("NOT VALID: muscle_node skipped ") and last.endswith(
        f"; exit status {EXIT_NOT_VALID} (--accept-skips: 0)"), proc.stdout
    skipped = float(last.removeprefix("NOT VALID: muscle_node skipped ").split()[0])
    assert skipped > stall_s - 0.3, last  # a loaded machine may skip more on its own
    print(f"stalled closed loop: {last}")
    assert (tmp_path / "out" / "closed_loop.png").is_file()  # the plot is made all the same
