"""SIGINT/SIGTERM for vm_ros node programs: a flag, installed before rclpy is imported.

A signal in the first second after launch used to land in rclpy's import (a KeyboardInterrupt
traceback for SIGINT, death by signal -15 for SIGTERM, no log file finished). The handlers are
therefore installed first thing in ``main`` (vm_ros.node.main), and run_node checks the flag
before building the node, and a request ends the node's spin (vm_ros.node.shell.spin): every
stop is a clean exit 0, and a run log that was opened is finished.
"""

from __future__ import annotations

import signal

STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)


class ShutdownRequest:
    """SIGINT/SIGTERM handlers that only set a flag and call the callbacks given to
    :meth:`when_requested` (which end the node's spin).

    rclpy's own handlers are not used: they shut the context down from the signal handler
    while a callback may be publishing (RCLError), chain a KeyboardInterrupt that can land in
    the middle of the clean-up, and in rclpy 7.1.6 EventsExecutor.spin() never returns after
    them (measured with a 1 kHz timer). A second signal interrupts at once (KeyboardInterrupt).
    """

    _installed: ShutdownRequest | None = None

    def __init__(self):
        self.requested = False
        self.signal: int | None = None
        self._callbacks = []
        for sig in STOP_SIGNALS:
            signal.signal(sig, self._handle)

    @classmethod
    def install(cls) -> ShutdownRequest:
        """The process's request (installed once, at the first call)."""
        if cls._installed is None:
            cls._installed = cls()
        return cls._installed

    def when_requested(self, callback) -> None:
        """Call ``callback()`` at the first signal (at once if one came already). It runs in
        Python's signal handler: on the main thread, between two bytecodes of whatever runs
        there (a node's callback, when it spins)."""
        self._callbacks.append(callback)
        if self.requested:
            callback()

    def _handle(self, signum, frame):
        if self.requested:
            raise KeyboardInterrupt
        self.requested, self.signal = True, signum
        for callback in self._callbacks:
            callback()


def main_after_signals(import_main, args=None) -> int:
    """Install the handlers, then import the program (``import_main()`` returns its main, which
    imports rclpy) and run it with ``args``: a signal during the import is a clean exit 0 with
    nothing started."""
    stop = ShutdownRequest.install()
    try:
        program_main = import_main()
    except KeyboardInterrupt:  # a second signal during the import
        return 0
    if stop.requested:  # stopped while rclpy was imported: nothing was started
        return 0
    return program_main(args)


__all__ = ["ShutdownRequest", "main_after_signals"]
