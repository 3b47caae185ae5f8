"""The study file: which runs a study makes, validated before anything runs.

A study is a YAML file (docs/studies.md has the format, config/studies/ an example):

    version: 1
    name: fig7_slow_fraction
    inputs:                       # each: scenario | inputs (CSV) | motion (+ geometry) | log
      - scenario: knee_extension
    settings: {duration: 30}      # parameters every run gets
    grid:                         # every combination of these values ...
      library.vasti.fpcsa_slow: [0.1, 0.5, 0.9]
      model.energetics.recovery_kernel: [fitted_fig7, pcr_slade2006]
    runs:                         # ... and/or a list of change sets (each crossed with the grid)
      - {recruitment: lumped}
    start_time_ns: 0              # log time of model time 0 (default: the wall clock)
    retries: 1                    # Dask retries of a run that raises unexpectedly

Runs = inputs x (runs x grid). Each run is one ``vm-ros simulate`` (scenario, inputs, motion) or
``vm-ros recompute`` (log) with the parameters as that verb's options, so that a study run and a
command-line run of the same parameters write the same log.

Parameters (PARAMETERS, then the two prefixes):
  model.SECTION.NAME[.slow|.fast]   a constant of the model file (config/model.yaml, or the
                                    ``params`` file), in the unit the file writes it in
  library.MUSCLE.FIELD              a muscle-library field (as --override MUSCLE.FIELD=VALUE)

A run's id is the SHA-256 (first 16 hex digits) of its verb, its input (files by content),
every parameter (files by content), the shipped files it reads because the study does not give
them (config/model.yaml without ``params``, config/muscles.yaml without ``library``,
config/energetics_models.yaml with published energetics models; by content) and the vm_ros
version: the same run in another study, or the same study started again, has the same id, which
is how a study resumes; after an upgrade that changes a default or the version, every run gets a
new id and runs again.

The results table has a column for every parameter the study changes: those of ``runs`` and
``grid`` (varied), then those of ``settings`` (the same value in every row), named as in the
file.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import tempfile
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path

import yaml

from vm_ros.errors import ConfigError, InputError, VmRosError, plain_value
from vm_ros.model.params import (
    DRIVE_LAWS,
    RECOVERY_MODES,
    SCHEMES,
    load_model_params,
    load_muscle_library,
    near_matches,
)
from vm_ros.recording.versions import VM_ROS_VERSION
from vm_ros.resources import config_dir

STUDY_VERSION = 1
TOP_LEVEL = ("version", "name", "description", "inputs", "settings", "grid", "runs",
             "start_time_ns", "retries")
MODEL_PREFIX, LIBRARY_PREFIX = "model.", "library."
FIBRE_KEYS = ("slow", "fast")  # the two values of a fibre-typed model constant
DEFAULT_RETRIES = 1


class StudyError(VmRosError):
    """A study file is invalid: ``path: field: reason`` on one line."""

    def __init__(self, path, field_name: str, reason: str):
        self.path, self.field, self.reason = str(path), field_name, reason
        super().__init__(f"{path}: {field_name}: {reason}")


# --- parameter values -----------------------------------------------------------------------


def _choice(choices) -> Callable:
    def check(value) -> str:
        if value not in choices:
            raise ValueError(f"{plain_value(value)} is not one of {', '.join(choices)}")
        return str(value)
    return check


def _positive(value) -> str:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not value > 0:
        raise ValueError(f"expected a number > 0, got {plain_value(value)}")
    return repr(float(value))


def _non_negative(value) -> str:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not value >= 0:
        raise ValueError(f"expected a number >= 0, got {plain_value(value)}")
    return repr(float(value))


def _count(value) -> str:
    if isinstance(value, bool) or not isinstance(value, int) or value < 1:
        raise ValueError(f"expected an integer >= 1, got {plain_value(value)}")
    return str(value)


def _models(value) -> str:
    from vm_ros.model.energetics_models.in_bank import model_names

    text = ",".join(map(str, value)) if isinstance(value, list) else str(value)
    if text.strip() == "none":
        return text
    try:
        if not model_names(text):
            raise ValueError("no model named: give a list of models, all or none")
    except InputError as error:
        raise ValueError(f"{plain_value(error.value)}: {error.reason}") from None
    return text


def _cost(value) -> str:
    from vm_ros.coordination.costs import COST_NAMES

    return _choice(COST_NAMES)(value)


def _method(value) -> str:
    from vm_ros.coordination.solver import METHODS

    return _choice(METHODS)(value)


def _file(value) -> str:
    if not isinstance(value, str) or not value:
        raise ValueError(f"expected a file name, got {plain_value(value)}")
    return value


@dataclass(frozen=True)
class Option:
    """A parameter given to the run's verb as one option: ``flag`` and the check that turns the
    study's value into the option's text (ValueError with the reason)."""

    flag: str
    check: Callable
    verbs: tuple = ("simulate", "recompute")
    is_file: bool = False


# study parameter -> verb option (model.* and library.* are handled by their prefixes)
PARAMETERS = {
    "recruitment": Option("--recruitment", _choice(SCHEMES)),
    "recovery_mode": Option("--recovery-mode", _choice(RECOVERY_MODES)),
    "drive_law": Option("--drive-law", _choice(DRIVE_LAWS)),
    "energetics_models": Option("--energetics-models", _models),
    "dt": Option("--dt", _positive, ("simulate", "recompute", "coordinate")),
    "duration": Option("--duration", _positive, ("simulate",)),
    "units_per_type": Option("--units-per-type", _count),
    "publish_rate": Option("--publish-rate", _positive),
    "telemetry_rate": Option("--telemetry-rate", _non_negative),
    "library": Option("--library", _file, ("simulate", "recompute", "coordinate"), True),
    # the base of model.* changes
    "params": Option("--params", _file, ("simulate", "recompute", "coordinate"), True),
    # vm-ros coordinate's (docs/coordination.md)
    "cost": Option("--cost", _cost, ("coordinate",)),
    "method": Option("--method", _method, ("coordinate",)),
    "smoothness": Option("--smoothness", _non_negative, ("coordinate",)),
    "reserve_weight": Option("--reserve-weight", _positive, ("coordinate",)),
    "node_step": Option("--node-step", _positive, ("coordinate",)),
    "lead_in": Option("--lead-in", _non_negative, ("coordinate",)),
    "iterations": Option("--iterations", _count, ("coordinate",)),
}


# shipped file a run reads unless the study gives its parameter: parameter -> file of config_dir()
DEFAULT_FILES = {"params": "model.yaml", "library": "muscles.yaml"}
# read (for its constants) only by a run with published energetics models
ENERGETICS_FILE = "energetics_models.yaml"
NO_MODELS = "none"


# --- inputs ---------------------------------------------------------------------------------


@dataclass(frozen=True)
class InputKind:
    """One kind of input: its verb, the option of its main value, and its other keys (study key
    -> verb option; file-valued keys are hashed by content)."""

    verb: str
    option: str | None  # None: positional (recompute's log)
    is_file: bool
    keys: Mapping = field(default_factory=dict)
    file_keys: tuple = ()
    required: tuple = ()


INPUT_KINDS = {
    "scenario": InputKind("simulate", "--scenario", False, {"muscles": "--muscles"}),
    "inputs": InputKind("simulate", "--inputs", True, {"muscles": "--muscles"}),
    "motion": InputKind("simulate", "--motion", True,
                        {"geometry": "--geometry", "excitations": "--excitations",
                         "excitation": "--excitation", "joint_map": "--joint-map",
                         "hold": "--hold", "muscles": "--muscles"},
                        ("geometry", "excitations")),
    "log": InputKind("recompute", None, True),
    "coordinate": InputKind("coordinate", "--motion", True,
                            {"targets": "--targets", "geometry": "--geometry",
                             "muscles": "--muscles"},
                            ("targets", "geometry"), ("targets", "geometry")),
}


def file_digest(path: Path) -> str:
    """SHA-256 of a file, or of a directory's files (names and bytes, sorted)."""
    digest = hashlib.sha256()
    files = sorted(p for p in path.rglob("*") if p.is_file()) if path.is_dir() else [path]
    for item in files:
        digest.update(str(item.relative_to(path)).encode() if path.is_dir() else b"")
        digest.update(item.read_bytes())
    return digest.hexdigest()


