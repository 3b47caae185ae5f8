"""Measure the model, the offline runner and muscle_node against vm_ros's speed targets; write
the results (JSON and CSV) and print a table.

Sections (all but coordination-walk, coordination-myolegs, report-walk, study and node-memory
by default; --only picks some):
  model     MuscleBank.step for 1, 10, 100, 1000 muscles (lumped units, energetics on,
            dt 1 ms), compiled (Numba) and NumPy back ends; the published energetics models'
            cost at 1000 muscles; the kernel per muscle-step: run against repeated step at 1,
            64, 100, 1000 and 10,000 muscles, serial and with the parallel switch (64, 1000,
            10,000), and the cold start (empty Numba cache) to the first run() result
  natural   natural units (20 per fibre type) over lumped units, cost ratio per step
  offline   the 180 s rectus femoris + vasti knee extension (dynamic recovery) with
            MuscleBank.run, wall time including set-up and input sampling
  decode    muscle_node's decoding of an 80-joint JointState (vm_ros.recording.cdr): a stream that
            keeps its names (the node's steady state; target <= 20 us per message), with and without
            the same padding bytes in every message, names changing every message, mcap_ros2's
            decoder and rclpy's deserialize_message; thread CPU time per message, medians of
            interleaved rounds, the load quoted (vm_ros_bench.decode_bench)
  node      muscle_node as a separate process: 1, 100 and 1000 muscles at 1 kHz publishing at
            100 Hz with MCAP (default batch: a tick per publish period), and 10 muscles
            publishing at 1 kHz; CPU, memory, model-time drift, time skipped, latency. After the
            1- and 100-muscle rows, the rclpy floor of the same traffic (vm_ros_bench.rclpy_floor:
            a bare rclpy node with muscle_node's subscriptions, timers, publishers of bytes of
            the same sizes, executor and MCAP writer, no model), measured the same way, and
            the node's CPU above it.
            rclpy runs in a loopback-only network namespace: inside scripts/netns-run it runs
            directly, otherwise this command starts one (unshare -n; needs root).
  joint     joint space (extra mujoco, with myo-sim; skipped with the reason without it), on
            the 80-muscle myo-sim leg imported once with vm-ros import-mjcf into
            OUT/joint-cache/ (reused while model, options and versions are unchanged):
            geometry evaluate(q, qdot) per call, compiled, NumPy and MuJoCo's exact tendons,
            and generalized_forces; muscle_node from joint_states at 1 kHz (the imported
            library's muscles, model 1 kHz, publish 100 Hz, MCAP) measured as the node
            section, alternating with the rclpy floor of the same traffic (joint_states of the
            14 coordinates in, the joint topics out; JOINT_FLOOR_PAIRS pairs, --quick one):
            the node's CPU above the floor per pair, median; the closed loop in one process
            (myoelbow; myolegs with its root fixed and free), wall time per simulated second at
            1 ms steps (vm_ros_bench.joint_bench).
            --quick imports at degree 3 over 100 poses (smaller polynomials: not comparable).
  study     runs only when named (--only study; about 17 minutes on a busy 2-core machine): a
            study on the embedded Dask LocalCluster (the study extra), 64 runs of the 30 s knee
            extension (fibre mix x recovery kernel) on 1 and 2 workers, speed-up and overhead
            per run; the client's memory over 1000 short runs (vm_ros_bench.study_bench)
  coordination
            live coordination per publish period without ROS (vm_ros_bench.coordination_bench):
            the receding-horizon solve and the period's model steps at 100 Hz with a 1 kHz
            model, 18 and 80 muscles; latency (solve), CPU per simulated second, load average
  coordination-walk
            runs only when named (--only coordination-walk; about a minute): vm-ros
            coordinate's offline solve of opensim-models' Gait10dof18musc walk at the model's
            F0, default options (6 steps) and --refine 4; reserve RMS per coordinate (% of
            peak; target < 3 %), forward runs, seconds (target < 10 s), load average. Skipped
            with the reason when the walk is not fetched (scripts/fetch-gait-data).
  coordination-myolegs
            runs only when named (--only coordination-myolegs; about a minute, plus the
            import when absent): vm-ros coordinate's offline solve on myo-sim's myolegs (the
            joint section's import in OUT/joint-cache/myolegs, made first when absent), 10 s of
            a gait-like motion (vm_ros_bench.coordination_bench.gait_motion), targets from
            MuJoCo's inverse dynamics, default options (--method auto: the receding horizon at
            this size): seconds (target < 60 s), CPU seconds, forward runs, reserve RMS per
            coordinate (% of peak); and the thread CPU of the geometry at 9 and 31 poses of
            that motion interpolated to the horizon's probe steps, what muscle_node's live
            coordination adds per publish period with a planned profile's positions
            (coordination_bench.planned_poses_ms). Skipped with the reason without the mujoco
            extra.
  help      `vm-ros --help` and `muscle_node --help` as child processes, 5 times each:
            median wall and CPU time (target < 0.5 s of CPU)
  report-walk
            runs only when named (--only report-walk; about a minute): vm-ros report of
            opensim-models' Gait10dof18musc walk simulated with its CMC controls (18 muscles),
            with and without plots; the plotting time is the difference (target < 5 s of
            CPU time; the wall time beside it).
            Skipped with the reason when the walk is not fetched (scripts/fetch-gait-data).
  node-memory
            runs only when named (--only node-memory; 7 minutes): muscle_node's resident
            memory over a long run, 100 muscles at 1 kHz, publish 100 Hz, MCAP as a rosbag2
            bag split every 60 s, 300 s after a 120 s warm-up (--node-duration S: S seconds,
            split every min(60, S/5) s; --quick: 60 s after 5 s; a one-hour soak:
            --node-duration 3600). VmRSS sampled every 5 s: after the warm-up and at the end,
            the growth in MiB and MiB/min, the least-squares slope (MiB/h, over the window and
            its second half) against 2 MiB/h, the number of bag files and whether every file
            reads back.

--compare [PEERS] (off by default) adds vm_ros beside its peers in the same process: OpenSim's
Millard 2012 muscle with the Umberger 2010 metabolics probe (the opensim extra) and MuJoCo's
muscle actuator (the mujoco extra), each at 1 and --compare-muscles N muscles (default 50),
1 ms steps from Python reading force (and energy rate) every step; thread CPU and wall time per
step, medians of 15 interleaved rounds of 1 s simulated each (--quick: 3 short rounds); the
cost per extra muscle (slope between 1 and N) and the ratios peer / vm_ros. No argument: every
peer (one not installed is a row with the reason); or a comma-separated list (opensim,mujoco).
vm_ros_bench.peer_compare has the definitions.

Timings are medians of repeated runs on a shared machine: compare ratios within one run rather
than absolute numbers across runs. Targets: 1 muscle <= 30 us per step; 1000 muscles <= 1 ms per
step; kernel <= 0.25 us per muscle-step at 1000 and 10,000 muscles, run at least as fast as
repeated step, 10,000 muscles in real time at 1 kHz with the parallel switch, cold start < 10 s;
knee extension offline < 5 s, logged < 3 s; --help < 0.5 s of CPU; node at 1 kHz, publish 100 Hz,
MCAP: 1 muscle <= 7 % of a core, 100 muscles <= 14 % (the node pinned to one CPU, the driver to the
other), 1000 muscles with no model time skipped, within one core, model time within 1 % of wall
time; joint: myolegs geometry evaluate <= 30 us of thread CPU (compiled), the node from
joint_states at 1 kHz <= 35 % of a core with latency p99 under a publish period; node-memory:
resident memory after the warm-up growing at most 2 MiB/h (the window's slope, extrapolated to an
hour); study: speed-up on 2 workers at least 1.8, overhead per run under 5 % of a 30 s run, the
client's memory growing at most 10 MiB from the 100th to the 1000th short run.
"""

