"""``vm-ros bench --compare``: vm_ros beside its peers in one process, at 1 muscle and at N.

Each system is a stepper that advances ``n`` muscles in 1 ms steps from Python, the way a user
calls it per control step, all with the same inputs (:func:`bench_inputs`): per muscle i an
excitation 0.5 + 0.45 sin(2 pi 2 Hz t + i) and a path length moving with one slider, rest_i +
0.02 rest_0 sin(2 pi 1 Hz t) (rest = L0 + L0T; the peers pull one body, see below), reading each
step the force of every muscle and, where the system has it, the energy rate:

- vm_ros: ``MuscleBank.step`` (the compiled back end when Numba is installed; lumped units,
  energetics on), reading ``out.force`` and ``out.energy_rate.total``.
- OpenSim (the ``opensim`` wheel): Millard2012EquilibriumMuscles with the vm_ros muscles' F0,
  L0 and tendon slack length (L0T x 0.964, the inverse of config/muscles.yaml's conversion), no
  pennation, each excited by one PrescribedController (an OpenSim Sine, the drive above) and an
  entry in one Umberger2010MuscleMetabolicsProbe (activation and maintenance, shortening, basal
  and work terms; the muscle's slow-twitch fraction) reporting each muscle's rate. Every muscle
  runs from its own point on the ground to one body on a slider joint whose coordinate is
  prescribed (an OpenSim Sine: +-2 % of the first muscle's rest length at 1 Hz), the points
  placed so that each path is at its muscle's rest length (L0 + L0T) at the middle of the swing.
  One body for all: a body per muscle would add multibody work that a model with many muscles per
  body does not have (docs/performance.md). A step is ``Manager.integrate(t + 1 ms)`` (OpenSim's
  default integrator; the Manager keeps no storage or trajectory of past states), realizing the
  state to Report and reading every tendon force and the probe's outputs.
- MuJoCo (the ``mujoco`` wheel): vm_ros_bench.mujoco_compare.

The steppers: vm_ros_bench.peers (vm_ros), vm_ros_bench.opensim_compare and
vm_ros_bench.mujoco_compare.

Timing: rounds interleave every (system, size) case, one block of steps each (a block is a whole
number of the inputs' 1 s cycles, at least one, about ``block_seconds``; the order is reversed
every other round), so a change in the machine's load hits all alike and every block sees the
same inputs. Each block is timed with the thread's CPU clock
(``time.thread_time_ns``: this thread only, not time spent waiting for a core) and the wall
clock; the figures are medians over the rounds. The cost per extra muscle is the slope between
the 1- and the N-muscle medians, (t_N - t_1) / (N - 1); ratios are peer over vm_ros. This
compares cost, not physiology (different models).
"""

from __future__ import annotations

import statistics
import time

from vm_ros.errors import VmRosError
from vm_ros_bench import mujoco_compare, opensim_compare
from vm_ros_bench.peers import CYCLE_STEPS, PeerStepper, VmRosMuscles

PEERS = ("opensim", "mujoco")


def peer_missing(peer: str) -> str | None:
    if peer == "opensim":
        return opensim_compare.opensim_missing()

    return mujoco_compare.missing()


def _peer(peer: str):
    """(stepper class, version, description) of an installed peer."""
    if peer == "opensim":
        return (opensim_compare.OpensimMuscles, f"OpenSim {opensim_compare.opensim_version()}",
                "Millard 2012 equilibrium muscle + Umberger 2010 probe")

    return (mujoco_compare.MujocoMuscles, f"MuJoCo {mujoco_compare.version()}",
            "MuJoCo muscle actuator on a spatial tendon (rigid tendon, no energetics)")


def _block_steps(stepper: PeerStepper, block_seconds: float, whole_cycles: bool) -> int:
    """Steps per timed block: about ``block_seconds`` from a warm-up (at least 5 steps); with
    ``whole_cycles`` a whole number of input cycles (at least one), since a step's cost can
    follow the inputs (OpenSim's error-controlled integrator takes more substeps where the
    activation changes fast)."""
    stepper.advance(5)  # first calls: compilation, caches
    t0, done = time.perf_counter(), 0
    while done < 5 or (time.perf_counter() - t0 < 0.2 * block_seconds and done < 2000):
        stepper.advance(1)
        done += 1
    per_step = (time.perf_counter() - t0) / done
    if whole_cycles:
        return CYCLE_STEPS * max(1, round(block_seconds / (per_step * CYCLE_STEPS)))
    return int(min(20000, max(5, block_seconds / per_step)))


