"""Run muscle_node on the knee-extension scenario for a few seconds and summarise what it published;
with --closed-loop, let it drive a MuJoCo arm over ROS 2 and plot the motion.

muscle_node runs as a child process (``python -P -m vm_ros.node`` of the vm_ros this process runs,
never a source tree in the working folder: vm_ros.child_process), so that it has a core and an
interpreter lock of its own, as in real use, and so that the demo also exercises its clean
shutdown: it is stopped with SIGINT, which finishes its MCAP file. This process runs the driver
(excitation and muscle_kinematics from the scenario, in real time) and a monitor that subscribes
to muscle_force, energy_rate and energy_total; with a log (the default) the table is computed from
muscle_node's MCAP log once it is finished (its outputs on model time, and its inputs at the
model time that applied them), with --no-mcap from the monitor's messages, by their stamps.

Every run covers the same model time: the scenario starts with the model (the driver holds the
scenario's t = 0 until the first muscle_force, whose stamp is the model's start) and the table
covers the messages stamped within --duration of it, however late they arrive. One total: the
energy between two messages is the change of energy_total (the model's own sum over its steps,
exact), split over muscles, fibre types and components in the proportions of energy_rate at the
two messages (its mean); so the table adds up to energy_total, and only the split between
messages is interpolated. A busy machine can stop muscle_node for tens of milliseconds; it
catches up on up to CATCH_UP_S of model time after such a stall (the default
max_catch_up_steps, 50 ms, is for controllers that would rather skip than run late), so that no
model time is skipped and the run does not depend on the load.

Validity (vm_ros.report.validity): when muscle_node skipped model time, or applied its
excitation or muscle_kinematics more than 20 ms off their time, or received them further apart
than its extrapolation_max_s, the summary says the numbers are not valid and the demo exits with
status 3 (EXIT_NOT_VALID); --accept-skips prints the same and exits 0. On a busy machine the
peaks are such numbers: the model's own output at an input applied off its time (a path-length
step, a drive switch moved), not a message that arrived late.

rclpy runs in a loopback-only network namespace: inside scripts/netns-run (VM_ROS_NETNS=1) the
demo runs directly, otherwise it starts one for itself (unshare -n; needs root).
"""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import textwrap
import time
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path

import numpy as np

from vm_ros import telemetry as tm
from vm_ros.child_process import loopback_only, module_command, node_environment
from vm_ros.errors import VmRosError
from vm_ros.model.params import load_muscle_library
from vm_ros.report.summary import split_energy
from vm_ros.report.validity import (
    DEFAULT_INPUT_BOUND_S,
    Validity,
    diagnostics_number,
    logged_gap_bound,
    logged_inputs,
    node_diagnostics,
    run_validity,
)

SCENARIO = "knee_extension"
CATCH_UP_S = 1.0  # s of model time muscle_node catches up on after a stall (module docstring)
LOOP_MCAP = "closed_loop.mcap"
LOOP_PNG = "closed_loop.png"
LOOP_MODEL = "myoelbow"  # --closed-loop's default --model


def add_arguments(parser) -> None:
    parser.add_argument("--duration", type=float, default=10.0, metavar="S",
                        help="seconds of model time from the model's start (default 10)")
    parser.add_argument("--mcap", metavar="FILE", default=None,
                        help="MCAP log muscle_node writes (default DIR/demo-<timestamp>.mcap)")
    parser.add_argument("--out", metavar="DIR", default=None,
                        help="folder of the demo's files (default out; with --closed-loop the "
                             "geometry (cached), MCAP and PNG, default "
                             "out/demo-closed-loop-<model>)")
    parser.add_argument("--no-mcap", action="store_true", help="do not record")
    parser.add_argument("--executor", choices=("events", "single_threaded"), default="events",
                        help="muscle_node's executor (default events)")
    parser.add_argument("--model-rate-hz", type=float, default=1000.0, metavar="HZ",
                        help="model step rate (default 1000)")
    parser.add_argument("--recruitment", choices=("lumped", "natural", "continuous"),
                        default="lumped", help="recruitment scheme (default lumped)")
    parser.add_argument("--startup-timeout", type=float, default=30.0, metavar="S",
                        help="longest wait for muscle_node's first output (default 30)")
    parser.add_argument("--accept-skips", action="store_true",
                        help="exit 0 even when the run is not valid (model time skipped, "
                             "inputs applied off their time or far apart: the summary says so; "
                             "default: exit status 3)")
    loop = parser.add_argument_group("closed loop (--closed-loop)")
    loop.add_argument("--closed-loop", action="store_true",
                      help="muscle_node drives mujoco_sim_node over ROS 2 (extra mujoco)")
    loop.add_argument("--model", default=None, metavar="NAME|FILE.xml",
                      help=f"myo-sim model name or MJCF file (default {LOOP_MODEL}); with "
                           f"--closed-loop only")