from __future__ import annotations

import csv
import json
import os
import platform
import statistics
import subprocess
import sys
import time
import traceback
from pathlib import Path

import vm_ros
from vm_ros.child_process import loopback_only, module_command
from vm_ros.errors import VmRosError
from vm_ros_bench import FOLDER, child_environment

SECTIONS = ("model", "natural", "offline", "help", "decode", "node", "joint", "coordination",
            "coordination-walk", "coordination-myolegs", "report-walk", "study", "node-memory")
DEFAULT_SECTIONS = ("model", "natural", "offline", "help", "decode", "node", "joint",
                    "coordination")  # node-memory and study: when named
MEMORY_DURATION_S, MEMORY_QUICK_DURATION_S = 300.0, 60.0  # node-memory window
MEMORY_WARMUP_S, MEMORY_QUICK_WARMUP_S = 120.0, 5.0
MEMORY_SPLIT_S = 60.0  # bag split (log time); shorter windows: a fifth of the window
MEMORY_FILES = 5  # files a window gives at least about, when shorter than 5 splits
MEMORY_SLOPE_TARGET_MIB_PER_HOUR = 2.0  # issue: +2 MiB at most over an hour after the warm-up
RSS_SAMPLE_PERIOD_S = 5.0
COMPARE_PEERS = ("opensim", "mujoco")  # --compare: vm_ros_bench.peer_compare.PEERS
COMPARE_MUSCLES, COMPARE_QUICK_MUSCLES = 50, 5  # the N of the per-muscle slope
COMPARE_ROUNDS, COMPARE_QUICK_ROUNDS = 15, 3  # interleaved rounds (--repeats overrides)
COMPARE_BLOCK_S, COMPARE_QUICK_BLOCK_S = 0.05, 0.005  # about this long per timed block


def add_arguments(parser) -> None:
    parser.add_argument("--out", metavar="DIR", default="bench-results",
                        help="folder for bench.json and bench.csv (default bench-results)")
    parser.add_argument("--only", choices=SECTIONS, action="append", metavar="SECTION",
                        help=f"run only these sections ({', '.join(SECTIONS)}); repeatable; "
                             "default all but node-memory (7 minutes), which runs only when "
                             "named")
    parser.add_argument("--quick", action="store_true",
                        help="fewer repeats and 10 s node runs (a smoke run, not the targets)")
    parser.add_argument("--repeats", type=int, default=None, metavar="N",
                        help="repeats per timing (default 7, --quick 3)")
    parser.add_argument("--node-duration", type=float, default=None, metavar="S",
                        help="seconds measured per node configuration (default 60, --quick "
                             "10; node-memory 300, --quick 60)")
    parser.add_argument("--compare", nargs="?", const="all", default=None, metavar="PEERS",
                        help="also time vm_ros beside its peers in one process at 1 and N "
                             "muscles: every peer (no argument) or a comma-separated list of "
                             f"{', '.join(COMPARE_PEERS)}; a peer not installed is skipped "
                             "with the reason")
    parser.add_argument("--compare-muscles", type=int, default=None, metavar="N",
                        help="the larger bank size of --compare (default "
                             f"{COMPARE_MUSCLES}, --quick {COMPARE_QUICK_MUSCLES})")


def _machine() -> dict:
    import numpy

    from vm_ros.model import kernel

    info = {
        "vm_ros": str(Path(vm_ros.__file__).parent),  # what is measured: the installed package
        "benchmarks": str(FOLDER),
        "python": platform.python_version(),
        "platform": platform.platform(),
        "machine": platform.machine(),
        "cpus": os.cpu_count(),
        "numpy": numpy.__version__,
        "numba": kernel.numba.__version__ if kernel.AVAILABLE else None,
        "load_average_start": os.getloadavg(),
        "date": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
    }
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                info["cpu"] = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return info


def _say(message: str) -> None:
    print(f"bench: {message}", file=sys.stderr, flush=True)


# node at 1 kHz, publish 100 Hz, MCAP on: muscles -> most CPU (% of one core)
JOINT_NODE_CPU_TARGET = 35.0  # myolegs from joint_states at 1 kHz, publish 100 Hz, MCAP
NODE_CPU_TARGETS = {1: 7.0, 100: 14.0, 1000: 100.0}  # issue 33: margin for any 2-core machine
FLOOR_MUSCLES = (1, 100)  # the rclpy floor of the same traffic, run after these node rows
JOINT_FLOOR_PAIRS = 2  # the joint node and its rclpy floor, run alternately (--quick: 1 pair)
JOINT_PAIR_KEYS = ("cpu_percent_one_core", "driver_cpu_percent_one_core",
                   "load_average_1min_start", "load_average_1min_end", "latency_p99_ms",
                   "latency_publish_wait_p99_ms",
                   "latency_after_publish_step_p99_ms")  # CSV rows of the node's later runs
