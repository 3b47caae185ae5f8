"""Model parameters: loading, unit conversion to SI, validation; frozen containers.

Every constant comes from ``config/model.yaml`` (or a user file of the same form), where each entry
carries its unit, confidence tag (C certain, L likely, R reconstructed) and source. Milliseconds,
N/cm^2, g/cm^3 and kJ are converted here, once; everything downstream is SI or VM's normalised
units (L0, L0/s, F0, f0.5).

Muscle libraries are YAML files with a top-level ``muscles:`` mapping of name to fields (SI, unit in
the field name): ``mass_kg``, ``l0_m``, ``l0t_m``, ``path_length_max_m`` (or ``lmax``),
``fpcsa_slow``, ``ur``, optional ``path_length_min_m``, ``source`` and ``description``.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml

from vm_ros.errors import ConfigError
from vm_ros.resources import config_dir

FIBRE_TYPES = ("slow", "fast")
SLOW, FAST = 0, 1
TAGS = ("C", "L", "R")

# Factor converting a config unit to SI (or to the normalised unit it stays in).
_TO_SI = {
    "ms": 1e-3,
    "s": 1.0,
    "N/cm^2": 1e4,
    "g/cm^3": 1e3,
    "kJ/(kg K)": 1e3,
}


def _load_yaml(path: Path) -> dict:
    try:
        with open(path, encoding="utf-8") as handle:
            data = yaml.safe_load(handle)
    except OSError as exc:
        raise ConfigError(path, "<file>", None, f"cannot read: {exc.strerror}") from exc
    except yaml.YAMLError as exc:
        raise ConfigError(path, "<file>", None, f"not valid YAML: {exc}") from exc
    if not isinstance(data, dict):
        raise ConfigError(path, "<file>", type(data).__name__, "top level must be a mapping")
    return data


def _entry_scale(path, name: str, entry) -> float:
    if not isinstance(entry, dict):
        raise ConfigError(path, name, entry, "must be a mapping with value/unit/tag/source")
    for key in ("unit", "tag", "source"):
        if key not in entry:
            raise ConfigError(path, f"{name}.{key}", None, "missing")
    if entry["tag"] not in TAGS:
        raise ConfigError(path, f"{name}.tag", entry["tag"], f"must be one of {TAGS}")
    return _TO_SI.get(entry["unit"], 1.0)


def _finite_number(path, name: str, value) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ConfigError(path, name, value, "must be a finite number")
    return float(value)


def _section(path, data: dict, name: str) -> dict:
    section = data.get(name)
    if not isinstance(section, dict):
        raise ConfigError(path, name, section, "missing or not a mapping")
    return section


def _fields_from_section(cls, path, section: dict, section_name: str, read) -> dict:
    names = {f.name for f in dataclasses.fields(cls)}
    unknown = sorted(set(section) - names)
    if unknown:
        raise ConfigError(path, f"{section_name}.{unknown[0]}", None, "unknown parameter")
    missing = sorted(names - set(section))
    if missing:
        raise ConfigError(path, f"{section_name}.{missing[0]}", None, "missing")
    return {name: read(f"{section_name}.{name}", section[name]) for name in names}


def _per_type_reader(path):
    def read(name, entry):
        scale = _entry_scale(path, name, entry)
        values = [_finite_number(path, f"{name}.{t}", entry.get(t)) for t in FIBRE_TYPES]
        return np.array(values) * scale

    return read


def _scalar_reader(path):
    def read(name, entry):
        scale = _entry_scale(path, name, entry)
        value = entry.get("value")
        if isinstance(value, (bool, str)):
            return value
        if isinstance(value, list):
            return tuple(_finite_number(path, name, v) * scale for v in value)
        return _finite_number(path, name, value) * scale

    return read


@dataclass(frozen=True)
class FibreTypeParams:
    """Per-fibre-type constants, each an array over the fibre-type axis (slow, fast) or over units.

    Time constants in s; velocities in L0/s; rates in f0.5. Sag (as1, as2, ts) is neutral for slow
    fibres and yield (cy) for fast ones, so one code path serves both types.
    """

    omega: np.ndarray
    beta: np.ndarray
    rho: np.ndarray
    vmax: np.ndarray
    cv0: np.ndarray
    cv1: np.ndarray
    av0: np.ndarray
    av1: np.ndarray
    av2: np.ndarray
    bv: np.ndarray
    af: np.ndarray
    nf0: np.ndarray
    nf1: np.ndarray
    tf1: np.ndarray
    tf2: np.ndarray
    tf3: np.ndarray
    tf4: np.ndarray
    as1: np.ndarray
    as2: np.ndarray
    ts: np.ndarray
    sag_rate_threshold: np.ndarray
    cy: np.ndarray
    vy: np.ndarray
    ty: np.ndarray
    f_half_pps: np.ndarray

    def take(self, index: np.ndarray) -> FibreTypeParams:
        """The same parameters gathered along the fibre-type axis (e.g. one entry per unit)."""
        return FibreTypeParams(
            **{f.name: getattr(self, f.name)[index] for f in dataclasses.fields(self)}
        )


@dataclass(frozen=True)
class GenericParams:
    """Constants shared by both fibre types (VM 4.0). Forces in F0, lengths in L0 or L0T."""

    fmin: float
    fmax: float
    c1: float
    k1: float
    lr1: float
    eta: float
    c2: float
    k2: float
    lr2: float
    ct: float
    kt: float
    lrt: float
    specific_tension: float  # Pa
    muscle_density: float  # kg/m^3
    ur_default: float
    l_activation_max_fraction: float
    l_activation_min: float
    fv_denominator_min: float


@dataclass(frozen=True)
class LumpedParams:
    """Tsianos 2012 Appendix A lumped-unit constants (polynomials in U2, highest power first)."""

    u1: float
    t_rise_poly: tuple
    t_fall_poly: tuple
    t_rise_step_scale: float
    w_slow_poly: tuple
    w_slow_a_poly: tuple
    w_slow_tau: float
    w_fast_b_poly: tuple
    w_fast_c_poly: tuple
    w_fast_offset: float
    w_fast_rise: float
    w_fast_tau_poly: tuple
    cap_recruitment_at_full: bool


@dataclass(frozen=True)
class NaturalParams:
    """Discrete natural-unit recruitment (Cheng 2000)."""

    units_per_type: float
    apportioning: str
    geometric_ratio: float
    u_threshold_min: float


@dataclass(frozen=True)
class ContinuousParams:
    """Continuous recruitment (Song 2008)."""

    u_threshold_min: float
    tau_rise: float
    tau_fall: float


@dataclass(frozen=True)
class EnergeticsParams:
    """Tsianos 2012 energetics. e1..e4 per fibre type (W/kg dry, V in L0/s); recovery in s."""

    e1: np.ndarray
    e2: np.ndarray
    e3: np.ndarray
    e4: np.ndarray
    recovery_ratio: np.ndarray
    activation_fraction: float
    dry_to_wet_mass: float
    heat_capacity: float  # J/(kg K)
    recovery_mode: str
    recovery_tau_rise: float
    recovery_tau_decay: float


@dataclass(frozen=True)
class ModelParams:
    """Everything in ``config/model.yaml``, validated and in SI/normalised units."""

    fibre: FibreTypeParams
    generic: GenericParams
    lumped: LumpedParams
    natural: NaturalParams
    continuous: ContinuousParams
    energetics: EnergeticsParams
    path: str = "<defaults>"

    def with_energetics(self, **changes) -> ModelParams:
        return dataclasses.replace(self, energetics=dataclasses.replace(self.energetics, **changes))


RECOVERY_MODES = ("static", "dynamic")
APPORTIONING = ("equal", "geometric")


def load_model_params(path: str | Path | None = None) -> ModelParams:
    """Load and validate a model parameter file (default: the shipped ``config/model.yaml``)."""
    path = Path(path) if path is not None else config_dir() / "model.yaml"
    data = _load_yaml(path)
    if data.get("fibre_types") != list(FIBRE_TYPES):
        raise ConfigError(
            path, "fibre_types", data.get("fibre_types"), f"must be {list(FIBRE_TYPES)}"
        )
    per_type, scalar = _per_type_reader(path), _scalar_reader(path)
    fibre = FibreTypeParams(
        **_fields_from_section(
            FibreTypeParams,
            path,
            _section(path, data, "fibre_type_parameters"),
            "fibre_type_parameters",
            per_type,
        )
    )
    generic = GenericParams(
        **_fields_from_section(
            GenericParams, path, _section(path, data, "generic"), "generic", scalar
        )
    )
    recruitment = _section(path, data, "recruitment")
    lumped = LumpedParams(
        **_fields_from_section(
            LumpedParams, path, _section(path, recruitment, "lumped"), "recruitment.lumped", scalar
        )
    )
    natural = NaturalParams(
        **_fields_from_section(
            NaturalParams,
            path,
            _section(path, recruitment, "natural"),
            "recruitment.natural",
            scalar,
        )
    )
    continuous = ContinuousParams(
        **_fields_from_section(
            ContinuousParams,
            path,
            _section(path, recruitment, "continuous"),
            "recruitment.continuous",
            scalar,
        )
    )
    energetics_section = _section(path, data, "energetics")
    per_type_names = {"e1", "e2", "e3", "e4", "recovery_ratio"}

    def read_energetics(name, entry):
        reader = per_type if name.rsplit(".", 1)[-1] in per_type_names else scalar
        return reader(name, entry)

    energetics = EnergeticsParams(
        **_fields_from_section(
            EnergeticsParams, path, energetics_section, "energetics", read_energetics
        )
    )
    params = ModelParams(fibre, generic, lumped, natural, continuous, energetics, str(path))
    _validate_model_params(params)
    return params


def _validate_model_params(p: ModelParams) -> None:
    path = p.path
    for name in ("tf1", "tf2", "tf3", "tf4", "ts", "ty", "vy", "af", "nf0", "bv"):
        values = getattr(p.fibre, name)
        if np.any(values <= 0):
            raise ConfigError(path, f"fibre_type_parameters.{name}", values.tolist(), "must be > 0")
    if np.any(p.fibre.vmax >= 0):
        raise ConfigError(
            path,
            "fibre_type_parameters.vmax",
            p.fibre.vmax.tolist(),
            "must be < 0 (shortening is negative)",
        )
    if np.any(p.fibre.nf1 <= p.fibre.nf0):
        raise ConfigError(
            path, "fibre_type_parameters.nf1", p.fibre.nf1.tolist(), "must exceed nf0"
        )
    g = p.generic
    if not 0 <= g.fmin < g.fmax:
        raise ConfigError(path, "generic.fmin", g.fmin, "need 0 <= fmin < fmax")
    for name in ("k1", "kt", "ct", "specific_tension", "muscle_density", "l_activation_min"):
        if getattr(g, name) <= 0:
            raise ConfigError(path, f"generic.{name}", getattr(g, name), "must be > 0")
    if not 0 < g.l_activation_max_fraction < 1:
        raise ConfigError(
            path,
            "generic.l_activation_max_fraction",
            g.l_activation_max_fraction,
            "must be in (0, 1)",
        )
    if not 0 < g.ur_default <= 1:
        raise ConfigError(path, "generic.ur_default", g.ur_default, "must be in (0, 1]")
    e = p.energetics
    if e.recovery_mode not in RECOVERY_MODES:
        raise ConfigError(
            path, "energetics.recovery_mode", e.recovery_mode, f"one of {RECOVERY_MODES}"
        )
    if not 0 < e.activation_fraction < 1:
        raise ConfigError(
            path, "energetics.activation_fraction", e.activation_fraction, "in (0, 1)"
        )
    if not 0 < e.recovery_tau_rise < e.recovery_tau_decay:
        raise ConfigError(
            path,
            "energetics.recovery_tau_rise",
            e.recovery_tau_rise,
            "need 0 < recovery_tau_rise < recovery_tau_decay",
        )
    if np.any(e.e4 <= 0):
        raise ConfigError(path, "energetics.e4", e.e4.tolist(), "must be > 0")
    n = p.natural
    if n.apportioning not in APPORTIONING:
        raise ConfigError(
            path, "recruitment.natural.apportioning", n.apportioning, f"one of {APPORTIONING}"
        )
    if n.units_per_type < 1 or n.units_per_type != int(n.units_per_type):
        raise ConfigError(
            path,
            "recruitment.natural.units_per_type",
            n.units_per_type,
            "must be a whole number >= 1",
        )
    c = p.continuous
    if c.tau_rise <= 0 or c.tau_fall <= 0:
        raise ConfigError(path, "recruitment.continuous.tau_rise", c.tau_rise, "must be > 0")


# ---------------------------------------------------------------------------------------------
# Muscle library


@dataclass(frozen=True)
class MuscleSpec:
    """One muscle's morphometry and fibre mix (SI).

    | field | unit | meaning |
    | mass_kg | kg | wet mass |
    | l0_m | m | optimal fascicle length |
    | l0t_m | m | tendon length at 1.0 F0 |
    | path_length_max_m | m | maximum anatomical musculotendon path length (or None with lmax) |
    | lmax | L0 | fascicle length at the maximum path length (or None with path_length_max_m) |
    | fpcsa_slow | 1 | fraction of PCSA in slow fibres |
    | ur | 1 | drive at which all units are recruited |
    """

    name: str
    mass_kg: float
    l0_m: float
    l0t_m: float
    fpcsa_slow: float
    ur: float
    path_length_max_m: float | None = None
    lmax: float | None = None
    path_length_min_m: float | None = None
    source: Mapping = field(default_factory=dict)
    description: str = ""


_MUSCLE_NUMBERS = (
    "mass_kg",
    "l0_m",
    "l0t_m",
    "fpcsa_slow",
    "ur",
    "path_length_max_m",
    "lmax",
    "path_length_min_m",
)
_MUSCLE_FIELDS = set(_MUSCLE_NUMBERS) | {"source", "description"}


def muscle_from_fields(name: str, fields: Mapping, path, ur_default: float) -> MuscleSpec:
    """Validate one muscle's fields (a mapping from a library file, overrides applied)."""
    where = f"muscles.{name}"
    if not isinstance(fields, Mapping):
        raise ConfigError(path, where, fields, "must be a mapping of fields")
    unknown = sorted(set(fields) - _MUSCLE_FIELDS)
    if unknown:
        raise ConfigError(
            path,
            f"{where}.{unknown[0]}",
            fields[unknown[0]],
            f"unknown field (known: {sorted(_MUSCLE_FIELDS)})",
        )
    values = {}
    for key in _MUSCLE_NUMBERS:
        if fields.get(key) is not None:
            values[key] = _finite_number(path, f"{where}.{key}", fields[key])
    for key in ("mass_kg", "l0_m", "l0t_m"):
        if key not in values:
            raise ConfigError(path, f"{where}.{key}", None, "missing")
        if values[key] <= 0:
            raise ConfigError(path, f"{where}.{key}", values[key], "must be > 0")
    if "fpcsa_slow" not in values:
        raise ConfigError(path, f"{where}.fpcsa_slow", None, "missing")
    if not 0 <= values["fpcsa_slow"] <= 1:
        raise ConfigError(path, f"{where}.fpcsa_slow", values["fpcsa_slow"], "must be in [0, 1]")
    values.setdefault("ur", ur_default)
    if not 0 < values["ur"] <= 1:
        raise ConfigError(path, f"{where}.ur", values["ur"], "must be in (0, 1]")
    if ("path_length_max_m" in values) == ("lmax" in values):
        raise ConfigError(
            path,
            f"{where}.path_length_max_m",
            fields.get("path_length_max_m"),
            "give exactly one of path_length_max_m and lmax",
        )
    if values.get("lmax", 1.5) <= 1.0:
        raise ConfigError(path, f"{where}.lmax", values["lmax"], "must be > 1 (in L0)")
    if values.get("path_length_max_m", 1.0) <= 0:
        raise ConfigError(
            path, f"{where}.path_length_max_m", values["path_length_max_m"], "must be > 0"
        )
    source = fields.get("source") or {}
    if not isinstance(source, Mapping):
        source = {"all": str(source)}
    return MuscleSpec(
        name=name, source=dict(source), description=str(fields.get("description", "")), **values
    )


