"""Run muscle_node on the knee-extension scenario for a few seconds and summarise what it published.

muscle_node runs as a child process (`python -m vm_ros.node`, the same code as the muscle_node
executable), so that it has a core and an interpreter lock of its own, as in real use, and so that
the demo also exercises its clean shutdown: it is stopped with SIGINT, which finishes its MCAP
file. This process runs the driver (excitation and muscle_kinematics from the scenario, in real
time) and a monitor that subscribes to muscle_force, energy_rate and energy_total; the table is
computed from those messages. Run it inside scripts/netns-run (as `make demo` does) to keep DDS
traffic on loopback.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from datetime import datetime
from pathlib import Path

from vm_ros.errors import VmRosError

HELP = "run muscle_node with a knee-extension driver and print forces and energies"
SCENARIO = "knee_extension"


def add_arguments(parser) -> None:
    parser.add_argument("--duration", type=float, default=10.0, metavar="S",
                        help="seconds to run after the first force arrives (default 10)")
    parser.add_argument("--mcap", metavar="FILE", default=None,
                        help="MCAP log muscle_node writes (default out/demo-<timestamp>.mcap)")
    parser.add_argument("--no-mcap", action="store_true", help="do not record")
    parser.add_argument("--executor", choices=("events", "single_threaded"), default="events",
                        help="muscle_node's executor (default events)")
    parser.add_argument("--model-rate-hz", type=float, default=1000.0, metavar="HZ",
                        help="model step rate (default 1000)")
    parser.add_argument("--recruitment", choices=("lumped", "natural", "continuous"),
                        default="lumped", help="recruitment scheme (default lumped)")
    parser.add_argument("--startup-timeout", type=float, default=30.0, metavar="S",
                        help="longest wait for muscle_node's first output (default 30)")


def _node_command(args, scenario, mcap_path: Path | None) -> list:
    params = {
        "muscles": "[" + ", ".join(scenario.muscles) + "]",
        "recovery_mode": scenario.recovery_mode,
        "recruitment": args.recruitment,
        "model_rate_hz": f"{args.model_rate_hz:g}",
        "executor": args.executor,
        "mcap.enabled": "false" if mcap_path is None else "true",
    }
    if mcap_path is not None:
        params["mcap.path"] = str(mcap_path)
    command = [sys.executable, "-m", "vm_ros.node", "--ros-args"]
    for name, value in params.items():
        command += ["-p", f"{name}:={value}"]
    return command


def _stop(process: subprocess.Popen, timeout_s: float = 15.0) -> int:
    """SIGINT (finishes the MCAP file), then SIGTERM, then SIGKILL."""
    for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGKILL):
        if process.poll() is not None:
            break
        process.send_signal(sig)
        try:
            process.wait(timeout=timeout_s)
        except subprocess.TimeoutExpired:
            continue
    return process.wait()


def format_summary(summary, mcap_path: Path | None) -> str:
    from vm_ros.telemetry import COMPONENT_LABELS, FIBRE_LABELS

    width = max(len(n) for n in (*summary.names, "muscle", "all muscles"))
    lines = [f"{SCENARIO}: {summary.duration_s:.2f} s of model time, {summary.messages} "
             "force messages", "",
             f"{'muscle':<{width}}  {'peak force (N)':>14}  {'mean force (N)':>14}"]
    for i, name in enumerate(summary.names):
        lines.append(f"{name:<{width}}  {summary.peak_force[i]:14.1f}  "
                     f"{summary.mean_force[i]:14.1f}")
    header = "  ".join(f"{c:>12}" for c in COMPONENT_LABELS)
    lines += ["", f"{'energy (J)':<{width}}  {'fibre':<5}  {header}"]  # (n, fibre, component)
    for i, name in enumerate(summary.names):
        for j, fibre in enumerate(FIBRE_LABELS):
            cells = "  ".join(f"{e:12.3f}" for e in summary.energy[i, j])
            lines.append(f"{name if j == 0 else '':<{width}}  {fibre:<5}  {cells}")
    cells = "  ".join(f"{e:12.3f}" for e in summary.energy[:, -1].sum(axis=0))
    lines.append(f"{'all muscles':<{width}}  {'all':<5}  {cells}")
    lines += ["", "energies: energy_rate messages integrated over the force stamps (rectangle "
                  "rule at the publish rate, so approximate)",
              f"energy_total over the run: {summary.energy_total:.3f} J (the model's own "
              f"cumulative total; integrated: {summary.energy[:, -1, -1].sum():.3f} J)"]
    diag = summary.diagnostics
    skipped = float(diag.get("skipped model time (s)", "0") or 0)
    if skipped > 0:
        lines.append(f"muscle_node fell behind real time and skipped {skipped:.3g} s of model "
                     "time (CPU starved; see its /diagnostics and max_catch_up_steps)")
    if diag:
        lines.append(f"muscle_node step time p50/p99: {diag.get('step time p50 (ms)')}/"
                     f"{diag.get('step time p99 (ms)')} ms, overruns: "
                     f"{diag.get('overruns (ticks longer than a step)')}")
    if mcap_path is not None:
        lines.append(f"MCAP log: {mcap_path}")
    return "\n".join(lines)


def run(args) -> int:
    try:
        import rclpy
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.signals import SignalHandlerOptions

        from vm_ros.demo_driver import DemoDriver, DemoMonitor
    except ImportError as exc:
        raise VmRosError(f"vm-ros demo needs ROS 2 (rclpy): pip install '.[ros]' ({exc})") from exc
    from vm_ros.scenarios import load_scenario

    if args.duration <= 0:
        raise VmRosError(f"--duration must be > 0 s (got {args.duration})")
    if not os.environ.get("HOME") and not os.environ.get("ROS_LOG_DIR"):
        raise VmRosError("rclpy needs HOME or ROS_LOG_DIR set")
    scenario = load_scenario(SCENARIO)
    mcap_path = None
    if not args.no_mcap:
        mcap_path = Path(args.mcap or datetime.now().strftime("out/demo-%Y%m%d-%H%M%S.mcap"))
        mcap_path = mcap_path.resolve()

    process = subprocess.Popen(_node_command(args, scenario, mcap_path))
    context = rclpy.Context()
    # no rclpy signal handlers here: Ctrl-C raises KeyboardInterrupt, and `finally` stops the node
    rclpy.init(context=context, signal_handler_options=SignalHandlerOptions.NO)
    executor = SingleThreadedExecutor(context=context)
    nodes = [DemoDriver(SCENARIO, context=context), DemoMonitor(context=context)]
    monitor = nodes[1]
    for node in nodes:
        executor.add_node(node)
    try:
        deadline = time.monotonic() + args.startup_timeout
        while not monitor.forces:
            if process.poll() is not None:
                raise VmRosError(f"muscle_node exited with status {process.returncode}")
            if time.monotonic() > deadline:
                raise VmRosError(f"no muscle_force within {args.startup_timeout:g} s")
            executor.spin_once(timeout_sec=0.05)
        print(f"vm-ros demo: muscle_node is running; {args.duration:g} s of {SCENARIO}...",
              file=sys.stderr)
        end = time.monotonic() + args.duration
        while time.monotonic() < end and process.poll() is None:
            executor.spin_once(timeout_sec=0.05)
    finally:
        status = _stop(process)
        executor.shutdown(timeout_sec=1.0)
        for node in nodes:
            node.destroy_node()
        rclpy.try_shutdown(context=context)
    if status != 0:
        raise VmRosError(f"muscle_node ended with status {status}")
    print(format_summary(monitor.summary(), mcap_path))
    return 0