FLOOR_LEVEL = "mcap"  # the floor's whole traffic (vm_ros_bench.rclpy_floor)
FLOOR_KEYS = ("cpu_percent_one_core", "driver_cpu_percent_one_core", "load_average_1min_start",
              "load_average_1min_end", "rss_final_mib", "rate_muscle_force_hz",
              "rate_excitation_sent_hz", "mcap_file_mib")  # its CSV rows


def _node_rows(duration_s: float, workdir: Path) -> list[dict]:
    configs = []
    for n in NODE_CPU_TARGETS:
        main = {"muscles": n, "model_rate_hz": 1000.0, "publish_rate_hz": 100.0, "mcap": True}
        configs.append(main)
        if n in FLOOR_MUSCLES:
            configs.append({**main, "floor_level": FLOOR_LEVEL})
    configs.append({"muscles": 10, "model_rate_hz": 1000.0, "publish_rate_hz": 1000.0,
                    "mcap": False})
    rows = []
    for config in configs:
        floor = config.get("floor_level")
        _say(f"{'rclpy floor of ' if floor else ''}node {config['muscles']} muscles, publish "
             f"{config['publish_rate_hz']:g} Hz, MCAP {'on' if config['mcap'] else 'off'}, "
             f"{duration_s:g} s ...")
        rows.append(_node_process(
            config, ["--muscles", str(config["muscles"]),
                     "--model-rate", str(config["model_rate_hz"]),
                     "--publish-rate", str(config["publish_rate_hz"]),
                     "--duration", str(duration_s),
                     "--workdir", str(workdir / f"{'floor' if floor else 'node'}-"
                                                f"{config['muscles']}"),
                     *([] if config["mcap"] else ["--no-mcap"]),
                     *(["--floor", floor] if floor else [])], duration_s))
    return rows


def _node_memory_row(duration_s: float, warmup_s: float, workdir: Path) -> dict:
    """The node-memory item (module docstring): one node_bench run logging to a split bag."""
    split_s = min(MEMORY_SPLIT_S, duration_s / MEMORY_FILES)
    config = {"muscles": 100, "model_rate_hz": 1000.0, "publish_rate_hz": 100.0, "mcap": True,
              "bag": True, "max_bag_duration_s": split_s}
    _say(f"node-memory: 100 muscles, publish 100 Hz, bag split every {split_s:g} s, "
         f"{warmup_s:g} s warm-up + {duration_s:g} s ...")
    return _node_process(config, [
        "--muscles", "100", "--model-rate", "1000", "--publish-rate", "100",
        "--duration", str(duration_s), "--warmup", str(warmup_s),
        "--bag", "--max-bag-duration", str(split_s), "--rss-period", str(RSS_SAMPLE_PERIOD_S),
        "--workdir", str(workdir)], duration_s + warmup_s)


def _node_process(config: dict, arguments: list, duration_s: float) -> dict:
    """``python -P -m vm_ros_bench.node_bench ARGUMENTS`` with this process's vm_ros (in a
    loopback-only namespace): its JSON after ``config``, or ``config`` with the error's last
    lines."""
    command = module_command("vm_ros_bench.node_bench", *arguments)
    if os.environ.get("VM_ROS_NETNS") != "1":
        command = loopback_only(command)
    result = subprocess.run(command, capture_output=True, text=True, env=child_environment(),
                            timeout=duration_s * 3 + 180)
    if result.returncode != 0:
        tail = (result.stderr or result.stdout).strip().splitlines()[-5:]
        _say(f"node run failed: {' | '.join(tail)}")
        return {**config, "error": " | ".join(tail)}
    return {**config, **json.loads(result.stdout[result.stdout.index("{"):])}