def load_muscle_library(path: str | Path | None = None) -> dict[str, dict]:
    """Read a muscle-library YAML file: ``{name: fields}`` (validated when a bank is built)."""
    path = Path(path) if path is not None else config_dir() / "muscles.yaml"
    data = _load_yaml(path)
    muscles = data.get("muscles")
    if not isinstance(muscles, dict) or not muscles:
        raise ConfigError(path, "muscles", muscles, "must be a non-empty mapping of name to fields")
    return muscles


def resolve_muscles(
    names, library: str | Path | None, overrides: Mapping | None, ur_default: float
) -> list[MuscleSpec]:
    """Pick ``names`` from a library, apply per-muscle ``overrides`` and validate each muscle."""
    lib_path = Path(library) if library is not None else config_dir() / "muscles.yaml"
    entries = load_muscle_library(lib_path)
    overrides = dict(overrides or {})
    if isinstance(names, str):
        names = [names]
    names = list(names)
    if not names:
        raise ConfigError(lib_path, "muscles", names, "need at least one muscle")
    if len(set(names)) != len(names):
        raise ConfigError(lib_path, "muscles", names, "muscle names must be unique")
    for name in overrides:
        if name not in names:
            raise ConfigError(
                "<overrides>", name, overrides[name], "override for a muscle not in the bank"
            )
    specs = []
    for name in names:
        if name not in entries:
            raise ConfigError(
                lib_path,
                f"muscles.{name}",
                None,
                f"not in the library (have: {', '.join(sorted(entries))})",
            )
        fields = dict(entries[name] or {})
        extra = overrides.get(name) or {}
        if not isinstance(extra, Mapping):
            raise ConfigError("<overrides>", name, extra, "must be a mapping of fields")
        if "lmax" in extra:
            fields.pop("path_length_max_m", None)
        if "path_length_max_m" in extra:
            fields.pop("lmax", None)
        fields.update(extra)
        specs.append(
            muscle_from_fields(name, fields, lib_path if not extra else "<overrides>", ur_default)
        )
    return specs
