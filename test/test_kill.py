"""A `vm-ros simulate` run stopped from outside: SIGINT/SIGTERM finish the log cleanly, SIGKILL
leaves a log readable up to its last complete chunk."""

from __future__ import annotations

import signal
import subprocess
import sys
import time

import numpy as np
import pytest
from mcap.reader import make_reader

from vm_ros.recording.reader import LogReader, LogReadError
from vm_ros.recording.run_log import read_run

STEP_NS, PUBLISH_NS = 1_000_000, 10_000_000


def _has_a_message(path) -> bool:
    """Whether the log being written already holds a complete message; False while the file is
    created but its magic not yet written (LogReadError: seen once under a loaded suite)."""
    try:
        return next(iter(LogReader(path).messages()), None) is not None
    except LogReadError:
        return False


def _start(path):
    """A long simulate run, returned once its log holds a first complete chunk."""
    proc = subprocess.Popen(
        [sys.executable, "-m", "vm_ros.cli", "simulate", "--scenario", "knee_extension",
         "--out", str(path), "--chunk-size", "16384"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline and proc.poll() is None:
        if path.exists() and _has_a_message(path):
            time.sleep(0.3)  # a few more chunks
            return proc
        time.sleep(0.05)
    proc.kill()
    pytest.fail(f"simulate did not start writing: {proc.communicate()}")


def _assert_gapless(run):
    """Every message decodes; inputs every step and outputs every publish period, no gap."""
    force = run.get("muscle_force")
    excitation = run.get("excitation")
    assert len(force) > 0 and len(excitation) >= len(force) * 10
    np.testing.assert_array_equal(run.model_time_ns(force.fields["stamp_ns"]),
                                  PUBLISH_NS * np.arange(1, len(force) + 1))
    np.testing.assert_array_equal(run.model_time_ns(excitation.time_ns),
                                  STEP_NS * np.arange(len(excitation)))
    assert np.all(np.isfinite(force.fields["effort"]))
    # the energy total of each tick follows its force message (maybe in the next chunk)
    totals = run.get("energy_total").time_ns
    assert len(force) - 1 <= len(totals) <= len(force)
    np.testing.assert_array_equal(totals, force.time_ns[: len(totals)])


@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGINT])
def test_sigterm_and_sigint_finish_the_log(tmp_path, signum):
    path = tmp_path / "stopped.mcap"
    proc = _start(path)
    proc.send_signal(signum)
    out, err = proc.communicate(timeout=30)
    assert proc.returncode == 128 + signum, err
    assert f"stopped by signal {int(signum)}" in err and "all muscles" in out
    run = read_run(path)
    assert run.complete and run.stop_reason is None
    _assert_gapless(run)
    with open(path, "rb") as stream:  # the summary and indexes are there for seeking readers
        summary = make_reader(stream).get_summary()
    assert summary.statistics.message_count == sum(len(s) for s in run.series.values())


def test_sigkill_leaves_a_log_readable_to_the_last_complete_chunk(tmp_path):
    path = tmp_path / "killed.mcap"
    proc = _start(path)
    proc.kill()
    proc.communicate(timeout=10)
    assert proc.returncode == -signal.SIGKILL
    run = read_run(path)
    assert not run.complete and run.stop_reason
    assert run.info.config.muscles == ("rectus_femoris", "vasti")
    assert set(run.attachments) == {"model.yaml", "muscles.yaml", "overrides.yaml"}
    _assert_gapless(run)
