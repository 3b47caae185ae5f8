"""The geometry file: joint coordinates, fitted muscle paths and how they were made (YAML).

Format ``vm_ros.geometry``, version 1 (documented in docs/geometry.md)::

    format: vm_ros.geometry
    version: 1
    source: {model: NAME, file: FILE, sha256: HEX, importer: ..., ...}   # free-form, recorded
    options: {degree: 6, ...}                                             # importer options
    coordinates:                                   # the independent inputs, in this order
      - {name: knee_angle_r, unit: rad, lower: -2.0944, upper: 0.1745}
    coupled_coordinates:                           # dependent coordinates: not inputs
      - {name: patella_angle, follows: [knee_angle_r], note: CoordinateCouplerConstraint ...,
         unit: rad, follows_values: [...], values: [...]}   # coupling table (optional)
    muscles:
      - name: vasti_r
        coordinates: [knee_angle_r]
        basis: monomial
        offset: [-0.9599]                          # x_j = (q_j - offset_j) / scale_j
        scale: [1.1344]
        exponents: [[0], [1], [2], ...]            # one row per term
        coefficients: [0.2312, -0.0123, ...]       # m
        fit: {length_rms_m: ..., length_max_m: ..., moment_arm_rms_m: ..., moment_arm_max_m:
              ..., poses_fit: N, poses_held_out: N, flags: [...]}

Floats are written with Python's shortest round-trip repr, so write -> read gives back the same
numbers bit for bit. Reading parses the YAML once per content: the parsed data are kept as JSON in
``parsed_cache_dir()``, named by the text's sha256 (and PyYAML's version), and read from there
when the same text comes again (myolegs' 420 kB file: YAML about 0.25 s, JSON about 6 ms; the
YAML's numbers, 51,000 scalars, go through PyYAML's Python resolver and constructor one by one).
JSON holds the same values (floats by their shortest repr); data JSON cannot give back equal
(non-string keys, dates, NaN) are not cached, and a cache that cannot be read or written is
passed over. Every problem reading a file is a ConfigError naming the file and field;
a file whose paths break the rules of vm_ros.geometry.checks over the coordinate box (a path
shorter than 1 mm or not finite at some pose, an absurd coefficient) is refused naming the muscle
and the pose.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import tempfile
from collections.abc import Mapping
from pathlib import Path

import numpy as np
import yaml

from vm_ros.errors import ConfigError
from vm_ros.geometry.checks import path_problem
from vm_ros.geometry.paths import (
    Coordinate,
    CoupledCoordinate,
    FitReport,
    MusclePath,
    PolynomialGeometry,
)
from vm_ros.resources import cache_home

FORMAT = "vm_ros.geometry"
VERSION = 1
MAX_EXPONENT = 20   # per coordinate; fitted paths use at most 6-8 (a larger one is a broken file)
_FIT_FIELDS = ("length_rms_m", "length_max_m", "moment_arm_rms_m", "moment_arm_max_m",
               "poses_fit", "poses_held_out")


def content_hash(path) -> str:
    """sha256 of a file's bytes (the source model's hash recorded in the geometry file)."""
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def geometry_to_dict(geometry: PolynomialGeometry) -> dict:
    """The file's content as plain Python data (lists, floats, ints, strings)."""
    muscles = []
    for m in geometry.muscles:
        entry = {"name": m.name, "coordinates": list(m.coordinates), "basis": m.basis,
                 "offset": [float(v) for v in m.offset], "scale": [float(v) for v in m.scale],
                 "exponents": m.exponents.tolist(),
                 "coefficients": [float(v) for v in m.coefficients]}
        if m.fit is not None:
            entry["fit"] = {**{k: plain_data(getattr(m.fit, k)) for k in _FIT_FIELDS},
                            "flags": list(m.fit.flags)}
        muscles.append(entry)
    return {
        "format": FORMAT, "version": VERSION,
        "source": plain_data(geometry.source), "options": plain_data(geometry.options),
        "coordinates": [{"name": c.name, "unit": c.unit, "lower": float(c.lower),
                         "upper": float(c.upper)} for c in geometry.coordinates],
        "coupled_coordinates": [_coupled_entry(c) for c in geometry.coupled],
        "muscles": muscles,
    }


