"""The node programs' spin (vm_ros.node.shell.spin): a stop request ends it at the next callback."""

from __future__ import annotations

import os
import signal
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
