"""Benchmarks of the model alone (no ROS): step cost against bank size and back end, natural
against lumped units, the cost of the published energetics models (energetics_models="all")
over the compiled step, run against repeated step per muscle-step (serial and parallel), the
cold start to the first run() result, and the 180 s knee-extension scenario offline.

Timings are wall-clock medians over repeats (``time.perf_counter``); one step is
``MuscleBank.step`` as a controller calls it (input checks, state copy) followed by reading the
force and the total energy rate of every muscle from its StepOutput (the other fields are computed
only when read), with a drive that changes every step and the path length moving, so neither the
activation nor the mechanics sit at a fixed point. Energetics are always on.
"""

from __future__ import annotations

import dataclasses
import os
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np

from vm_ros.child_process import SAFE_PATH_FLAG
from vm_ros.model import MuscleBank, kernel, load_model_params, load_muscle_library
from vm_ros.model.params import resolve_muscles
from vm_ros_bench import child_environment

DT = 1e-3


def library_bank(n: int, recruitment: str = "lumped", backend: str = "auto",
                 units_per_type: int | None = None, params=None,
                 recovery_mode: str | None = None, parallel: bool | None = None) -> MuscleBank:
    """A bank of ``n`` muscles cycling through the shipped library (names m0, m1, ...)."""
    params = params or load_model_params()
    if units_per_type is not None:
        params = dataclasses.replace(
            params, natural=dataclasses.replace(params.natural, units_per_type=units_per_type)
        )
    base = resolve_muscles(list(load_muscle_library()), None, None, params.generic.ur_default)
    specs = [dataclasses.replace(base[i % len(base)], name=f"m{i}") for i in range(n)]
    return MuscleBank(specs, params, recruitment=recruitment, backend=backend,
                      recovery_mode=recovery_mode, parallel=parallel)


def _inputs(bank: MuscleBank, steps: int):
    """(k, n) drive sweeping 0.05..0.95 at 2 Hz and a path moving +-2 % around rest at 1 Hz."""
    t = DT * np.arange(steps)[:, None]
    phase = np.arange(bank.n)[None, :]
    u = 0.5 + 0.45 * np.sin(2 * np.pi * 2.0 * t + phase)
    rest = bank.l0_m + bank.l0t_m
    amplitude = 0.02 * rest
    lp = rest + amplitude * np.sin(2 * np.pi * t + phase)
    vp = amplitude * 2 * np.pi * np.cos(2 * np.pi * t + phase)
    return u, lp, vp


def time_step(bank: MuscleBank, repeats: int = 7, min_seconds: float = 0.2) -> dict:
    """Median wall time (s) of one ``bank.step`` and reading its force and energy rate, over
    ``repeats`` blocks of steps."""
    u, lp, vp = _inputs(bank, 4000)
    bank.reset(lp[0], excitation=u[0])
    for j in range(20):  # warm-up (compilation, caches)
        bank.step(DT, u[j], lp[j], vp[j])
    start = time.perf_counter()
    probe = 0
    while time.perf_counter() - start < 0.05 and probe < 2000:
        bank.step(DT, u[probe % 4000], lp[probe % 4000], vp[probe % 4000])
        probe += 1
    per_step = (time.perf_counter() - start) / probe
    block = int(min(4000, max(5, min_seconds / per_step)))
    samples = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        for j in range(block):
            out = bank.step(DT, u[j], lp[j], vp[j])
            _ = out.force, out.energy_rate.total
        samples.append((time.perf_counter() - t0) / block)
    return {"median_s": statistics.median(samples), "min_s": min(samples),
            "max_s": max(samples), "steps_per_repeat": block, "repeats": repeats}


def bench_model_step(counts=(1, 10, 100, 1000), backends=("numba", "numpy"), repeats=7,
                     min_seconds=0.2, progress=None) -> list[dict]:
    """Step cost for each bank size and back end (lumped units, static recovery); with the
    compiled back end and 1000 muscles also the published models' cost
    (:func:`bench_energetics_models`, rows with ``models_over_none``)."""
    rows = []
    if "numba" in backends and kernel.AVAILABLE and 1000 in counts:
        for selection in ENERGETICS_TARGETS:
            rows += bench_energetics_models(1000, repeats=repeats, progress=progress,
                                            selection=selection)
        rows.append(bench_umberger_numpy_floor(1000, repeats=repeats, progress=progress))
    for backend in backends:
        if backend == "numba" and not kernel.AVAILABLE:
            rows.append({"backend": backend, "skipped": "numba not importable"})
            continue
        for n in counts:
            bank = library_bank(n, backend=backend)
            timing = time_step(bank, repeats, min_seconds)
            rows.append({"backend": backend, "muscles": n, "recruitment": "lumped",
                         "step_us": 1e6 * timing["median_s"],
                         "step_us_min": 1e6 * timing["min_s"],
                         "step_us_max": 1e6 * timing["max_s"],
                         "us_per_muscle": 1e6 * timing["median_s"] / n,
                         "realtime_factor_at_1khz": DT / timing["median_s"],
                         "steps_per_repeat": timing["steps_per_repeat"], "repeats": repeats})
            if progress:
                progress(f"step {backend} {n} muscles: {rows[-1]['step_us']:.1f} us")
    return rows


