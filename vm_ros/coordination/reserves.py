"""Reserve moments per coordinate, and the frames where the muscles cannot reach the target.

reserve = target - moment of the muscles' forward-run forces (N m or N), per frame and
coordinate: what an ideal actuator at that coordinate would have to add.

Capacity (a necessary condition, computed from two forward runs along the motion: every drive
held at 1, and every drive at 0): at frame f, coordinate c, direction s = sign(target),

    capacity = sum_i max(0, s r_ic) F_i(U = 1) - sum_i max(0, -s r_ic) F_i(U = 0)

the most the muscles can give in that direction when each muscle is either fully driven or
passive. A frame whose |target| exceeds it is infeasible; the moment the muscles lack is
|target| - capacity. Biarticular muscles are counted at full drive for each coordinate they
help, so a frame can be infeasible for a combination of coordinates yet pass this test.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class ReserveSummary:
    """Per coordinate: ``rms``, ``peak`` (N m or N), ``rms_percent``, ``peak_percent`` (of the
    target's peak |moment|), ``target_peak``."""

    coordinates: tuple
    rms: np.ndarray
    peak: np.ndarray
    target_peak: np.ndarray

    @property
    def rms_percent(self) -> np.ndarray:
        return 100.0 * self.rms / self.target_peak

    @property
    def peak_percent(self) -> np.ndarray:
        return 100.0 * self.peak / self.target_peak


def summarize_reserves(coordinates, reserve: np.ndarray, target: np.ndarray) -> ReserveSummary:
    """ReserveSummary of reserves and targets (T, C)."""
    return ReserveSummary(tuple(coordinates), np.sqrt(np.mean(reserve ** 2, axis=0)),
                          np.abs(reserve).max(axis=0),
                          np.maximum(np.abs(target).max(axis=0), 1e-9))


@dataclass(frozen=True)
class InfeasibleFrame:
    """A frame the muscles cannot reach: model time (s), coordinate, target and lacking moment
    (N m or N, > 0)."""

    time_s: float
    coordinate: str
    target: float
    lacking: float


def capacity(moment_arm: np.ndarray, force_full: np.ndarray, force_passive: np.ndarray,
             direction: np.ndarray) -> np.ndarray:
    """(T, C) capacity in ``direction`` (T, C) of +-1 (module docstring), from moment arms
    (T, n, C) and forces (T, n) at drive 1 and 0."""
    signed = moment_arm * direction[:, None, :]
    helping = np.clip(signed, 0.0, None)
    resisting = np.clip(-signed, 0.0, None)
    return (np.einsum("tic,ti->tc", helping, force_full)
            - np.einsum("tic,ti->tc", resisting, force_passive))


def infeasible_frames(frame_times_s, coordinates, target, moment_arm, force_full,
                      force_passive) -> list[InfeasibleFrame]:
    """Every (frame, coordinate) whose |target| exceeds the capacity, in time order."""
    direction = np.where(target >= 0, 1.0, -1.0)
    lack = np.abs(target) - capacity(moment_arm, force_full, force_passive, direction)
    frames, cols = np.nonzero(lack > 0)
    return [InfeasibleFrame(float(frame_times_s[f]), coordinates[c], float(target[f, c]),
                            float(lack[f, c])) for f, c in zip(frames, cols, strict=True)]
