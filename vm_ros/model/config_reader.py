"""The reader of vm_ros's constant files (config/model.yaml, config/energetics_models.yaml):
each constant an entry {value (or one value per fibre type), unit, tag, source}, read into the
fields of a frozen dataclass, each field declaring the unit it holds (``holds``); the unit written
in the file must be one of vm_ros.model.units.UNITS for the same quantity and is converted once.

    data = load_yaml(path)
    values = read_section(SomeConstants, path, yaml_section(path, data, "section.name"),
                          "section.name", info)     # info: {dotted name: ParamInfo}
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml

from vm_ros.errors import ConfigError
from vm_ros.model.units import unit_for_field

FIBRE_TYPES = ("slow", "fast")
TAGS = ("C", "L", "R")


def holds(unit: str):
    """A dataclass field whose value is in ``unit`` (a key of vm_ros.model.units.UNITS); the
    loader accepts any unit of the same quantity in the file and converts it."""
    return field(metadata={"unit": unit})


@dataclass(frozen=True)
class ParamInfo:
    """Where a model constant comes from, as written in its file.

    ``name`` is dotted (``fibre_type_parameters.tf1``); ``unit`` is the unit written in the file
    (``ms``); ``si`` the unit of the loaded value (``s``); ``tag`` C, L or R; ``source`` the
    citation.
    """

    name: str
    unit: str
    si: str
    tag: str
    source: str


def load_yaml(path: Path) -> dict:
    try:
        with open(path, encoding="utf-8") as handle:
            # libyaml's parser where PyYAML has it (the same safe constructor and resolver:
            # the same values), as vm_ros.geometry.file reads geometry files: an imported
            # library of 80 muscles took longer to parse in Python than to simulate 10 s
            data = yaml.load(handle, Loader=getattr(yaml, "CSafeLoader", yaml.SafeLoader))
    except OSError as exc:
        raise ConfigError(path, "<file>", None, f"cannot read: {exc.strerror}") from exc
    except yaml.YAMLError as exc:
        raise ConfigError(path, "<file>", None, f"not valid YAML: {exc}") from exc
    if not isinstance(data, dict):
        raise ConfigError(path, "<file>", type(data).__name__, "top level must be a mapping")
    return data


def finite_number(path, name: str, value) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ConfigError(path, name, value, "must be a finite number")
    return float(value)


def yaml_section(path, data: dict, dotted: str) -> dict:
    """The mapping at ``dotted`` (``"recruitment.lumped"``) in ``data``."""
    section, parts = data, dotted.split(".")
    for depth in range(len(parts)):
        section = section.get(parts[depth])
        if not isinstance(section, dict):
            where = ".".join(parts[: depth + 1])
            raise ConfigError(path, where, section, "missing or not a mapping")
    return section


def _read_value(path, name: str, kind: str, entry: dict, factor: float):
    """One entry's value, by the kind of the field it fills (its annotation)."""
    if kind == "np.ndarray":  # one value per fibre type
        return np.array([finite_number(path, f"{name}.{t}", entry.get(t)) for t in FIBRE_TYPES]
                        ) * factor
    value = entry.get("value")
    if kind == "float":
        return finite_number(path, f"{name}.value", value) * factor
    if kind == "tuple":  # polynomial coefficients
        if not isinstance(value, list) or not value:
            raise ConfigError(path, f"{name}.value", value, "must be a non-empty list of numbers")
        return tuple(finite_number(path, f"{name}.value", v) * factor for v in value)
    if kind == "bool":
        if not isinstance(value, bool):
            raise ConfigError(path, f"{name}.value", value, "must be true or false")
        return value
    if kind == "str":
        if not isinstance(value, str):
            raise ConfigError(path, f"{name}.value", value, "must be a name (text)")
        return value
    raise TypeError(f"{name}: no reader for fields of type {kind}")


# Parameters a model file held before the model's equations changed: a file with one of them (a
# log's attached model.yaml from an earlier version) was written for other equations, so it is
# refused with why, not read with the new ones
RETIRED = {
    "recruitment.lumped.relative_rise_power": (
        "a parameter of the drive filter before it kept a filtered drive per fibre type "
        "(removed 2026-12-03, docs/model.md section 5d): this model file, or the log it is "
        "attached to, was written by an earlier vm_ros whose equations this version does not "
        "have; recompute such a log with the vm_ros version in its metadata"),
}


def read_section(cls, path, section: dict, section_name: str, info: dict) -> dict:
    """The fields of ``cls`` from one section of a model file, converted to the unit each field
    holds; each entry's unit, tag and source go into ``info``."""
    fields = {f.name: f for f in dataclasses.fields(cls)}
    unknown = sorted(set(section) - set(fields))
    for name in unknown:
        if f"{section_name}.{name}" in RETIRED:
            raise ConfigError(path, f"{section_name}.{name}", None,
                              RETIRED[f"{section_name}.{name}"])
    if unknown:
        raise ConfigError(path, f"{section_name}.{unknown[0]}", None, "unknown parameter")
    missing = sorted(set(fields) - set(section))
    if missing:
        raise ConfigError(path, f"{section_name}.{missing[0]}", None, "missing")
    values = {}
    for name, f in fields.items():
        where, entry = f"{section_name}.{name}", section[name]
        keys = {*FIBRE_TYPES} if f.type == "np.ndarray" else {"value"}
        if not isinstance(entry, dict):
            raise ConfigError(path, where, entry,
                              f"must be a mapping with {'/'.join(sorted(keys))}/unit/tag/source")
        for key in ("unit", "tag", "source"):
            if key not in entry:
                raise ConfigError(path, f"{where}.{key}", None, "missing")
        extra = sorted(set(entry) - keys - {"unit", "tag", "source"})
        if extra:
            raise ConfigError(path, f"{where}.{extra[0]}", entry[extra[0]],
                              f"unknown key (an entry has {', '.join(sorted(keys))}, unit, tag, "
                              f"source)")
        if entry["tag"] not in TAGS:
            raise ConfigError(path, f"{where}.tag", entry["tag"], f"must be one of {TAGS}")
        if not isinstance(entry["source"], str) or not entry["source"].strip():
            raise ConfigError(path, f"{where}.source", entry["source"], "must be a citation")
        unit = unit_for_field(path, f"{where}.unit", entry["unit"], f.metadata["unit"])
        values[name] = _read_value(path, where, f.type, entry, unit.factor)
        info[where] = ParamInfo(where, unit.symbol, unit.si, entry["tag"], entry["source"])
    return values


__all__ = ["FIBRE_TYPES", "TAGS", "ParamInfo", "finite_number", "holds", "load_yaml",
           "read_section", "yaml_section"]
