"""Error hierarchy of vm_ros: every error a user can cause carries the offending value."""

from __future__ import annotations

import numpy as np

ITEMS_SHOWN = 4  # items of a long list or dict that an error message quotes


def plain_value(value) -> str:
    """A value as a short, plain literal: numbers as numbers (not np.float64(...)), long lists
    by their first items and length, long text cut."""
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, np.ndarray):
        value = value.tolist()
    if isinstance(value, (list, tuple)):
        shown = ", ".join(plain_value(v) for v in value[:ITEMS_SHOWN])
        more = f", ... ({len(value)} items)" if len(value) > ITEMS_SHOWN else ""
        return f"[{shown}{more}]"
    if isinstance(value, dict):
        items = list(value.items())
        shown = ", ".join(f"{plain_value(k)}: {plain_value(v)}" for k, v in items[:ITEMS_SHOWN])
        more = f", ... ({len(items)} items)" if len(items) > ITEMS_SHOWN else ""
        return f"{{{shown}{more}}}"
    if isinstance(value, float):
        return repr(value)
    text = repr(value)
    return text if len(text) <= 120 else f"{text[:100]}... ({len(text)} chars)"


class VmRosError(Exception):
    """Base class of every error vm_ros raises on purpose."""


FILE_FIELDS = ("-", "<file>")  # ConfigError.field of an error about the file as a whole


class ConfigError(VmRosError):
    """A configuration file or override is invalid.

    Attributes: ``path`` (file, or ``"<overrides>"``), ``field`` (dotted name; ``"-"`` or
    ``"<file>"``: the file as a whole, and the message names no field), ``value``.
    """

    def __init__(self, path, field: str, value, reason: str):
        self.path = str(path)
        self.field = field
        self.value = value
        self.reason = reason
        where = "" if field in FILE_FIELDS else f" field '{field}' = {plain_value(value)}:"
        super().__init__(f"{self.path}:{where} {reason}")


class InputError(VmRosError):
    """An input to the model (drive, path length, time step) is unusable; the state is untouched."""

    def __init__(self, name: str, value, reason: str):
        self.name = name
        self.value = value
        self.reason = reason
        super().__init__(f"input '{name}': {reason} (got {plain_value(value)})")
