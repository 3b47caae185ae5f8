"""The node programs' spin (vm_ros.node.shell.spin): a stop request ends it at the next callback;
and their end (vm_ros.node.shell.run_node): a DDS teardown that does not end is cut off."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time

import pytest


@pytest.mark.parametrize("executor_kind", ["events", "single_threaded"])
def test_a_signal_ends_the_spin_at_the_next_callback(ros, executor_kind):
    """SIGTERM sent from a 10 ms timer's callback: the spin returns well before SPIN_CHECK_S,
    the longest it waits when nothing ends it sooner (so a stop that only the timeout noticed
    fails here), and the request records the signal."""
    from rclpy.node import Node

    from vm_ros.node.shell import SPIN_CHECK_S, make_executor, spin
    from vm_ros.node.signals import STOP_SIGNALS, ShutdownRequest

    saved = {sig: signal.getsignal(sig) for sig in STOP_SIGNALS}
    node = Node("spin_probe", context=ros.context)
    executor = make_executor(executor_kind, context=ros.context)
    sent = []
    started = time.monotonic()

    def tick():
        if not sent and time.monotonic() - started > 0.2:
            sent.append(time.monotonic())
            os.kill(os.getpid(), signal.SIGTERM)

    node.create_timer(0.01, tick)
    executor.add_node(node)
    try:
        stop = ShutdownRequest()  # this process's handlers until the finally
        spin(executor, ros.context, stop)
        ended = time.monotonic()
    finally:
        for sig, handler in saved.items():
            signal.signal(sig, handler)
        executor.shutdown()
        node.destroy_node()
    assert sent, "the timer never fired"
    assert stop.requested and stop.signal == signal.SIGTERM
    assert ended - sent[0] < SPIN_CHECK_S / 2


def test_a_callback_given_after_the_request_runs_at_once():
    from vm_ros.node.signals import STOP_SIGNALS, ShutdownRequest

    saved = {sig: signal.getsignal(sig) for sig in STOP_SIGNALS}
    calls = []
    try:
        stop = ShutdownRequest()
        stop.when_requested(lambda: calls.append("before"))
        os.kill(os.getpid(), signal.SIGINT)
        assert calls == ["before"] and stop.signal == signal.SIGINT
        stop.when_requested(lambda: calls.append("after"))
        assert calls == ["before", "after"]
    finally:
        for sig, handler in saved.items():
            signal.signal(sig, handler)


HANGING_TEARDOWN = textwrap.dedent("""
    import os, signal, sys, time
    from pathlib import Path
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from vm_ros.node import shell

    shell.TEARDOWN_LIMIT_S = 1.0

    class Stuck(Node):
        def destroy_node(self):
            while True:          # as rcl_node_fini spun in Fast DDS, holding the GIL
                pass

    def make_node():
        node = Stuck("stuck_teardown")
        os.kill(os.getpid(), signal.SIGTERM)   # a stop request: the spin returns at once
        return node

    def finish(node):
        Path(sys.argv[1]).write_text("finished")

    sys.exit(shell.run_node("stuck", shell.argparse.ArgumentParser(), make_node,
                            lambda node: SingleThreadedExecutor(), ["stuck"], finish=finish))
""")


def test_a_teardown_that_does_not_end_is_cut_off_after_the_node_finished(ros, tmp_path):
    """A node program whose DDS teardown never returns (a destroy_node that spins in a loop,
    as Fast DDS's participant destruction once spun for over an hour, holding the GIL) ends
    TEARDOWN_LIMIT_S (1 s here) after its spin: exit status 1, every thread's stack on stderr
    (the hung destroy_node named), and its own outputs finished first (``finish`` ran)."""
    marker = tmp_path / "finished"
    started = time.monotonic()
    done = subprocess.run([sys.executable, "-c", HANGING_TEARDOWN, str(marker)],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 1, done.stderr[-2000:]
    assert "Timeout" in done.stderr and "destroy_node" in done.stderr, done.stderr[-2000:]
    assert marker.read_text() == "finished"
    assert time.monotonic() - started < 60
