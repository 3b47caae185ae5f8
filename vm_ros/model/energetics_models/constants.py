"""Constants and options of the energetics models, loaded from ``config/energetics_models.yaml``.

Each entry of the file is ``{value, unit, tag, source}`` and is read by model.yaml's reader
(vm_ros.model.params): the unit must measure what the field holds (vm_ros.model.units), options
hold ``bool``. A bad entry is a one-line ConfigError naming file,
field and value. The loaded containers are frozen; ``dataclasses.replace`` makes variants.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from vm_ros.errors import ConfigError, InputError
from vm_ros.model.config_reader import holds, load_yaml, read_section, yaml_section
from vm_ros.resources import config_dir

FILE_NAME = "energetics_models.yaml"
UMBERGER_VARIANTS = ("uchida2016", "umberger2003", "umberger2010")


@dataclass(frozen=True)
class UmbergerConstants:
    """Umberger et al. 2003 / Umberger 2010 as OpenSim 4.6's Umberger2010MuscleMetabolicsProbe
    computes it (option names are OpenSim's); see config/energetics_models.yaml."""

    activation_maintenance_rate_on: bool = holds("bool")
    shortening_rate_on: bool = holds("bool")
    basal_rate_on: bool = holds("bool")
    mechanical_work_rate_on: bool = holds("bool")
    enforce_minimum_heat_rate_per_muscle: bool = holds("bool")
    use_Bhargava_recruitment_model: bool = holds("bool")  # noqa: N815 (OpenSim's name)
    include_negative_mechanical_work: bool = holds("bool")
    forbid_negative_total_power: bool = holds("bool")
    aerobic_factor: float = holds("1")
    basal_coefficient: float = holds("W/kg")
    basal_exponent: float = holds("1")
    muscle_effort_scaling_factor: float = holds("1")
    max_contraction_velocity: float = holds("L0/s")
    specific_tension: float = holds("Pa")
    density: float = holds("kg/m^3")
    activation_maintenance_fast_rate: float = holds("W/kg")
    activation_maintenance_base_rate: float = holds("W/kg")
    activation_maintenance_exponent: float = holds("1")
    lengthened_activation_maintenance_fraction: float = holds("1")
    shortening_heat_fast_at_vmax: float = holds("W/kg")
    shortening_heat_slow_at_vmax: float = holds("W/kg")
    fast_to_slow_vmax_ratio: float = holds("1")
    max_slow_shortening_heat_rate: float = holds("W/kg")
    shortening_exponent: float = holds("1")
    lengthening_coefficient_with_negative_work: float = holds("1")
    lengthening_coefficient: float = holds("1")
    minimum_heat_rate: float = holds("W/kg")


@dataclass(frozen=True)
class BhargavaConstants:
    """Bhargava et al. 2004 as OpenSim 4.6's Bhargava2004MuscleMetabolicsProbe computes it
    (option names are OpenSim's); see config/energetics_models.yaml."""

    activation_rate_on: bool = holds("bool")
    maintenance_rate_on: bool = holds("bool")
    shortening_rate_on: bool = holds("bool")
    basal_rate_on: bool = holds("bool")
    mechanical_work_rate_on: bool = holds("bool")
    enforce_minimum_heat_rate_per_muscle: bool = holds("bool")
    use_force_dependent_shortening_prop_constant: bool = holds("bool")
    include_negative_mechanical_work: bool = holds("bool")
    forbid_negative_total_power: bool = holds("bool")
    basal_coefficient: float = holds("W/kg")
    basal_exponent: float = holds("1")
    muscle_effort_scaling_factor: float = holds("1")
    specific_tension: float = holds("Pa")
    density: float = holds("kg/m^3")
    activation_constant_slow_twitch: float = holds("W/kg")
    activation_constant_fast_twitch: float = holds("W/kg")
    maintenance_constant_slow_twitch: float = holds("W/kg")
    maintenance_constant_fast_twitch: float = holds("W/kg")
    decay_function_value: float = holds("1")
    maintenance_length_dependence_x: tuple = holds("L0")
    maintenance_length_dependence_y: tuple = holds("1")
    shortening_coefficient: float = holds("1")
    shortening_isometric_coefficient: float = holds("1")
    shortening_total_force_coefficient: float = holds("1")
    lengthening_total_force_coefficient: float = holds("1")
    minimum_heat_rate: float = holds("W/kg")


@dataclass(frozen=True)
class LichtwarkConstants:
    """Lichtwark & Wilson 2005 (maintenance decay) / 2007 (supplement) heat rates as Koelewijn et
    al. 2019 formulate them; see config/energetics_models.yaml (section lichtwark)."""

    include_negative_mechanical_work: bool = holds("bool")
    max_contraction_velocity: float = holds("L0/s")
    force_velocity_curvature: float = holds("1")
    stable_maintenance_fraction: float = holds("1")
    maintenance_decay_constant: float = holds("1")
    maintenance_decay_fast_amplitude: float = holds("1")
    maintenance_decay_fast_rate: float = holds("1/s")
    maintenance_decay_slow_amplitude: float = holds("1")
    maintenance_decay_slow_rate: float = holds("1/s")
    lengthening_maintenance_floor: float = holds("1")
    lengthening_maintenance_decay: float = holds("1")
    lengthening_heat_coefficient: float = holds("1")


@dataclass(frozen=True)
class HoudijkConstants:
    """Houdijk et al. 2006 as Koelewijn et al. 2019 formulate it; see
    config/energetics_models.yaml (section houdijk)."""

    include_negative_mechanical_work: bool = holds("bool")
    forbid_negative_total_power: bool = holds("bool")
    total_heat_slow_twitch: float = holds("W/kg")
    total_heat_fast_twitch: float = holds("W/kg")
    activation_fraction_slow_twitch: float = holds("1")
    activation_fraction_fast_twitch: float = holds("1")
    shortening_coefficient_slow_twitch: float = holds("F0")
    shortening_coefficient_fast_twitch: float = holds("F0")
    max_frequency_base_slow_twitch: float = holds("1")
    max_frequency_base_fast_twitch: float = holds("1")
    max_frequency_slope_slow_twitch: float = holds("1")
    max_frequency_slope_fast_twitch: float = holds("1")
    activation_frequency_offset: float = holds("1")
    activation_frequency_constant: float = holds("1")


@dataclass(frozen=True)
class MargariaConstants:
    """Margaria 1968's efficiencies of positive and negative work; see
    config/energetics_models.yaml (section margaria)."""

    include_negative_mechanical_work: bool = holds("bool")
    positive_work_efficiency: float = holds("1")
    negative_work_efficiency: float = holds("1")


@dataclass(frozen=True)
class MinettiConstants:
    """Minetti & Alexander 1997's phi(v); see config/energetics_models.yaml (section minetti)."""

    max_contraction_velocity: float = holds("L0/s")
    phi_numerator: tuple = holds("1")
    phi_denominator: tuple = holds("1")


def _constants(path: Path, data: dict, section: str, cls):
    """One section of the file as ``cls``, read as model.yaml's sections are (each entry
    {value, unit, tag, source}; unit checked against what the field holds)."""
    return cls(**read_section(cls, path, yaml_section(path, data, section), section, {}))


def _path(path) -> Path:
    return Path(path) if path is not None else config_dir() / FILE_NAME


def load_umberger_constants(variant: str = "uchida2016", path=None) -> UmbergerConstants:
    """The umberger section with the options of ``variant`` (one of UMBERGER_VARIANTS:
    uchida2016 is OpenSim 4.6's default set) applied."""
    path = _path(path)
    data = load_yaml(path)
    constants = _constants(path, data, "umberger", UmbergerConstants)
    variants = data.get("umberger_variants")
    if not isinstance(variants, dict) or variant not in variants:
        known = ", ".join(variants) if isinstance(variants, dict) else "none"
        raise ConfigError(path, "umberger_variants", variant, f"unknown variant; known: {known}")
    options = variants[variant]
    flags = {f.name for f in dataclasses.fields(UmbergerConstants) if f.metadata["unit"] == "bool"}
    if not isinstance(options, dict) or not set(options) <= flags or not all(
            isinstance(v, bool) for v in options.values()):
        raise ConfigError(path, f"umberger_variants.{variant}", options,
                          "must map option names to true or false")
    return dataclasses.replace(constants, **options)


def load_bhargava_constants(path=None) -> BhargavaConstants:
    """The bhargava section of the file."""
    path = _path(path)
    constants = _constants(path, load_yaml(path), "bhargava", BhargavaConstants)
    x = constants.maintenance_length_dependence_x
    if len(x) < 2 or len(x) != len(constants.maintenance_length_dependence_y) or any(
            b <= a for a, b in zip(x[:-1], x[1:], strict=True)):
        raise ConfigError(path, "bhargava.maintenance_length_dependence_x", list(x),
                          "must rise strictly, have at least 2 points and as many as the ordinates")
    return constants


def load_lichtwark_constants(path=None) -> LichtwarkConstants:
    """The lichtwark section of the file."""
    path = _path(path)
    return _constants(path, load_yaml(path), "lichtwark", LichtwarkConstants)


def load_houdijk_constants(path=None) -> HoudijkConstants:
    """The houdijk section of the file."""
    path = _path(path)
    return _constants(path, load_yaml(path), "houdijk", HoudijkConstants)


def load_margaria_constants(path=None) -> MargariaConstants:
    """The margaria section of the file; the positive-work efficiency must be positive and the
    negative-work efficiency negative (Margaria's sign convention)."""
    path = _path(path)
    constants = _constants(path, load_yaml(path), "margaria", MargariaConstants)
    if not constants.positive_work_efficiency > 0.0:
        raise ConfigError(path, "margaria.positive_work_efficiency",
                          constants.positive_work_efficiency, "must be positive")
    if not constants.negative_work_efficiency < 0.0:
        raise ConfigError(path, "margaria.negative_work_efficiency",
                          constants.negative_work_efficiency,
                          "must be negative (work absorbed, energy spent)")
    return constants


def load_minetti_constants(path=None) -> MinettiConstants:
    """The minetti section of the file: phi's numerator has 3 coefficients, its denominator 4
    (constant first)."""
    path = _path(path)
    constants = _constants(path, load_yaml(path), "minetti", MinettiConstants)
    for name, count in (("phi_numerator", 3), ("phi_denominator", 4)):
        if len(getattr(constants, name)) != count:
            raise ConfigError(path, f"minetti.{name}", list(getattr(constants, name)),
                              f"must have {count} coefficients, constant first")
    return constants


def muscle_mass(max_isometric_force, optimal_fibre_length, specific_tension: float,
                density: float):
    """Muscle mass (kg) as OpenSim 4.6's metabolic probes compute it when no mass is provided:
    m = F0 / sigma * rho * L0 (F0 in N, L0 in m, specific tension sigma in Pa, density rho in
    kg/m^3; OpenSim's defaults 0.25e6 Pa and 1059.7 kg/m^3)."""
    return max_isometric_force / specific_tension * density * optimal_fibre_length


def basal_rate(body_mass: float, constants, include_basal: bool | None = None) -> float:
    """Whole-body basal rate (W), once per body, never per muscle: basal_coefficient *
    body_mass ** basal_exponent (body_mass in kg, > 0) when ``include_basal`` (None: the
    constants' ``basal_rate_on``, off in the shipped config), else 0 (OpenSim 4.6 probes)."""
    if not (constants.basal_rate_on if include_basal is None else include_basal):
        return 0.0
    if not (np.isfinite(body_mass) and body_mass > 0.0):
        raise InputError("body_mass", body_mass, "must be a finite mass > 0 kg")
    return constants.basal_coefficient * body_mass ** constants.basal_exponent


def probe_total(rates, body_mass: float, constants, include_basal: bool = True):
    """Whole-body metabolic rate (W) as OpenSim 4.6's Umberger2010 and Bhargava2004 probes report
    it (their first output, TOTAL): the muscles' ``rates.total`` summed over the last axis (the
    muscles), plus, with ``include_basal`` (the probes' basal_rate_on, on by default in OpenSim),
    the basal rate once (:func:`basal_rate`). Shape: ``rates.total`` without its last axis."""
    return np.sum(rates.total, axis=-1) + basal_rate(body_mass, constants, include_basal)