def _joint_section(out: Path, quick: bool, repeats: int, min_seconds: float,
                   node_duration_s: float) -> dict:
    """The joint section's three items (module docstring); each a dict with ``skipped`` when
    it cannot run here."""
    from vm_ros_bench import joint_bench

    reason = joint_bench.missing_extra()
    if reason is not None:
        _say(f"joint: skipped, {reason}")
        return {"geometry": {"skipped": reason}, "node": {"skipped": reason},
                "motion": {"skipped": reason}, "closed_loop": [{"skipped": reason}]}
    from vm_ros.geometry.mujoco_backend import load_model

    used = load_model(joint_bench.MODEL).describe()  # a bare myo-sim name wins (load_model)
    _say(f"joint: {joint_bench.MODEL} is the {used}")
    cache = out / "joint-cache"
    imported = joint_bench.import_myolegs(cache / ("myolegs-quick" if quick else "myolegs"),
                                          quick=quick, progress=_say)
    _say(f"joint: myolegs import {'reused' if imported['reused'] else 'made'} "
         f"({Path(imported['geometry']).parent})")
    _say("joint: geometry evaluation ...")
    geometry = joint_bench.bench_geometry(imported["geometry"], repeats, min_seconds,
                                          progress=_say)
    config = {"model": joint_bench.MODEL, "joint_rate_hz": 1000.0, "model_rate_hz": 1000.0,
              "publish_rate_hz": 100.0, "mcap": True}
    arguments = ["--geometry", imported["geometry"], "--library", imported["library"],
                 "--joint-rate", "1000", "--model-rate", "1000", "--publish-rate", "100",
                 "--duration", str(node_duration_s), "--warmup", "2" if quick else "5"]
    runs = {"node": [], "floor": []}
    for pair in range(1 if quick else JOINT_FLOOR_PAIRS):  # node, floor, node, floor, ...
        for kind in runs:
            floor = ["--floor", FLOOR_LEVEL] if kind == "floor" else []
            _say(f"joint: {'rclpy floor of ' if floor else ''}muscle_node from joint_states at "
                 f"1 kHz, {node_duration_s:g} s (pair {pair + 1}) ...")
            runs[kind].append(_node_process(
                {**config, **({"floor_level": FLOOR_LEVEL} if floor else {})},
                [*arguments, "--workdir", str(out / f"{kind}-joint"), *floor], node_duration_s))
    _say(f"joint: simulate --motion, {joint_bench.MOTION_S:g} s of {joint_bench.MODEL} ...")
    motion = joint_bench.bench_motion(imported, repeats=max(1, repeats // 2),
                                      duration_s=1.0 if quick else joint_bench.MOTION_S,
                                      progress=_say)
    _say("joint: closed loop ...")
    loops = joint_bench.bench_closed_loop(
        joint_bench.closed_loop_cases(imported["library"], cache),
        duration_s=0.2 if quick else 2.0, repeats=repeats, progress=_say)
    return {"model_used": used, "import": imported, "geometry": geometry,
            "node": runs["node"][0], "node_repeats": runs["node"][1:], "floor": runs["floor"],
            "motion": motion, "closed_loop": loops}


KERNEL_SERIAL_COUNTS = (1, 64, 100, 1000, 10000)
KERNEL_PARALLEL_COUNTS = (64, 1000, 10000)
KERNEL_TARGET_US = 0.25  # per muscle-step on one core at 1000 and 10,000 muscles


def _study_section(quick: bool) -> dict:
    """vm_ros_bench.study_bench (the study extra; without it the reason)."""
    from vm_ros.study import require_extra

    try:
        require_extra()
    except VmRosError as error:
        _say(f"study: skipped: {error}")
        return {"error": str(error)}
    from vm_ros_bench import study_bench

    return study_bench.bench_study(quick, progress=_say)


def kernel_available() -> bool:
    from vm_ros.model import kernel

    return kernel.AVAILABLE


def _kernel_rows(quick: bool) -> dict:
    """run against repeated step per muscle-step, serial and with the parallel switch, and the
    cold start to the first run() (model_bench)."""
    from vm_ros_bench import model_bench

    repeats = 2 if quick else 5
    serial_counts = (1, 100) if quick else KERNEL_SERIAL_COUNTS
    parallel_counts = (100,) if quick else KERNEL_PARALLEL_COUNTS
    _say(f"kernel: run and step per muscle-step at {', '.join(map(str, serial_counts))} "
         "muscles, serial ...")
    serial = model_bench.bench_run_vs_step(serial_counts, repeats)
    _say("kernel: the same with the parallel switch on ...")
    parallel = model_bench.bench_run_vs_step(parallel_counts, repeats, parallel=True)
    if quick:
        return {"serial": serial, "parallel": parallel,
                "cold_start": {"skipped": "--quick (compiles from an empty cache: about 11-12 s)"}}
    _say("kernel: cold start (empty compilation cache) to the first run() ...")
    return {"serial": serial, "parallel": parallel,
            "cold_start": model_bench.cold_start_to_first_run()}


def _kernel_csv_rows(r: dict, add) -> None:
    serial = {row["muscles"]: row for row in r["serial"]}
    for n, row in serial.items():
        case = f"{n} muscles, compiled, serial (load {row['load_1min']:.2f})"
        target = n in (1000, 10000)
        add("kernel", case, "run per muscle-step", row["run_us_per_muscle_step"], "us",
            f"<= {KERNEL_TARGET_US:g} us" if target else None,
            row["run_us_per_muscle_step"] <= KERNEL_TARGET_US if target else None)
        add("kernel", case, "step per muscle-step", row["step_us_per_muscle_step"], "us")
        add("kernel", case, "run speed / repeated step", row["run_over_step_speed"], "ratio",
            ">= 1", row["run_over_step_speed"] >= 1.0)
    for row in r["parallel"]:
        n = row["muscles"]
        case = (f"{n} muscles, compiled, parallel {'on' if row['parallel_blocks'] else 'serial'}"
                f" (load {row['load_1min']:.2f})")
        add("kernel", case, "run per muscle-step", row["run_us_per_muscle_step"], "us")
        if n in serial:
            add("kernel", case, "parallel speed-up of run", serial[n]["run_us_per_muscle_step"]
                / row["run_us_per_muscle_step"], "ratio")
        if n == 10000:
            step_us = row["run_us_per_muscle_step"] * n
            add("kernel", case, "run per 1 ms step", step_us, "us", "<= 1000 us (real time)",
                step_us <= 1000.0)
    cold = r["cold_start"]
    if "error" in cold or "skipped" in cold:
        add("kernel", "cold start", "error" if "error" in cold else "skipped",
            cold.get("error") or cold["skipped"], "")
    else:
        case = f"cold start to the first run(), {cold['muscles']} muscles"
        add("kernel", case, "wall", cold["cold_start_s"], "s", f"< {cold['target_s']:g} s",
            cold["cold_start_s"] < cold["target_s"])
        if "imports_s" in cold:
            add("kernel", case, "of which imports", cold["imports_s"], "s")


def _myolegs_csv_rows(r: dict | None, add) -> None:
    from vm_ros_bench.coordination_bench import MYOLEGS_TARGET_S

    if not r or "error" in r:
        return
    if "skipped" in r:
        add("coordination-myolegs", "myolegs", "skipped", r["skipped"], "")
        return
    case = (f"myolegs, {r['muscles']} muscles, {r['motion_s']:g} s gait-like motion, "
            f"{r.get('method', 'trajectory')}")
    for name, value in r["rms_percent"].items():
        add("coordination-myolegs", case, f"reserve_rms_percent {name}", value, "%")
    for key in ("forward_runs", "cpu_s", "targets_s", "load_average_start", "infeasible_frames"):
        add("coordination-myolegs", case, key, r[key], "s" if key.endswith("_s") else "")
    add("coordination-myolegs", case, "seconds", r["seconds"], "s",
        f"< {MYOLEGS_TARGET_S:g} s", r["seconds"] < MYOLEGS_TARGET_S)
    for count, ms in r.get("planned_poses_ms", {}).items():
        add("coordination-myolegs", f"myolegs, {r['muscles']} muscles, live coordination's "
            f"horizon motion from {count} planned poses per period", "thread_cpu_ms_median",
            ms, "ms")


def _csv_rows(results: dict) -> list[dict]:
    """Flat (section, case, metric, value, min, max, unit, target, met) rows of the main numbers
    (min and max over the repeats where the value is a median of repeats)."""
    rows = []

    def add(section, case, metric, value, unit, target=None, met=None, low=None, high=None):
        rows.append({"section": section, "case": case, "metric": metric, "value": value,
                     "min": "" if low is None else low, "max": "" if high is None else high,
                     "unit": unit, "target": target or "", "met": "" if met is None else met})

    for r in results.get("model", []):
        if "step_us" not in r:
            continue
        target = {1: 30.0, 1000: 1000.0}.get(r["muscles"]) if r["backend"] == "numba" else None
        add("model", f"{r['backend']} {r['muscles']} muscles", "step median", r["step_us"], "us",
            f"<= {target:g} us" if target else None,
            None if target is None else r["step_us"] <= target, r["step_us_min"],
            r["step_us_max"])
    for r in results.get("model", []):
        if "models_over_none" in r:  # every published energetics model against none
            for key, clock in (("models_over_none", "wall"),
                               ("models_over_none_thread_cpu", "thread CPU")):
                if key in r:
                    add("model", f"{r['backend']} {r['muscles']} muscles, {r['call']}",
                        f"{clock}: {r['energetics_models']} models "
                        f"({r.get('selection', 'all')}) / none", r[key],
                        "ratio", f"<= {r['target_ratio']:g}", r[key] <= r["target_ratio"])
        elif "least_ratio" in r:  # the one-model row's least ratio with NumPy's transcendentals
            add("model", f"numba {r['muscles']} muscles, run",
                "thread CPU: umberger2010's NumPy part / none + 1", r["least_ratio"], "ratio")
    for r in results.get("natural", []):
        add("natural", f"{r['backend']} {r['muscles']} muscles, {r['units_per_type']} units/type",
            "natural / lumped step cost", r["natural_over_lumped"], "ratio")
    if "offline" in results:
        r = results["offline"]
        add("offline", f"knee extension {r['simulated_s']:g} s, {r['backend']}", "wall",
            r["wall_s"], "s", "< 5 s", r["wall_s"] < 5.0)
        logged = r.get("logged")
        if logged:
            case = "knee extension logged as vm-ros simulate logs it, in process"
            add("offline", case, "simulate wall", logged["simulate_s"], "s", "< 3 s",
                logged["simulate_s"] < 3.0)
            add("offline", case, "model alone (MuscleBank.run)", logged["model_s"], "s")
            add("offline", case, "simulate / model alone", logged["simulate_over_model"], "ratio",
                "<= 5", logged["simulate_over_model"] <= 5.0)
            if "recompute_s" in logged:
                ratio = logged["recompute_over_simulate_paired"]
                add("offline", "its recompute (vm-ros recompute of that log), in process",
                    "recompute wall", logged["recompute_s"], "s")
                add("offline", "its recompute (vm-ros recompute of that log), in process",
                    "recompute / simulate (paired)", ratio, "ratio", "<= 2", ratio <= 2.0)
            if "cli_s" in logged:
                add("offline", "the same as a vm-ros simulate process", "wall", logged["cli_s"],
                    "s")
    if "decode" in results:
        _decode_csv_rows(results["decode"], add)
    if "compare" in results:
        _compare_csv_rows(results["compare"], add)
    floors = {r["muscles"]: r["cpu_percent_one_core"] for r in results.get("node", [])
              if r.get("floor_level") and "error" not in r}
    for r in results.get("node", []):
        case = (f"{'rclpy floor, ' if r.get('floor_level') else ''}"
                f"{r['muscles']} muscles, publish {r['publish_rate_hz']:g} Hz"
                f"{', MCAP' if r['mcap'] else ''}")
        if "error" in r:
            add("node", case, "error", r["error"], "")
            continue
        if r.get("floor_level"):
            for key in FLOOR_KEYS:
                add("node", case, key, r[key], "")
            continue
        main = r["publish_rate_hz"] == 100.0 and r["mcap"]
        if main and r["muscles"] in floors:
            add("node", case, "cpu above the rclpy floor", r["cpu_percent_one_core"]
                - floors[r["muscles"]], "points of a core")
        cpu_target = NODE_CPU_TARGETS.get(r["muscles"]) if main else None
        for key, value in r.items():
            if key in ("muscles", "model_rate_hz", "publish_rate_hz", "mcap", "floor_level") or \
                    isinstance(value, (list, dict)):
                continue
            target = met = None
            if cpu_target is not None and key == "cpu_percent_one_core":
                target, met = f"<= {cpu_target:g} %", value <= cpu_target
            if main and key == "model_wall_drift_percent":
                target, met = "within 1 %", abs(value) <= 1.0
            if main and r["muscles"] == 1000 and key == "model_time_skipped_s":
                target, met = "0 s", value == 0
            add("node", case, key, value, "", target, met)
    if "kernel" in results:
        _kernel_csv_rows(results["kernel"], add)
    if "joint" in results:
        _joint_csv_rows(results["joint"], add)
    if "node-memory" in results:
        _memory_csv_rows(results["node-memory"], add)
    for r in results.get("coordination", []):
        case = f"{r['muscles']} muscles, {r['settings']}, publish {r['publish_rate_hz']:g} Hz"
        for key in ("solve_ms_median", "solve_ms_p99", "period_ms_median", "period_ms_p99",
                    "load_average_start"):
            add("coordination", case, key, r[key], "")
        add("coordination", case, "cpu_percent_one_core", r["cpu_percent_one_core"], "",
            "< 100 %", r["cpu_percent_one_core"] < 100.0)
    from vm_ros_bench.coordination_bench import WALK_TARGET_PERCENT, WALK_TARGET_S

    for r in results.get("coordination-walk", []):
        if "skipped" in r:
            add("coordination-walk", "Gait10dof18musc walk", "skipped", r["skipped"], "")
            continue
        case = f"Gait10dof18musc walk, {r['case']}"
        for name, value in r["rms_percent"].items():
            add("coordination-walk", case, f"reserve_rms_percent {name}", value, "%",
                f"< {WALK_TARGET_PERCENT:g} %", value < WALK_TARGET_PERCENT)
        add("coordination-walk", case, "forward_runs", r["forward_runs"], "")
        add("coordination-walk", case, "load_average_start", r["load_average_start"], "")
        add("coordination-walk", case, "seconds", r["seconds"], "s", f"< {WALK_TARGET_S:g} s",
            r["seconds"] < WALK_TARGET_S)
    _myolegs_csv_rows(results.get("coordination-myolegs"), add)
    for r in results.get("help", []):
        if "skipped" in r:
            add("help", f"{r['command']} --help", "skipped", r["skipped"], "")
            continue
        add("help", f"{r['command']} --help", "wall", r["wall_s"], "s")
        add("help", f"{r['command']} --help", "cpu", r["cpu_s"], "s", f"< {r['target_s']:g} s",
            r["cpu_s"] < r["target_s"])
    r = results.get("report-walk")
    if r and "skipped" in r:
        add("report-walk", "Gait10dof18musc walk", "skipped", r["skipped"], "")
    elif r and "plotting_s" in r:
        case = "Gait10dof18musc walk, 18 muscles, CMC controls"
        add("report-walk", case, "report", r["report_s"], "s")
        add("report-walk", case, "report --no-plots", r["no_plots_s"], "s")
        add("report-walk", case, "plotting (the difference)", r["plotting_s"], "s")
        add("report-walk", case, "plotting, CPU time", r["plotting_cpu_s"], "s",
            f"< {r['target_s']:g} s", r["plotting_cpu_s"] < r["target_s"])
        add("report-walk", case, "load_average_start", r["load_average_start"], "")
    if "study" in results and "error" not in results["study"]:
        from vm_ros_bench import study_bench

        study_bench.csv_rows(results["study"], add)
    return rows


def _decode_csv_rows(r: dict, add) -> None:
    load = f"load {r['load_1min_start']:.2f}-{r['load_1min_end']:.2f}"
    timed = {row["case"]: row for row in r["rows"] if "us" in row}
    for row in r["rows"]:
        case = f"JointState {r['joints']} joints, {row['case']} ({load})"
        if "skipped" in row:
            add("decode", case, "skipped", row["skipped"], "")
            continue
        stream = row["case"].startswith("stream")  # a publisher that keeps its names
        add("decode", case, f"per message median, {r['clock']}", row["us"], "us",
            f"<= {r['target_us']:g} us" if stream else None,
            row["us"] <= r["target_us"] if stream else None, row["us_min"], row["us_max"])
    if "stream" in timed:
        for name in ("rclpy", "stream, padding varies", "new names"):
            if name in timed:
                add("decode", f"JointState {r['joints']} joints, {name} / stream ({load})",
                    "per message", timed[name]["us"] / timed["stream"]["us"], "ratio")


def _compare_csv_rows(compare: dict, add) -> None:
    n = compare["muscles"]
    for r in compare["systems"]:
        if "skipped" in r:
            add("compare", r["system"], "skipped", r["skipped"], "")
            continue
        for size, key in ((1, "timing_1"), (n, "timing_n")):
            timing = r[key]
            case = f"{r['version']}, {size} muscle{'s' if size > 1 else ''}"
            add("compare", case, "step median, thread CPU", timing["cpu_us"], "us",
                low=timing["cpu_us_min"], high=timing["cpu_us_max"])
            add("compare", case, "step median, wall", timing["wall_us"], "us",
                low=timing["wall_us_min"], high=timing["wall_us_max"])
        case = f"{r['version']}, slope 1..{n} muscles"
        add("compare", case, "per extra muscle, thread CPU", r["per_muscle_cpu_us"], "us")
        add("compare", case, "per extra muscle, wall", r["per_muscle_wall_us"], "us")
        if r["system"] != "vm_ros":
            case = f"{r['system']} / vm_ros"
            add("compare", case, "step at 1 muscle, thread CPU", r["over_vm_ros_step_1_cpu"],
                "ratio")
            add("compare", case, "per extra muscle, thread CPU",
                r["over_vm_ros_per_muscle_cpu"], "ratio")
            add("compare", case, "step at 1 muscle, wall", r["over_vm_ros_step_1_wall"],
                "ratio")
            add("compare", case, "per extra muscle, wall", r["over_vm_ros_per_muscle_wall"],
                "ratio")


def _compare_peers(value: str) -> tuple:
    """The peers of --compare's value ("all" or a comma-separated list), checked."""
    if value == "all":
        return COMPARE_PEERS
    peers = tuple(dict.fromkeys(name.strip() for name in value.split(",") if name.strip()))
    unknown = [name for name in peers if name not in COMPARE_PEERS]
    if unknown or not peers:
        raise VmRosError(f"--compare: unknown peer {', '.join(unknown) or repr(value)}; "
                         f"choose from {', '.join(COMPARE_PEERS)}")
    return peers


def _memory_csv_rows(r: dict, add) -> None:
    case = (f"{r['muscles']} muscles, bag split {r['max_bag_duration_s']:g} s, "
            f"{r.get('duration_s', 0):.0f} s after {r.get('warmup_s', 0):.0f} s")
    if "error" in r:
        add("node-memory", case, "error", r["error"], "")
        return
    slope = r["rss_slope_mib_per_hour"]
    add("node-memory", case, "RSS slope, per hour", slope, "MiB/h",
        f"<= {MEMORY_SLOPE_TARGET_MIB_PER_HOUR:g} MiB/h",
        slope <= MEMORY_SLOPE_TARGET_MIB_PER_HOUR)
    add("node-memory", case, "RSS after warm-up", r["rss_window_start_mib"], "MiB")
    add("node-memory", case, "RSS final", r["rss_final_mib"], "MiB")
    add("node-memory", case, "RSS growth at the end", r["rss_growth_mib"], "MiB")
    add("node-memory", case, "RSS growth per minute", r["rss_growth_mib_per_min"], "MiB/min")
    add("node-memory", case, "RSS growth (max)", r["rss_max_growth_mib"], "MiB")
    add("node-memory", case, "RSS slope, second half", r["rss_slope_second_half_mib_per_hour"],
        "MiB/h")
    add("node-memory", case, "bag files", r.get("log_files", 0), "files")
    complete = bool(r.get("log_read_complete"))
    add("node-memory", case, "all files read back", complete, "", "yes", complete)
    add("node-memory", case, "messages read back", r.get("log_messages_read", 0), "messages")
    add("node-memory", case, "bag size", r.get("mcap_file_mib", float("nan")), "MiB")
    add("node-memory", case, "CPU of one core", r["cpu_percent_one_core"], "%")
    add("node-memory", case, "model time vs wall time", r["model_wall_drift_percent"], "%")


def _joint_floor_rows(case: str, nodes: list[dict], floors: list[dict], add) -> None:
    """The joint node's later runs (JOINT_PAIR_KEYS), its rclpy floor's runs (FLOOR_KEYS) and
    the node's CPU above the floor: node minus floor of each pair, the median over pairs."""
    for k, node in enumerate(nodes[1:], start=2):
        if "error" not in node:
            for key in JOINT_PAIR_KEYS:
                add("joint", f"{case} (pair {k})", key, node[key], "")
    above = []
    for k, (node, floor) in enumerate(zip(nodes, floors, strict=False), start=1):
        where = f"rclpy floor, {case} (pair {k})"
        if "error" in floor:
            add("joint", where, "error", floor["error"], "")
            continue
        for key in FLOOR_KEYS:
            add("joint", where, key, floor[key], "")
        if "error" not in node:
            above.append(node["cpu_percent_one_core"] - floor["cpu_percent_one_core"])
    if above:
        add("joint", case, "cpu above the rclpy floor", statistics.median(above),
            "points of a core", low=min(above), high=max(above))


def _joint_csv_rows(joint: dict, add) -> None:
    if "model_used" in joint:
        add("joint", "model", "used", joint["model_used"], "")
    geometry = joint["geometry"]
    if "skipped" in geometry:
        add("joint", "geometry", "skipped", geometry["skipped"], "")
    for r in geometry.get("rows", []):
        size = (f" x {geometry['coordinates']} q" if r["call"] != "evaluate" else ", exact"
                if r["backend"] == "mujoco" else f", {geometry['polynomial_terms']} terms")
        case = f"{geometry['model']} {r['call']} {r['backend']} ({geometry['muscles']} m{size})"
        if "skipped" in r:
            add("joint", case, "skipped", r["skipped"], "")
            continue
        add("joint", case, "per call median", r["call_us"], "us", low=r["call_us_min"],
            high=r["call_us_max"])
        if "call_cpu_us" in r:
            geometry_target = r["backend"] == "compiled" and r["call"] == "evaluate"
            add("joint", case, "thread CPU per call median", r["call_cpu_us"], "us",
                "<= 30 us" if geometry_target else None,
                r["call_cpu_us"] <= 30.0 if geometry_target else None)
    for key in ("length_max_diff_vs_mujoco_mm", "moment_arm_max_diff_vs_mujoco_mm"):
        if key in geometry:
            add("joint", f"{geometry['model']} polynomial vs MuJoCo", key, geometry[key], "mm")
    node = joint["node"]
    case = (f"node {node.get('model', '')} {node.get('n_muscles', '?')} m, joint_states "
            f"{node.get('joint_rate_hz', 0):g} Hz, MCAP")
    if "skipped" in node or "error" in node:
        add("joint", case, "skipped" if "skipped" in node else "error",
            node.get("skipped", node.get("error")), "")
    else:
        for key, value in node.items():
            if key not in ("model", "n_muscles", "joint_rate_hz", "model_rate_hz",
                           "publish_rate_hz", "mcap", "input", "floor_level") and \
                    not isinstance(value, (list, dict)):
                target = met = None  # issue 33: 35 % of a core, p99 under a publish period
                if key == "cpu_percent_one_core":
                    target, met = f"<= {JOINT_NODE_CPU_TARGET:g} %", value <= JOINT_NODE_CPU_TARGET
                if key == "latency_p99_ms":
                    period_ms = 1e3 / node.get("publish_rate_hz", 100.0)
                    target, met = f"< {period_ms:g} ms", value < period_ms
                add("joint", case, key, value, "", target, met)
        _joint_floor_rows(case, [node, *joint.get("node_repeats", [])], joint.get("floor", []),
                          add)
    motion = joint.get("motion")
    if motion and "skipped" in motion:
        add("joint", "simulate --motion", "skipped", motion["skipped"], "")
    elif motion:
        case = (f"simulate --motion {motion['model']} {motion['motion_s']:g} s, "
                f"{motion['muscles']} m, in process")
        from vm_ros_bench.joint_bench import MOTION_S

        # the target is for MOTION_S of motion; a --quick run's is scaled to its length
        target = motion["target_s"] * motion["motion_s"] / MOTION_S
        add("joint", case, "wall", motion["simulate_s"], "s", f"< {target:g} s",
            motion["simulate_s"] < target, motion["simulate_s_min"], motion["simulate_s_max"])
        if "simulate_cpu_s" in motion:
            add("joint", case, "process CPU", motion["simulate_cpu_s"], "s")
        add("joint", case, "model alone (MuscleBank.run)", motion["model_s"], "s")
        add("joint", case, "simulate / model alone (paired)",
            motion["simulate_over_model_paired"], "ratio")
    for r in joint["closed_loop"]:
        if "skipped" in r:
            add("joint", "closed loop", "skipped", r["skipped"], "")
            continue
        case = f"closed loop {r['model']} {r['muscles']} m, {r['root']}"
        add("joint", case, "wall per simulated s", r["wall_per_sim_s"], "s/s",
            low=r["wall_per_sim_s_min"], high=r["wall_per_sim_s_max"])


def _table(rows: list[dict]) -> str:
    lines = [f"{'section':11} {'case':52} {'metric':30} {'value':>12} {'min..max':>19} "
             f"{'target':>12}  met"]
    for r in rows:
        value = r["value"]
        text = f"{value:12.4g}" if isinstance(value, float) else f"{str(value)[:12]:>12}"
        spread = f"{r['min']:.4g}..{r['max']:.4g}" if r["min"] != "" else ""
        met = {True: "yes", False: "NO", "": ""}[r["met"]]
        lines.append(f"{r['section']:11} {r['case'][:52]:52} {r['metric'][:30]:30} {text} "
                     f"{spread:>19} {r['target']:>12}  {met}")
    return "\n".join(lines)


def _write(out: Path, results: dict) -> list[dict]:
    """bench.json and bench.csv of the results so far (each replaced whole, so that a run
    stopped while writing keeps the previous section's files); the CSV rows."""
    results["machine"]["load_average_end"] = os.getloadavg()
    failed = {name for name, value in results.items()
              if isinstance(value, dict) and "traceback" in value}
    rows = _csv_rows({name: value for name, value in results.items() if name not in failed})
    rows += [_error_row(name, results[name]["error"]) for name in sorted(failed)]
    json_text = json.dumps(results, indent=2, default=str) + "\n"
    for name, write in (("bench.json", lambda h: h.write(json_text)),
                        ("bench.csv", lambda h: _write_csv(h, rows))):
        partial = out / f".{name}.partial"
        with open(partial, "w", newline="") as handle:
            write(handle)
        partial.replace(out / name)
    return rows


def _write_csv(handle, rows: list[dict]) -> None:
    writer = csv.DictWriter(handle, fieldnames=CSV_FIELDS)
    writer.writeheader()
    writer.writerows(rows)


CSV_FIELDS = ["section", "case", "metric", "value", "min", "max", "unit", "target", "met"]


def _error_row(section: str, error: str) -> dict:
    return {**dict.fromkeys(CSV_FIELDS, ""), "section": section, "case": "section",
            "metric": "error", "value": error}


def _measure(name: str, measure, results: dict, out: Path) -> None:
    """``results[name] = measure()``, then the files written: each section's results are on
    disk as it ends. A section that raises is recorded (its error and traceback in bench.json,
    an error row in bench.csv) and the run goes on with the next."""
    try:
        results[name] = measure()
    except Exception as exc:  # recorded and reported; the other sections run
        error = f"{type(exc).__name__}: {str(exc).strip().splitlines()[0] if str(exc) else ''}"
        _say(f"{name}: failed ({error}); the sections before it are kept in {out}")
        results[name] = {"error": error, "traceback": traceback.format_exc()}
    _write(out, results)


def run(args) -> int:
    from vm_ros_bench import coordination_bench, decode_bench, model_bench, offline_bench

    sections = args.only or list(DEFAULT_SECTIONS)
    repeats = args.repeats or (3 if args.quick else 7)
    if repeats < 1:
        raise VmRosError("--repeats must be >= 1")
    node_duration = args.node_duration or (10.0 if args.quick else 60.0)
    if args.compare is not None:  # checked before any section runs
        peers = _compare_peers(args.compare)
        compare_muscles = args.compare_muscles or (
            COMPARE_QUICK_MUSCLES if args.quick else COMPARE_MUSCLES)
        if compare_muscles < 2:
            raise VmRosError(f"--compare-muscles must be >= 2, got {compare_muscles}")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    results: dict = {"machine": _machine(), "sections": sections}
    min_seconds = 0.05 if args.quick else 0.2
    _say(f"benchmarks from {FOLDER}, measuring vm_ros in {results['machine']['vm_ros']}; "
         f"results in {out}, written as each section ends")

    def model():
        _say("model step ...")
        return model_bench.bench_model_step(repeats=repeats, min_seconds=min_seconds,
                                            progress=_say)

    def natural():
        _say("natural against lumped units ...")
        return model_bench.bench_natural_ratio(repeats=repeats, min_seconds=min_seconds,
                                               progress=_say)

    def offline():
        _say("knee extension offline ...")
        return model_bench.bench_knee_offline(repeats=1 if args.quick else 3, progress=_say)

    def compare():
        from vm_ros_bench import peer_compare

        _say(f"compare: vm_ros beside {', '.join(peers)} ...")
        return peer_compare.compare(
            peers, muscles=compare_muscles, rounds=args.repeats or (
                COMPARE_QUICK_ROUNDS if args.quick else COMPARE_ROUNDS),
            block_seconds=COMPARE_QUICK_BLOCK_S if args.quick else COMPARE_BLOCK_S,
            whole_cycles=not args.quick, progress=_say)

    steps = [  # (results key, measure): in this order, each written as it ends
        ("model", model),
        ("kernel", lambda: _kernel_rows(args.quick)),
        ("natural", natural),
        ("offline", offline),
        ("help", lambda: offline_bench.bench_help(progress=_say)),
        ("decode", lambda: decode_bench.bench_joint_state_decode(
            repeats=repeats, min_seconds=min_seconds, progress=_say)),
        ("node", lambda: _node_rows(node_duration, out)),
        ("joint", lambda: _joint_section(out, args.quick, repeats, min_seconds,
                                         node_duration)),
        ("coordination", lambda: coordination_bench.bench_coordination(
            seconds=1.0 if args.quick else 3.0, progress=_say)),
        ("coordination-walk", lambda: coordination_bench.bench_walk(progress=_say)),
        ("coordination-myolegs", lambda: coordination_bench.bench_myolegs(
            out / "joint-cache", progress=_say)),
        ("report-walk", lambda: offline_bench.bench_report_walk(
            repeats=1 if args.quick else 3, progress=_say)),
        ("study", lambda: _study_section(args.quick)),
        ("node-memory", lambda: _node_memory_row(
            args.node_duration or (MEMORY_QUICK_DURATION_S if args.quick else MEMORY_DURATION_S),
            MEMORY_QUICK_WARMUP_S if args.quick else MEMORY_WARMUP_S, out / "node-memory")),
        ("compare", compare)]
    chosen = {"kernel": "model" in sections and kernel_available(),
              "compare": args.compare is not None}
    for name, measure in steps:
        if chosen.get(name, name in sections):
            _measure(name, measure, results, out)
    rows = _write(out, results)
    machine = results["machine"]
    print(f"vm-ros bench on {machine.get('cpu', machine['machine'])}, {machine['cpus']} CPUs, "
          f"Python {machine['python']}, NumPy {machine['numpy']}, Numba {machine['numba']}; "
          f"load average {machine['load_average_start'][0]:.2f} -> "
          f"{machine['load_average_end'][0]:.2f}")
    print(_table(rows))
    print(f"results: {out / 'bench.json'}, {out / 'bench.csv'}")
    failed = [name for name, value in results.items()
              if isinstance(value, dict) and "traceback" in value]
    if failed:
        _say(f"failed: {', '.join(failed)} (their errors in {out / 'bench.json'})")
    return 1 if failed else 0
