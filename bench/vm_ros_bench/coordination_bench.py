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


WALK_CASES = {"default": {}, "refine 6": {"refine": 6}}   # SolverOptions changes per case
WALK_TARGET_PERCENT, WALK_TARGET_S = 3.0, 10.0            # issue 30: 3 % RMS of peak in < 10 s


def bench_walk(progress=print) -> list[dict]:
    """The offline solve of opensim-models' Gait10dof18musc walk (issue 30's speed item): the
    model imported at its own F0 (`--specific-tension vm`), the hip, knee and ankle ID moments,
    default cost, per case of WALK_CASES: reserve RMS per coordinate (% of peak), forward runs,
    wall-clock seconds of the solve and the load average before it. One row with ``skipped``
    when the walk's files are not fetched (scripts/fetch-gait-data)."""
    import tempfile

    from vm_ros.coordination.problem import build_problem
    from vm_ros.coordination.solver import SolverOptions, solve
    from vm_ros.coordination.targets import load_targets
    from vm_ros.importers.motion import read_motion
    from vm_ros.model.params import load_model_params, resolve_muscles
    from vm_ros.node.motion_inputs import JointMotion
    from vm_ros.validation.walk import STRENGTHS, import_walk
    from vm_ros.validation.walk_data import WalkDataError, walk_files

    try:
        files = walk_files()
    except WalkDataError as error:
        return [{"skipped": str(error)}]
    params = load_model_params()
    rows = []
    with tempfile.TemporaryDirectory(prefix="vm_ros_bench_walk_") as out:
        geometry, library = import_walk(files, STRENGTHS["model F0"], out)
        motion = JointMotion.from_motion(read_motion(files["motion"]), geometry,
                                         geometry.coordinate_names, {})
        targets = load_targets(str(files["inverse_dynamics"]), geometry=geometry, motion=motion)
        muscles = geometry.muscle_names
        specs = resolve_muscles(muscles, library, None, params.generic.ur_default)
        problem = build_problem(geometry, motion, targets, muscles)
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
