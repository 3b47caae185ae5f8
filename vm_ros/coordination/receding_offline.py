"""Offline receding-horizon coordination: muscle_node's live coordinator (receding.py) run over a
whole prescribed motion without ROS, then one forward run of the full model for the results
(docs/coordination.md, "Receding horizon over a whole motion").

Each period of ``period_s`` from the bank's state, RecedingHorizon.solve gets what the live node
predicts, here known exactly: the path lengths and velocities of the coming probe steps (the
problem's, at each step's start), the moment arms and targets at the probe steps' ends (linear
between the target frames, held beyond the last); its first block's drive is applied for the
period and the bank stepped on. The run starts ``receding_lead_in_s`` (SolverOptions) before
the motion (forward.py's lead-in: first pose held, here with the first frame's targets
tracked) at the steady state of a drive found by solving the first period
``receding_start_iterations`` times, each from the steady state of the last answer, and that
drive is applied over the first period: so the run starts as forward.ForwardModel's runs do,
at the steady state of its first drive, and the lead-in lets the loop settle where that guess
was off. The drives (constant over each period) become nodes at every model step, so the
forward run of forward.ForwardModel reproduces the loop's trajectory exactly; every reported
reserve, force and energy comes from that run.

Cost: one probe of B + 1 copies of the muscles over the horizon and one small QP per period,
about the live node's CPU per simulated second whatever the motion's length, against the
three-stage solver's linear programme and Gauss-Newton QP over the whole motion. What is
approximated beyond the three-stage solver: the horizon (0.15 s at the live defaults) sees no
further ahead, and each period takes one linearised step (receding.py's docstring).
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np

from vm_ros.coordination.forward import ForwardModel
from vm_ros.coordination.problem import CoordinationProblem
from vm_ros.coordination.receding import HorizonSettings, RecedingHorizon, at_times
from vm_ros.coordination.solver import (
    CoordinationResult,
    SolverOptions,
    _iteration,
    _result,
    checked_rate,
    reference_objective,
)
from vm_ros.errors import VmRosError


def horizon_inputs(problem: CoordinationProblem, forward: ForwardModel,
                   coordinator: RecedingHorizon, first_step: int) -> tuple:
    """(path length, path velocity, moment arm, target) of the period starting at run step
    ``first_step`` (the lead-in's steps first): the forward run's path at the probe steps'
    starts, the moment arms and targets at their ends (the first frame's over the lead-in)."""
    dt = problem.dt_s
    last = len(forward.path_length) - 1
    steps = np.clip(first_step + np.round(coordinator.start_offsets_s / dt).astype(int), 0, last)
    ends = (first_step - forward.lead_steps) * dt + coordinator.end_offsets_s
    return (forward.path_length[steps], forward.path_velocity[steps],
            at_times(problem.moment_arm, problem.frame_times_s, ends),
            at_times(problem.target, problem.frame_times_s, ends))


def receding_drives(bank, problem: CoordinationProblem, forward: ForwardModel,
                    period_s: float, settings: HorizonSettings,
                    start_iterations: int) -> tuple[np.ndarray, int]:
    """((k, n) the drive of every step of ``forward``'s runs (lead-in first), the periods whose
    QP was not solved): the coordinator over the whole run (module docstring); ``bank`` holds
    the problem's muscles and is left at the motion's end."""
    n, dt = len(problem.muscles), problem.dt_s
    total = len(forward.path_length)
    period_steps = max(int(round(period_s / dt)), 1)
    coordinator = RecedingHorizon(bank, np.arange(n), period_steps * dt, settings)

    def restart(drive):
        bank.reset(path_length=forward.path_length[0], excitation=drive)
        coordinator.plan = np.repeat(drive[None], coordinator.n_blocks, axis=0)
        coordinator.drive = drive

    drive = np.zeros(n)
    for _ in range(int(start_iterations)):   # the first period from its own steady state
        restart(drive)
        drive = coordinator.solve(bank.restore_point(), *horizon_inputs(
            problem, forward, coordinator, 0)).drive
    restart(drive)
    drives = np.empty((total, n))
    for first in range(0, total, period_steps):
        end = min(first + period_steps, total)
        if first > 0:
            drive = coordinator.solve(bank.restore_point(), *horizon_inputs(
                problem, forward, coordinator, first)).drive
        drives[first:end] = drive
        bank.run(dt, np.repeat(drive[None], end - first, axis=0),
                 forward.path_length[first:end], forward.path_velocity[first:end])
    return drives, coordinator.qp.unsolved


def solve(bank, problem: CoordinationProblem, options: SolverOptions | None = None,
          progress=None, settings: HorizonSettings | None = None) -> CoordinationResult:
    """The drives of ``bank``'s muscles (the problem's, in order) by the receding horizon over
    the whole motion (module docstring), as a CoordinationResult like solver.solve's: drive
    nodes at every model step, one kept iterate (J of solver.py at those nodes). ``options``:
    the cost, the receding horizon's period, lead-in and start iterations, and the stage 3
    settings of the reported objective; muscle weights other than 1 are an error (the
    coordinator weighs all muscles alike); ``settings``: the
    coordinator's (default: the live node's HorizonSettings with ``options.cost``: tracking in
    N m, not relative to each coordinate's peak)."""
    options = options or SolverOptions()
    rate = checked_rate(bank, problem, options)
    weighted = sorted(m for m, w in options.muscle_weights.items() if w != 1.0)
    if weighted:
        raise VmRosError(f"muscle weight for {weighted[0]!r}: the receding-horizon method "
                         f"weighs all muscles alike (use --method trajectory)")
    settings = settings or HorizonSettings(cost=options.cost)
    started = time.perf_counter()
    forward = ForwardModel(bank, problem, problem.dt_s, {options.cost: rate},
                           lead_in_s=options.receding_lead_in_s)
    drives, unsolved = receding_drives(bank, problem, forward, options.receding_period_s,
                                       settings, options.receding_start_iterations)
    nodes = np.vstack([drives, drives[-1:]])   # a node at every step's start, and the end
    objective = reference_objective(problem, options, forward)
    base = forward.run(nodes)
    history = [_iteration(objective, nodes, base, 0.0, forward, started)]
    if progress is not None:
        progress(history[-1])
    return dataclasses.replace(
        _result(problem, options, forward, objective, nodes, base, history, started),
        unsolved_qps=unsolved)


__all__ = ["horizon_inputs", "receding_drives", "solve"]
