"""Target joint moments of a motion: what the muscles of a coordination solve must produce.

``load_targets(spec, geometry=..., motion=...)`` returns them at the frames of ``motion`` (a
vm_ros.node.motion_inputs.JointMotion) for its coordinates, with the times of the motion file's
own axis (``motion.start_s + motion.time_s``). The spec says where they come from:

    PATH.sto | sto:PATH                              an inverse-dynamics storage file
    mujoco | mujoco:MODEL                            MuJoCo inverse dynamics of the motion
    opensim-id:MODEL.osim[,LOADS.xml][,lowpass=HZ]   OpenSim's InverseDynamicsTool on it

- **Storage file** (OpenSim's ID output, ``.sto``/``.mot``): a time column and one column per
  coordinate named ``<coordinate>_moment`` (N m, rotational) or ``<coordinate>_force`` (N,
  translational). Its rows are put on the motion's frames: a row within ALIGN_FRACTION of a frame
  interval of a frame is that frame (OpenSim's ID rows start at -5e-7 s and drift from IK's by up
  to 1.5e-6 s), other frames are interpolated linearly between rows; a frame outside the file's
  rows is an error. Columns of coordinates the motion does not drive (for a gait model: the
  pelvis and lumbar rows that no muscle crosses) are kept in ``unmatched`` with their values,
  not dropped; they are residuals by design.
- **MuJoCo** (extra ``mujoco``; MJCF and myo-sim models): ``mj_inverse`` at every frame with the
  constraint solver disabled (no contact, no equality forces): qfrc_inverse = M(q) qacc +
  c(q, qvel) - qfrc_passive. qpos comes from the motion's coordinates (joint equalities set the
  dependent joints, every other joint stays at qpos0), qvel = G(q) qdot with G the geometry's
  velocity map, qacc the derivative of qvel (velocity_from_positions' smoothing spline). The
  coordinate moments are G^T qfrc_inverse (virtual work through the couplings). A free or ball
  root is held at qpos0: the model hangs from it, and the root's generalized forces are the
  residual that holds it in space (there is no ground contact); they are reported in
  ``unmatched``, like every other degree of freedom no coordinate accounts for. ``MODEL`` is an
  MJCF file or a myo-sim name; without it, the model the geometry was imported from.
- **OpenSim** (extra ``opensim``): OpenSim's InverseDynamicsTool on the motion's file, the
  model's muscles excluded (as OpenSim's ID setups do), with the external loads file (its data
  file is found relative to the XML, as OpenSim's tools find it) and, with ``lowpass=HZ``,
  OpenSim's low-pass filter of the coordinates (Gait10dof18musc's ID setup uses 6 Hz); its
  output is read as a storage file, above.

Sign convention: OpenSim's and MuJoCo's, the generalized force that produces the motion along
the coordinate (tau = r^T F for muscle forces F and moment arms r, vm_ros.geometry.paths).
"""

from __future__ import annotations

import contextlib
import os
import sys
import tempfile
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from vm_ros.coordination.settings import solver_settings
from vm_ros.errors import VmRosError
from vm_ros.storage import read_columns

# a source row within this fraction of the smallest frame interval of a frame is that frame
ALIGN_FRACTION = 0.01
# column suffixes of OpenSim's inverse-dynamics output, by coordinate unit
SUFFIX = {"rad": "_moment", "m": "_force"}
KIND = {"rad": "rotational", "m": "translational"}

SPEC_HELP = ("PATH.sto (inverse dynamics, columns <coordinate>_moment/_force), mujoco[:MODEL] "
             "(MuJoCo inverse dynamics of the motion) or opensim-id:MODEL.osim[,LOADS.xml]"
             "[,lowpass=HZ] (OpenSim's InverseDynamicsTool)")


class TargetsError(VmRosError):
    """Target joint moments that cannot be used; the message names the spec and the problem."""


@dataclass(frozen=True)
class JointMomentTargets:
    """Joint moments the muscles must produce over a motion.

    | field | shape | unit |
    | --- | --- | --- |
    | times_s | (T,) | s, the motion's frames on its file's time axis (start_s + time_s) |
    | coordinates | (C,) | the motion's coordinates, in its order |
    | moments_nm | (T, C) | N m (rotational), N (translational) |
    | source | | the spec, with the file or model it named |
    | unmatched | (U,) | labels of generalized forces no coordinate of the motion takes |
    | unmatched_nm | (T, U) | their values (residuals), N m or N |
    | notes | | how the targets were made, one line each |
    """

    times_s: np.ndarray
    coordinates: tuple[str, ...]
    moments_nm: np.ndarray
    source: str
    unmatched: tuple[str, ...] = ()
    unmatched_nm: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    notes: tuple[str, ...] = ()

    def peak_nm(self) -> np.ndarray:
        """max |moment| over the frames, per coordinate (C,)."""
        return np.abs(self.moments_nm).max(axis=0)


