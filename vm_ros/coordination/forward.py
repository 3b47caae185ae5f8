"""Forward runs of the full bank over a prescribed motion, and their sensitivity to the drives.

Drives are given at nodes t_j = j h - T_lead (j = 0 .. N - 1, the last at or after the motion's
end) and interpolated linearly to each model step's start (as an excitation table is,
vm_ros.offline.excitations). A run starts T_lead (the lead-in, ``lead_in_s`` rounded up to whole
node steps; config/coordination.yaml drives.lead_in) before the motion's first frame: the bank
at static equilibrium at the first pose with its activation at the steady state of the first
step's drive (a run from rest would spend its first 0.2-0.3 s activating), the first pose held
(path velocity 0) over the lead-in, whose drives are free, then the motion; MuscleBank.run
steps it all: drive filter, activation, fascicle mass, tendon. Model time 0 is the motion's
first frame; forces, rates and the sensitivity's windows are of the motion's steps only.

Because the motion is prescribed, muscle i's force and energy depend only on muscle i's drive.
So one run probes every muscle at once, and the sensitivity of forces and costs to the drive
nodes comes from ``groups`` perturbed runs: run g raises (or, near 1, lowers) by ``delta`` every
node j with j mod groups = g, of every muscle; the change at times in [t_{j-1}, t_{j-1} +
groups h) is put down to node j. This is exact for a model whose response to a drive change
has faded within groups h - 2 h (the hat function's width); the activation's 90 % rise time is
0.2-0.3 s and a drive change leaves a tail for longer: ``memory_s`` (config/coordination.yaml,
0.6 s, measured on the walk) sets groups = memory_s / h + 2. Results beyond the window are
dropped (a truncated Jacobian: it slows the iteration, it does not change what it converges to,
the forward run being exact).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import sparse

from vm_ros.coordination.problem import CoordinationProblem


def hat_matrix(sample_times_s: np.ndarray, node_step_s: float, n_nodes: int) -> sparse.csr_matrix:
    """(len(sample_times), n_nodes) linear interpolation between nodes j h (held past the last)."""
    t = np.clip(np.asarray(sample_times_s, dtype=float) / node_step_s, 0.0, n_nodes - 1)
    low = np.minimum(np.floor(t).astype(int), n_nodes - 2) if n_nodes > 1 else np.zeros(
        len(t), int)
    w = t - low if n_nodes > 1 else np.zeros(len(t))
    rows = np.arange(len(t))
    if n_nodes == 1:
        return sparse.csr_matrix((np.ones(len(t)), (rows, low)), shape=(len(t), 1))
    return sparse.csr_matrix((np.concatenate([1 - w, w]), (np.concatenate([rows, rows]),
                                                           np.concatenate([low, low + 1]))),
                             shape=(len(t), n_nodes))


@dataclass(frozen=True)
class LeadIn:
    """The steps of a forward run before the motion's first frame, first pose held: drive,
    path length (m) and velocity (0 m/s), (k_lead, n) each. A run replayed from the steady
    state of drive[0] at path_length[0] through these steps reaches the motion's start in the
    state the solver's runs do (``replay``)."""

    drive: np.ndarray
    path_length: np.ndarray
    path_velocity: np.ndarray


def replay(bank, problem: CoordinationProblem, out: ForwardOutput):
    """``bank`` (the problem's muscles, any energetics models) run over ``out``'s lead-in and
    drives along the motion as the solver's run was; returns the Trajectory of the motion's
    steps only."""
    lead = out.lead_in
    first = lead.drive[0] if len(lead.drive) else out.drive_steps[0]
    bank.reset(path_length=problem.path_length[0], excitation=first)
    if len(lead.drive):
        bank.run(problem.dt_s, lead.drive, lead.path_length, lead.path_velocity)
    return bank.run(problem.dt_s, out.drive_steps, problem.path_length, problem.path_velocity)