def dumps(geometry: PolynomialGeometry) -> str:
    """YAML text of a geometry (leaf lists in flow style)."""
    return yaml.safe_dump(geometry_to_dict(geometry), sort_keys=False, default_flow_style=None,
                          width=100)


def write_geometry(geometry: PolynomialGeometry, path) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(dumps(geometry))
    return path


def load_geometry(path, backend: str = "auto") -> PolynomialGeometry:
    """Read a geometry file; ConfigError (file, field, value, reason) on any problem."""
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as exc:
        raise ConfigError(path, "-", None, f"cannot read the geometry file: "
                          f"{exc.strerror or exc}") from exc
    return loads(text, path, backend=backend)


def loads(text: str, path="<geometry>", backend: str = "auto") -> PolynomialGeometry:
    return geometry_from_dict(parsed(text, path), path, backend=backend)


def parsed_cache_dir() -> Path:
    """Where parsed geometry files are kept (module docstring)."""
    return cache_home() / "geometry-parsed"


def parsed(text: str, path="<geometry>"):
    """The YAML data of ``text`` (a safe load), from the cache of parsed files when it holds
    this text (module docstring); ConfigError when it is not YAML."""
    entry = parsed_cache_dir() / (f"{hashlib.sha256(text.encode()).hexdigest()}"
                                  f"-pyyaml{yaml.__version__}.json")
    try:
        return json.loads(entry.read_text())
    except (OSError, ValueError):
        pass
    try:
        data = yaml.load(text, Loader=getattr(yaml, "CSafeLoader", yaml.SafeLoader))
    except yaml.YAMLError as exc:
        raise ConfigError(path, "-", None, f"not valid YAML: {exc}".splitlines()[0]) from exc
    _keep(entry, data)
    return data


def _keep(entry: Path, data) -> None:
    """Write ``data`` as JSON to ``entry`` (whole or not at all) if JSON gives it back equal."""
    try:
        encoded = json.dumps(data, separators=(",", ":"))
    except (TypeError, ValueError):  # a date, a set: not JSON
        return
    if json.loads(encoded) != data:  # a non-string key, NaN (not equal to itself)
        return
    part = None
    try:
        entry.parent.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile("w", dir=entry.parent, suffix=".part",
                                         delete=False) as file:
            part = file.name
            file.write(encoded)
        os.replace(part, entry)
    except OSError:
        if part is not None:
            with contextlib.suppress(OSError):
                os.unlink(part)


def geometry_from_dict(data, path="<geometry>", backend: str = "auto") -> PolynomialGeometry:
    if not isinstance(data, dict):
        raise ConfigError(path, "-", type(data).__name__, "not a vm_ros geometry file (a YAML "
                          f"mapping with format: {FORMAT}; make one with vm-ros import-osim or "
                          "import-mjcf)")
    if data.get("format") != FORMAT:
        raise ConfigError(path, "format", data.get("format"), f"expected {FORMAT!r}")
    if data.get("version") != VERSION:
        raise ConfigError(path, "version", data.get("version"),
                          f"this vm_ros reads version {VERSION}")
    coordinates = [_item(path, f"coordinates[{i}]", lambda e: Coordinate(
        str(e["name"]), str(e["unit"]), float(e["lower"]), float(e["upper"])), entry)
        for i, entry in enumerate(_list(path, data, "coordinates"))]
    coupled = [_item(path, f"coupled_coordinates[{i}]", _coupled, entry)
               for i, entry in enumerate(data.get("coupled_coordinates") or [])]
    muscles = [_item(path, f"muscles[{i}]", _muscle, entry)
               for i, entry in enumerate(_list(path, data, "muscles"))]
    if not muscles:
        raise ConfigError(path, "muscles", [], "no muscles")
    for key in ("source", "options"):
        if not isinstance(data.get(key) or {}, dict):
            raise ConfigError(path, key, type(data[key]).__name__, "must be a mapping")
    try:
        geometry = PolynomialGeometry(coordinates, muscles, coupled, source=data.get("source"),
                                      options=data.get("options"), backend=backend)
    except (ValueError, TypeError) as exc:
        raise ConfigError(path, "muscles", None, str(exc)) from exc
    problem = path_problem(geometry)
    if problem is not None:
        i, reason = problem
        raise ConfigError(path, f"muscles[{i}]", geometry.muscle_names[i], reason)
    return geometry


