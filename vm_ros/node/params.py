"""muscle_node's ROS parameters: one table, validated in one place (no rclpy here).

The node declares every entry of :data:`PARAMS` up front (vm_ros.node turns each into a
ParameterDescriptor) and hands the values to :meth:`NodeConfig.from_values`, which checks types,
ranges, choices and the cross-field rules and raises ConfigError naming the parameter. The
README's parameter table is this table.

Parameters marked ``runtime`` may be changed while the node runs (``ros2 param set``); they only
affect how inputs are conditioned. Everything else is read-only: changing the muscles, rates or
model while the model runs would need a new model.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Mapping
from dataclasses import dataclass

import yaml

from vm_ros.errors import ConfigError, InputError, VmRosError
from vm_ros.model.params import DRIVE_LAWS, RECOVERY_MODES, SCHEMES

PARAMS_SOURCE = "<parameters>"  # ConfigError.path for a bad parameter value

# Stale-input policies (input_timeout_s exceeded, or the input never arrived):
#   hold        keep the last drive (0 until the first excitation arrives)
#   zero_drive  drive 0 for every muscle while excitation is stale (muscles relax)
#   pause       the model does not advance while excitation or kinematics is stale; model time
#               resumes from where it stopped (no catch-up), the paused time is counted
STALE_POLICIES = ("hold", "zero_drive", "pause")
EXECUTORS = ("events", "single_threaded")

KIND_TYPES = {
    "bool": (bool,),
    "integer": (int,),
    "double": (int, float),  # a params file may write 1000 for 1000.0
    "string": (str,),
    "string_array": (list, tuple),
    "double_array": (list, tuple),
}


@dataclass(frozen=True)
class ParamSpec:
    """One parameter: name, default, kind (a key of KIND_TYPES), unit, description, limits."""

    name: str
    default: object
    kind: str
    unit: str
    description: str
    low: float | None = None  # inclusive
    high: float | None = None  # inclusive
    choices: tuple = ()
    runtime: bool = False  # may change while running (else read-only)

    @property
    def field(self) -> str:
        """The NodeConfig attribute name (dots of namespaced parameters become underscores)."""
        return self.name.replace(".", "_")

    def describe(self) -> str:
        unit = f" [{self.unit}]" if self.unit and self.unit != "-" else ""
        choices = f" One of: {', '.join(self.choices)}." if self.choices else ""
        return f"{self.description}{unit}.{choices}"

    def limits_text(self) -> str:
        if self.low is None and self.high is None:
            return ""
        low = "-inf" if self.low is None else f"{self.low:g}"
        high = "inf" if self.high is None else f"{self.high:g}"
        return f"[{low}, {high}]"


PARAMS = (
    ParamSpec("muscles", ["rectus_femoris", "vasti"], "string_array", "-",
              "Muscle names from the library, in the order used by excitation_array, "
              "energy_rate and muscle_force"),
    ParamSpec("library", "", "string", "path",
              "Muscle-library YAML file ('' = the shipped config/muscles.yaml)"),
    ParamSpec("model", "", "string", "path",
              "Model-parameter YAML file ('' = the shipped config/model.yaml)"),
    ParamSpec("overrides", "", "string", "YAML",
              "Per-muscle field overrides as a YAML mapping, e.g. "
              "'{vasti: {fpcsa_slow: 0.5}}' ('' = none)"),
    ParamSpec("recruitment", "lumped", "string", "-",
              "Motor-unit recruitment scheme: lumped (Tsianos 2012), natural (discrete units), "
              "continuous (Song 2008)", choices=tuple(SCHEMES)),
    ParamSpec("units_per_type", 0, "integer", "units",
              "Natural motor units per fibre type (natural recruitment only; 0 = model file value)",
              low=0, high=1000),
    ParamSpec("recovery_mode", "static", "string", "-",
              "Recovery heat: static (R x initial) or dynamic (filtered, Tsianos 2012 App. B)",
              choices=tuple(RECOVERY_MODES)),
    ParamSpec("drive_law", "", "string", "-",
              "Drive filter of lumped units ('' = the model file's): relative_drive (follows "
              "natural units through steps) or tsianos2012 (the paper's law, as reconstructed)",
              choices=("", *DRIVE_LAWS)),
    ParamSpec("energetics_models", [], "string_array", "-",
              "Published energetics models computed beside Tsianos 2012 on the same state and "
              "published on energy_rate_models (names from vm_ros.model.energetics_models, or "
              "[all]; [] = none)"),
    ParamSpec("model_rate_hz", 1000.0, "double", "Hz",
              "Model step rate; the model advances in fixed steps of 1/model_rate_hz by elapsed "
              "ROS time", low=10.0, high=20000.0),
    ParamSpec("publish_rate_hz", 100.0, "double", "Hz",
              "Output rate of muscle_force and the energy topics (published every "
              "round(model_rate_hz/publish_rate_hz) model steps)", low=0.1, high=20000.0),
    ParamSpec("batch_steps", 0, "integer", "steps",
              "Model steps per timer tick, run in one MuscleBank.run with each step's inputs "
              "sampled at its own time (0 = one publish period, round(model_rate_hz / "
              "publish_rate_hz); 1 = a tick per step); at most max_catch_up_steps",
              low=0, high=100000),
    ParamSpec("max_catch_up_steps", 50, "integer", "steps",
              "Most model steps run in one timer tick after a stall; time beyond is skipped "
              "and counted", low=1, high=100000),
    ParamSpec("initial_path_length_m", [], "double_array", "m",
              "Path length per muscle to start from ([] = wait for the first muscle_kinematics "
              "message covering every muscle)"),
    ParamSpec("input_timeout_s", 0.5, "double", "s",
              "Age of an input (ROS time since it arrived) after which it counts as stale",
              low=1e-3, high=1e6, runtime=True),
    ParamSpec("stale_input_policy", "zero_drive", "string", "-",
              "What a stale or missing input does: hold (keep the last drive), zero_drive "
              "(drive 0 while excitation is stale), pause (no model steps while any input is "
              "stale)", choices=STALE_POLICIES, runtime=True),
    ParamSpec("extrapolation_max_s", 0.05, "double", "s",
              "Longest time a kinematics sample is extrapolated with its velocity; the length "
              "is held after that", low=0.0, high=10.0, runtime=True),
    ParamSpec("path_length_margin_l0", 0.5, "double", "L0",
              "Margin around each muscle's anatomical path-length range (library "
              "path_length_min_m/path_length_max_m) outside which lengths are rejected",
              low=0.0, high=100.0, runtime=True),
    ParamSpec("path_speed_max_m_per_s", 10.0, "double", "m/s",
              "Path velocities of larger magnitude are rejected as non-physical",
              low=1e-3, high=1e3, runtime=True),
    ParamSpec("geometry", "", "string", "path",
              "Geometry file (vm_ros.geometry YAML): node muscles it covers are driven from "
              "joint_states, and joint_efforts/joint_effort_commands are published ('' = none: "
              "muscle space only)"),
    ParamSpec("joint_map", "", "string", "YAML",
              "Robot joints -> geometry coordinates, e.g. '{knee: knee_angle_r, hip: "
              "{coordinate: hip_flexion_r, sign: -1, offset: 0.1}}': model q = sign * robot q + "
              "offset (rad or m); coordinates not mapped keep their own name ('' = none)"),
    ParamSpec("joints", [], "string_array", "-",
              "Robot joint names in the order of joint_efforts and joint_effort_commands ([] = "
              "every geometry coordinate in the file's order, under its robot name)"),
    ParamSpec("coordination.enabled", False, "bool", "-",
              "Live coordination (needs a geometry): the joint-driven muscles' drives are solved "
              "each publish period over a receding horizon so that their joint efforts follow "
              "the targets of joint_effort_trajectory or joint_effort_targets(_array) at least "
              "cost; excitation is not used for them"),
    ParamSpec("coordination.horizon_s", 0.15, "double", "s",
              "Look-ahead of the receding horizon (at least one publish period is used)",
              low=0.005, high=2.0),
    ParamSpec("coordination.blocks", 3, "integer", "blocks",
              "Piecewise-constant drive blocks over the horizon (the first is the next publish "
              "period)", low=1, high=20),
    ParamSpec("coordination.sample_period_s", 0.005, "double", "s",
              "Step of the horizon's forward runs and spacing of the tracked samples (rounded to "
              "divide the publish period)", low=0.001, high=0.1),
    ParamSpec("coordination.cost", "tsianos2012", "string", "-",
              "Cost beside tracking, a name of the coordination costs: tsianos2012 (VM's "
              "metabolic rate), drive2 (sum of drive^2) or a published energetics model's "
              "rate on VM's state"),
    ParamSpec("coordination.effort_weight", 0.0, "double", "(N m)^2 per W or per drive^2",
              "Weight of the cost against tracking error ((N m)^2 per W for tsianos2012, per "
              "drive^2 for drive2; 0 = the cost's default: 0.001 and 0.1)", low=0.0, high=1e6),
    ParamSpec("coordination.smoothness", 1.0, "double", "(N m)^2 per drive^2",
              "Weight of drive changes from one block to the next", low=0.0, high=1e6),
    ParamSpec("coordination.damping", 0.0, "double", "(N m)^2 per drive^2",
              "Weight of each drive's step away from the plan the period is linearised about "
              "(a trust region)", low=0.0, high=1e6),
    ParamSpec("coordination.probe_drive", 0.2, "double", "1",
              "Drive step of the horizon's derivative runs (a secant per block): a muscle at "
              "rest shows force within a short block only for a step that recruits it (with 4 "
              "blocks use 0.4: docs/node.md section 13); at most 0.5, so that the step down "
              "taken where a step up would pass 1 stays >= 0 (the bank clips drives, which "
              "would bend the secant)", low=0.01, high=0.5),
    ParamSpec("coordination.plan_offset_max", 0.1, "double", "1 (of the coordinate's box)",
              "A planned profile's positions further than this share of the geometry box's "
              "width from the latest joint sample are counted (plan_far_from_joints); the plan "
              "is still moved to start from the sample", low=0.0, high=1e6),
    ParamSpec("coordination.lag_window_s", 2.0, "double", "s",
              "Window of published steps over which diagnostics report the tracking lag and "
              "error", low=0.05, high=60.0),
    ParamSpec("qos_depth", 10, "integer", "messages",
              "History depth of every subscription and publisher (raise it for bursts: 100 "
              "holds a 100 ms stall at 1 kHz input)", low=1, high=10000),
    ParamSpec("diagnostics_period_s", 1.0, "double", "s",
              "Period of /diagnostics (steady clock, also while a simulated clock is paused)",
              low=0.01, high=3600.0),
    ParamSpec("executor", "events", "string", "-",
              "Executor muscle_node's main() spins with: events "
              "(rclpy.experimental.EventsExecutor) or single_threaded", choices=EXECUTORS),
    ParamSpec("mcap.enabled", False, "bool", "-",
              "Record inputs as received and outputs as published to an MCAP file"),
    ParamSpec("mcap.path", "", "string", "path",
              "MCAP file to write ('' = muscle_node-<YYYYmmdd-HHMMSS>.mcap in the working "
              "directory); a path without .mcap is a rosbag2 bag directory NAME/ with "
              "NAME_0.mcap and metadata.yaml"),
    ParamSpec("mcap.flush_interval_s", 1.0, "double", "s",
              "Longest wall time a logged message waits in memory before its chunk is written "
              "to the file: what a crash (SIGKILL) can lose", low=1e-3, high=3600.0),
    ParamSpec("mcap.max_bag_size", 0, "integer", "bytes",
              "With a bag directory (mcap.path without .mcap): start a new file NAME_<k>.mcap "
              "once the current one holds this many bytes, as ros2 bag record --max-bag-size "
              "(0 = one file)", low=0, high=2**62),
    ParamSpec("mcap.max_bag_duration_s", 0.0, "double", "s",
              "With a bag directory: start a new file once the current one spans this much log "
              "time, as ros2 bag record --max-bag-duration (0 = one file)", low=0.0, high=1e9),
)

PARAMS_BY_NAME = {p.name: p for p in PARAMS}


@dataclass(frozen=True)
class NodeConfig:
    """Validated parameter values; attribute names follow ParamSpec.field."""

    muscles: tuple
    library: str
    model: str
    overrides: str
    recruitment: str
    units_per_type: int
    recovery_mode: str
    drive_law: str
    energetics_models: tuple
    model_rate_hz: float
    publish_rate_hz: float
    batch_steps: int
    max_catch_up_steps: int
    initial_path_length_m: tuple
    input_timeout_s: float
    stale_input_policy: str
    extrapolation_max_s: float
    path_length_margin_l0: float
    path_speed_max_m_per_s: float
    geometry: str
    joint_map: str
    joints: tuple
    coordination_enabled: bool
    coordination_horizon_s: float
    coordination_blocks: int
    coordination_sample_period_s: float
    coordination_cost: str
    coordination_effort_weight: float
    coordination_smoothness: float
    coordination_damping: float
    coordination_probe_drive: float
    coordination_plan_offset_max: float
    coordination_lag_window_s: float
    qos_depth: int
    diagnostics_period_s: float
    executor: str
    mcap_enabled: bool
    mcap_path: str
    mcap_flush_interval_s: float
    mcap_max_bag_size: int
    mcap_max_bag_duration_s: float

    @classmethod
    def defaults(cls) -> NodeConfig:
        return cls.from_values({})

    @classmethod
    def from_values(cls, values: Mapping[str, object]) -> NodeConfig:
        """Validate parameter values by name (missing names take their default)."""
        unknown = sorted(set(values) - set(PARAMS_BY_NAME))
        if unknown:
            raise ConfigError(PARAMS_SOURCE, unknown[0], values[unknown[0]],
                              f"unknown parameter (known: {', '.join(PARAMS_BY_NAME)})")
        fields = {p.field: _checked(p, values.get(p.name, p.default)) for p in PARAMS}
        config = cls(**fields)
        config._check_cross_fields()
        return config

    def with_values(self, values: Mapping[str, object]) -> NodeConfig:
        """A copy with some parameters changed, validated like from_values."""
        current = {p.name: getattr(self, p.field) for p in PARAMS}
        return NodeConfig.from_values({**current, **values})

    def _check_cross_fields(self) -> None:
        if not self.muscles:
            raise ConfigError(PARAMS_SOURCE, "muscles", [], "need at least one muscle")
        repeated = [name for name, k in Counter(self.muscles).items() if k > 1]
        if repeated:
            shown = ", ".join(repeated[:3]) + (f" and {len(repeated) - 3} more"
                                                if len(repeated) > 3 else "")
            raise ConfigError(PARAMS_SOURCE, "muscles", list(self.muscles),
                              f"names must be unique: {shown} named more than once")
        if self.publish_rate_hz > self.model_rate_hz:
            raise ConfigError(PARAMS_SOURCE, "publish_rate_hz", self.publish_rate_hz,
                              f"must not exceed model_rate_hz ({self.model_rate_hz:g} Hz)")
        self.energetics_model_names()  # raises on an unknown name
        if self.steps_per_tick > self.max_catch_up_steps:
            raise ConfigError(PARAMS_SOURCE, "batch_steps", self.batch_steps,
                              f"{self.steps_per_tick} steps per tick exceed max_catch_up_steps "
                              f"({self.max_catch_up_steps}): raise it or lower batch_steps")
        splits = self.mcap_max_bag_size or self.mcap_max_bag_duration_s
        if splits and (not self.mcap_path or self.mcap_path.lower().endswith(".mcap")):
            name = "mcap.max_bag_size" if self.mcap_max_bag_size else "mcap.max_bag_duration_s"
            raise ConfigError(PARAMS_SOURCE, name, getattr(self, name.replace(".", "_")),
                              "splitting needs mcap.path to name a bag directory (no .mcap)")
        lengths = self.initial_path_length_m
        if lengths and len(lengths) != len(self.muscles):
            raise ConfigError(PARAMS_SOURCE, "initial_path_length_m", list(lengths),
                              f"need one length per muscle ({len(self.muscles)}) or []")
        if any(x <= 0 for x in lengths):
            raise ConfigError(PARAMS_SOURCE, "initial_path_length_m", list(lengths),
                              "lengths must be > 0 m")
        self.overrides_mapping()  # raises on a bad YAML mapping
        # imported here: muscle_node --help reads PARAMS without the geometry modules
        from vm_ros.joint_space import parse_joint_map

        parse_joint_map(self.joint_map, PARAMS_SOURCE)  # syntax; coordinates: JointSpace
        for name in ("joint_map", "joints", "coordination.enabled"):
            value = getattr(self, name.replace(".", "_"))
            if value and not self.geometry:
                raise ConfigError(PARAMS_SOURCE, name, _plain(value),
                                  "needs a geometry file (the geometry parameter)")
        if self.coordination_enabled:
            from vm_ros.coordination import costs  # not for --help: loads the model

            try:
                costs.cost_named(self.coordination_cost)
            except VmRosError as exc:
                raise ConfigError(PARAMS_SOURCE, "coordination.cost", self.coordination_cost,
                                  str(exc)) from None

    def overrides_mapping(self) -> dict:
        """The ``overrides`` parameter parsed: ``{muscle: {field: value}}``."""
        if not self.overrides.strip():
            return {}
        try:
            data = yaml.safe_load(self.overrides)
        except yaml.YAMLError as exc:
            raise ConfigError(PARAMS_SOURCE, "overrides", self.overrides,
                              f"not valid YAML: {exc}") from exc
        if not isinstance(data, dict) or not all(isinstance(v, dict) for v in data.values()):
            raise ConfigError(PARAMS_SOURCE, "overrides", self.overrides,
                              "must be a YAML mapping {muscle: {field: value}}")
        return data

    @property
    def step_ns(self) -> int:
        """Model step (ns); the model's dt is exactly step_ns * 1e-9 s."""
        return int(round(1e9 / self.model_rate_hz))

    @property
    def publish_every_steps(self) -> int:
        return max(1, int(round(self.model_rate_hz / self.publish_rate_hz)))

    def energetics_model_names(self) -> tuple:
        """The energetics_models parameter as model names ("all" expanded)."""
        from vm_ros.model.energetics_models.in_bank import model_names  # reads the model's curves

        try:
            return model_names(list(self.energetics_models))
        except InputError as exc:
            raise ConfigError(PARAMS_SOURCE, "energetics_models", list(self.energetics_models),
                              f"{exc.value}: {exc.reason}") from exc

    @property
    def steps_per_tick(self) -> int:
        """Model steps per timer tick (batch_steps, 0: one publish period)."""
        return self.batch_steps or self.publish_every_steps

    def as_parameters(self) -> dict:
        """Parameter name -> value (lists for arrays), e.g. for the run log."""
        return {p.name: _plain(getattr(self, p.field)) for p in PARAMS}


