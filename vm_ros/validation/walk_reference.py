"""OpenSim beside vm_ros on the Gait10dof18musc walk: the reference solutions a coordination
result is compared with, and the comparison itself.

- ``static_optimization(files)``: OpenSim's StaticOptimization (extra ``opensim``) on the walk's
  model, IK motion (low-pass 6 Hz, as the walk's ID setup) and ground reactions, with the CMC
  setup's pelvis residual and joint reserve actuators; minimises sum a^2 per frame with the
  muscles' force-length-velocity (OpenSim's defaults). Returns muscle forces and activations.
- ``cmc_forces(files)``: CMC's muscle forces from opensim-models' reference output.
- ``umberger_probe(files)``: OpenSim's Umberger 2010 probe over a CMC walk (the ankle-spring
  variant: the only reference CMC run with probes), as a time-averaged whole-body rate.
- ``gait_events(files)``: heel strikes and toe-offs from the vertical ground reaction;
  ``walking_speed(files)``: the treadmill belt speed from the foot in stance.
- ``compare(ours, reference)``: per muscle, Pearson correlation and RMS difference on the
  reference's frames within the common time span.

Every function takes the ``walk_files()`` mapping of vm_ros.validation.walk_data.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from dataclasses import dataclass
from pathlib import Path
from xml.etree import ElementTree

import numpy as np

from vm_ros.storage import read_columns

SO_LOWPASS_HZ = 6.0   # the walk's ID setup (walk_Setup_ID.xml): coordinates filtered at 6 Hz
SO_EXPONENT = 2       # OpenSim StaticOptimization's default activation exponent: sum a^2


@dataclass(frozen=True)
class MuscleSeries:
    """Per-muscle time courses.

    | field | shape | unit |
    | --- | --- | --- |
    | times_s | (T,) | s, the walk's time axis (the IK file's) |
    | muscles | (M,) | muscle names |
    | values | (T, M) | ``unit`` |
    """

    source: str
    times_s: np.ndarray
    muscles: tuple[str, ...]
    values: np.ndarray
    unit: str

    def column(self, name: str) -> np.ndarray:
        return self.values[:, self.muscles.index(name)]


def model_muscles(model_file) -> tuple[str, ...]:
    """Names of the model's muscles (every ForceSet entry whose tag ends in 'Muscle')."""
    root = ElementTree.parse(model_file).getroot()
    forces = root.find(".//ForceSet/objects")
    return tuple(e.get("name") for e in (forces if forces is not None else [])
                 if e.tag.endswith("Muscle"))


def body_mass_kg(model_file) -> float:
    """Sum of the model's body masses (kg), from its XML."""
    root = ElementTree.parse(model_file).getroot()
    return float(sum(float(body.findtext("mass", "0")) for body in root.iter("Body")))


def _series(path, muscles, source: str, unit: str) -> MuscleSeries:
    time, columns, _ = read_columns(path, source)
    present = tuple(m for m in muscles if m in columns)
    return MuscleSeries(source, time, present, np.column_stack([columns[m] for m in present]),
                        unit)


def cmc_forces(files) -> MuscleSeries:
    """CMC's muscle forces (N) of opensim-models' reference output."""
    return _series(files["cmc_forces"], model_muscles(files["model"]), "CMC forces", "N")


def umberger_probe(files) -> dict:
    """OpenSim's Umberger 2010 probe over the CMC walk: ``total_w`` (time average of
    metabolics_TOTAL, W; its BASAL column is 0, so it is the muscles' rate), ``per_kg`` (W/kg,
    mass of the metabolics model), ``muscles_w`` {muscle: W}, ``span_s`` (start, end)."""
    from scipy import integrate

    time, columns, labels = read_columns(files["cmc_probes"], "Umberger probes")
    duration = time[-1] - time[0]

    def mean(values):
        return float(integrate.trapezoid(values, time) / duration)

    mass = body_mass_kg(files["model_metabolics"])
    total = mean(columns["metabolics_TOTAL"])
    return {"total_w": total, "per_kg": total / mass, "mass_kg": mass,
            "basal_w": mean(columns["metabolics_BASAL"]),
            "muscles_w": {label.removeprefix("metabolics_"): mean(columns[label])
                          for label in labels if label not in ("metabolics_TOTAL",
                                                               "metabolics_BASAL")},
            "span_s": (float(time[0]), float(time[-1]))}


def gait_events(files, threshold_n: float) -> dict[str, dict[str, list[float]]]:
    """{'r'|'l': {'strike': [s...], 'off': [s...]}}: times where the foot's vertical ground
    reaction crosses ``threshold_n`` upwards (heel strike) or downwards (toe-off)."""
    time, columns, _ = read_columns(files["grf"], "ground reactions")
    out = {}
    for side, label in (("r", "ground_force_vy"), ("l", "1_ground_force_vy")):
        loaded = columns[label] > threshold_n
        change = np.flatnonzero(np.diff(loaded.astype(int))) + 1
        out[side] = {"strike": [float(time[i]) for i in change if loaded[i]],
                     "off": [float(time[i]) for i in change if not loaded[i]]}
    return out


def cycle_percent(times_s, strikes) -> tuple[np.ndarray, np.ndarray]:
    """(mask of times within the first full cycle between two strikes, % of that cycle)."""
    if len(strikes) < 2:
        return np.zeros(len(times_s), bool), np.full(len(times_s), np.nan)
    start, end = strikes[0], strikes[1]
    percent = 100.0 * (np.asarray(times_s) - start) / (end - start)
    return (percent >= 0) & (percent <= 100), percent


