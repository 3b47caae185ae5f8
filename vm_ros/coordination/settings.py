"""The coordination's settings: config/coordination.yaml read into one dataclass per section
(each entry with its unit, checked by config_reader), shared by the solver, the targets'
low-pass and the command line."""

from __future__ import annotations

import functools
from dataclasses import dataclass
from pathlib import Path

from vm_ros.model.config_reader import holds, load_yaml, read_section, yaml_section
from vm_ros.resources import config_dir

SETTINGS_FILE = "coordination.yaml"


@dataclass(frozen=True)
class TargetSettings:
    lowpass: float = holds("1/s")
    lowpass_order: float = holds("1")


@dataclass(frozen=True)
class DriveSettings:
    node_step: float = holds("s")
    lead_in: float = holds("s")


@dataclass(frozen=True)
class DistributionSettings:
    reserve_weight: float = holds("1")
    smoothness: float = holds("s")
    window: float = holds("s")
    overlap: float = holds("s")


@dataclass(frozen=True)
class TrackingSettings:
    iterations: float = holds("1")
    patience: float = holds("1")
    lead: float = holds("s")
    gain: float = holds("1")
    tolerance: float = holds("1")


@dataclass(frozen=True)
class GaussNewtonSettings:
    steps: float = holds("1")
    reserve_weight: float = holds("1")
    smoothness: float = holds("1")
    smoothness_cutoff: float = holds("1/s")
    damping: float = holds("1")
    delta: float = holds("1")
    memory: float = holds("s")
    tolerance: float = holds("1")
    eps: float = holds("1")


@dataclass(frozen=True)
class RecedingSettings:
    above: float = holds("1")
    period: float = holds("s")
    lead_in: float = holds("s")
    start_iterations: float = holds("1")


_SECTIONS = {"targets": TargetSettings, "drives": DriveSettings,
             "distribution": DistributionSettings, "tracking": TrackingSettings,
             "gauss_newton": GaussNewtonSettings, "receding": RecedingSettings}


@functools.cache
def solver_settings(path: Path | None = None) -> dict:
    """{section: settings dataclass} of config/coordination.yaml (or ``path``, same layout);
    ConfigError naming file and field for a bad entry."""
    path = Path(path) if path is not None else config_dir() / SETTINGS_FILE
    data = load_yaml(path)
    return {name: cls(**read_section(cls, path, yaml_section(path, data, name), name, {}))
            for name, cls in _SECTIONS.items()}


__all__ = ["SETTINGS_FILE", "solver_settings"]