def align_to_frames(times, values, frames, what: str) -> np.ndarray:
    """``values`` (n, k) at ``times`` (n,) put on ``frames`` (T,): a time within ALIGN_FRACTION of
    the smallest interval (of either axis) of a frame counts as that frame, the rest is linear
    interpolation; TargetsError when a frame lies outside the rows."""
    times = np.asarray(times, dtype=float).copy()
    frames = np.asarray(frames, dtype=float)
    values = np.asarray(values, dtype=float).reshape(len(times), -1)
    steps = np.concatenate([np.diff(times), np.diff(frames)])
    tolerance = ALIGN_FRACTION * steps.min() if len(steps) else 0.0
    nearest = np.clip(np.searchsorted(frames, times), 1, max(len(frames) - 1, 1))
    candidates = np.stack([frames[nearest - 1], frames[np.minimum(nearest, len(frames) - 1)]])
    best = candidates[np.argmin(np.abs(candidates - times), axis=0), np.arange(len(times))]
    snap = np.abs(best - times) <= tolerance
    times[snap] = best[snap]
    if frames[0] < times[0] or frames[-1] > times[-1]:
        raise TargetsError(f"{what}: its rows cover {times[0]:.6g} to {times[-1]:.6g} s, the "
                           f"motion {frames[0]:.6g} to {frames[-1]:.6g} s: give targets over the "
                           "whole motion (or trim the motion)")
    if len(times) == 1:
        return np.repeat(values, len(frames), axis=0)
    return np.column_stack([np.interp(frames, times, column) for column in values.T])


def _units(geometry, coordinates) -> dict[str, str]:
    units = {c.name: c.unit for c in (*geometry.coordinates, *geometry.coupled)}
    return {name: units.get(name, "rad") for name in coordinates}


def targets_from_storage(path, geometry, motion, source: str | None = None,
                         notes=()) -> JointMomentTargets:
    """Targets from an inverse-dynamics storage file (module docstring)."""
    time, columns, labels = read_columns(path, "targets")
    what = f"targets {path}"
    units = _units(geometry, motion.coordinates)
    chosen = []
    for name in motion.coordinates:
        label = name + SUFFIX[units[name]]
        other = [name + suffix for suffix in SUFFIX.values() if name + suffix != label]
        if label not in columns:
            hint = (f"it has {other[0]}, but {name} is {KIND[units[name]]}"
                    if other[0] in columns else f"columns: {', '.join(labels[:8])}"
                    + (", ..." if len(labels) > 8 else ""))
            raise TargetsError(f"{what}: no column {label} for coordinate {name} of the motion "
                               f"({hint})")
        chosen.append(label)
    frames = motion.start_s + motion.time_s
    unmatched = [label for label in labels if label not in chosen]
    values = np.column_stack([columns[label] for label in chosen + unmatched])
    aligned = align_to_frames(time, values, frames, what)
    k = len(chosen)
    notes = list(notes)
    if unmatched:
        notes.append(f"{what}: {len(unmatched)} column(s) not taken by a coordinate of the "
                     f"motion, kept as residuals: {', '.join(unmatched)}")
    return JointMomentTargets(frames, tuple(motion.coordinates), aligned[:, :k],
                              source or str(path), tuple(unmatched), aligned[:, k:],
                              tuple(notes))


def _mujoco_model_source(model: str, geometry) -> str:
    if model:
        return model
    source = getattr(geometry, "source", {}) or {}
    found = source.get("file") or source.get("model")
    if not found:
        raise TargetsError("targets mujoco: the geometry names no MuJoCo model (it was not "
                           "imported from one): write mujoco:MODEL (an MJCF file or a myo-sim "
                           "name)")
    return str(found)