_COUPLING_KEYS = ("unit", "follows_values", "values")   # the coupling table, when stored


def _coupled_entry(c: CoupledCoordinate) -> dict:
    entry = {"name": c.name, "follows": list(c.follows), "note": c.note}
    if c.has_function:
        entry.update({k: plain_data(getattr(c, k)) for k in _COUPLING_KEYS})
    return entry


def _coupled(entry: dict) -> CoupledCoordinate:
    table = {k: entry.get(k) for k in _COUPLING_KEYS}
    if table["unit"] is not None:
        table["unit"] = str(table["unit"])
    return CoupledCoordinate(str(entry["name"]), tuple(str(n) for n in entry.get("follows", ())),
                             str(entry.get("note", "")), **table)


def _muscle(entry: dict) -> MusclePath:
    fit = entry.get("fit")
    report = None if fit is None else FitReport(
        **{k: (int(fit[k]) if k.startswith("poses") else float(fit[k])) for k in _FIT_FIELDS},
        flags=tuple(str(f) for f in fit.get("flags", ())))
    basis = str(entry.get("basis", "monomial"))
    if basis != "monomial":
        raise ValueError(f"basis {basis!r}: this vm_ros reads 'monomial'")
    coords = tuple(str(c) for c in entry["coordinates"])
    rows = entry["exponents"]
    if not (isinstance(rows, list) and all(
            isinstance(row, list) and len(row) == len(coords) and all(
                isinstance(e, int) and not isinstance(e, bool) and 0 <= e <= MAX_EXPONENT
                for e in row) for row in rows)):
        raise ValueError(f"exponents must be a list of rows of {len(coords)} integers "
                         f"0-{MAX_EXPONENT} (one per coordinate of the muscle)")
    return MusclePath(str(entry["name"]), coords,
                      tuple(float(v) for v in entry.get("offset", [0.0] * len(coords))),
                      tuple(float(v) for v in entry.get("scale", [1.0] * len(coords))),
                      np.array(rows, dtype=np.int64).reshape(-1, len(coords)),
                      np.array(entry["coefficients"], dtype=float), report, basis)


def _list(path, data: dict, key: str) -> list:
    value = data.get(key)
    if not isinstance(value, list):
        raise ConfigError(path, key, value, "must be a list")
    return value


def _item(path, field: str, make, entry):
    try:
        return make(entry)
    except KeyError as exc:
        raise ConfigError(path, field, None, f"missing key {exc.args[0]!r}") from exc
    except (TypeError, ValueError, AttributeError, OverflowError) as exc:
        raise ConfigError(path, field, _short(entry), str(exc)) from exc


def _short(entry):
    if isinstance(entry, dict):
        return entry.get("name", "<mapping>")
    return entry


def plain_data(value):
    """Mappings, sequences, arrays and numpy scalars as plain JSON/YAML-safe Python values
    (mapping keys as strings); used for the geometry file and the run logs' records."""
    if isinstance(value, Mapping):
        return {str(k): plain_data(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [plain_data(v) for v in value]
    if isinstance(value, np.ndarray):
        return plain_data(value.tolist())
    if isinstance(value, np.generic):
        return value.item()
    return value


__all__ = ["FORMAT", "VERSION", "content_hash", "dumps", "geometry_from_dict", "plain_data",
           "geometry_to_dict", "load_geometry", "loads", "parsed", "parsed_cache_dir",
           "write_geometry"]