@dataclass(frozen=True)
class StudyInput:
    """One input of a study: ``label`` for the table, the verb and its arguments, ``content``
    (what the run id hashes: kind, option values, file digests), its place in the study file
    (``inputs[0]``) and the muscles it names (``muscles:``, checked against each run's
    library)."""

    label: str
    verb: str
    argv: tuple
    content: Mapping
    where: str = ""
    muscles: tuple = ()


# --- runs -----------------------------------------------------------------------------------


@dataclass(frozen=True)
class RunSpec:
    """One run of a study.

    | field | meaning |
    | --- | --- |
    | run_id | 16 hex digits, content hash of verb, input and parameters |
    | index | position in the study's order (inputs, then change sets) |
    | input | the input's label (``scenario:knee_extension``, ``log:runs/a.mcap``, ...) |
    | verb | ``simulate`` or ``recompute`` |
    | argv | the verb's arguments, without --out, --start-time and the model file |
    | changes | the varied parameters' values (the table's parameter columns) |
    | params_text | the model file with the model.* changes (None: no model file given) |
    """

    run_id: str
    index: int
    input: str
    verb: str
    argv: tuple
    changes: Mapping
    params_text: str | None = None

    @property
    def params_name(self) -> str:
        """File name of ``params_text`` under the study's params/ folder (by content)."""
        return hashlib.sha256(self.params_text.encode()).hexdigest()[:16] + ".yaml"


