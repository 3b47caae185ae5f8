"""Error hierarchy of vm_ros: every error a user can cause carries the offending value."""

from __future__ import annotations


class VmRosError(Exception):
    """Base class of every error vm_ros raises on purpose."""


class ConfigError(VmRosError):
    """A configuration file or override is invalid.

    Attributes: ``path`` (file, or ``"<overrides>"``), ``field`` (dotted name), ``value``.
    """

    def __init__(self, path, field: str, value, reason: str):
        self.path = str(path)
        self.field = field
        self.value = value
        self.reason = reason
        super().__init__(f"{self.path}: field '{field}' = {value!r}: {reason}")


class InputError(VmRosError):
    """An input to the model (drive, path length, time step) is unusable; the state is untouched."""

    def __init__(self, name: str, value, reason: str):
        self.name = name
        self.value = value
        self.reason = reason
        super().__init__(f"input '{name}': {reason} (got {value!r})")
