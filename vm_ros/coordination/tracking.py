"""Stage 2 of the coordination (docs/coordination.md): the drives whose forward run gives each
muscle its target force F*_i(t) (stage 1, distribution.py), by iterative learning control.

With the motion prescribed each muscle's force depends only on its own drive, so one forward
run of the whole bank (forward.ForwardModel.run, from the steady state of the first drive)
tells every muscle its error at once. Start: the static drive of the target force,
u_i(t_j) = F_i^-1(F*_i(t_j + lead)) from the stage-1 table (StaticTable.drive_for), at each
drive node t_j; then, one forward run per iteration,

    u_i(t_j) <- clip(u_i(t_j) + g e_i(t_j + lead) / max(dF_i/du, floor_i), 0, 1)
    e_i = F*_i - F_i (forward run, at the frames; linear between them)

with dF_i/du the table's slope at the target's static drive (floor_i: 5 % of the muscle's
largest slope) and ``lead`` about the activation's delay. The iterate with the smallest
reserves (max over coordinates of RMS reserve / peak of the forward run) is kept; the loop
stops when that is below ``tolerance``, after ``patience`` iterations without a better one, or
after ``iterations``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vm_ros.coordination.distribution import StaticTable

SLOPE_FLOOR = 0.05     # of each muscle's largest table slope


@dataclass
class Tracked:
    """Stage 2's best iterate: drive nodes (N, n), its forward run, its score (max RMS
    reserve / peak), the scores of every iteration."""

    nodes: np.ndarray
    forward: object
    score: float
    scores: list


def _at_nodes(times: np.ndarray, frame_times: np.ndarray, values: np.ndarray) -> np.ndarray:
    """(N, n) frame values (T, n) interpolated to ``times`` (held beyond the ends)."""
    return np.stack([np.interp(times, frame_times, values[:, i])
                     for i in range(values.shape[1])], axis=1)


def track(forward, table: StaticTable, target_force: np.ndarray, lead_s: float, gain: float,
          iterations: int, tolerance: float, patience: int = 3, progress=None) -> Tracked:
    """Stage 2 (module docstring) on ``forward`` (forward.ForwardModel); ``progress`` is
    called with (drive nodes, forward run) after each run."""
    p = forward.problem
    frame_times = p.frame_times_s
    shifted = forward.node_times_s + lead_s
    static = table.drive_for(target_force)
    slope = table.slope(static)
    steepest = (np.diff(table.force, axis=2)
                / np.diff(table.levels, axis=2).clip(min=1e-9)).max(axis=(0, 2))
    slope = np.maximum(slope, SLOPE_FLOOR * steepest.clip(min=1e-9))
    # a frame's error is put on the nodes around t_f - lead, by their hat weights
    spread = forward.node_weights(frame_times - lead_s).T.tocsr()
    weight = np.maximum(np.asarray(spread.sum(axis=1)), 1e-9)
    nodes = np.clip(_at_nodes(shifted, frame_times, static), 0.0, 1.0)
    best, scores, since = None, [], 0
    for _ in range(max(1, iterations)):
        out = forward.run(nodes)
        reserves = p.target - p.moments(out.force_frames)
        score = float(np.max(np.sqrt(np.mean(reserves ** 2, axis=0)) / p.peak))
        scores.append(score)
        if progress is not None:
            progress(nodes, out)
        if best is None or score < best.score:
            best, since = Tracked(nodes, out, score, scores), 0
        else:
            since += 1
        if score <= tolerance or since >= patience:
            break
        error = (target_force - out.force_frames) / slope
        nodes = np.clip(nodes + gain * (spread @ error) / weight, 0.0, 1.0)
    return best