def targets_from_mujoco(model: str, geometry, motion) -> JointMomentTargets:
    """MuJoCo inverse dynamics of the motion (module docstring)."""
    from vm_ros.geometry.mujoco_backend import MujocoGeometry, require_mujoco
    from vm_ros.importers.motion import velocity_from_positions

    mujoco = require_mujoco()
    name = _mujoco_model_source(model, geometry)
    exact = MujocoGeometry(name, clamp=False)
    m = exact.model
    missing = [c for c in motion.coordinates if c not in exact.coordinate_names]
    if missing:
        raise TargetsError(f"targets mujoco:{name}: the motion's coordinate(s) "
                           f"{', '.join(missing)} are not muscle-crossed joints of the model")
    index = [exact.coordinate_names.index(c) for c in motion.coordinates]
    q_all = np.tile(m.qpos0[exact.qpos_addresses], (len(motion.time_s), 1))
    qdot_all = np.zeros_like(q_all)
    q_all[:, index] = motion.q
    qdot_all[:, index] = motion.qdot
    n = len(motion.time_s)
    qpos = np.empty((n, m.nq))
    qvel = np.empty((n, m.nv))
    maps = np.empty((n, m.nv, len(exact.coordinate_names)))
    for i in range(n):
        exact.set_pose(q_all[i])
        qpos[i] = exact.data.qpos
        maps[i] = exact.velocity_map(qpos[i])
        qvel[i] = maps[i] @ qdot_all[i]
    qacc = np.column_stack([velocity_from_positions(motion.time_s, qvel[:, v])
                            for v in range(m.nv)]) if m.nv else np.zeros((n, 0))
    data = mujoco.MjData(m)
    flags = m.opt.disableflags
    m.opt.disableflags = flags | int(mujoco.mjtDisableBit.mjDSBL_CONSTRAINT)
    forces = np.empty((n, m.nv))
    try:
        for i in range(n):
            data.qpos[:], data.qvel[:], data.qacc[:] = qpos[i], qvel[i], qacc[i]
            mujoco.mj_inverse(m, data)
            forces[i] = data.qfrc_inverse
    finally:
        m.opt.disableflags = flags
    moments = np.einsum("tvc,tv->tc", maps, forces)[:, index]
    covered = np.abs(maps).max(axis=(0, 2)) > 0
    labels = _dof_labels(m)
    unmatched = [(labels[v], v) for v in range(m.nv) if not covered[v]]
    notes = [f"MuJoCo {mujoco.__version__} mj_inverse of {name}: constraints (contact, "
             "equalities) disabled; qacc from a smoothing spline of qvel"]
    held = [c for c in exact.coordinate_names if c not in motion.coordinates]
    if held:
        notes.append(f"coordinates of the model not in the motion held at qpos0: "
                     f"{', '.join(held)}")
    roots = sorted({label.split("[")[0] for label, _ in unmatched if "[" in label})
    if roots:
        peak = max(float(np.abs(forces[:, v]).max()) for label, v in unmatched
                   if label.split("[")[0] in roots)
        notes.append(f"free/ball joint(s) {', '.join(roots)} held at qpos0 without contact: "
                     f"their generalized forces (peak {peak:.4g} N or N m) are the residual that "
                     "holds the model in space, reported in unmatched")
    if unmatched:
        notes.append(f"{len(unmatched)} degree(s) of freedom crossed by no muscle, kept as "
                     f"residuals: {', '.join(label for label, _ in unmatched)}")
    return JointMomentTargets(motion.start_s + motion.time_s, tuple(motion.coordinates), moments,
                              f"mujoco:{name}", tuple(label for label, _ in unmatched),
                              forces[:, [v for _, v in unmatched]],
                              tuple(notes))


def _dof_labels(m) -> list[str]:
    """One label per degree of freedom: the joint's name, with [k] for a free or ball joint."""
    import mujoco

    labels = []
    for v in range(m.nv):
        j = int(m.dof_jntid[v])
        name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, j) or f"joint{j}"
        several = int(m.jnt_type[j]) in (int(mujoco.mjtJoint.mjJNT_FREE),
                                         int(mujoco.mjtJoint.mjJNT_BALL))
        labels.append(f"{name}[{v - m.jnt_dofadr[j]}]" if several else name)
    return labels


@contextlib.contextmanager
def _tool_run_in(path: Path):
    """OpenSim's tools resolve an external-loads data file relative to the working directory,
    and InverseDynamicsTool prints the model's summary on the process's standard output (not
    through its logger): the block runs in ``path`` with file descriptor 1 on /dev/null."""
    before = Path.cwd()
    sys.stdout.flush()
    saved = os.dup(1)
    null = os.open(os.devnull, os.O_WRONLY)
    os.chdir(path)
    os.dup2(null, 1)
    try:
        yield
    finally:
        os.dup2(saved, 1)
        os.close(saved)
        os.close(null)
        os.chdir(before)


