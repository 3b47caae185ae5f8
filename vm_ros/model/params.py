"""Model parameters: loading, unit conversion to SI, validation; frozen containers.

Every constant comes from ``config/model.yaml`` (or a user file of the same form), where each entry
carries its unit, confidence tag (C certain, L likely, R reconstructed) and source. Each field
declares the unit its value is held in (``holds``); the unit written in the file must be one of
vm_ros.model.units.UNITS for the same quantity, and is converted here, once (ms, N/cm^2, g/cm^3,
kJ); everything downstream is SI or VM's normalised units (L0, L0/s, F0, f0.5). The unit, tag and
source of each constant stay on the loaded parameters (``ModelParams.info``; ``vm-ros params``).

Muscle libraries are YAML files with a top-level ``muscles:`` mapping of name to fields (SI, unit in
the field name): ``mass_kg``, ``l0_m``, ``l0t_m``, ``path_length_max_m`` (or ``lmax``),
``fpcsa_slow``, ``ur``, optional ``path_length_min_m``, ``source`` and ``description``.
"""

from __future__ import annotations

import dataclasses
import difflib
from collections import Counter
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from vm_ros.errors import ConfigError
from vm_ros.model.config_reader import (  # the {value, unit, tag, source} reader
    FIBRE_TYPES,
    ParamInfo,
    finite_number,
    holds,
    load_yaml,
    read_section,
    yaml_section,
)
from vm_ros.resources import config_dir

SLOW, FAST = 0, 1


@dataclass(frozen=True)
class FibreTypeParams:
    """Per-fibre-type constants, each an array over the fibre-type axis (slow, fast) or over units.

    Time constants in s; velocities in L0/s; rates in f0.5. Sag (as1, as2, ts) is neutral for slow
    fibres and yield (cy) for fast ones, so one code path serves both types.
    """

    omega: np.ndarray = holds("1")
    beta: np.ndarray = holds("1")
    rho: np.ndarray = holds("1")
    vmax: np.ndarray = holds("L0/s")
    cv0: np.ndarray = holds("1")
    cv1: np.ndarray = holds("1")
    av0: np.ndarray = holds("1")
    av1: np.ndarray = holds("1")
    av2: np.ndarray = holds("1")
    bv: np.ndarray = holds("L0/s")
    af: np.ndarray = holds("f0.5")
    nf0: np.ndarray = holds("1")
    nf1: np.ndarray = holds("1")
    tf1: np.ndarray = holds("s")
    tf2: np.ndarray = holds("s")
    tf3: np.ndarray = holds("s")
    tf4: np.ndarray = holds("s")
    as1: np.ndarray = holds("1")
    as2: np.ndarray = holds("1")
    ts: np.ndarray = holds("s")
    sag_rate_threshold: np.ndarray = holds("f0.5")
    cy: np.ndarray = holds("1")
    vy: np.ndarray = holds("L0/s")
    ty: np.ndarray = holds("s")
    f_half_pps: np.ndarray = holds("1/s")

    def take(self, index: np.ndarray) -> FibreTypeParams:
        """The same parameters gathered along the fibre-type axis (e.g. one entry per unit)."""
        return FibreTypeParams(
            **{f.name: getattr(self, f.name)[index] for f in dataclasses.fields(self)}
        )


@dataclass(frozen=True)
class GenericParams:
    """Constants shared by both fibre types (VM 4.0). Forces in F0, lengths in L0 or L0T."""

    fmin: float = holds("f0.5")
    fmax: float = holds("f0.5")
    c1: float = holds("F0")
    k1: float = holds("1")
    lr1: float = holds("1")
    eta: float = holds("F0 s/L0")
    c2: float = holds("F0")
    k2: float = holds("1/L0")
    lr2: float = holds("L0")
    ct: float = holds("F0/L0T")
    kt: float = holds("L0T")
    lrt: float = holds("L0T")
    specific_tension: float = holds("Pa")
    muscle_density: float = holds("kg/m^3")
    ur_default: float = holds("1")
    l_activation_max_fraction: float = holds("1")
    l_activation_min: float = holds("L0")
    fv_denominator_min: float = holds("1")