def time_interleaved(cases: dict, rounds: int, block_seconds: float,
                     whole_cycles: bool = False) -> dict:
    """{name: timing} for steppers ``cases`` {name: PeerStepper}: per-step thread CPU and wall
    time (us), medians over ``rounds`` interleaved rounds, with min and max."""
    blocks = {name: _block_steps(stepper, block_seconds, whole_cycles)
              for name, stepper in cases.items()}
    cpu = {name: [] for name in cases}
    wall = {name: [] for name in cases}
    order = list(cases)
    for r in range(rounds):
        for name in (order if r % 2 == 0 else order[::-1]):
            steps = blocks[name]
            w0, c0 = time.perf_counter_ns(), time.thread_time_ns()
            cases[name].advance(steps)
            c1, w1 = time.thread_time_ns(), time.perf_counter_ns()
            cpu[name].append(1e-3 * (c1 - c0) / steps)
            wall[name].append(1e-3 * (w1 - w0) / steps)
    return {name: {"cpu_us": statistics.median(cpu[name]), "cpu_us_min": min(cpu[name]),
                   "cpu_us_max": max(cpu[name]), "wall_us": statistics.median(wall[name]),
                   "wall_us_min": min(wall[name]), "wall_us_max": max(wall[name]),
                   "steps_per_block": blocks[name]} for name in cases}


def compare(peers=PEERS, muscles: int = 50, rounds: int = 15, block_seconds: float = 0.05,
            whole_cycles: bool = True, progress=None) -> dict:
    """vm_ros and each installed peer of ``peers`` at 1 and ``muscles`` muscles (module
    docstring); a peer that is not installed is a row with ``skipped`` and the reason.
    ``whole_cycles``: every block a whole number of 1 s input cycles (False: quick runs)."""
    if muscles < 2:
        raise VmRosError(f"--compare-muscles must be >= 2, got {muscles}")
    if rounds < 1:
        raise VmRosError(f"compare rounds must be >= 1, got {rounds}")
    systems = [{"system": "vm_ros", "stepper": VmRosMuscles}]
    for peer in peers:
        reason = peer_missing(peer)
        if reason is not None:
            systems.append({"system": peer, "skipped": reason})
            if progress:
                progress(f"compare: {peer} skipped, {reason}")
            continue
        stepper, version, description = _peer(peer)
        systems.append({"system": peer, "version": version, "model": description,
                        "stepper": stepper})
    cases = {}
    for system in systems:
        stepper = system.pop("stepper", None)
        for n in ((1, muscles) if stepper else ()):
            if progress:
                progress(f"compare: building {system['system']}, {n} muscles ...")
            cases[(system["system"], n)] = stepper(n)
    vm = cases[("vm_ros", 1)]
    systems[0].update(version=f"vm_ros {vm.bank.backend}",
                      model="Virtual Muscle, lumped units, Tsianos 2012 energetics")
    if progress:
        progress(f"compare: {len(cases)} cases, {rounds} interleaved rounds ...")
    timing = time_interleaved(cases, rounds, block_seconds, whole_cycles)
    for system in systems:
        if "skipped" in system:
            continue
        name = system["system"]
        one, many = timing[(name, 1)], timing[(name, muscles)]
        system.update({"muscles": muscles, "rounds": rounds,
                       "step_1_cpu_us": one["cpu_us"], "step_1_wall_us": one["wall_us"],
                       "step_n_cpu_us": many["cpu_us"], "step_n_wall_us": many["wall_us"],
                       "per_muscle_cpu_us": (many["cpu_us"] - one["cpu_us"]) / (muscles - 1),
                       "per_muscle_wall_us": (many["wall_us"] - one["wall_us"]) / (muscles - 1),
                       "timing_1": one, "timing_n": many,
                       "reading_n": cases[(name, muscles)].reading()})
    base = systems[0]
    for system in systems[1:]:
        if "skipped" in system:
            continue
        for key in ("step_1_cpu_us", "step_1_wall_us", "per_muscle_cpu_us",
                    "per_muscle_wall_us"):
            system[f"over_vm_ros_{key[:-3]}"] = system[key] / base[key]
    return {"muscles": muscles, "rounds": rounds, "block_seconds": block_seconds,
            "whole_cycles": whole_cycles,
            "clock": "thread CPU time (time.thread_time_ns) and wall (perf_counter_ns)",
            "systems": systems}
