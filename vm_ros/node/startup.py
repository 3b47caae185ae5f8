"""muscle_node's start-up without ROS: parameter values -> the model it runs, and the one line a
start-up error prints.

The node (vm_ros.node.shell) declares its parameters, hands their values to
:func:`build_model`, and prints :func:`error_line` of any VmRosError with exit status 2. A test
can take the same path without rclpy through :func:`check_parameters`.

Every error names a node parameter and its value: an error inside the library, model or
geometry file is reported against the parameter that named the file (an unknown muscle against
``muscles``, an unknown override field against ``overrides``).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from vm_ros.errors import FILE_FIELDS, ConfigError, plain_value
from vm_ros.joint_space import JointSpace
from vm_ros.model import MuscleBank
from vm_ros.model.run_config import RunConfig
from vm_ros.node.inputs import InputLimits
from vm_ros.node.params import PARAMS_SOURCE, NodeConfig

EXIT_BAD_PARAMETER = 2  # exit status of a start-up error (argparse's for a usage error)
LINE_MAX_CHARS = 600  # longest start-up error line (a value or reason is shortened to fit)


@dataclass(frozen=True)
class NodeModel:
    """What the node runs, built from validated parameters."""

    config: NodeConfig
    run_config: RunConfig
    bank: MuscleBank
    joint_space: JointSpace | None
    limits: InputLimits
    initial_path_length_m: np.ndarray | None  # None: wait for muscle_kinematics


def check_parameters(values: Mapping[str, object]) -> NodeModel:
    """Parameter values by name (as rclpy delivers them) -> the node's model; ConfigError
    naming the parameter otherwise."""
    return build_model(NodeConfig.from_values(values))


def build_model(config: NodeConfig) -> NodeModel:
    """The bank, joint space and input limits of ``config``; ConfigError naming the node
    parameter (module docstring)."""
    c = config
    run_config = RunConfig(
        tuple(c.muscles), recruitment=c.recruitment, recovery_mode=c.recovery_mode,
        drive_law=c.drive_law or None, energetics_models=c.energetics_model_names(),
        overrides=c.overrides_mapping(), library=Path(c.library) if c.library else None,
        params=Path(c.model) if c.model else None, units_per_type=c.units_per_type or None,
        geometry=Path(c.geometry) if c.geometry else None, joint_map=c.joint_map,
        joints=tuple(c.joints))
    try:
        bank = run_config.make_bank()
    except ConfigError as exc:
        raise _against_parameter(exc, c, run_config) from exc
    try:
        joint_space = (JointSpace.load(c.geometry, c.joint_map, bank.names, c.joints,
                                       PARAMS_SOURCE) if c.geometry else None)
    except ConfigError as exc:
        inner = exc.__cause__
        if exc.field != "geometry" or not isinstance(inner, ConfigError):
            raise
        field = "" if inner.field in FILE_FIELDS else f"field '{inner.field}': "
        raise ConfigError(PARAMS_SOURCE, "geometry", c.geometry,
                          f"{field}{inner.reason}") from exc
    driven = joint_space.driven if joint_space is not None else ()
    limits = InputLimits.for_bank(bank, c)
    initial = np.array(c.initial_path_length_m) if c.initial_path_length_m else None
    used = ~np.isin(bank.names, driven)  # joint-driven muscles wait for joint_states
    if initial is not None:
        bad = used & ((initial < limits.path_length_min_m) | (initial > limits.path_length_max_m))
        if np.any(bad):
            i = int(np.argmax(bad))
            raise ConfigError(
                PARAMS_SOURCE, "initial_path_length_m", [float(x) for x in initial],
                f"{bank.names[i]}: {float(initial[i]):g} m outside its physical range "
                f"{float(limits.path_length_min_m[i]):.4g} .. "
                f"{float(limits.path_length_max_m[i]):.4g} m")
    return NodeModel(c, run_config, bank, joint_space, limits, initial)


def _against_parameter(exc: ConfigError, c: NodeConfig, run_config: RunConfig) -> ConfigError:
    """A bank-building error restated against the node parameter that caused it."""
    parts = exc.field.split(".")
    if exc.path == "<overrides>":
        return ConfigError(PARAMS_SOURCE, "overrides", c.overrides,
                           f"{exc.field}: {exc.reason}")
    if parts[0] == "muscles" and len(parts) == 2 and parts[1] in c.muscles:
        return ConfigError(PARAMS_SOURCE, "muscles", parts[1], f"{exc.reason} ({exc.path})")
    if exc.path == str(run_config.library_path):
        name, value = "library", c.library
    elif exc.path == str(run_config.params_path):
        name, value = "model", c.model
    else:
        return exc
    field = "" if exc.field in FILE_FIELDS else f"field '{exc.field}': "
    return ConfigError(PARAMS_SOURCE, name, value or str(exc.path), f"{field}{exc.reason}")


# --- the error line ------------------------------------------------------------------------------


def error_line(program: str, exc: BaseException) -> str:
    """The single stderr line of a start-up error: ``program: error: ...`` naming the parameter
    (or file field) and its value, newlines folded, at most LINE_MAX_CHARS characters."""
    if isinstance(exc, ConfigError):
        where = "parameter" if exc.path == PARAMS_SOURCE else f"{exc.path}: field"
        value = "" if exc.value is None else f" = {plain_value(exc.value)}"
        text = f"{where} '{exc.field}'{value}: {exc.reason}"
    else:
        text = str(exc)
    text = " ".join(f"{program}: error: {text}".split())
    if len(text) > LINE_MAX_CHARS:
        text = text[: LINE_MAX_CHARS - 20] + f"... ({len(text)} chars)"
    return text


__all__ = ["EXIT_BAD_PARAMETER", "NodeModel", "build_model", "check_parameters", "error_line"]