@dataclass(frozen=True)
class LumpedParams:
    """Tsianos 2012 Appendix A lumped-unit constants (polynomials in U2, highest power first)."""

    u1: float = holds("1")
    t_rise_poly: tuple = holds("s")
    t_fall_poly: tuple = holds("s")
    t_rise_step_scale: float = holds("1/s")
    drive_law: str = holds("-")
    relative_rise_poly: tuple = holds("s")
    relative_fall_poly: tuple = holds("s")
    relative_fall_power: float = holds("1")
    relative_fall_floor: float = holds("s")
    drive_tau_min: float = holds("s")
    w_slow_poly: tuple = holds("1")
    w_slow_a_poly: tuple = holds("1")
    w_slow_tau: float = holds("1")
    w_fast_b_poly: tuple = holds("1")
    w_fast_c_poly: tuple = holds("1")
    w_fast_offset: float = holds("1")
    w_fast_rise: float = holds("1")
    w_fast_tau_poly: tuple = holds("1")
    cap_recruitment_at_full: bool = holds("bool")


@dataclass(frozen=True)
class NaturalParams:
    """Discrete natural-unit recruitment (Cheng 2000)."""

    units_per_type: float = holds("1")
    apportioning: str = holds("-")
    geometric_ratio: float = holds("1")
    u_threshold_min: float = holds("1")


@dataclass(frozen=True)
class ContinuousParams:
    """Continuous recruitment (Song 2008)."""

    u_threshold_min: float = holds("1")
    tau_rise: float = holds("s")
    tau_fall: float = holds("s")


@dataclass(frozen=True)
class EnergeticsParams:
    """Tsianos 2012 energetics. e1..e4 per fibre type (W/kg dry, V in L0/s); recovery in s.

    Dynamic recovery uses the kernel named ``recovery_kernel`` (one of RECOVERY_KERNELS), whose
    time constants are the fields ``<name>_tau_rise`` and ``<name>_tau_decay``;
    ``recovery_tau_rise`` and ``recovery_tau_decay`` are the selected kernel's (docs/model.md
    section 7).
    """

    e1: np.ndarray = holds("W s/(kg L0)")
    e2: np.ndarray = holds("W/kg")
    e3: np.ndarray = holds("W L0/(kg s)")
    e4: np.ndarray = holds("L0/s")
    recovery_ratio: np.ndarray = holds("1")
    activation_fraction: float = holds("1")
    dry_to_wet_mass: float = holds("1")
    heat_capacity: float = holds("J/(kg K)")
    recovery_mode: str = holds("-")
    recovery_kernel: str = holds("-")
    fitted_fig7_tau_rise: float = holds("s")
    fitted_fig7_tau_decay: float = holds("s")
    pcr_slade2006_tau_rise: float = holds("s")
    pcr_slade2006_tau_decay: float = holds("s")

    def kernel_taus(self, kernel: str | None = None) -> tuple[float, float]:
        """(tr, td) in s of the recovery kernel ``kernel`` (default: the selected one)."""
        name = self.recovery_kernel if kernel is None else kernel
        if name not in RECOVERY_KERNELS:
            raise ConfigError("<parameters>", "energetics.recovery_kernel", name,
                              f"one of {RECOVERY_KERNELS}")
        return getattr(self, f"{name}_tau_rise"), getattr(self, f"{name}_tau_decay")

    @property
    def recovery_tau_rise(self) -> float:
        """tr (s) of the selected recovery kernel."""
        return self.kernel_taus()[0]

    @property
    def recovery_tau_decay(self) -> float:
        """td (s) of the selected recovery kernel."""
        return self.kernel_taus()[1]


# Sections of a model file: dotted name in the file -> attribute of ModelParams, class.
SECTIONS = {
    "fibre_type_parameters": ("fibre", FibreTypeParams),
    "generic": ("generic", GenericParams),
    "recruitment.lumped": ("lumped", LumpedParams),
    "recruitment.natural": ("natural", NaturalParams),
    "recruitment.continuous": ("continuous", ContinuousParams),
    "energetics": ("energetics", EnergeticsParams),
}