def compare(ours: MuscleSeries, reference: MuscleSeries) -> dict[str, dict[str, float]]:
    """Per muscle in both: ``r`` (Pearson correlation), ``rms`` (RMS of the difference, in the
    unit) and ``rms_of_peak`` (that RMS / the reference's peak |value|), on the reference's
    frames within both time spans (ours interpolated linearly)."""
    t = reference.times_s
    inside = (t >= ours.times_s[0]) & (t <= ours.times_s[-1])
    out = {}
    for name in (m for m in reference.muscles if m in ours.muscles):
        ref = reference.column(name)[inside]
        own = np.interp(t[inside], ours.times_s, ours.column(name))
        rms = float(np.sqrt(np.mean((own - ref) ** 2)))
        spread = np.std(own) * np.std(ref)
        out[name] = {"r": float(np.mean((own - own.mean()) * (ref - ref.mean())) / spread)
                     if spread > 0 else float("nan"),
                     "rms": rms, "rms_of_peak": rms / max(float(np.abs(ref).max()), 1e-12)}
    return out


@contextlib.contextmanager
def _in_directory(path: Path):
    before = Path.cwd()
    os.chdir(path)
    try:
        yield
    finally:
        os.chdir(before)


def static_optimization(files, start_s: float | None = None, end_s: float | None = None
                        ) -> dict[str, MuscleSeries]:
    """OpenSim's StaticOptimization on the walk (module docstring): {'force': N, 'activation':
    1, 'reserve': N or N m (the residual and reserve actuators' forces)}. VmRosError without
    the opensim extra."""
    from vm_ros.importers.osim import load_opensim

    osim = load_opensim()
    muscles = model_muscles(files["model"])
    motion_time, _, _ = read_columns(files["motion"], "motion")
    start = float(motion_time[0] if start_s is None else start_s)
    end = float(motion_time[-1] if end_s is None else end_s)
    model = osim.Model(str(files["model"]))
    reserves = osim.ForceSet(str(files["reserves"]))
    reserve_names = tuple(reserves.get(i).getName() for i in range(reserves.getSize()))
    for i in range(reserves.getSize()):
        model.addForce(reserves.get(i).clone())
    model.finalizeConnections()
    analysis = osim.StaticOptimization()
    analysis.setStartTime(start)
    analysis.setEndTime(end)
    analysis.setUseModelForceSet(True)
    analysis.setActivationExponent(SO_EXPONENT)
    analysis.setUseMusclePhysiology(True)
    model.addAnalysis(analysis)
    with tempfile.TemporaryDirectory(prefix="vm_ros_so_") as out:
        tool = osim.AnalyzeTool()
        tool.setName("walk")
        tool.setModel(model)
        tool.setCoordinatesFileName(str(files["motion"]))
        tool.setLowpassCutoffFrequency(SO_LOWPASS_HZ)
        tool.setExternalLoadsFileName(str(files["grf_loads"]))
        tool.setInitialTime(start)
        tool.setFinalTime(end)
        tool.setResultsDir(out)
        with _in_directory(Path(files["grf_loads"]).parent):
            state = model.initSystem()
            tool.loadStatesFromFile(state)
            tool.run()
        force = Path(out) / "walk_StaticOptimization_force.sto"
        activation = Path(out) / "walk_StaticOptimization_activation.sto"
        return {"force": _series(force, muscles, "OpenSim SO forces", "N"),
                "activation": _series(activation, muscles, "OpenSim SO activations", "1"),
                "reserve": _series(force, reserve_names, "OpenSim SO reserves", "N or N m")}


def walking_speed(files, strikes, window) -> float:
    """Treadmill belt speed (m/s): minus the slope of the right heel's (calcn_r) forward position
    over ``window`` (fractions) of the right gait cycle between ``strikes[0]`` and
    ``strikes[1]`` (flat foot, mid stance), from the IK motion through the model's kinematics
    (extra ``opensim``). The pelvis of this walk stays in place: it is a treadmill walk."""
    from vm_ros.importers.motion import read_motion
    from vm_ros.importers.osim import load_opensim

    osim = load_opensim()
    model = osim.Model(str(files["model"]))
    state = model.initSystem()
    motion = read_motion(files["motion"])
    coordinates = model.getCoordinateSet()
    rotational = {coordinates.get(i).getName() for i in range(coordinates.getSize())
                  if coordinates.get(i).getMotionType() == osim.Coordinate.Rotational}
    values = motion.to_si(rotational)
    start, end = strikes[0], strikes[1]
    heel = model.getBodySet().get("calcn_r")
    pick = np.flatnonzero((motion.time >= start + window[0] * (end - start))
                          & (motion.time <= start + window[1] * (end - start)))
    x = []
    for i in pick:
        for j, name in enumerate(motion.names):
            coordinates.get(name).setValue(state, float(values[i, j]), False)
        model.realizePosition(state)
        x.append(heel.getPositionInGround(state).get(0))
    return float(-np.polyfit(motion.time[pick], x, 1)[0])


__all__ = ["MuscleSeries", "body_mass_kg", "cmc_forces", "compare", "cycle_percent",
           "gait_events", "model_muscles", "static_optimization", "umberger_probe",
           "walking_speed"]