def _plain(value):
    return list(value) if isinstance(value, tuple) else value


def _checked(spec: ParamSpec, value):
    """Type, range and choice check of one value; returns it in its NodeConfig form."""

    def fail(reason):
        raise ConfigError(PARAMS_SOURCE, spec.name, value, reason)

    types = KIND_TYPES[spec.kind]
    if isinstance(value, bool) and spec.kind != "bool" or not isinstance(value, types):
        fail(f"expected {spec.kind.replace('_', ' ')}")
    if spec.kind == "string_array":
        if not all(isinstance(v, str) for v in value):
            fail("expected a list of strings")
        return tuple(value)
    if spec.kind == "double_array":
        if not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value):
            fail("expected a list of numbers")
        if not all(math.isfinite(v) for v in value):
            fail("numbers must be finite")
        return tuple(float(v) for v in value)
    if spec.kind == "double":
        value = float(value)
        if not math.isfinite(value):
            fail("must be finite")
    if spec.low is not None and value < spec.low or spec.high is not None and value > spec.high:
        fail(f"out of range {spec.limits_text()}")
    if spec.choices and value not in spec.choices:
        fail(f"must be one of: {', '.join(spec.choices)}")
    return value


def runtime_parameter_names() -> tuple:
    return tuple(p.name for p in PARAMS if p.runtime)


__all__ = [
    "EXECUTORS",
    "PARAMS",
    "PARAMS_BY_NAME",
    "STALE_POLICIES",
    "NodeConfig",
    "ParamSpec",
    "runtime_parameter_names",
]