ENERGETICS_TARGET = 1.5  # all published models add at most 50 % to the compiled step
# selection -> target ratio: every model, and one (Umberger 2010: the F_iso and power of every
# Umberger variant, without the recruitment's sine and cosine)
ENERGETICS_TARGETS = {"all": ENERGETICS_TARGET, "umberger2010": 1.1}


def bench_energetics_models(n: int = 1000, batch: int = 100, repeats: int = 7,
                            progress=None, selection: str = "all") -> list[dict]:
    """Per-step cost of the compiled bank with every published energetics model against none,
    for ``run`` over ``batch``-step batches and for ``batch`` calls of ``step`` reading the
    force and the total energy rate every step and the models' rates every 10th step (as
    muscle_node publishes at 100 Hz from 1 kHz) or every step; medians of ``repeats``
    interleaved repeats (none, all, none, all, ...) so that a change in the machine's load hits
    both alike. Each repeat is timed by the wall clock (``models_over_none``) and by the
    calling thread's CPU time (``models_over_none_thread_cpu``: the bank runs in this thread,
    so that on a shared machine other processes' work does not enter it)."""
    plain = library_bank(n, backend="numba")
    models = MuscleBank(list(plain.specs), plain.params, backend="numba",
                        energetics_models=selection)
    u, lp, vp = _inputs(plain, batch)
    for bank in (plain, models):
        bank.reset(lp[0], excitation=u[0])
        bank.run(DT, u, lp, vp)  # warm-up
        bank.step(DT, u[0], lp[0], vp[0])

    def run_once(bank):
        t0, c0 = time.perf_counter(), time.thread_time()
        bank.run(DT, u, lp, vp)
        return (time.perf_counter() - t0) / batch, (time.thread_time() - c0) / batch

    def stepping(read_every: int):
        def step_once(bank):
            t0, c0 = time.perf_counter(), time.thread_time()
            for j in range(batch):
                out = bank.step(DT, u[j], lp[j], vp[j])
                _ = out.force, out.energy_rate.total
                if (j + 1) % read_every == 0:
                    _ = out.energy_rate_models
            return (time.perf_counter() - t0) / batch, (time.thread_time() - c0) / batch
        return step_once

    rows = []
    for call, timer in (("run", run_once),
                        ("step, models read every 10th", stepping(10)),
                        ("step, models read every step", stepping(1))):
        none, every = [], []
        for _ in range(repeats):
            none.append(timer(plain))
            every.append(timer(models))
        base, cost = (statistics.median(t[0] for t in x) for x in (none, every))
        base_cpu, cost_cpu = (statistics.median(t[1] for t in x) for x in (none, every))
        rows.append({"backend": "numba", "muscles": n, "call": call, "batch_steps": batch,
                     "energetics_models": len(models.energetics_models),
                     "selection": selection,
                     "none_step_us": 1e6 * base, "models_step_us": 1e6 * cost,
                     "models_over_none": cost / base,
                     "none_step_thread_cpu_us": 1e6 * base_cpu,
                     "models_step_thread_cpu_us": 1e6 * cost_cpu,
                     "models_over_none_thread_cpu": cost_cpu / base_cpu,
                     "target_ratio": ENERGETICS_TARGETS.get(selection, ENERGETICS_TARGET),
                     "repeats": repeats})
        if progress:
            progress(f"energetics models {selection} {call} {n} muscles: {1e6 * base:.0f} -> "
                     f"{1e6 * cost:.0f} us per step ({cost / base:.2f}x; thread CPU "
                     f"{cost_cpu / base_cpu:.2f}x)")
    return rows



