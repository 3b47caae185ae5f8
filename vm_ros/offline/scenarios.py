"""Built-in scenarios: named input time series for offline runs, validation and the demo.

    scenario = load_scenario("knee_extension")
    bank = scenario.make_bank(recruitment="lumped")
    inputs = scenario.inputs(bank)
    u, lp, vp = inputs.excitation(t), inputs.path_length(t), inputs.path_velocity(t)

Constants live in ``config/scenarios.yaml`` with their sources. Path lengths are placed so that at
the middle of the motion the fascicles sit at ``mid_range_length`` (L0) with the tendon carrying
``mid_range_tendon_force`` (F0).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml

from vm_ros.errors import ConfigError
from vm_ros.model import MuscleBank
from vm_ros.model.curves import tendon_length_at_force
from vm_ros.model.units import unit_for_field
from vm_ros.resources import config_dir

# What each scenario constant holds (its SI or normalised unit, vm_ros.model.units): a unit
# written in config/scenarios.yaml must be one of that quantity's units, and is converted.
HOLDS = {
    "duration": "s", "energy_bin": "s", "frequency": "1/s", "angle_min": "rad", "angle_max": "rad",
    "drive": "1", "drive_fraction": "1", "drive_amplitude": "1", "moment_arm": "m",
    "mid_range_length": "L0", "mid_range_tendon_force": "F0", "path_speed": "L0/s",
    "recovery_mode": "-",
}


@dataclass(frozen=True)
class ScenarioInputs:
    """Input functions of time: t (s) a number gives an (n_muscles,) array, t an array of k
    times gives (k, n_muscles) at once (the same values)."""

    excitation: Callable[[float], np.ndarray]
    path_length: Callable[[float], np.ndarray]
    path_velocity: Callable[[float], np.ndarray]
    joint_angle: Callable[[float], float] | None = None  # rad, where the scenario has a joint

    def sample(self, times) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Excitation, path length and path velocity at each of ``times`` (s), each (k, n): the
        inputs of ``MuscleBank.run``."""
        times = np.asarray(times, dtype=float)
        return tuple(np.array(fn(times), dtype=float)
                     for fn in (self.excitation, self.path_length, self.path_velocity))


def _per_muscle(values, n: int) -> np.ndarray:
    """A value per time (a number or (k,)) as the same value for every muscle: (n,) or (k, n)."""
    values = np.asarray(values, dtype=float)
    return np.broadcast_to(values[..., None], (*values.shape, n)).copy()


@dataclass(frozen=True)
class Scenario:
    """A named scenario; ``values`` holds its constants in SI (angles in rad)."""

    name: str
    description: str
    muscles: tuple
    values: dict = field(default_factory=dict)

    @property
    def duration_s(self) -> float:
        return float(self.values["duration"])

    @property
    def recovery_mode(self) -> str:
        return str(self.values.get("recovery_mode", "static"))

    def make_bank(self, recruitment: str = "lumped", **kwargs) -> MuscleBank:
        kwargs.setdefault("recovery_mode", self.recovery_mode)
        return MuscleBank.from_config(list(self.muscles), recruitment=recruitment, **kwargs)

    def mid_path_length(self, bank: MuscleBank) -> np.ndarray:
        g = bank.params.generic
        l_se = tendon_length_at_force(self.values["mid_range_tendon_force"], g.ct, g.kt, g.lrt)
        return bank.l0_m * self.values["mid_range_length"] + bank.l0t_m * l_se

    def inputs(self, bank: MuscleBank) -> ScenarioInputs:
        return _BUILDERS[self.name](self, bank)