@dataclass(frozen=True)
class Study:
    """A validated study: its file, name, runs (study order), varied parameters (in file
    order), start time, retries and the parameters every run gets (``settings``, in file
    order). The table has a column for each parameter the study changes:
    ``parameter_columns``."""

    path: Path
    name: str
    runs: tuple
    varied: tuple
    start_time_ns: int | None
    retries: int
    settings: Mapping = field(default_factory=dict)

    @property
    def parameter_columns(self) -> tuple:
        """The varied parameters, then those of ``settings``: every parameter the study
        changes, named as in the study file."""
        return (*self.varied, *self.settings)

    def value(self, spec: RunSpec, key: str):
        """The value of parameter ``key`` in run ``spec`` (None: the verb's default, for a
        parameter of another change set)."""
        return self.settings[key] if key in self.settings else spec.changes.get(key)


def _load(path: Path) -> dict:
    try:
        data = yaml.safe_load(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise StudyError(path, "file", f"cannot read ({exc.strerror or exc})") from None
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f"line {mark.line + 1}" if mark is not None else "file"
        raise StudyError(path, where, f"not valid YAML ({getattr(exc, 'problem', exc)})") \
            from None
    if not isinstance(data, dict):
        raise StudyError(path, "file", "expected a mapping (version, inputs, grid or runs, ...)")
    return data


def _resolve(base: Path, text: str) -> Path:
    path = Path(text).expanduser()
    return path if path.is_absolute() else base / path


class _Checker:
    """Validation of one study file; errors name the field (``grid.dt[2]``)."""

    def __init__(self, path: Path):
        self.path = path
        self.base = path.parent
        self._digests: dict = {}
        self._libraries: dict = {}

    def fail(self, where: str, reason: str):
        raise StudyError(self.path, where, reason)

    def existing(self, where: str, text) -> Path:
        if not isinstance(text, str) or not text:
            self.fail(where, f"expected a file name, got {plain_value(text)}")
        path = _resolve(self.base, text)
        if not path.exists():
            self.fail(where, f"no such file: {path}")
        return path

    def digest(self, path: Path) -> str:
        if path not in self._digests:
            self._digests[path] = file_digest(path)
        return self._digests[path]

    # inputs

    def study_input(self, where: str, entry) -> StudyInput:
        if not isinstance(entry, dict):
            self.fail(where, f"expected a mapping with one of {', '.join(INPUT_KINDS)}")
        kinds = [k for k in INPUT_KINDS if k in entry]
        if len(kinds) != 1:
            self.fail(where, f"give exactly one of {', '.join(INPUT_KINDS)} (got "
                             f"{', '.join(entry) or 'none'})")
        name = kinds[0]
        kind = INPUT_KINDS[name]
        unknown = [k for k in entry if k != name and k not in kind.keys]
        if unknown:
            known = ", ".join(kind.keys) or "none"
            self.fail(f"{where}.{unknown[0]}", f"not a key of a {name} input (its keys: {known})")
        missing = [k for k in kind.required if k not in entry]
        if missing:
            self.fail(where, f"a {name} input needs {missing[0]}: FILE")
        value = entry[name]
        content: dict = {"kind": name}
        if kind.is_file:
            path = self.existing(f"{where}.{name}", value)
            main, content[name] = str(path), self.digest(path)
            label = f"{name}:{value}"
        else:
            from vm_ros.offline.scenarios import scenario_names

            if value not in scenario_names():
                self.fail(f"{where}.{name}", f"unknown scenario {plain_value(value)} (have: "
                                             f"{', '.join(scenario_names())})")
            main, content[name] = value, [value, self.digest(config_dir() / "scenarios.yaml")]
            label = f"{name}:{value}"
        argv = [kind.option, main] if kind.option else [main]
        if name == "motion" and "geometry" not in entry:
            self.fail(where, "a motion input needs geometry: GEOMETRY.yaml")
        for key, option in kind.keys.items():
            if key not in entry:
                continue
            argv_values, content[key] = self.input_value(f"{where}.{key}", key, entry[key],
                                                         key in kind.file_keys)
            argv += [item for text in argv_values for item in (option, text)]
        muscles = tuple(entry.get("muscles") or ()) if "muscles" in kind.keys else ()
        return StudyInput(label, kind.verb, tuple(argv), content, where, muscles)

    def input_value(self, where: str, key: str, value, is_file: bool):
        """(option values, hashed content) of one input key."""
        if is_file:
            path = self.existing(where, value)
            return [str(path)], self.digest(path)
        if key == "muscles":
            if not isinstance(value, list) or not value or not all(
                    isinstance(m, str) and m for m in value):
                self.fail(where, f"expected a list of muscle names, got {plain_value(value)}")
            return [",".join(value)], value
        if key == "hold":
            if not isinstance(value, list) or not all(isinstance(h, str) for h in value):
                self.fail(where, "expected a list of COORDINATE=VALUE texts, e.g. [knee=30deg]")
            return list(value), value
        if key == "excitation":
            if isinstance(value, bool) or not isinstance(value, (int, float)) \
                    or not 0 <= value <= 1:
                self.fail(where, f"expected a drive in [0, 1], got {plain_value(value)}")
            return [repr(float(value))], value
        if key == "joint_map":  # YAML text, or a file name (hashed by content)
            path = _resolve(self.base, str(value))
            if path.is_file():
                return [str(path)], self.digest(path)
            return [str(value)], value
        self.fail(where, "unknown key")

    # parameters

    def parameter(self, where: str, key, value, verbs) -> None:
        """Check one parameter's value (ValueError -> StudyError naming ``where``)."""
        if not isinstance(key, str):
            self.fail(where, f"parameter names are text, got {plain_value(key)}")
        if key.startswith(MODEL_PREFIX) or key.startswith(LIBRARY_PREFIX):
            parts = key.split(".")
            if len(parts) < 3 or not all(parts):
                self.fail(where, f"expected {MODEL_PREFIX}SECTION.NAME or "
                                 f"{LIBRARY_PREFIX}MUSCLE.FIELD, got {key!r}")
            if isinstance(value, (dict, list)) and key.startswith(LIBRARY_PREFIX):
                self.fail(where, f"expected a single value, got {plain_value(value)}")
            return
        option = PARAMETERS.get(key)
        if option is None:
            self.fail(where, f"unknown parameter {key!r} (known: {', '.join(PARAMETERS)}, "
                             f"{MODEL_PREFIX}SECTION.NAME, {LIBRARY_PREFIX}MUSCLE.FIELD)")
        other = sorted(set(verbs) - set(option.verbs))
        if other:
            takes = [name for name, each in PARAMETERS.items() if other[0] in each.verbs]
            self.fail(where, f"{key} is not a parameter of a {other[0]} run (its parameters: "
                             f"{', '.join(takes)}, {MODEL_PREFIX}*, {LIBRARY_PREFIX}*)")
        try:
            option.check(value)
        except ValueError as error:
            self.fail(where, str(error))
        if option.is_file:
            self.existing(where, value)

    def library_muscles(self, where: str, path: Path) -> dict:
        """The muscles of a library file (read once); its errors name ``where``."""
        if path not in self._libraries:
            try:
                self._libraries[path] = load_muscle_library(path)
            except VmRosError as error:
                self.fail(where, str(error))
        return self._libraries[path]

    def input_muscles(self, item: StudyInput, library: Path, library_at: str) -> None:
        """Each muscle the input names is in the run's muscle library (``library``, given at
        ``library_at``), else StudyError naming the muscle and the input."""
        if not item.muscles:
            return
        known = self.library_muscles(library_at, library)
        for i, muscle in enumerate(item.muscles):
            if muscle not in known:
                self.fail(f"{item.where}.muscles[{i}]",
                          f"muscle {muscle!r} of input {item.label} is not in the muscle "
                          f"library {library} ({near_matches(muscle, known)})")

    def parameter_content(self, key: str, value):
        """What the run id hashes for one parameter: file parameters by content."""
        option = PARAMETERS.get(key)
        if option is not None and option.is_file:
            return self.digest(_resolve(self.base, value))
        return value


def _grid(checker: _Checker, grid, verbs) -> list[tuple[dict, dict]]:
    """[(point, {parameter: where})]: every combination of the grid's values, each parameter
    with the place of its value (``grid.dt[1]``)."""
    if grid is None:
        return [({}, {})]
    if not isinstance(grid, dict) or not grid:
        checker.fail("grid", "expected a mapping of parameter -> list of values")
    for key, values in grid.items():
        if not isinstance(values, list) or not values:
            checker.fail(f"grid.{key}", f"expected a non-empty list of values, got "
                                        f"{plain_value(values)}")
        for i, value in enumerate(values):
            checker.parameter(f"grid.{key}[{i}]", key, value, verbs)
    keys = list(grid)
    return [({key: grid[key][i] for key, i in zip(keys, combo, strict=True)},
             {key: f"grid.{key}[{i}]" for key, i in zip(keys, combo, strict=True)})
            for combo in itertools.product(*(range(len(grid[key])) for key in keys))]


def _change_sets(checker: _Checker, runs, verbs) -> list[tuple[dict, dict]]:
    """[(changes, {parameter: where})] of the list of change sets (``runs[2].dt``)."""
    if runs is None:
        return [({}, {})]
    if not isinstance(runs, list) or not runs:
        checker.fail("runs", "expected a non-empty list of parameter mappings")
    for i, changes in enumerate(runs):
        if not isinstance(changes, dict):
            checker.fail(f"runs[{i}]", f"expected a mapping of parameter -> value, got "
                                       f"{plain_value(changes)}")
        for key, value in changes.items():
            checker.parameter(f"runs[{i}].{key}", key, value, verbs)
    return [(dict(changes), {key: f"runs[{i}].{key}" for key in changes})
            for i, changes in enumerate(runs)]


def _model_text(checker: _Checker, where: Mapping, base: Path, changes: Mapping) -> str:
    """The model file ``base`` with the model.* ``changes``, checked by loading it; an error
    names the place of the change at fault (``where``: parameter -> place in the study)."""
    original = base.read_text(encoding="utf-8")
    data = yaml.safe_load(original)
    for key, value in changes.items():
        if not _set_constant(data, key, value):
            checker.fail(where[key], f"{key}: no such constant in {base} (a constant is "
                                     f"{MODEL_PREFIX}SECTION.NAME, or .slow/.fast for fibre-type "
                                     "parameters; `vm-ros params` lists them)")
    text = yaml.safe_dump(data, sort_keys=False)
    error = _model_error(text)
    if error is not None:
        checker.fail(_place_of(error.field, original, changes, where),
                     f"model constant {error.field} = {plain_value(error.value)}: "
                     f"{error.reason}")
    return text


def _set_constant(data: dict, key: str, value) -> bool:
    """Set model.* constant ``key`` in a model file's ``data``; False when it has none."""
    parts = key[len(MODEL_PREFIX):].split(".")
    node = data
    for part in parts[:-1]:
        node = node.get(part) if isinstance(node, dict) else None
    last = parts[-1]
    if isinstance(node, dict) and isinstance(node.get(last), dict) and "value" in node[last]:
        node[last]["value"] = value
    elif isinstance(node, dict) and last in FIBRE_KEYS and last in node and "unit" in node:
        node[last] = value
    else:
        return False
    return True


def _model_error(text: str) -> ConfigError | None:
    """The error of loading a model file of ``text``, or None."""
    with tempfile.TemporaryDirectory(prefix="vm_ros-study-") as tmp:
        path = Path(tmp) / "model.yaml"
        path.write_text(text, encoding="utf-8")
        try:
            load_model_params(path)
        except ConfigError as error:
            return error
    return None


def _place_of(constant: str, original: str, changes: Mapping, where: Mapping) -> str:
    """The place of the model.* change at fault for an error in ``constant``: the change that
    set it (``energetics.recovery_kernel``, or a part of it), else the first change that fails
    on its own (``generic.fmax`` below ``generic.fmin``), else the places of all the run's
    model.* changes and of its ``params``."""
    for key in changes:
        name = key[len(MODEL_PREFIX):]
        if constant == name or constant.startswith(f"{name}.") or name.startswith(f"{constant}."):
            return where[key]
    for key, value in changes.items():
        data = yaml.safe_load(original)
        _set_constant(data, key, value)
        if _model_error(yaml.safe_dump(data, sort_keys=False)) is not None:
            return where[key]
    return " and ".join(where[key] for key in [*changes, "params"] if key in where)


def _check_library(checker: _Checker, where: Mapping, library: Path | None, changes: Mapping,
                   seen: set) -> None:
    """Build a one-muscle bank for each library change not checked before (ConfigError ->
    StudyError naming the change's place, ``where[key]``)."""
    from vm_ros.model import MuscleBank

    for key, value in changes.items():
        if not key.startswith(LIBRARY_PREFIX):
            continue
        muscle, _, name = key[len(LIBRARY_PREFIX):].partition(".")
        token = (library, muscle, name, json.dumps(value, default=str))
        if token in seen:
            continue
        seen.add(token)
        try:
            MuscleBank.from_config(
                [muscle], overrides={muscle: {name: value}},
                library=library or config_dir() / DEFAULT_FILES["library"],
                params=config_dir() / DEFAULT_FILES["params"])
        except VmRosError as error:
            checker.fail(where[key], f"{key} = {plain_value(value)}: {error}")


def run_id(content: Mapping) -> str:
    text = json.dumps(content, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def default_files(parameters: Mapping) -> dict:
    """{file name: path} of the shipped files a run with ``parameters`` reads because the study
    does not give them: the model file (no ``params``), the muscle library (no ``library``),
    the energetics models' constants (with published energetics models)."""
    files = {name: config_dir() / name for key, name in DEFAULT_FILES.items()
             if key not in parameters}
    if str(parameters.get("energetics_models", NO_MODELS)).strip() != NO_MODELS:
        files[ENERGETICS_FILE] = config_dir() / ENERGETICS_FILE
    return files


def run_content(checker: _Checker, item: StudyInput, parameters: Mapping) -> dict:
    """What a run's id hashes: study format version, vm_ros version, verb, input, parameters
    (files by content) and the shipped files the run reads (by content)."""
    return {"version": STUDY_VERSION, "vm_ros": VM_ROS_VERSION, "verb": item.verb,
            "input": item.content,
            "parameters": {k: checker.parameter_content(k, v) for k, v in parameters.items()},
            "defaults": {name: checker.digest(path)
                         for name, path in default_files(parameters).items()}}


def load_study(path) -> Study:
    """Read and validate a study file; StudyError (one line naming the field) on anything
    wrong. Nothing runs and nothing is written."""
    path = Path(path)
    checker = _Checker(path)
    data = _load(path)
    unknown = [key for key in data if key not in TOP_LEVEL]
    if unknown:
        checker.fail(str(unknown[0]), f"unknown key (known: {', '.join(TOP_LEVEL)})")
    if data.get("version") != STUDY_VERSION:
        checker.fail("version", f"must be {STUDY_VERSION} (this vm_ros reads study files of "
                                f"version {STUDY_VERSION}), got {plain_value(data.get('version'))}")
    inputs = data.get("inputs")
    if not isinstance(inputs, list) or not inputs:
        checker.fail("inputs", "expected a non-empty list (scenario, inputs, motion or log "
                               "entries)")
    study_inputs = [checker.study_input(f"inputs[{i}]", entry) for i, entry in enumerate(inputs)]
    verbs = sorted({item.verb for item in study_inputs})
    settings = data.get("settings") or {}
    if not isinstance(settings, dict):
        checker.fail("settings", "expected a mapping of parameter -> value")
    for key, value in settings.items():
        checker.parameter(f"settings.{key}", key, value, verbs)
    change_sets = _change_sets(checker, data.get("runs"), verbs)
    grid = _grid(checker, data.get("grid"), verbs)
    varied = list(dict.fromkeys(key for changes, _ in change_sets for key in changes))
    varied += [key for key in (data.get("grid") or {}) if key not in varied]
    overlap = [key for key in varied if key in settings]
    if overlap:
        checker.fail(f"settings.{overlap[0]}", "also varied in grid or runs: give it in one place")
    both = [key for key in (data.get("grid") or {})
            if any(key in changes for changes, _ in change_sets)]
    if both:
        checker.fail(f"grid.{both[0]}", "also given in runs: give it in one place")
    start = data.get("start_time_ns")
    if start is not None and (isinstance(start, bool) or not isinstance(start, int) or start < 0):
        checker.fail("start_time_ns", f"expected an integer number of ns >= 0, got "
                                      f"{plain_value(start)}")
    retries = data.get("retries", DEFAULT_RETRIES)
    if isinstance(retries, bool) or not isinstance(retries, int) or retries < 0:
        checker.fail("retries", f"expected an integer >= 0, got {plain_value(retries)}")
    runs, seen_library, model_texts = [], set(), {}
    settings_at = {key: f"settings.{key}" for key in settings}
    for item in study_inputs:
        for changes, changes_at in change_sets:
            for point, point_at in grid:
                varied_values = {**changes, **point}
                parameters = {**settings, **varied_values}
                where = {**settings_at, **changes_at, **point_at}  # parameter -> its place
                argv = list(item.argv)
                for key, value in parameters.items():
                    option = PARAMETERS.get(key)
                    if option is None or key == "params":
                        continue
                    text = option.check(value)
                    argv += [option.flag, str(_resolve(checker.base, text))
                             if option.is_file else text]
                for key, value in parameters.items():
                    if key.startswith(LIBRARY_PREFIX):
                        argv += ["--override", f"{key[len(LIBRARY_PREFIX):]}={json.dumps(value)}"]
                library = (_resolve(checker.base, parameters["library"])
                           if "library" in parameters else None)
                checker.input_muscles(item, library or config_dir() / DEFAULT_FILES["library"],
                                      where.get("library", item.where))
                _check_library(checker, where, library, parameters, seen_library)
                model = {k: v for k, v in parameters.items() if k.startswith(MODEL_PREFIX)}
                params_text = None
                if model or "params" in parameters:
                    base = (_resolve(checker.base, parameters["params"])
                            if "params" in parameters else config_dir() / DEFAULT_FILES["params"])
                    token = (str(base), json.dumps(model, sort_keys=True, default=str))
                    if token not in model_texts:
                        model_texts[token] = _model_text(checker, where, base, model)
                    params_text = model_texts[token]
                runs.append(RunSpec(run_id(run_content(checker, item, parameters)), len(runs),
                                    item.label, item.verb, tuple(argv), varied_values,
                                    params_text))
    ids = [r.run_id for r in runs]
    if len(set(ids)) != len(ids):
        twice = next(r for r in runs if ids.count(r.run_id) > 1)
        checker.fail("runs", f"the same run twice ({twice.input}, {plain_value(twice.changes)}): "
                             "every run must differ in its input or parameters")
    return Study(path, str(data.get("name") or path.stem), tuple(runs), tuple(varied),
                 start, retries, dict(settings))
