"""The installed muscle_node recording to a disk that fills: a 16 KiB tmpfs has no room for the
log's attachments (full when the log opens at the model start), a 64 KiB one fills at the first
chunk (about 5 s in). The node keeps running and publishing, /diagnostics reports the failed
recorder with the messages the file really holds, SIGINT ends it with status 0.

Each node runs in a private mount namespace (`unshare -m`, root) with the tmpfs mounted over an
empty folder; the test reads the file through /proc/<pid>/root while the node runs."""

from __future__ import annotations

import signal
import subprocess
from pathlib import Path

import pytest
from conftest import STRICT
from test_node_process import MUSCLES, installed, lengths, ros_args  # noqa: F401 (fixtures)

from vm_ros.recording.reader import LogReader

pytestmark = pytest.mark.ros


def _check_tmpfs_mounts(folder: Path) -> None:
    probe = subprocess.run(["unshare", "-m", "mount", "-t", "tmpfs", "-o", "size=16k", "tmpfs",
                            str(folder)], capture_output=True, text=True, timeout=30)
    if probe.returncode != 0:
        reason = f"cannot mount a tmpfs in a private mount namespace: {probe.stderr.strip()}"
        if STRICT:
            pytest.fail(f"{reason} (not skipped: CI or VM_ROS_NETNS=1 is set)")
        pytest.skip(reason)


@pytest.mark.parametrize("size", ["16k", "64k"], ids=["full-at-open", "full-at-first-chunk"])
def test_node_keeps_running_when_the_disk_is_full(ros, installed, lengths, tmp_path,  # noqa: F811
                                                   size):
    shim, env = installed
    disk = tmp_path / "disk"
    disk.mkdir()
    _check_tmpfs_mounts(disk)
    command = ["unshare", "-m", "sh", "-c", f'mount -t tmpfs -o size={size} tmpfs "$0" && '
               'exec "$@"', str(disk), str(shim), *ros_args(
                   muscles="[" + ", ".join(MUSCLES) + "]",
                   initial_path_length_m="[" + ", ".join(f"{x:.6f}" for x in lengths) + "]",
                   mcap__enabled="true", mcap__path=str(disk / "run.mcap"))]
    probe = ros.probe()
    process = subprocess.Popen(command, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                               text=True)
    try:
        def failed():
            return (process.poll() is not None
                    or probe.last_diagnostics().get("mcap", "").startswith("error:"))
        assert ros.spin_until(failed, timeout_s=40)
        assert process.poll() is None, process.communicate()[1]
        n = len(probe.forces)
        assert ros.spin_until(lambda: len(probe.forces) >= n + 200, timeout_s=10)  # ~2 s more
        diagnostics = probe.last_diagnostics()
        in_file = sum(1 for _ in LogReader(f"/proc/{process.pid}/root{disk}/run.mcap")
                      .messages())
        process.send_signal(signal.SIGINT)
        _, stderr = process.communicate(timeout=15)
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
    assert process.returncode == 0, stderr
    assert "Traceback" not in stderr, stderr
    assert diagnostics["_level"] == 2 and diagnostics["_message"] == "MCAP recording failed"
    assert "No space left on device" in diagnostics["mcap"]
    assert int(diagnostics["mcap messages written"]) == in_file
    assert int(diagnostics["mcap messages dropped"]) > 200
    if size == "16k":
        assert in_file == 0 and "cannot start the log" in diagnostics["mcap"]
    assert stderr.count("No space left on device") in (1, 2), stderr  # not once per message