def _command_line(args) -> list[str]:
    """``args`` as a vm-ros command line (to run the demo again inside a namespace)."""
    argv = ["demo", "--duration", repr(args.duration), "--executor", args.executor,
            "--model-rate-hz", repr(args.model_rate_hz), "--recruitment", args.recruitment,
            "--startup-timeout", repr(args.startup_timeout)]
    for flag, value in (("--mcap", args.mcap), ("--out", args.out), ("--model", args.model)):
        if value is not None:
            argv += [flag, str(value)]
    for flag, on in (("--no-mcap", args.no_mcap), ("--closed-loop", args.closed_loop),
                     ("--accept-skips", args.accept_skips)):
        if on:
            argv.append(flag)
    return argv


def _in_loopback_namespace(args) -> int:
    """Run this demo again in a new loopback-only network namespace; its exit status."""
    if shutil.which("unshare") is None or shutil.which("ip") is None:
        raise VmRosError("rclpy must run in a loopback-only network namespace: run the demo "
                         "inside scripts/netns-run, or install util-linux and iproute2")
    print("vm-ros demo: starting a loopback-only network namespace (unshare -n)",
          file=sys.stderr)
    process = subprocess.Popen(loopback_only(module_command("vm_ros.cli",
                                                             *_command_line(args))))
    while True:
        try:
            return process.wait()
        except KeyboardInterrupt:  # the demo in the namespace got it too and stops cleanly
            continue


def _node_command(args, scenario, mcap_path: Path | None) -> list:
    """muscle_node (the installed package) with the scenario's muscles, catching up on CATCH_UP_S
    of model time after a stall."""
    params = {
        "muscles": "[" + ", ".join(scenario.muscles) + "]",
        "recovery_mode": scenario.recovery_mode,
        "recruitment": args.recruitment,
        "model_rate_hz": f"{args.model_rate_hz:g}",
        "max_catch_up_steps": str(max(1, round(CATCH_UP_S * args.model_rate_hz))),
        "executor": args.executor,
        "mcap.enabled": "false" if mcap_path is None else "true",
    }
    if mcap_path is not None:
        params["mcap.path"] = str(mcap_path)
    command = module_command("vm_ros.node", "--ros-args")
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


@dataclass(frozen=True)
class DemoSummary:
    """What the monitor saw within the run's model time (messages 0..k-1, stamped within the
    duration of the first).

    | field | shape | unit |
    | names | (n,) | muscle names |
    | duration_s | () | s, first to last stamp |
    | messages | () | k, force messages in the window |
    | peak_force, mean_force | (n,) | N, over the k messages |
    | energy | (n, 3 fibres, 4 components) | J, from message 0 to k-1 (demo_summary) |
    | energy_total | () | J, change of energy_total from message 0 to k-1 |
    | validity | Validity | skipped model time and input gaps (vm_ros.report.validity) |
    | diagnostics | dict | the node's last /diagnostics values (key -> text) |
    """

    names: tuple
    duration_s: float
    messages: int
    peak_force: np.ndarray
    mean_force: np.ndarray
    energy: np.ndarray
    energy_total: float
    validity: Validity
    diagnostics: dict


def demo_summary(names, stamps_ns, efforts, rates, totals, duration_s: float,
                 diagnostics: dict, inputs=(),
                 gap_bound_s: float = DEFAULT_INPUT_BOUND_S) -> DemoSummary:
    """The table's numbers from muscle_node's outputs (the i-th of each published together,
    stamped ``stamps_ns`` on model time), over those stamped within ``duration_s`` of the
    first, in the order of their stamps; ``inputs``: (topic, log times, header stamps) of the
    inputs as muscle_node logged them (() when not known), checked against ``gap_bound_s``
    (vm_ros.report.validity.run_validity)."""
    k = min(len(stamps_ns), len(efforts), len(rates), len(totals))
    if k < 2:
        raise VmRosError(f"too few messages from muscle_node ({k})")
    stamps = np.asarray(stamps_ns[:k], dtype=np.int64)
    order = np.argsort(stamps, kind="stable")
    stamps = stamps[order]
    k = int(np.searchsorted(stamps, stamps[0] + round(duration_s * 1e9), side="right"))
    order, stamps = order[:k], stamps[:k]
    force = np.asarray(efforts, dtype=float)[order]
    totals = np.asarray(totals, dtype=float)[order]
    return DemoSummary(
        names=tuple(names), duration_s=float((stamps[-1] - stamps[0]) * 1e-9), messages=k,
        peak_force=force.max(axis=0), mean_force=force.mean(axis=0),
        energy=split_energy(np.asarray(rates, dtype=float)[order], totals),
        energy_total=float(totals[-1] - totals[0]),
        validity=run_validity(stamps, diagnostics_number(diagnostics, "skipped model time (s)"),
                              inputs, gap_bound_s),
        diagnostics=dict(diagnostics))