def _knee_extension(s: Scenario, bank: MuscleBank) -> ScenarioInputs:
    v = s.values
    w = 2 * np.pi * v["frequency"]
    mid_angle = 0.5 * (v["angle_min"] + v["angle_max"])
    half_range = 0.5 * (v["angle_max"] - v["angle_min"])
    mid = s.mid_path_length(bank)
    arm = v["moment_arm"]

    def angle(t):  # extension angle: starts flexed (angle_min), extends during the first half
        return mid_angle - half_range * np.cos(w * np.asarray(t, dtype=float))

    def excitation(t):
        phase = (np.asarray(t, dtype=float) * v["frequency"]) % 1.0
        return _per_muscle(np.where(phase < v["drive_fraction"], v["drive"], 0.0), bank.n)

    def path_length(t):  # extension shortens the knee extensors
        return mid - arm * (np.asarray(angle(t))[..., None] - mid_angle)

    def path_velocity(t):
        return _per_muscle(-arm * half_range * w * np.sin(w * np.asarray(t, dtype=float)),
                           bank.n)

    return ScenarioInputs(excitation, path_length, path_velocity, angle)


def _constant(values):
    """A function of time that is ``values`` (n,) at every time (t an array: (k, n))."""
    values = np.asarray(values, dtype=float)
    return lambda t: np.broadcast_to(values, (*np.shape(t), *values.shape)).copy()


def _isometric_ramp(s: Scenario, bank: MuscleBank) -> ScenarioInputs:
    peak, duration = s.values["drive"], s.duration_s
    return ScenarioInputs(
        lambda t: _per_muscle(peak * np.maximum(
            0.0, 1.0 - np.abs(2.0 * np.asarray(t, dtype=float) / duration - 1.0)), bank.n),
        _constant(s.mid_path_length(bank)), _constant(np.zeros(bank.n)))


def _sinusoidal_drive(s: Scenario, bank: MuscleBank) -> ScenarioInputs:
    v = s.values
    return ScenarioInputs(
        lambda t: _per_muscle(v["drive"] + v["drive_amplitude"] * np.sin(
            2 * np.pi * v["frequency"] * np.asarray(t, dtype=float)), bank.n),
        _constant(s.mid_path_length(bank)), _constant(np.zeros(bank.n)))


def _isovelocity(s: Scenario, bank: MuscleBank) -> ScenarioInputs:
    v = s.values
    half = 0.5 * s.duration_s
    speed = v["path_speed"] * bank.l0_m
    mid = s.mid_path_length(bank)

    def path_length(t):  # shorten for the first half, lengthen back in the second
        return mid + speed * (np.abs(np.asarray(t, dtype=float) - half)[..., None] - 0.5 * half)

    def path_velocity(t):
        return speed * np.where(np.asarray(t, dtype=float) >= half, 1.0, -1.0)[..., None]

    return ScenarioInputs(_constant(np.full(bank.n, v["drive"])), path_length, path_velocity)


_BUILDERS = {"knee_extension": _knee_extension, "isometric_ramp": _isometric_ramp,
             "sinusoidal_drive": _sinusoidal_drive, "isovelocity": _isovelocity}


def scenario_names() -> tuple:
    return tuple(_BUILDERS)


def load_scenario(name: str, path: str | Path | None = None) -> Scenario:
    """Load a built-in scenario's constants from ``config/scenarios.yaml`` (or ``path``)."""
    path = Path(path) if path is not None else config_dir() / "scenarios.yaml"
    # libyaml's parser (the same safe constructor: the same values), as load_yaml reads the
    # model files: 1.5 ms instead of 15 ms, paid by every run of a study
    data = yaml.load(path.read_text(encoding="utf-8"),
                     Loader=getattr(yaml, "CSafeLoader", yaml.SafeLoader))
    entries = data.get("scenarios", {})
    if name not in _BUILDERS or name not in entries:
        raise ConfigError(path, f"scenarios.{name}", name,
                          f"unknown scenario (have: {', '.join(scenario_names())})")
    entry = entries[name]
    values = {}
    for key, item in entry.items():
        if not (isinstance(item, dict) and "value" in item):
            continue
        field = f"scenarios.{name}.{key}"
        if key not in HOLDS:
            raise ConfigError(path, field, key, f"unknown constant (have: {', '.join(HOLDS)})")
        unit = unit_for_field(path, f"{field}.unit", item.get("unit"), HOLDS[key])
        value = item["value"]
        values[key] = value * unit.factor if isinstance(
            value, (int, float)) and not isinstance(value, bool) else value
    return Scenario(name, entry.get("description", ""), tuple(entry["muscles"]), values)
