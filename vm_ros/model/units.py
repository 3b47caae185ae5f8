"""Units accepted in configuration files: each unit's quantity and its factor to SI.

A configuration entry writes its unit as text (``unit: ms``). The loader looks the text up in
:data:`UNITS` and multiplies by the unit's ``factor`` to get the value in the unit's ``si`` form;
the field it fills declares which ``si`` form it holds (``tf1`` holds s), so ``ms`` is accepted for
``tf1`` and ``mm`` is not. Text not in the table is an error, never a factor of 1.

VM's normalised units (L0, L0T, F0, f0.5 and their combinations) are units of their own: they are
kept as they are (factor 1) and never mixed with m, N or pulses/s. ``"1"`` is a pure number,
``"bool"`` a flag and ``"-"`` a name chosen from a list (no unit).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from vm_ros.errors import ConfigError


@dataclass(frozen=True)
class Unit:
    """A unit as written in a file: ``value_si = value * factor``, in the unit ``si``."""

    symbol: str
    si: str
    factor: float
    quantity: str


_TABLE = (
    # quantity in SI
    Unit("s", "s", 1.0, "time"),
    Unit("ms", "s", 1e-3, "time"),
    Unit("1/s", "1/s", 1.0, "rate"),
    Unit("Hz", "1/s", 1.0, "rate"),
    Unit("pulses/s", "1/s", 1.0, "rate"),
    Unit("m", "m", 1.0, "length"),
    Unit("cm", "m", 1e-2, "length"),
    Unit("mm", "m", 1e-3, "length"),
    Unit("kg", "kg", 1.0, "mass"),
    Unit("g", "kg", 1e-3, "mass"),
    Unit("rad", "rad", 1.0, "angle"),
    Unit("deg", "rad", math.pi / 180.0, "angle"),
    Unit("Pa", "Pa", 1.0, "stress"),
    Unit("N/m^2", "Pa", 1.0, "stress"),
    Unit("kPa", "Pa", 1e3, "stress"),
    Unit("N/cm^2", "Pa", 1e4, "stress"),
    Unit("kg/m^3", "kg/m^3", 1.0, "density"),
    Unit("g/cm^3", "kg/m^3", 1e3, "density"),
    Unit("J/(kg K)", "J/(kg K)", 1.0, "specific heat capacity"),
    Unit("kJ/(kg K)", "J/(kg K)", 1e3, "specific heat capacity"),
    # Barclay 1996 energy-rate coefficients: W per kg of dry muscle, velocity in L0/s
    Unit("W/kg", "W/kg", 1.0, "power per mass"),
    Unit("W s/(kg L0)", "W s/(kg L0)", 1.0, "power per mass per velocity (L0/s)"),
    Unit("W L0/(kg s)", "W L0/(kg s)", 1.0, "power per mass times velocity (L0/s)"),
    # VM's normalised units
    Unit("L0", "L0", 1.0, "length in optimal fascicle lengths"),
    Unit("1/L0", "1/L0", 1.0, "inverse length in optimal fascicle lengths"),
    Unit("L0T", "L0T", 1.0, "length in tendon lengths at F0"),
    Unit("L0/s", "L0/s", 1.0, "velocity in optimal fascicle lengths per second"),
    Unit("F0", "F0", 1.0, "force in maximal isometric forces"),
    Unit("F0/L0T", "F0/L0T", 1.0, "stiffness in F0 per tendon length at F0"),
    Unit("F0 s/L0", "F0 s/L0", 1.0, "viscosity in F0 per L0/s"),
    Unit("f0.5", "f0.5", 1.0, "firing rate in f0.5"),
    # no unit
    Unit("1", "1", 1.0, "pure number"),
    Unit("bool", "bool", 1.0, "flag (true or false)"),
    Unit("-", "-", 1.0, "name from a list"),
)

#: Every accepted unit, by the text written in a file.
UNITS: dict[str, Unit] = {unit.symbol: unit for unit in _TABLE}


def units_for(si: str) -> list[str]:
    """The accepted units of the quantity held in ``si`` (e.g. ``"s"`` -> ``["s", "ms"]``)."""
    return [unit.symbol for unit in _TABLE if unit.si == si]


def unit_for_field(path, field: str, written, si: str) -> Unit:
    """The unit ``written`` for a field that holds ``si``; a ConfigError naming file, field, unit
    when ``written`` is not in :data:`UNITS` or measures another quantity."""
    if si not in UNITS:
        raise ValueError(f"field {field} declares {si!r}, which is not in the unit table")
    accepted = ", ".join(units_for(si))
    quantity = UNITS[si].quantity
    unit = UNITS.get(written) if isinstance(written, str) else None
    if unit is None:
        raise ConfigError(path, field, written,
                          f"not an accepted unit; this field is a {quantity}: use {accepted}")
    if unit.si != si:
        raise ConfigError(path, field, written,
                          f"'{written}' is a {unit.quantity} ({unit.si}) but this field is a "
                          f"{quantity} ({si}): use {accepted}")
    return unit