def format_summary(summary: DemoSummary, mcap_path: Path | None, description: str = "",
                   accepted: bool = False) -> str:
    """The demo's report: forces, energies by muscle, fibre type and component, one total; last
    the validity (``accepted``: --accept-skips)."""

    width = max(len(n) for n in (*summary.names, "muscle", "all muscles"))
    lines = textwrap.wrap(f"{SCENARIO}: {description}", 100) if description else [SCENARIO]
    lines += [f"{summary.duration_s:.2f} s of model time, {summary.messages} messages from "
              "muscle_node", "",
              f"{'muscle':<{width}}  {'peak force (N)':>14}  {'mean force (N)':>14}"]
    for i, name in enumerate(summary.names):
        lines.append(f"{name:<{width}}  {summary.peak_force[i]:14.1f}  "
                     f"{summary.mean_force[i]:14.1f}")
    header = "  ".join(f"{c:>12}" for c in tm.COMPONENT_LABELS)
    lines += ["", f"{'energy (J)':<{width}}  {'fibre':<5}  {header}"]  # (n, fibre, component)
    for i, name in enumerate(summary.names):
        for j, fibre in enumerate(tm.FIBRE_LABELS):
            cells = "  ".join(f"{e:12.3f}" for e in summary.energy[i, j])
            lines.append(f"{name if j == 0 else '':<{width}}  {fibre:<5}  {cells}")
    cells = "  ".join(f"{e:12.3f}" for e in summary.energy[:, -1].sum(axis=0))
    lines.append(f"{'all muscles':<{width}}  {'all':<5}  {cells}")
    lines.append("")
    lines.append(f"total energy: {summary.energy_total:.3f} J (muscle_node's energy_total; the "
                 "table splits it by energy_rate)")
    diag = summary.diagnostics
    if diag:
        p50 = diagnostics_number(diag, "step time p50 (ms)")
        p99 = diagnostics_number(diag, "step time p99 (ms)")
        budget = 1e6 / diagnostics_number(diag, "model rate (Hz)")
        lines.append(f"model step time: {1e3 * p50:.0f} us median, {1e3 * p99:.0f} us at the "
                     f"99th percentile (real time allows {budget:.0f} us per step)")
    if mcap_path is not None:
        lines.append(f"MCAP log: {mcap_path}")
    lines += summary.validity.lines(accepted)
    return "\n".join(lines)