@dataclass
class ForwardOutput:
    """One forward run.

    | field | shape | unit |
    | --- | --- | --- |
    | drive_steps | (k, n) | drive of each step |
    | force | (k + 1, n) | N, tendon force at model times 0, dt, ..., k dt |
    | force_frames | (T, n) | N, at the target frames |
    | rates | dict name -> (k, n) | the per-muscle cost rates of each step (costs.py) |
    | trajectory | Trajectory | MuscleBank.run's outputs, the lead-in's steps first |
    | lead_in | LeadIn | the lead-in's steps (none without one) |

    Every field but ``trajectory`` and ``lead_in`` is of the motion's steps only.
    """

    drive_steps: np.ndarray
    force: np.ndarray
    force_frames: np.ndarray
    rates: dict
    trajectory: object
    lead_in: LeadIn

    def motion_rate(self, rate_function) -> np.ndarray:
        """(k, n) ``rate_function(trajectory, drive)`` (costs.py) over the motion's steps, the
        lead-in's left out."""
        drive = np.vstack([self.lead_in.drive, self.drive_steps])
        return rate_function(self.trajectory, drive)[len(self.lead_in.drive):]


class ForwardModel:
    """Forward runs of ``bank`` over ``problem`` with drives at nodes every ``node_step_s``;
    ``rate_functions``: name -> f(trajectory, drive_steps) -> (k, n) per-muscle rates kept
    with each run (the costs')."""

    def __init__(self, bank, problem: CoordinationProblem, node_step_s: float,
                 rate_functions: dict, memory_s: float = 0.8, lead_in_s: float = 0.0):
        self.bank = bank
        self.problem = problem
        self.node_step_s = float(node_step_s)
        # the lead-in: whole node steps before the motion's first frame, first pose held
        lead_nodes = int(np.ceil(max(float(lead_in_s), 0.0) / self.node_step_s - 1e-9))
        self.lead_in_s = lead_nodes * self.node_step_s
        self.lead_steps = int(round(self.lead_in_s / problem.dt_s))
        self.n_nodes = lead_nodes + int(np.ceil(problem.duration_s / self.node_step_s
                                                - 1e-9)) + 1
        # node times on the motion's model time (the lead-in's are negative)
        self.node_times_s = np.arange(self.n_nodes) * self.node_step_s - self.lead_in_s
        total = self.lead_steps + problem.n_steps
        self.all_steps = hat_matrix(np.arange(total) * problem.dt_s, self.node_step_s,
                                    self.n_nodes)
        self.steps = self.all_steps[self.lead_steps:]
        self.path_length = np.vstack([np.repeat(problem.path_length[:1], self.lead_steps, 0),
                                      problem.path_length])
        self.path_velocity = np.vstack([np.zeros((self.lead_steps, len(problem.muscles))),
                                        problem.path_velocity])
        # force at model times 0 .. k dt, interpolated to the frames
        times = np.arange(problem.n_steps + 1) * problem.dt_s
        position = np.clip(problem.frame_times_s / problem.dt_s, 0, problem.n_steps)
        low = np.minimum(np.floor(position).astype(int), problem.n_steps - 1)
        w = position - low
        rows = np.arange(len(position))
        self.frames = sparse.csr_matrix(
            (np.concatenate([1 - w, w]), (np.concatenate([rows, rows]),
                                          np.concatenate([low, low + 1]))),
            shape=(len(position), len(times)))
        self.rate_functions = dict(rate_functions)
        self.groups = max(2, min(self.n_nodes, int(np.ceil(memory_s / self.node_step_s)) + 2))
        self.runs = 0
        self._initial_states: dict = {}

    def node_weights(self, times_s: np.ndarray) -> sparse.csr_matrix:
        """(len(times), N) hat weights of the nodes at model times ``times_s`` (the motion's)."""
        return hat_matrix(np.asarray(times_s) + self.lead_in_s, self.node_step_s, self.n_nodes)

    def run(self, nodes: np.ndarray) -> ForwardOutput:
        """The forward run of drives ``nodes`` (N, n) in [0, 1]: the lead-in, then the motion;
        the output holds the motion's steps (and the lead-in's in ``lead_in``)."""
        p = self.problem
        drive = np.clip(np.ascontiguousarray(self.all_steps @ nodes), 0.0, 1.0)
        initial = self._initial(drive[0])
        trajectory = self.bank.run(p.dt_s, drive, self.path_length, self.path_velocity)
        self.runs += 1
        force = np.vstack([initial.force[None, :], trajectory.force])[self.lead_steps:]
        motion = slice(self.lead_steps, None)
        lead_in = LeadIn(drive[:self.lead_steps], self.path_length[:self.lead_steps],
                         self.path_velocity[:self.lead_steps])
        out = ForwardOutput(drive[motion], force, self.frames @ force, {}, trajectory, lead_in)
        out.rates.update({name: out.motion_rate(f) for name, f in self.rate_functions.items()})
        return out

    def _initial(self, drive: np.ndarray):
        """The bank reset to the steady state of ``drive`` at the first path length; the
        last few such states are kept (perturbed runs share the first drive)."""
        key = drive.tobytes()
        kept = self._initial_states.get(key)
        if kept is None:
            out = self.bank.reset(path_length=self.path_length[0], excitation=drive)
            if len(self._initial_states) >= 4:
                self._initial_states.pop(next(iter(self._initial_states)))
            kept = self._initial_states[key] = (self.bank.state, out)
        self.bank.set_state(kept[0])
        return kept[1]

    def windows(self, group: int) -> list[tuple[int, int, int]]:
        """(node, first, end) of the nodes of ``group``: the forces at model times (first,
        end] dt and the motion's steps first .. end - 1 are put down to that node (module
        docstring; model time 0 is the motion's first frame, a lead-in's nodes come before it);
        first < 0 for node 0, whose drive also sets the initial state."""
        p = self.problem
        span = int(round(self.groups * self.node_step_s / p.dt_s))
        out = []
        for j in range(group, self.n_nodes, self.groups):
            first = int(round((j - 1) * self.node_step_s / p.dt_s)) - self.lead_steps
            out.append((j, first, min(p.n_steps + 1, first + span)))
        return out

    def sensitivity(self, nodes: np.ndarray, base: ForwardOutput, delta: float = 0.02):
        """d(force at frames)/d(node drive) per muscle as a sparse (T, N) matrix each, and
        d(integral of each rate)/d(node drive) (N, n) per rate name, from ``groups`` perturbed
        runs around ``nodes`` (module docstring)."""
        p = self.problem
        n = nodes.shape[1]
        frame_step = np.clip(p.frame_times_s / p.dt_s, 0, p.n_steps)
        step = np.where(nodes + delta <= 1.0, delta, -delta)
        rows = [[] for _ in range(n)]
        cols = [[] for _ in range(n)]
        vals = [[] for _ in range(n)]
        grads = {name: np.zeros_like(nodes) for name in self.rate_functions}
        for g in range(self.groups):
            windows = self.windows(g)
            perturbed = nodes.copy()
            chosen = [j for j, _, _ in windows]
            perturbed[chosen] += step[chosen]
            out = self.run(perturbed)
            d_frames = out.force_frames - base.force_frames
            for j, first, end in windows:
                inside = np.flatnonzero((frame_step > first) & (frame_step <= end))
                for i in range(n):
                    rows[i].append(inside)
                    cols[i].append(np.full(len(inside), j))
                    vals[i].append(d_frames[inside, i] / step[j, i])
                for name, rate in out.rates.items():
                    start = max(first, 0)
                    change = (rate[start:end] - base.rates[name][start:end]).sum(axis=0)
                    grads[name][j] = change * p.dt_s / step[j]
        shape = (len(p.frame_times_s), self.n_nodes)
        jac = [sparse.csr_matrix((np.concatenate(vals[i]), (np.concatenate(rows[i]),
                                                            np.concatenate(cols[i]))),
                                 shape=shape) for i in range(n)]
        return jac, grads
