"""RunConfig: what builds a run's muscle bank, so that a log can rebuild it offline.

    config = RunConfig(("vasti", "rectus_femoris"), recruitment="lumped",
                       overrides={"vasti": {"fpcsa_slow": 0.5}})
    bank = config.make_bank()

``params`` and ``library`` are YAML files (None: the shipped ``config/model.yaml`` and
``config/muscles.yaml``); a run log attaches their exact bytes (vm_ros.recording.run_log).
A joint-space run also names its ``geometry`` file (attached the same way), the ``joint_map``
YAML and the ``joints`` order of its joint outputs (vm_ros.joint_space).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import yaml

from vm_ros.errors import ConfigError
from vm_ros.model.bank import MuscleBank
from vm_ros.resources import config_dir


@dataclass(frozen=True)
class RunConfig:
    """| field | meaning |
    | muscles | muscle names, bank order |
    | recruitment | "lumped", "natural" or "continuous" |
    | recovery_mode | "static", "dynamic" or None (the model file's default) |
    | drive_law | the lumped drive filter's law (params.DRIVE_LAWS) or None (the model file's) |
    | overrides | ``{muscle: {field: value}}`` applied to the library entries |
    | library | muscle-library YAML path, or None for the shipped one |
    | params | model-parameter YAML path, or None for the shipped one |
    | units_per_type | natural units per fibre type, or None (model file) |
    | geometry | geometry YAML path (vm_ros.geometry), or None: muscle space only |
    | joint_map | robot joints -> coordinates, the ``joint_map`` YAML text ("" = own names) |
    | joints | robot joints ordering joint_efforts (() = every coordinate) |
    | energetics_models | published energetics models run beside Tsianos 2012 (names of
      vm_ros.model.energetics_models.MODEL_NAMES; () none): the energy_rate_models channel |
    """

    muscles: tuple
    recruitment: str = "lumped"
    recovery_mode: str | None = None
    overrides: Mapping = field(default_factory=dict)
    library: Path | None = None
    params: Path | None = None
    units_per_type: int | None = None
    geometry: Path | None = None
    joint_map: str = ""
    joints: tuple = ()
    drive_law: str | None = None
    energetics_models: tuple = ()

    @property
    def library_path(self) -> Path:
        return Path(self.library) if self.library is not None else config_dir() / "muscles.yaml"

    @property
    def params_path(self) -> Path:
        return Path(self.params) if self.params is not None else config_dir() / "model.yaml"

    def make_bank(self) -> MuscleBank:
        return MuscleBank.from_config(
            list(self.muscles), recruitment=self.recruitment, overrides=dict(self.overrides),
            library=self.library_path, params=self.params_path,
            recovery_mode=self.recovery_mode, units_per_type=self.units_per_type,
            drive_law=self.drive_law, energetics_models=tuple(self.energetics_models))

    def replace(self, **changes) -> RunConfig:
        return dataclasses.replace(self, **changes)

    def with_overrides(self, extra: Mapping) -> RunConfig:
        """A copy with ``extra`` merged field by field into the overrides."""
        merged = {name: dict(fields) for name, fields in self.overrides.items()}
        for name, fields in extra.items():
            merged.setdefault(name, {}).update(fields)
        return self.replace(overrides=merged)


def parse_override(text: str) -> dict:
    """``"vasti.fpcsa_slow=0.5"`` -> ``{"vasti": {"fpcsa_slow": 0.5}}`` (value read as YAML)."""
    key, sep, value = text.partition("=")
    muscle, dot, name = key.strip().partition(".")
    if not sep or not dot or not muscle or not name:
        raise ConfigError("<overrides>", key.strip() or text, text,
                          "expected MUSCLE.FIELD=VALUE, e.g. vasti.fpcsa_slow=0.5")
    try:
        parsed = yaml.safe_load(value)
    except yaml.YAMLError as exc:
        raise ConfigError("<overrides>", key.strip(), value, f"not a YAML value: {exc}") from exc
    return {muscle: {name: parsed}}


def parse_overrides(texts) -> dict:
    """Merge several ``MUSCLE.FIELD=VALUE`` strings into ``{muscle: {field: value}}``."""
    merged: dict = {}
    for text in texts or ():
        for muscle, fields in parse_override(text).items():
            merged.setdefault(muscle, {}).update(fields)
    return merged
