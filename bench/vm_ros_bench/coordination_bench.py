"""Live coordination's cost per publish period (no ROS): what muscle_node with
``coordination.enabled`` adds to its model steps, at 100 Hz publishing with a 1 kHz model, for 18
and 80 muscles (issue 30's sizes: Gait10dof18musc, myolegs).

Each period: RecedingHorizon.solve (the probe run of B + 1 copies of the muscles over the horizon
and the bounded least squares) from the bank's state, then MuscleBank.run of the period's 10 steps
with its drives, as the node does. Muscles: the shipped library's, repeated under new names to
make up the count; each crosses one of ``n / 3`` coordinates (rounded up) with a moment arm of
+-3 cm (flexors and extensors in turn); path lengths swing about the middle of each muscle's
range at 1 Hz; targets 30 % of each coordinate's flexor capacity at full drive, at 1 Hz.
Default settings (horizon 0.15 s, 3 blocks, samples every 5 ms, the tsianos2012 cost).

Reported: per period, the solve (the latency from a period's start to its drives) and the
period's whole work, wall-clock median, p99 and max over 3 s of model time after 0.5 s of
warm-up; ``cpu_percent_one_core`` = work per simulated second (process CPU time, so another
process's load does not count) x 100; the load average at the start and end.
"""

from __future__ import annotations

import dataclasses
import os
import time

import numpy as np

from vm_ros.blas_threads import limit_blas_threads
from vm_ros.coordination.receding import HorizonSettings, RecedingHorizon
from vm_ros.model import MuscleBank
from vm_ros.model.params import load_muscle_library

DT_S, PERIOD_STEPS = 1e-3, 10
ARM_M = 0.03
# (muscles, settings name): default settings, and for 80 muscles also two lighter problems
LIGHT = HorizonSettings(blocks=2, eval_step_s=0.01)
CASES = ((18, "default"), (80, "default"), (80, "blocks 2"), (80, "blocks 2, samples every 10 ms"))
SETTINGS = {"default": HorizonSettings(), "blocks 2": HorizonSettings(blocks=2),
            "blocks 2, samples every 10 ms": LIGHT}


def muscle_bank(n: int) -> MuscleBank:
    """``n`` muscles from the shipped library, its entries repeated under new names."""
    library = list(load_muscle_library())  # the shipped library's names
    base = MuscleBank.from_config(library)
    specs = [dataclasses.replace(base.specs[i % len(library)], name=f"m{i:03d}")
             for i in range(n)]
    return MuscleBank(specs, base.params)