@dataclass(frozen=True)
class ModelParams:
    """Everything in ``config/model.yaml``, validated and in SI/normalised units.

    ``info`` maps each constant's dotted name to its :class:`ParamInfo` (unit as written, tag,
    source); :meth:`value_of` gives its current value.
    """

    fibre: FibreTypeParams
    generic: GenericParams
    lumped: LumpedParams
    natural: NaturalParams
    continuous: ContinuousParams
    energetics: EnergeticsParams
    path: str = "<defaults>"
    info: dict = field(default_factory=dict, compare=False, repr=False)

    def with_energetics(self, **changes) -> ModelParams:
        return dataclasses.replace(self, energetics=dataclasses.replace(self.energetics, **changes))

    def value_of(self, name: str):
        """The value (SI or normalised) of the constant ``name`` (``fibre_type_parameters.tf1``)."""
        section, _, field_name = name.rpartition(".")
        if section not in SECTIONS:
            raise KeyError(name)
        return getattr(getattr(self, SECTIONS[section][0]), field_name)


# recruitment schemes (vm_ros.model.recruitment: lumped Tsianos 2012, natural Song 2008 units,
# continuous); named here, with the other option names, for readers that need no equations
SCHEMES = ("lumped", "natural", "continuous")
RECOVERY_MODES = ("static", "dynamic")
# Dynamic recovery kernels (docs/model.md section 7), each with <name>_tau_rise/_tau_decay fields.
RECOVERY_KERNELS = ("fitted_fig7", "pcr_slade2006")
DRIVE_LAWS = ("tsianos2012", "relative_drive")
APPORTIONING = ("equal", "geometric")