def bench_umberger_numpy_floor(n: int = 1000, batch: int = 100, repeats: int = 7,
                               progress=None) -> dict:
    """What NumPy's transcendentals in Umberger 2010's path cost alone, over the compiled run
    without models (thread CPU, medians of ``repeats`` interleaved repeats): the calls
    CompiledModels.fill (vm_ros.model.energetics_models.compiled) makes by NumPy to keep the
    NumPy path's bits, FL's two powers and exp over both fibre types, and Umberger's
    effective_excitation_powers (of A_eff, which the models' path computes compiled), on a
    ``batch``-step run's own lengths, excitation and activation in chunks of
    in_bank.CHUNK_MUSCLE_STEPS. 1 + this is the least ratio the one-model
    row can reach while NumPy computes them."""
    from vm_ros.model.energetics_models.constants import load_umberger_constants
    from vm_ros.model.energetics_models.in_bank import CHUNK_MUSCLE_STEPS
    from vm_ros.model.energetics_models.umberger import (
        effective_excitation_powers,
        scaled_effective_excitation,
    )
    from vm_ros.model.layout import T, type_columns

    plain = library_bank(n, backend="numba")
    u, lp, vp = _inputs(plain, batch)
    plain.reset(lp[0], excitation=u[0])
    run = plain.run(DT, u, lp, vp)
    ft = type_columns(plain.params.fibre, (2, 1))
    constants = load_umberger_constants("umberger2010")
    chunks = max(1, run.fascicle_length.size // CHUNK_MUSCLE_STEPS)
    lengths = np.array_split((run.fascicle_length / plain.l0_m).reshape(1, -1), chunks, axis=1)
    # A_eff (compiled in the models' path) computed beforehand: only its powers are NumPy's
    effective = np.array_split(scaled_effective_excitation(
        constants.muscle_effort_scaling_factor, np.asarray(run.excitation, dtype=float).ravel(),
        np.asarray(run.effective_activation, dtype=float)[..., 0].ravel()), chunks)

    def numpy_part():
        for x, a_eff in zip(lengths, effective, strict=True):
            fl = np.power(x, ft[T.beta])   # as CompiledModels.fill, around its compiled loop
            np.power(fl, ft[T.rho], out=fl)
            np.exp(np.negative(fl, out=fl), out=fl)
            effective_excitation_powers(constants, a_eff)

    def timed(call):
        c0 = time.thread_time()
        call()
        return (time.thread_time() - c0) / batch

    runs, parts = [], []
    for _ in range(repeats):
        runs.append(timed(lambda: plain.run(DT, u, lp, vp)))
        parts.append(timed(numpy_part))
    base, part = statistics.median(runs), statistics.median(parts)
    if progress:
        progress(f"umberger2010's NumPy transcendentals alone: {1e6 * part:.0f} us per step over "
                 f"the run's {1e6 * base:.0f} us ({part / base:.3f}x)")
    return {"muscles": n, "batch_steps": batch, "none_step_thread_cpu_us": 1e6 * base,
            "numpy_part_step_thread_cpu_us": 1e6 * part, "numpy_part_over_none": part / base,
            "least_ratio": 1.0 + part / base, "target_ratio": ENERGETICS_TARGETS["umberger2010"],
            "repeats": repeats}

def bench_natural_ratio(units_per_type: int = 20, counts=(1, 10), backends=("numba", "numpy"),
                        repeats=7, min_seconds=0.2, progress=None) -> list[dict]:
    """Cost of natural units (``units_per_type`` per fibre type) over lumped units, per step."""
    rows = []
    for backend in backends:
        if backend == "numba" and not kernel.AVAILABLE:
            continue
        for n in counts:
            lumped = time_step(library_bank(n, "lumped", backend), repeats, min_seconds)
            natural = time_step(library_bank(n, "natural", backend, units_per_type), repeats,
                                min_seconds)
            rows.append({"backend": backend, "muscles": n, "units_per_type": units_per_type,
                         "lumped_step_us": 1e6 * lumped["median_s"],
                         "natural_step_us": 1e6 * natural["median_s"],
                         "natural_over_lumped": natural["median_s"] / lumped["median_s"]})
            if progress:
                progress(f"natural/lumped {backend} {n} muscles: "
                         f"{rows[-1]['natural_over_lumped']:.2f}")
    return rows


def knee_extension_offline(duration_s: float | None = None, backend: str = "auto") -> dict:
    """The Fig. 7 scenario (rectus femoris + vasti, dynamic recovery) offline with
    ``MuscleBank.run``: wall time of building the bank, sampling the scenario's inputs at every
    step and running every step, with the total energy as a check of the result."""
    from vm_ros.offline.scenarios import load_scenario

    t0 = time.perf_counter()
    scenario = load_scenario("knee_extension")
    bank = scenario.make_bank(params=load_model_params(), backend=backend)
    inputs = scenario.inputs(bank)
    duration = duration_s or scenario.duration_s
    times = DT * np.arange(int(round(duration / DT)))
    t1 = time.perf_counter()
    u, lp, vp = inputs.sample(times)
    t2 = time.perf_counter()
    bank.reset(lp[0])
    trajectory = bank.run(DT, u, lp, vp)
    t3 = time.perf_counter()
    return {"backend": bank.backend, "simulated_s": float(duration), "steps": len(times),
            "muscles": bank.n, "recovery_mode": bank.recovery_mode,
            "wall_s": t3 - t0, "setup_s": t1 - t0, "inputs_s": t2 - t1, "run_s": t3 - t2,
            "total_energy_j": trajectory.last.total_energy}


def bench_knee_offline(repeats: int = 3, progress=None, logged: bool = True) -> dict:
    """Median over repeats of :func:`knee_extension_offline` (the first run, which may compile,
    is reported separately); with ``logged``, under "logged" the same scenario as `vm-ros
    simulate` writes it against the model alone (vm_ros_bench.offline_bench)."""
    first = knee_extension_offline()
    runs = [knee_extension_offline() for _ in range(repeats)]
    result = {key: statistics.median(r[key] for r in runs)
              for key in ("wall_s", "setup_s", "inputs_s", "run_s")}
    result.update({key: runs[0][key] for key in
                   ("backend", "simulated_s", "steps", "muscles", "recovery_mode",
                    "total_energy_j")})
    result["first_run_wall_s"] = first["wall_s"]
    result["repeats"] = repeats
    if logged:
        from vm_ros_bench.offline_bench import bench_offline_logged

        result["logged"] = bench_offline_logged(repeats=repeats, progress=progress)
    if progress:
        progress(f"knee extension 180 s offline: {result['wall_s']:.2f} s wall")
    return result


def _per_muscle_step_us(call, steps: int, n: int, repeats: int) -> float:
    samples = []
    for _ in range(repeats):
        start = time.perf_counter()
        call()
        samples.append((time.perf_counter() - start) / (steps * n))
    return 1e6 * statistics.median(samples)


def bench_run_vs_step(counts=(1, 100, 1000, 10000), repeats: int = 5,
                      parallel: bool = False) -> list[dict]:
    """Per muscle-step wall time (us, medians) of repeated ``step`` and of one ``run`` over the
    same k steps (k about 600,000 / n muscle-steps, 20 to 20,000 steps), compiled back end,
    with the parallel switch as given; the 1-minute load average is recorded."""
    rows = []
    for n in counts:
        bank = library_bank(n, backend="numba", parallel=parallel)
        k = int(max(20, min(20000, 6e5 / n)))
        u, lp, vp = _inputs(bank, k)
        bank.reset(lp[0], excitation=u[0])
        bank.run(DT, u[:5], lp[:5], vp[:5])  # warm-up

        def steps(bank=bank, u=u, lp=lp, vp=vp, k=k):
            for j in range(k):
                bank.step(DT, u[j], lp[j], vp[j])

        step_us = _per_muscle_step_us(steps, k, n, repeats)
        run_us = _per_muscle_step_us(lambda bank=bank, u=u, lp=lp, vp=vp: bank.run(DT, u, lp, vp),
                                     k, n, repeats)
        rows.append({"muscles": n, "steps": k, "parallel": bool(parallel),
                     "parallel_blocks": bool(bank._compiled.parallel_chunk),
                     "step_us_per_muscle_step": step_us, "run_us_per_muscle_step": run_us,
                     "run_over_step_speed": step_us / run_us,
                     "load_1min": os.getloadavg()[0]})
    return rows


def cold_start_to_first_run(n: int = 10) -> dict:
    """Wall time (s) of a fresh Python process from start to the first ``run()`` result of an
    n-muscle bank with an empty compilation cache (NUMBA_CACHE_DIR a new temporary folder):
    imports, compilation and the run; ``imports_s`` the imports alone (vm_ros.model, NumPy,
    SciPy, Numba), the rest is the bank, the kernel's compilation and the run."""
    code = ("import time; t = time.perf_counter()\n"
            "from vm_ros_bench.model_bench import DT, _inputs, library_bank\n"
            "imported = time.perf_counter() - t\n"
            f"b = library_bank({int(n)}); u, lp, vp = _inputs(b, 100); b.reset(lp[0])\n"
            "b.run(DT, u, lp, vp); print(imported, time.perf_counter() - t)")
    with tempfile.TemporaryDirectory(prefix="vm_ros-cold-") as cache:
        env = {**child_environment(), "NUMBA_CACHE_DIR": cache}
        python = [sys.executable, "-P"] if SAFE_PATH_FLAG else [sys.executable]
        done = subprocess.run([*python, "-c", code], env=env, capture_output=True, text=True,
                              timeout=600)
    if done.returncode != 0:
        return {"muscles": n, "error": (done.stderr.strip().splitlines() or ["failed"])[-1]}
    imports_s, total_s = (float(x) for x in done.stdout.strip().splitlines()[-1].split())
    return {"muscles": n, "cold_start_s": total_s, "imports_s": imports_s, "target_s": 10.0}