def bench_case(n: int, seconds: float = 3.0, warmup_s: float = 0.5,
               settings: HorizonSettings | None = None) -> dict:
    """One muscle count (module docstring)."""
    bank = muscle_bank(n)
    c = -(-n // 3)
    sign = np.where(np.arange(n) % 2 == 0, 1.0, -1.0)
    arms = np.zeros((n, c))
    arms[np.arange(n), np.arange(n) % c] = ARM_M * sign
    lo = np.array([s.path_length_min_m or 0.97 * s.l0t_m + 0.6 * s.l0_m for s in bank.specs])
    hi = np.array([s.path_length_max_m or s.l0t_m + 1.2 * s.l0_m for s in bank.specs])
    mid, swing = (lo + hi) / 2, 0.2 * (hi - lo)
    capacity = (np.maximum(arms, 0.0) * bank.f0[:, None]).sum(axis=0)

    def length(t):
        return mid + swing * np.sin(2 * np.pi * np.asarray(t))[..., None]

    def velocity(t):
        return swing * 2 * np.pi * np.cos(2 * np.pi * np.asarray(t))[..., None]

    def target(t):
        return 0.3 * capacity * (0.5 + 0.5 * np.sin(2 * np.pi * np.asarray(t)))[..., None]

    coordinator = RecedingHorizon(bank, np.arange(n), PERIOD_STEPS * DT_S,
                                  settings or HorizonSettings())
    horizon_arms = np.broadcast_to(arms, (coordinator.steps, n, c))
    bank.reset(path_length=length(0.0))
    solve_ns, period_ns = [], []
    periods = int(round((warmup_s + seconds) / (PERIOD_STEPS * DT_S)))
    warm = int(round(warmup_s / (PERIOD_STEPS * DT_S)))
    t0, cpu_start = 0.0, 0.0
    for k in range(periods):
        if k == warm:
            cpu_start = time.process_time()
        started = time.perf_counter_ns()
        start, end = t0 + coordinator.start_offsets_s, t0 + coordinator.end_offsets_s
        plan = coordinator.solve(bank.restore_point(), length(start), velocity(start),
                                 horizon_arms, target(end))
        solved = time.perf_counter_ns()
        t = t0 + DT_S * np.arange(PERIOD_STEPS)
        bank.run(DT_S, np.repeat(plan.drive[None], PERIOD_STEPS, axis=0), length(t), velocity(t))
        done = time.perf_counter_ns()
        if k >= warm:
            solve_ns.append(solved - started)
            period_ns.append(done - started)
        t0 += PERIOD_STEPS * DT_S
    cpu_s = time.process_time() - cpu_start

    def ms(values, q):
        return float(np.percentile(values, q)) * 1e-6

    return {"muscles": n, "coordinates": c, "publish_rate_hz": 1.0 / (PERIOD_STEPS * DT_S),
            "model_rate_hz": 1.0 / DT_S, "horizon_s": coordinator.steps * coordinator.probe_dt_s,
            "blocks": coordinator.n_blocks, "solve_ms_median": ms(solve_ns, 50),
            "solve_ms_p99": ms(solve_ns, 99), "solve_ms_max": ms(solve_ns, 100),
            "period_ms_median": ms(period_ns, 50), "period_ms_p99": ms(period_ns, 99),
            "cpu_percent_one_core": 100.0 * cpu_s / seconds}


def bench_coordination(cases=CASES, seconds: float = 3.0, progress=None) -> list[dict]:
    """Every case of ``cases`` ((muscles, settings name)), with the load average around each;
    one BLAS thread, as muscle_node with coordination sets (vm_ros.blas_threads)."""
    limit_blas_threads(1)
    rows = []
    for n, name in cases:
        if progress is not None:
            progress(f"coordination: {n} muscles, {name}, 100 Hz, {seconds:g} s ...")
        load_start = os.getloadavg()[0]
        row = bench_case(n, seconds, settings=SETTINGS[name])
        rows.append(row | {"settings": name, "load_average_start": load_start,
                           "load_average_end": os.getloadavg()[0]})
    return rows


if __name__ == "__main__":
    import json

    print(json.dumps(bench_coordination(progress=print), indent=2))


WALK_CASES = {"default": {}, "refine 4": {"refine": 4}}   # SolverOptions changes per case
WALK_TARGET_PERCENT, WALK_TARGET_S = 3.0, 10.0            # issue 30: 3 % RMS of peak in < 10 s


def bench_walk(progress=print) -> list[dict]:
    """The offline solve of opensim-models' Gait10dof18musc walk (issue 30's speed item): the
    model imported at its own F0 (`--specific-tension vm`), the hip, knee and ankle ID moments,
    default cost, per case of WALK_CASES: reserve RMS per coordinate (% of peak), forward runs,
    wall-clock seconds of the solve and the load average before it. One row with ``skipped``
    when the walk's files are not fetched (scripts/fetch-gait-data)."""
    import tempfile

    from vm_ros.coordination.solver import SolverOptions, solve
    from vm_ros.model.params import load_model_params
    from vm_ros.validation.walk import STRENGTHS, walk_problem
    from vm_ros.validation.walk_data import WalkDataError, walk_files

    try:
        files = walk_files()
    except WalkDataError as error:
        return [{"skipped": str(error)}]
    params = load_model_params()
    rows = []
    with tempfile.TemporaryDirectory(prefix="vm_ros_bench_walk_") as out:
        w = walk_problem(files, STRENGTHS["model F0"], out, params)
        specs, problem = w.specs, w.problem
        for case, changes in WALK_CASES.items():
            load = os.getloadavg()[0]
            started = time.perf_counter()
            result = solve(MuscleBank(specs, params, "lumped"), problem,
                           SolverOptions(**changes))
            seconds = time.perf_counter() - started
            rms = dict(zip(problem.coordinates, result.summary.rms_percent.tolist(),
                           strict=True))
            progress(f"coordination-walk {case}: worst reserve RMS {max(rms.values()):.2f} % "
                     f"of peak, {result.forward_runs} runs, {seconds:.1f} s")
            rows.append({"case": case, "rms_percent": rms, "forward_runs": result.forward_runs,
                         "seconds": seconds, "load_average_start": load})
    return rows


# myolegs (issue 30's speed item: 80 muscles, 10 s of motion solved in under a minute)
MYOLEGS_S, MYOLEGS_FRAME_S, MYOLEGS_TARGET_S = 10.0, 0.01, 60.0
GAIT_CYCLE_S = 1.1   # s per stride (both legs), about 109 steps per minute
# Gait-like sagittal angles (deg) over the gait cycle phase p (0 = heel strike): an offset plus
# bumps a exp(k (cos 2 pi (p - c) - 1)) for (a, c, k); shaped after the normal-walking curves
# of Perry 1992 (hip about 27 deg flexed at heel strike, 8 deg extended in terminal stance;
# knee 20 deg in loading response, 60 deg in initial swing; ankle 7 deg plantarflexion after
# heel strike, 11 deg dorsiflexion in terminal stance, 22 deg plantarflexion at toe-off), drawn
# from those landmarks, not fitted to data; bump widths such that the angular accelerations
# stay within 34 / 132 / 129 rad/s^2 (hip, knee, ankle: the curves' second derivative at a
# 1.1 s stride). The left leg half a cycle later; every other coordinate of the model held at
# 0 (inside every range of myolegs).
GAIT_ANGLES_DEG = {"hip_flexion": (-10.0, ((40.0, 0.95, 1.5),)),
                   "knee_angle": (2.0, ((18.0, 0.15, 6.0), (58.0, 0.72, 4.0))),
                   "ankle_angle": (0.0, ((-7.0, 0.07, 12.0), (12.0, 0.42, 5.0),
                                         (-22.0, 0.63, 10.0)))}


def gait_angles_deg(joint: str, phase) -> np.ndarray:
    """GAIT_ANGLES_DEG[joint] at gait phases ``phase`` (cycles; periodic)."""
    offset, bumps = GAIT_ANGLES_DEG[joint]
    phase = np.asarray(phase, dtype=float)
    return offset + sum(a * np.exp(k * (np.cos(2 * np.pi * (phase - c)) - 1.0))
                        for a, c, k in bumps)


def gait_motion(coordinate_names, duration_s: float = MYOLEGS_S,
                frame_s: float = MYOLEGS_FRAME_S) -> tuple[np.ndarray, list]:
    """(times (s), one column in degrees per name): GAIT_ANGLES_DEG for ``<joint>_r`` and
    ``<joint>_l`` (half a cycle later), 0 for every other name."""
    t = np.arange(0.0, duration_s + frame_s / 2, frame_s)
    phase = {"r": t / GAIT_CYCLE_S, "l": t / GAIT_CYCLE_S + 0.5}
    columns = []
    for name in coordinate_names:
        joint, _, side = name.rpartition("_")
        columns.append(gait_angles_deg(joint, phase[side]) if joint in GAIT_ANGLES_DEG
                       else np.zeros_like(t))
    return t, columns


def bench_myolegs(cache, progress=print, duration_s: float = MYOLEGS_S) -> dict:
    """`vm-ros coordinate` on myo-sim's myolegs (the joint section's import, cached in
    ``cache``/myolegs): ``gait_motion`` written as a .mot, targets ``mujoco`` (MuJoCo's inverse
    dynamics of the motion, the root held in space), every muscle of the library, default
    options (vm_ros.coordination.methods: "auto" picks the receding horizon at this size):
    seconds of the targets and of the solve (wall, and the process's CPU time: the
    machine's other load does not count in it), the seconds at each kept iterate (the first:
    after the two stages' start), forward runs, reserve RMS per coordinate (% of its target's
    peak), the load average before and after. ``skipped`` without the mujoco extra."""
    import tempfile
    from pathlib import Path

    from vm_ros.coordination.methods import chosen_method, solve
    from vm_ros.coordination.problem import build_problem
    from vm_ros.coordination.solver import SolverOptions
    from vm_ros.coordination.targets import load_targets
    from vm_ros.geometry import load_geometry
    from vm_ros.importers.motion import read_motion
    from vm_ros.model.params import load_model_params, load_muscle_library, resolve_muscles
    from vm_ros.node.motion_inputs import JointMotion
    from vm_ros_bench import joint_bench

    reason = joint_bench.missing_extra()
    if reason is not None:
        return {"skipped": reason}
    imported = joint_bench.import_myolegs(Path(cache) / "myolegs", progress=progress)
    geometry = load_geometry(imported["geometry"])
    library = load_muscle_library(imported["library"])
    muscles = tuple(m for m in geometry.muscle_names if m in library)
    with tempfile.TemporaryDirectory(prefix="vm_ros_bench_myolegs_") as tmp:
        times, columns = gait_motion(geometry.coordinate_names, duration_s)
        path = joint_bench.write_mot(Path(tmp) / "gait.mot", times, geometry.coordinate_names,
                                     columns, title="myolegs gait-like motion")
        motion = JointMotion.from_motion(read_motion(path), geometry,
                                         geometry.coordinate_names, {})
    started = time.perf_counter()
    targets = load_targets("mujoco", geometry=geometry, motion=motion)
    targets_s = time.perf_counter() - started
    params = load_model_params()
    specs = resolve_muscles(muscles, imported["library"], None, params.generic.ur_default)
    problem = build_problem(geometry, motion, targets, muscles)
    load = os.getloadavg()[0]
    started, cpu = time.perf_counter(), time.process_time()
    options = SolverOptions()
    result = solve(MuscleBank(specs, params, "lumped"), problem, options)
    seconds, cpu_s = time.perf_counter() - started, time.process_time() - cpu
    rms = dict(zip(problem.coordinates, result.summary.rms_percent.tolist(), strict=True))
    peak = dict(zip(problem.coordinates, problem.peak.tolist(), strict=True))
    method = chosen_method(problem, options)
    progress(f"coordination-myolegs: {len(muscles)} muscles, {duration_s:g} s, {method}: worst "
             f"reserve "
             f"RMS {max(rms.values()):.2f} % of peak, {result.forward_runs} runs, "
             f"{seconds:.1f} s ({cpu_s:.1f} s of CPU; targets {targets_s:.1f} s)")
    return {"muscles": len(muscles), "coordinates": len(problem.coordinates),
            "method": method, "motion_s": duration_s, "frames": len(problem.frame_times_s),
            "rms_percent": rms, "target_peak": peak, "forward_runs": result.forward_runs,
            "seconds": seconds, "cpu_s": cpu_s, "targets_s": targets_s,
            "kept_step_s": [it.seconds for it in result.history],
            "load_average_start": load, "load_average_end": os.getloadavg()[0],
            "infeasible_frames": len(result.infeasible),
            "planned_poses_ms": planned_poses_ms(geometry, motion)}


PLANNED_POSE_COUNTS = (9, 31)   # poses per publish period: every 20 ms / every 5 ms of 0.15 s


def planned_poses_ms(geometry, motion, calls: int = 200) -> dict:
    """What live coordination with a planned profile's positions adds per publish period
    (vm_ros.node.live_coordination.motion_at_poses: the geometry at the horizon's planned poses,
    interpolated to its 31 probe offsets, every muscle and coordinate): thread CPU (ms), median
    of ``calls`` calls at consecutive frames of ``motion``, per pose count of
    PLANNED_POSE_COUNTS."""
    from vm_ros.node.live_coordination import motion_at_poses

    q, qdot = np.asarray(motion.q, dtype=float), np.asarray(motion.qdot, dtype=float)
    rows, output = np.arange(len(geometry.muscle_names)), np.arange(q.shape[1])
    offsets = np.linspace(0.0, 0.15, 31)
    medians = {}
    for count in PLANNED_POSE_COUNTS:
        poses, speeds, at = q[:count], qdot[:count], np.linspace(0.0, 0.15, count)

        def call(poses=poses, speeds=speeds, at=at):
            return motion_at_poses(geometry, rows, output, poses, speeds, at, offsets)
        call()   # compiled before the timing
        times = []
        for _ in range(calls):
            started = time.thread_time_ns()
            call()
            times.append(time.thread_time_ns() - started)
        medians[str(count)] = float(np.median(times)) * 1e-6
    return medians