def run(args) -> int:
    if args.duration <= 0:
        raise VmRosError(f"--duration must be > 0 s (got {args.duration})")
    if args.model is not None and not args.closed_loop:
        raise VmRosError(f"--model {args.model} is the closed-loop demo's model: add "
                         f"--closed-loop (the knee demo runs the {SCENARIO} scenario's muscles)")
    if os.environ.get("VM_ROS_NETNS") != "1":
        return _in_loopback_namespace(args)
    if args.closed_loop:
        return run_closed_loop(args)
    try:
        import rclpy
        from rclpy.experimental import EventsExecutor
        from rclpy.signals import SignalHandlerOptions

        from vm_ros.demo_driver import DemoDriver, DemoMonitor
    except ImportError as exc:
        raise VmRosError(f"vm-ros demo needs ROS 2 (rclpy): pip install '.[ros]' ({exc})") from exc
    from vm_ros.offline.scenarios import load_scenario

    if not os.environ.get("HOME") and not os.environ.get("ROS_LOG_DIR"):
        raise VmRosError("rclpy needs HOME or ROS_LOG_DIR set")
    scenario = load_scenario(SCENARIO)
    mcap_path = None
    if not args.no_mcap:
        mcap_path = Path(args.mcap or Path(args.out or "out")
                         / datetime.now().strftime("demo-%Y%m%d-%H%M%S.mcap"))
        mcap_path = mcap_path.resolve()

    context = rclpy.Context()
    # no rclpy signal handlers here: Ctrl-C raises KeyboardInterrupt, and `finally` stops the node
    rclpy.init(context=context, signal_handler_options=SignalHandlerOptions.NO)
    # the events executor: half the single-threaded one's CPU, so that the driver's ticks stay
    # on time on a busy machine
    executor = EventsExecutor(context=context)
    driver, monitor = DemoDriver(SCENARIO, context=context), DemoMonitor(context=context)
    for node in (driver, monitor):
        executor.add_node(node)
    # started once this process's ROS side is up, right before the block that stops it: a
    # failure before (rclpy's start) must not leave muscle_node running on its own
    process = subprocess.Popen(_node_command(args, scenario, mcap_path),
                               env=node_environment())
    try:
        deadline = time.monotonic() + args.startup_timeout
        while not monitor.stamps_ns:
            if process.poll() is not None:
                raise VmRosError(f"muscle_node exited with status {process.returncode}")
            if time.monotonic() > deadline:
                raise VmRosError(f"no muscle_force within {args.startup_timeout:g} s")
            executor.spin_once(timeout_sec=0.05)
        driver.start(monitor.stamps_ns[0])
        print(f"vm-ros demo: muscle_node is running; {args.duration:g} s of {SCENARIO}...",
              file=sys.stderr)
        deadline = time.monotonic() + args.duration + args.startup_timeout
        while (monitor.model_time_s() < args.duration and process.poll() is None
               and time.monotonic() < deadline):
            executor.spin_once(timeout_sec=0.05)
    finally:
        status = _stop(process)
        executor.shutdown(timeout_sec=1.0)
        for node in (driver, monitor):
            node.destroy_node()
        rclpy.try_shutdown(context=context)
    if status != 0:
        raise VmRosError(f"muscle_node ended with status {status}")
    if mcap_path is None:  # the monitor's messages, by their stamps; input timing not known
        summary = demo_summary(monitor.names, monitor.stamps_ns, monitor.efforts,
                               monitor.energy_rates, monitor.energy_totals, args.duration,
                               monitor.diagnostics)
    else:
        summary = logged_summary(mcap_path, args.duration, monitor.diagnostics)
    print(format_summary(summary, mcap_path, scenario.description, args.accept_skips))
    return summary.validity.exit_status(args.accept_skips)


def logged_summary(path: Path, duration_s: float, diagnostics: dict) -> DemoSummary:
    """:func:`demo_summary` of muscle_node's finished log: muscle_force, energy_rate and
    energy_total on model time (the stamps they were logged at), excitation and
    muscle_kinematics as logged, the node's extrapolation_max_s and its last /diagnostics (else
    ``diagnostics``, the monitor's)."""
    from vm_ros.recording import read_run

    run = read_run(path, topics=(tm.TOPIC_FORCE, tm.TOPIC_ENERGY_RATE, tm.TOPIC_ENERGY_TOTAL,
                                 tm.TOPIC_EXCITATION, tm.TOPIC_KINEMATICS,
                                 tm.TOPIC_DIAGNOSTICS))
    series = [run.get(t) for t in (tm.TOPIC_FORCE, tm.TOPIC_ENERGY_RATE, tm.TOPIC_ENERGY_TOTAL)]
    if any(s is None or len(s) < 2 for s in series):
        raise VmRosError(f"{path}: fewer than 2 outputs of muscle_node logged")
    force, rate, total = series
    common = np.intersect1d(np.intersect1d(force.time_ns, rate.time_ns), total.time_ns)
    rows = [np.searchsorted(s.time_ns, common) for s in series]
    n = len(force.names)
    rates = rate.fields["data"][rows[1]].reshape(len(common), n, 3, 4)
    logged = node_diagnostics(run)
    diagnostics = logged[-1] if logged else diagnostics
    return demo_summary(force.names, common, force.fields["effort"][rows[0]], rates,
                        total.fields["data"][rows[2]], duration_s, diagnostics,
                        logged_inputs(run), logged_gap_bound(run))


# ---------------------------------------------------------------------------- --closed-loop

_SOURCE_KEYS = ("model", "file", "sha256", "mujoco", "myo_sim")