def parse_opensim_spec(text: str) -> tuple[Path, Path | None, float]:
    """``MODEL.osim[,LOADS.xml][,lowpass=HZ]`` -> (model, loads or None, cutoff Hz or -1)."""
    parts = [p.strip() for p in text.split(",") if p.strip()]
    lowpass = -1.0
    files = []
    for part in parts:
        key, sep, value = part.partition("=")
        if not sep:
            files.append(Path(part))
            continue
        if key != "lowpass":
            raise TargetsError(f"targets opensim-id:{text}: unknown option {key!r} (only "
                               "lowpass=HZ)")
        try:
            lowpass = float(value)
        except ValueError:
            lowpass = float("nan")
        if not lowpass > 0:
            raise TargetsError(f"targets opensim-id:{text}: lowpass={value!r} is not a positive "
                               "frequency in Hz")
    if not 1 <= len(files) <= 2 or files[0].suffix.lower() != ".osim":
        raise TargetsError(f"targets opensim-id:{text}: expected MODEL.osim[,LOADS.xml]"
                           "[,lowpass=HZ]")
    for path in files:
        if not path.is_file():
            raise TargetsError(f"targets opensim-id:{text}: no such file {path}")
    return files[0], (files[1] if len(files) > 1 else None), lowpass


def targets_from_opensim(text: str, geometry, motion) -> JointMomentTargets:
    """OpenSim's InverseDynamicsTool on the motion file (module docstring)."""
    model_path, loads, lowpass = parse_opensim_spec(text)
    from vm_ros.importers.osim import load_opensim

    opensim = load_opensim()
    motion_file = Path(motion.source).resolve()
    if not motion_file.is_file():
        raise TargetsError(f"targets opensim-id:{text}: the motion {motion.source} is not a "
                           "file OpenSim can read")
    frames = motion.start_s + motion.time_s
    with tempfile.TemporaryDirectory(prefix="vm_ros_id_") as out:
        model = opensim.Model(str(model_path.resolve()))  # referenced: the tool does not own it
        tool = opensim.InverseDynamicsTool()
        tool.setModel(model)
        tool.setCoordinatesFileName(str(motion_file))
        tool.setLowpassCutoffFrequency(lowpass)
        excluded = opensim.ArrayStr()
        excluded.append("Muscles")  # the targets are what the muscles must produce
        tool.setExcludedForces(excluded)
        tool.setStartTime(float(frames[0]))
        tool.setEndTime(float(frames[-1]))
        tool.setResultsDir(out)
        tool.setOutputGenForceFileName("inverse_dynamics.sto")
        where = loads.resolve().parent if loads else Path(out)
        if loads:
            tool.setExternalLoadsFileName(str(loads.resolve()))
        with _tool_run_in(where):
            try:
                ok = tool.run()
            except RuntimeError as exc:
                raise TargetsError(f"targets opensim-id:{text}: OpenSim failed: "
                                   f"{str(exc).strip().splitlines()[0]}") from exc
        result = Path(out) / "inverse_dynamics.sto"
        if not ok or not result.is_file():
            raise TargetsError(f"targets opensim-id:{text}: OpenSim's InverseDynamicsTool "
                               "wrote no result")
        note = (f"OpenSim {opensim.__version__} InverseDynamicsTool on {motion_file.name} with "
                f"{loads.name if loads else 'no external loads'}, "
                + (f"coordinates low-pass filtered at {lowpass:g} Hz" if lowpass > 0
                   else "coordinates not filtered"))
        return targets_from_storage(result, geometry, motion, f"opensim-id:{text}", (note,))


SOURCES = {
    "sto": lambda rest, geometry, motion: targets_from_storage(Path(rest), geometry, motion),
    "mujoco": targets_from_mujoco,
    "opensim-id": targets_from_opensim,
}


