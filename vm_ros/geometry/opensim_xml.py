"""OpenSim's own polynomial paths, read without OpenSim: FunctionBasedPath XML -> MusclePath.

OpenSim 4.6's PolynomialPathFitter writes ``<model>_FunctionBasedPathSet.xml``: one
``FunctionBasedPath`` per path (name ``/forceset/<muscle>``), with ``coordinate_paths`` (the
arguments, in order) and a ``length_function`` holding a ``MultivariatePolynomialFunction``
(``dimension`` k, ``order`` n, ``coefficients``). OpenSim evaluates

    L(q) = sum_t c_t * prod_j q_j ** e_tj        (raw coordinate values: rad, m)

over every exponent tuple e with sum(e) <= n, in the order of OpenSim's
``MultivariatePolynomial::generateCombinations`` (MultivariatePolynomialFunction.cpp): tuples
ascending lexicographically with the first coordinate's exponent the slowest and the last one's
the fastest, i.e. for k = 2, n = 2: (0,0) (0,1) (0,2) (1,0) (1,1) (2,0). The XML's own comment
says "ascending powers starting from the last independent component". Checked numerically
against OpenSim 4.6 (test/test_opensim_xml.py). A vm_ros MusclePath with offset 0, scale 1 and
these exponents is the same polynomial.

Moment arms: vm_ros always uses r = -dL/dq of the length polynomial. If the file also carries
``moment_arm_functions`` (``setIncludeMomentArmFunctions(True)``; OpenSim then uses those for its
moment arms), they are not read; ``FunctionBasedPaths.separate_moment_arms`` names those paths.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ElementTree
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from vm_ros.errors import VmRosError
from vm_ros.geometry.file import content_hash
from vm_ros.geometry.paths import MusclePath, PolynomialGeometry


def opensim_exponents(dimension: int, order: int) -> np.ndarray:
    """Exponent rows of an OpenSim MultivariatePolynomialFunction, in its coefficient order
    (shape (C(dimension + order, order), dimension))."""
    rows: list[tuple[int, ...]] = []

    def extend(prefix: tuple[int, ...], total: int) -> None:
        if len(prefix) == dimension:
            rows.append(prefix)
            return
        for power in range(order - total + 1):
            extend(prefix + (power,), total + power)

    extend((), 0)
    return np.array(rows, dtype=np.int64).reshape(-1, dimension)


@dataclass(frozen=True)
class FunctionBasedPaths:
    """What a FunctionBasedPath file holds: the paths as MusclePaths (file order) and the names
    of those that also carry separately fitted moment-arm functions (not used by vm_ros)."""

    paths: tuple[MusclePath, ...]
    separate_moment_arms: tuple[str, ...]

    @property
    def coordinate_names(self) -> tuple[str, ...]:
        """Every coordinate some path uses, in order of first use."""
        names: dict[str, None] = {}
        for path in self.paths:
            names.update(dict.fromkeys(path.coordinates))
        return tuple(names)


def _text(element, tag: str, where: str) -> str:
    child = element.find(tag)
    if child is None or child.text is None or not child.text.strip():
        raise VmRosError(f"{where}: no <{tag}>")
    return child.text.strip()


def _name(element, parents: dict) -> str:
    """A path's muscle: the last part of its name (``/forceset/rf`` -> ``rf``); a path embedded in
    a model file is named after the force that owns it."""
    name = element.get("name", "")
    if name.startswith("/") or "/" in name:
        return [part for part in name.split("/") if part][-1]
    owner = parents.get(element)
    while owner is not None and owner.get("name") is None:
        owner = parents.get(owner)
    if name in ("", "path") and owner is not None:
        return owner.get("name")
    return name


def _coordinate_name(path: str) -> str:
    parts = [part for part in path.split("/") if part and part != ".."]
    if not parts:
        raise ValueError(f"empty coordinate path {path!r}")
    return parts[-1]


def _root(xml):
    """Parse a file path, or XML text starting with '<'."""
    try:
        if isinstance(xml, str) and xml.lstrip().startswith("<"):
            return ElementTree.fromstring(xml), "<xml>"
        path = Path(xml)
        return ElementTree.parse(path).getroot(), str(path)
    except OSError as exc:
        raise VmRosError(f"{xml}: cannot read ({exc.strerror or exc})") from exc
    except ElementTree.ParseError as exc:
        raise VmRosError(f"{xml}: not valid XML ({exc})") from exc


def parse_function_based_paths(xml, coordinates=None) -> FunctionBasedPaths:
    """Every FunctionBasedPath in an XML file (or text). ``coordinates``: optional names (or
    Coordinate objects) the paths may use; a path naming another coordinate is an error."""
    root, where = _root(xml)
    known = None if coordinates is None else {getattr(c, "name", c) for c in coordinates}
    parents = {child: parent for parent in root.iter() for child in parent}
    paths, separate = [], []
    for element in root.iter("FunctionBasedPath"):
        name = _name(element, parents)
        here = f"{where}: FunctionBasedPath {name!r}"
        coords = tuple(_coordinate_name(p) for p in _text(element, "coordinate_paths",
                                                            here).split())
        function = element.find("length_function")
        if function is None or len(function) == 0:
            raise VmRosError(f"{here}: no <length_function>")
        polynomial = function.find("MultivariatePolynomialFunction")
        if polynomial is None:
            raise VmRosError(f"{here}: length_function is <{function[0].tag}>; only "
                             "MultivariatePolynomialFunction is read")
        try:
            dimension = int(_text(polynomial, "dimension", here))
            order = int(_text(polynomial, "order", here))
            coefficients = np.array([float(v) for v in
                                     _text(polynomial, "coefficients", here).split()])
        except ValueError as exc:
            raise VmRosError(f"{here}: {exc}") from None
        expected = math.comb(dimension + order, order) if dimension >= 1 and order >= 0 else -1
        if dimension != len(coords) or coefficients.shape != (expected,):
            raise VmRosError(f"{here}: dimension {dimension}, order {order} and "
                             f"{len(coords)} coordinates need {expected} coefficients and "
                             f"dimension = {len(coords)}; got {coefficients.size}")
        if known is not None:
            unknown = [c for c in coords if c not in known]
            if unknown:
                raise VmRosError(f"{here}: unknown coordinate(s) {', '.join(unknown)}")
        moment_arms = element.find("moment_arm_functions")
        if moment_arms is not None and len(moment_arms):
            separate.append(name)
        try:
            paths.append(MusclePath(name, coords, (0.0,) * dimension, (1.0,) * dimension,
                                    opensim_exponents(dimension, order), coefficients))
        except ValueError as exc:
            raise VmRosError(f"{here}: {exc}") from None
    if not paths:
        raise VmRosError(f"{where}: no FunctionBasedPath in it")
    names = [p.name for p in paths]
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise VmRosError(f"{where}: paths listed twice: {', '.join(twice)}")
    return FunctionBasedPaths(tuple(paths), tuple(separate))


def read_function_based_paths(xml, coordinates=None) -> list[MusclePath]:
    """The MusclePaths of a FunctionBasedPath file (needs nothing but NumPy); see
    ``parse_function_based_paths``."""
    return list(parse_function_based_paths(xml, coordinates).paths)


def function_based_paths_geometry(xml, coordinates, coupled=(), source=None,
                                  options=None) -> PolynomialGeometry:
    """A PolynomialGeometry from a FunctionBasedPath file: ``coordinates`` (Coordinate objects
    with the valid box) must cover every coordinate the paths use; only those are kept, in the
    given order. ``source`` is merged into the recorded source (file name and sha256 added)."""
    coordinates = list(coordinates)
    parsed = parse_function_based_paths(xml, coordinates)
    used = set(parsed.coordinate_names)
    recorded = {"function_based_paths": Path(xml).name, "function_based_paths_sha256":
                content_hash(xml)} if not str(xml).lstrip().startswith("<") else {}
    if parsed.separate_moment_arms:
        recorded["separate_moment_arm_functions_ignored"] = list(parsed.separate_moment_arms)
    return PolynomialGeometry([c for c in coordinates if c.name in used], parsed.paths,
                              [c for c in coupled if set(c.follows) <= used],
                              source={**(source or {}), **recorded}, options=options)


__all__ = ["FunctionBasedPaths", "function_based_paths_geometry", "opensim_exponents",
           "parse_function_based_paths", "read_function_based_paths"]