def prepare_geometry(model: str, out: Path) -> tuple[Path, Path]:
    """DIR/geometry.yaml and DIR/muscles.yaml of ``model``: reused when the geometry's source
    (model name, XML file and hash, MuJoCo and myo-sim versions) is this model's, else made with
    ``vm-ros import-mjcf MODEL --out DIR`` (a child process; its exit status checked)."""
    import yaml

    from vm_ros.geometry.mujoco_backend import load_model

    geometry, library = out / "geometry.yaml", out / "muscles.yaml"
    source = load_model(model).as_dict()
    if geometry.is_file() and library.is_file():
        with open(geometry, encoding="utf-8") as handle:
            cached = (yaml.load(handle, Loader=getattr(yaml, "CSafeLoader", yaml.SafeLoader))
                      or {}).get("source", {})
        if all(cached.get(k) == source.get(k) for k in _SOURCE_KEYS):
            print(f"vm-ros demo: reusing {geometry} and {library}", file=sys.stderr)
            return geometry, library
    print(f"vm-ros demo: vm-ros import-mjcf {model} --out {out}", file=sys.stderr)
    status = subprocess.run(module_command("vm_ros.cli", "import-mjcf", model,
                                           "--out", str(out))).returncode
    if status != 0:
        raise VmRosError(f"vm-ros import-mjcf {model} ended with status {status}")
    return geometry, library


def loop_parameters(args, geometry_path: Path, library_path: Path, mcap_path: Path):
    """(muscle_node parameters, mujoco_sim_node parameters, drive, muscle names): every
    geometry muscle the library has, joint_map identity over the geometry's coordinates,
    pulses about the first coordinate at the middle of its range (where the sim starts)."""
    import yaml

    from vm_ros.closed_loop import pulse_excitation
    from vm_ros.geometry import load_geometry

    geometry = load_geometry(geometry_path)
    in_library = load_muscle_library(library_path)
    rows = [i for i, name in enumerate(geometry.muscle_names) if name in in_library]
    if not rows:
        raise VmRosError(f"no muscle of {geometry_path} has parameters in {library_path}")
    muscles = [geometry.muscle_names[i] for i in rows]
    joints = list(geometry.coordinate_names)
    q0 = (geometry.lower + geometry.upper) / 2
    drive = pulse_excitation(geometry.evaluate(q0).moment_arm[rows, 0], joints[0])
    joint_map = yaml.safe_dump({j: j for j in joints}, default_flow_style=True).strip()
    rate = float(args.model_rate_hz)
    muscle_node = {
        "muscles": muscles, "library": str(library_path), "geometry": str(geometry_path),
        "joint_map": joint_map, "joints": joints, "recruitment": args.recruitment,
        "model_rate_hz": rate, "publish_rate_hz": rate, "executor": args.executor,
        "mcap": {"enabled": True, "path": str(mcap_path)}}
    model = args.model
    if Path(model).suffix.lower() == ".xml" or Path(model).exists():
        model = str(Path(model).resolve())
    sim_node = {"model": model, "joints": joints, "initial_positions": q0.tolist(),
                "dt": 0.001, "tick_s": 0.001, "wait_for_command": True}
    return muscle_node, sim_node, drive, muscles


def _params_file(path: Path, params: dict) -> Path:
    """A ROS 2 parameters file (``/**: ros__parameters: ...``), so that the run can be repeated
    by hand with --params-file."""
    import yaml

    path.write_text(yaml.safe_dump({"/**": {"ros__parameters": params}}, sort_keys=False))
    return path


def _wait(executor, predicate, timeout_s: float, processes: dict, what: str) -> None:
    deadline = time.monotonic() + timeout_s
    while not predicate():
        for name, process in processes.items():
            if process.poll() is not None:
                raise VmRosError(f"{name} exited with status {process.returncode} ({what})")
        if time.monotonic() > deadline:
            raise VmRosError(f"{what}: not within {timeout_s:g} s")
        executor.spin_once(timeout_sec=0.05)