def zero_phase_lowpass(times_s, values, cutoff_hz: float, order: int, what: str) -> np.ndarray:
    """``values`` (T, k) at uniformly spaced ``times_s`` (T,) low-passed without phase shift: a
    Butterworth filter of ``order`` at ``cutoff_hz`` run forward and backward
    (``scipy.signal.filtfilt``; the gain at the cutoff is 1/2, the effective order doubled),
    the ends padded by odd reflection (filtfilt's default). TargetsError (naming ``what``) when
    the times are not uniform within ALIGN_FRACTION of their median interval, the cutoff is not
    below the Nyquist frequency, or there are too few frames for the padding."""
    from scipy import signal

    times = np.asarray(times_s, dtype=float)
    values = np.asarray(values, dtype=float).reshape(len(times), -1)
    steps = np.diff(times)
    if len(steps) < 2:
        raise TargetsError(f"{what}: {len(times)} frame(s) are too few for a low-pass")
    if np.ptp(steps) > ALIGN_FRACTION * np.median(steps):
        raise TargetsError(f"{what}: a low-pass needs uniformly spaced frames (intervals "
                           f"{steps.min():g}-{steps.max():g} s)")
    nyquist = 0.5 / np.median(steps)
    if not 0 < cutoff_hz < nyquist:
        raise TargetsError(f"{what}: low-pass cutoff {cutoff_hz:g} Hz must lie in (0, "
                           f"{nyquist:g}) Hz, the frames' Nyquist frequency")
    b, a = signal.butter(int(order), cutoff_hz / nyquist)
    if len(times) <= 3 * max(len(a), len(b)):
        raise TargetsError(f"{what}: {len(times)} frames are too few for a low-pass of order "
                           f"{order} (more than {3 * max(len(a), len(b))} needed)")
    return signal.filtfilt(b, a, values, axis=0)


def configured_lowpass_order() -> int:
    """The order of the targets' low-pass: ``targets.lowpass_order`` of
    config/coordination.yaml."""
    return int(solver_settings()["targets"].lowpass_order)


def lowpass_targets(targets: JointMomentTargets, cutoff_hz: float,
                    order: int | None = None) -> JointMomentTargets:
    """``targets`` with their moments and residuals low-passed at ``cutoff_hz``
    (zero_phase_lowpass; ``order`` None: configured_lowpass_order), a note saying so. For
    inverse dynamics whose ground reaction forces were not filtered as the kinematics were
    (the impact transients at heel strike then appear in the moments: Bisseling & Hof 2006;
    Kristianslund et al. 2012 recommend one cutoff for both); TargetsError as
    zero_phase_lowpass."""
    what = f"targets {targets.source}"
    order = configured_lowpass_order() if order is None else order
    moments = zero_phase_lowpass(targets.times_s, targets.moments_nm, cutoff_hz, order, what)
    unmatched = np.asarray(targets.unmatched_nm, dtype=float)
    if unmatched.size:
        unmatched = zero_phase_lowpass(targets.times_s, unmatched, cutoff_hz, order, what)
    note = (f"low-passed at {cutoff_hz:g} Hz (Butterworth of order {order}, forward and "
            f"backward)")
    return replace(targets, moments_nm=moments, unmatched_nm=unmatched,
                   notes=(*targets.notes, note))


def content_above(times_s, values, cutoff_hz: float,
                  order: int | None = None) -> np.ndarray | None:
    """RMS over the frames of the part of ``values`` (T, k) above ``cutoff_hz`` (the values
    less their zero_phase_lowpass; ``order`` None: configured_lowpass_order), per column (k,);
    None where the frames allow no low-pass (not uniform, too few, cutoff at or above
    Nyquist)."""
    order = configured_lowpass_order() if order is None else order
    try:
        smooth = zero_phase_lowpass(times_s, values, cutoff_hz, order, "content above")
    except TargetsError:
        return None
    values = np.asarray(values, dtype=float).reshape(smooth.shape)
    return np.sqrt(np.mean((values - smooth) ** 2, axis=0))


def load_targets(spec: str, *, geometry, motion) -> JointMomentTargets:
    """Target joint moments at the frames of ``motion`` (a JointMotion) for its coordinates, from
    ``spec`` (SPEC_HELP; module docstring); TargetsError (one line) for bad input."""
    text = str(spec).strip()
    kind, sep, rest = text.partition(":")
    if sep and kind in SOURCES:
        return SOURCES[kind](rest, geometry, motion)
    if text in SOURCES and text != "sto":
        return SOURCES[text]("", geometry, motion)
    path = Path(text)
    if not path.is_file():
        raise TargetsError(f"targets {text!r}: neither a file nor a source ({SPEC_HELP})")
    return targets_from_storage(path, geometry, motion)


__all__ = ["ALIGN_FRACTION", "SPEC_HELP", "JointMomentTargets", "TargetsError",
           "align_to_frames", "configured_lowpass_order", "content_above", "load_targets",
           "lowpass_targets", "targets_from_mujoco", "zero_phase_lowpass",
           "targets_from_opensim", "targets_from_storage"]