def load_model_params(path: str | Path | None = None) -> ModelParams:
    """Load and validate a model parameter file (default: the shipped ``config/model.yaml``).

    Each entry's unit must be in vm_ros.model.units.UNITS and measure what its field holds
    (``ms`` for a time constant, not ``mm`` or ``msec``); values are converted once, here.
    """
    path = Path(path) if path is not None else config_dir() / "model.yaml"
    data = load_yaml(path)
    if data.get("fibre_types") != list(FIBRE_TYPES):
        raise ConfigError(
            path, "fibre_types", data.get("fibre_types"), f"must be {list(FIBRE_TYPES)}"
        )
    info: dict[str, ParamInfo] = {}
    groups = {}
    for section_name, (attribute, cls) in SECTIONS.items():
        section = yaml_section(path, data, section_name)
        groups[attribute] = cls(**read_section(cls, path, section, section_name, info))
    params = ModelParams(**groups, path=str(path), info=info)
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
    if e.recovery_kernel not in RECOVERY_KERNELS:
        raise ConfigError(
            path, "energetics.recovery_kernel", e.recovery_kernel, f"one of {RECOVERY_KERNELS}"
        )
    for kernel in RECOVERY_KERNELS:
        tau_rise, tau_decay = e.kernel_taus(kernel)
        if not 0 < tau_rise < tau_decay:
            raise ConfigError(path, f"energetics.{kernel}_tau_rise", tau_rise,
                              f"need 0 < {kernel}_tau_rise < {kernel}_tau_decay")
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
    lumped = p.lumped
    if lumped.drive_law not in DRIVE_LAWS:
        raise ConfigError(
            path, "recruitment.lumped.drive_law", lumped.drive_law, f"one of {DRIVE_LAWS}"
        )
    if lumped.drive_tau_min <= 0:
        raise ConfigError(
            path, "recruitment.lumped.drive_tau_min", lumped.drive_tau_min, "must be > 0"
        )
    if lumped.relative_fall_power <= 0:
        raise ConfigError(path, "recruitment.lumped.relative_fall_power",
                          lumped.relative_fall_power, "must be > 0")
    if lumped.relative_fall_floor < 0:
        raise ConfigError(path, "recruitment.lumped.relative_fall_floor",
                          lumped.relative_fall_floor, "must be >= 0")
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
    | specific_tension_pa | Pa | this muscle's F0 / PCSA (None: the model's generic value) |
    """

    name: str
    mass_kg: float = holds("kg")
    l0_m: float = holds("m")
    l0t_m: float = holds("m")
    fpcsa_slow: float = holds("1")
    ur: float = holds("1")
    path_length_max_m: float | None = field(default=None, metadata={"unit": "m"})
    lmax: float | None = field(default=None, metadata={"unit": "L0"})
    path_length_min_m: float | None = field(default=None, metadata={"unit": "m"})
    specific_tension_pa: float | None = field(default=None, metadata={"unit": "Pa"})
    source: Mapping = field(default_factory=dict)
    description: str = ""


# A muscle's own specific tension must be in Pa: this band (5-200 N/cm^2) catches N/cm^2 by mistake.
SPECIFIC_TENSION_BAND_PA = (5e4, 2e6)
# The numeric fields of a library entry (unit in the field name, SI or L0; never converted).
_MUSCLE_NUMBERS = tuple(f.name for f in dataclasses.fields(MuscleSpec) if "unit" in f.metadata)
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
            values[key] = finite_number(path, f"{where}.{key}", fields[key])
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
    sigma = values.get("specific_tension_pa")
    if sigma is not None:
        low, high = SPECIFIC_TENSION_BAND_PA
        if not low <= sigma <= high:
            raise ConfigError(path, f"{where}.specific_tension_pa", sigma,
                              f"give Pa in {low:g}-{high:g} (5-200 N/cm^2)")
        if not (source.get("specific_tension_pa") or source.get("all")):
            raise ConfigError(path, f"{where}.source.specific_tension_pa", None,
                              "a muscle's own specific tension needs its source")
    return MuscleSpec(
        name=name, source=dict(source), description=str(fields.get("description", "")), **values
    )


def load_muscle_library(path: str | Path | None = None) -> dict[str, dict]:
    """Read a muscle-library YAML file: ``{name: fields}`` (validated when a bank is built)."""
    path = Path(path) if path is not None else config_dir() / "muscles.yaml"
    data = load_yaml(path)
    muscles = data.get("muscles")
    if not isinstance(muscles, dict) or not muscles:
        raise ConfigError(path, "muscles", muscles, "must be a non-empty mapping of name to fields")
    return muscles


def near_matches(name: str, known) -> str:
    """``"near matches: a, b"`` for a mistyped ``name`` (names containing it, then similar ones),
    or all of ``known`` when there are few."""
    known = sorted(known)
    if len(known) <= 8:
        return f"have: {', '.join(known)}"
    text = str(name).lower()
    near = [k for k in known if text and text in k.lower()]
    near += difflib.get_close_matches(str(name), known, n=5, cutoff=0.6)
    near = list(dict.fromkeys(near))[:5]
    return f"near matches: {', '.join(near)}" if near else "no near match"


def model_rows(params: ModelParams) -> list[tuple[ParamInfo, object]]:
    """Each constant of ``params`` with its current value (SI or normalised), in file order."""
    return [(info, params.value_of(name)) for name, info in params.info.items()]


def muscle_rows(spec: MuscleSpec) -> list[tuple[ParamInfo, object]]:
    """Each numeric field of a muscle with its value (SI or L0) and the source given for it."""
    rows = []
    for f in dataclasses.fields(MuscleSpec):
        value = getattr(spec, f.name)
        if "unit" not in f.metadata or value is None:
            continue
        source = spec.source.get(f.name) or spec.source.get("all", "")
        if not source and f.name == "ur":
            source = "not given for this muscle: the model's generic.ur_default"
        unit = f.metadata["unit"]
        rows.append((ParamInfo(f"muscles.{spec.name}.{f.name}", unit, unit, "", str(source)),
                     value))
    return rows


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
    repeated = next((n for n, k in Counter(names).items() if k > 1), None)
    if repeated is not None:
        raise ConfigError(lib_path, "muscles", repeated,
                          f"listed {names.count(repeated)} times; muscle names must be unique")
    for name in overrides:
        if name not in names:
            raise ConfigError(
                "<overrides>", name, overrides[name], "override for a muscle not in the bank"
            )
    specs = []
    for name in names:
        if name not in entries:
            raise ConfigError(lib_path, f"muscles.{name}", name,
                              f"not in the library ({len(entries)} muscles); "
                              + near_matches(name, entries))
        fields = dict(entries[name] or {})
        extra = overrides.get(name) or {}
        if not isinstance(extra, Mapping):
            raise ConfigError("<overrides>", name, extra, "must be a mapping of fields")
        if "lmax" in extra:
            fields.pop("path_length_max_m", None)
        if "path_length_max_m" in extra:
            fields.pop("lmax", None)
        source = {**(fields.get("source") or {}), **(extra.get("source") or {})}
        fields.update(extra)
        if source:
            fields["source"] = source
        specs.append(
            muscle_from_fields(name, fields, lib_path if not extra else "<overrides>", ur_default)
        )
    return specs