def run_closed_loop(args) -> int:
    """The --closed-loop demo (module docstring)."""
    try:
        import rclpy
        from rclpy.experimental import EventsExecutor
        from rclpy.signals import SignalHandlerOptions

        from vm_ros.demo_driver import LoopDriver
    except ImportError as exc:
        raise VmRosError(f"vm-ros demo needs ROS 2 (rclpy): pip install '.[ros]' ({exc})") from exc
    from vm_ros.geometry.mujoco_backend import require_mujoco

    require_mujoco()
    args.model = args.model or LOOP_MODEL
    if args.no_mcap:
        raise VmRosError("--closed-loop plots from muscle_node's MCAP: drop --no-mcap")
    if not os.environ.get("HOME") and not os.environ.get("ROS_LOG_DIR"):
        raise VmRosError("rclpy needs HOME or ROS_LOG_DIR set")
    out = Path(args.out or Path("out") / f"demo-closed-loop-{Path(str(args.model)).stem}")
    out = out.resolve()
    out.mkdir(parents=True, exist_ok=True)
    mcap_path = Path(args.mcap).resolve() if args.mcap else out / LOOP_MCAP
    geometry_path, library_path = prepare_geometry(args.model, out)
    muscle_params, sim_params, drive, muscles = loop_parameters(
        args, geometry_path, library_path, mcap_path)
    commands = {
        "muscle_node": module_command(
            "vm_ros.node", "--ros-args", "--params-file",
            str(_params_file(out / "muscle_node.yaml", muscle_params))),
        "mujoco_sim_node": module_command(
            "vm_ros.sim", "--ros-args", "--params-file",
            str(_params_file(out / "mujoco_sim_node.yaml", sim_params)))}
    print(f"vm-ros demo: {drive.description}", file=sys.stderr)
    wall_start = time.monotonic()
    # the nodes talk over UDP: a first send over shared memory can stall a node for 333 ms
    environment = node_environment()
    context = rclpy.Context()
    # no rclpy signal handlers here: Ctrl-C raises KeyboardInterrupt, and `finally` stops both
    rclpy.init(context=context, signal_handler_options=SignalHandlerOptions.NO)
    # the events executor, as the knee demo's: the single-threaded one's spin_once took this
    # process about 110 ms of CPU per second for a 100 Hz drive, beside the loop it drives
    executor = EventsExecutor(context=context)
    driver = LoopDriver(muscles, drive, context=context)
    executor.add_node(driver)
    statuses = {}
    # as in the knee demo: started right before the block that stops it
    processes = {"muscle_node": subprocess.Popen(commands["muscle_node"], env=environment)}
    try:
        # muscle_node starts on the first joint_states: it must have a drive by then, so the
        # simulator starts only once muscle_node has received some (else the arm would fall)
        _wait(executor, lambda: driver.sent_to_subscriber >= 2, args.startup_timeout,
              processes, "waiting for muscle_node to subscribe to excitation")
        processes["mujoco_sim_node"] = subprocess.Popen(commands["mujoco_sim_node"],
                                                         env=environment)
        _wait(executor, lambda: driver.efforts > 0, args.startup_timeout, processes,
              "waiting for muscle_node's first joint_efforts")
        driver.stop_listening()
        loop_start = time.monotonic()
        print(f"vm-ros demo: the loop is closed; {args.duration:g} s of {args.model}...",
              file=sys.stderr)
        end = loop_start + args.duration
        try:
            while time.monotonic() < end and all(p.poll() is None for p in processes.values()):
                executor.spin_once(timeout_sec=0.05)
        except KeyboardInterrupt:  # Ctrl-C once the loop runs: stop early, still plot
            print("vm-ros demo: interrupted, stopping the nodes", file=sys.stderr)
        loop_wall_s = time.monotonic() - loop_start
    finally:
        for name, process in processes.items():  # muscle_node first: it finishes the MCAP
            statuses[name] = _stop(process)
        executor.shutdown(timeout_sec=1.0)
        driver.destroy_node()
        rclpy.try_shutdown(context=context)
    failed = [f"{name} ended with status {status}" for name, status in statuses.items()
              if status != 0]
    if failed:
        raise VmRosError("; ".join(failed))
    from vm_ros.sim.loop_log import format_loop_summary, plot_loop_log, read_loop_log

    log = read_loop_log(mcap_path)
    print(f"closed loop over ROS 2: {args.model}, {len(muscles)} muscles "
          f"({', '.join(muscles)}), joints {', '.join(log.joints)}")
    print(f"drive: {drive.description}")
    print(format_loop_summary(log))
    print(f"wall time: {loop_wall_s:.2f} s closed loop, {time.monotonic() - wall_start:.2f} s "
          "from starting the nodes to stopping them")
    print(f"MCAP log: {mcap_path}")
    try:
        png = plot_loop_log(log, out / LOOP_PNG, f"{args.model}: muscle_node driving "
                            "mujoco_sim_node over ROS 2")
        print(f"plot: {png}")
    except ModuleNotFoundError:
        print("matplotlib is not installed: no plot (pip install 'vm_ros[plot]')")
    print("\n".join(log.validity.lines(args.accept_skips)))  # last: the verdict on the above
    return log.validity.exit_status(args.accept_skips)
