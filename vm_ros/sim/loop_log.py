"""The closed loop over ROS as muscle_node logged it: motion, joint torques, forces and energy
read from its MCAP file, a one-screen summary and a plot (no rclpy, no MuJoCo; matplotlib for
the plot).

    log = read_loop_log("out/demo-closed-loop-myoelbow/closed_loop.mcap")
    print(format_loop_summary(log))
    plot_loop_log(log, "closed_loop.png", "myoelbow over ROS 2")

Channels used (muscle_node's run log with a geometry, vm_ros.recording.run_log): joint_states
(in, as received from the simulator), joint_efforts (out: the coordinates used and tau = r^T F),
muscle_force, excitation, energy_rate_total, energy_total and /diagnostics. Times are seconds
from the model start (the first muscle_force), on the ROS clock muscle_node ran on.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from vm_ros import telemetry as tm
from vm_ros.geometry.file import loads as load_geometry_text
from vm_ros.recording import read_run
from vm_ros.recording.run_log import ATTACHMENT_GEOMETRY, RunLogError
from vm_ros.report.summary import joint_work_increments
from vm_ros.report.validity import (
    Validity,
    diagnostics_number,
    logged_gap_bound,
    node_diagnostics,
    run_validity,
)

TOPICS = (tm.TOPIC_JOINT_STATES, tm.TOPIC_JOINT_EFFORTS, tm.TOPIC_FORCE, tm.TOPIC_EXCITATION,
          tm.TOPIC_ENERGY_RATE_TOTAL, tm.TOPIC_ENERGY_TOTAL, tm.TOPIC_DIAGNOSTICS)


@dataclass(frozen=True)
class Series:
    """Times (s from the model start) and values (k,) or (k, m) of one channel."""

    time_s: np.ndarray
    values: np.ndarray


@dataclass(frozen=True)
class LoopLog:
    """One closed-loop run log, as arrays.

    | field | shape | unit |
    | --- | --- | --- |
    | joints | (n_q,) | joint names of joint_states (columns of q, efforts) |
    | rotational | (n_q,) | bool: hinge (rad, plotted in deg) or slide (m) |
    | q | Series (k, n_q) | rad or m, joint_states as received |
    | effort_q, tau | Series (k, n_q) | rad or m; N m or N: joint_efforts position and effort |
    | effort_qdot | Series (k, n_q) | rad/s or m/s: joint_efforts velocity |
    | muscles | (n,) | muscle names (columns of force, drive) |
    | moment_arm_sign | (n,) | sign of r on the joint that moves most, at its mid-range |
    | force | Series (k, n) | N |
    | drive | Series (k, n) | 1, excitation as received |
    | energy_rate | Series (k,) | W, energy_rate_total |
    | energy | Series (k,) | J, energy_total |
    | diagnostics | list of dict | muscle_node's /diagnostics values (key -> text), in order |
    | validity | Validity | skipped model time, joint_states gaps (vm_ros.report.validity) |
    """

    path: Path
    joints: tuple
    rotational: np.ndarray
    q: Series
    effort_q: Series
    effort_qdot: Series
    tau: Series
    muscles: tuple
    moment_arm_sign: np.ndarray
    force: Series
    drive: Series
    energy_rate: Series
    energy: Series
    diagnostics: list
    validity: Validity

    @property
    def duration_s(self) -> float:
        """Model time from the first to the last muscle_force."""
        return float(self.force.time_s[-1]) if len(self.force.time_s) else 0.0

    def joint_work_j(self) -> tuple[float, float]:
        """(net, positive) work of the joint torques on the joints (J): the sum over the
        joint_efforts samples of vm_ros.report.summary.joint_work_increments (published at
        every model step here: the model-step sum of tau . qdot dt), the positive samples'."""
        work = joint_work_increments(self.tau.time_s, self.tau.values,
                                     self.effort_qdot.values).sum(axis=1)
        return float(work.sum()), float(work[work > 0].sum())


def _series(run, topic: str, field: str, t0_ns: int, columns=None) -> Series:
    series = run.get(topic)
    if series is None or not len(series):
        return Series(np.zeros(0), np.zeros((0, len(columns or ()))))
    values = series.fields[field]
    if columns is not None and series.names is not None:
        index = [list(series.names).index(c) for c in columns]
        values = values[:, index]
    return Series((series.time_ns - t0_ns) * 1e-9, values)


def read_loop_log(path) -> LoopLog:
    """A muscle_node run log with a geometry -> LoopLog. RunLogError when it lacks muscle
    outputs or joint channels (a run without a geometry, or one that never started)."""
    run = read_run(path, topics=TOPICS)
    forces = run.get(tm.TOPIC_FORCE)
    efforts = run.get(tm.TOPIC_JOINT_EFFORTS)
    states = run.get(tm.TOPIC_JOINT_STATES)
    for name, series in ((tm.TOPIC_FORCE, forces), (tm.TOPIC_JOINT_EFFORTS, efforts),
                         (tm.TOPIC_JOINT_STATES, states)):
        if series is None or len(series) < 2:
            raise RunLogError(path, f"fewer than 2 messages on {name}: not a closed-loop run "
                              "of muscle_node with a geometry, or it never started")
    t0 = int(forces.time_ns[0])
    joints = tuple(efforts.names)
    muscles = tuple(forces.names)
    q = _series(run, tm.TOPIC_JOINT_STATES, "position", t0, joints)
    sign, rotational = np.ones(len(muscles)), np.ones(len(joints), dtype=bool)
    if ATTACHMENT_GEOMETRY in run.attachments:  # joints named as coordinates: joint_map identity
        geometry = load_geometry_text(run.attachments[ATTACHMENT_GEOMETRY].decode())
        units = {c.name: c.unit for c in geometry.coordinates}
        rotational = np.array([units.get(j, "rad") == "rad" for j in joints])
        moving = joints[int(np.argmax(np.nanmax(q.values, axis=0)
                                      - np.nanmin(q.values, axis=0)))]
        if moving in units:
            r = geometry.evaluate((geometry.lower + geometry.upper) / 2).moment_arm[
                :, geometry.coordinate_index(moving)]
            by_name = dict(zip(geometry.muscle_names, r, strict=True))
            sign = np.array([np.sign(by_name.get(m, 0.0)) for m in muscles])
    diagnostics = node_diagnostics(run)
    validity = run_validity(
        forces.time_ns, diagnostics_number(diagnostics[-1], "skipped model time (s)")
        if diagnostics else float("nan"),
        [(tm.TOPIC_JOINT_STATES, states.time_ns, states.fields.get("stamp_ns"))],
        logged_gap_bound(run))
    return LoopLog(
        Path(path), joints, rotational, q,
        _series(run, tm.TOPIC_JOINT_EFFORTS, "position", t0),
        _series(run, tm.TOPIC_JOINT_EFFORTS, "velocity", t0),
        _series(run, tm.TOPIC_JOINT_EFFORTS, "effort", t0),
        muscles, sign,
        _series(run, tm.TOPIC_FORCE, "effort", t0),
        _series(run, tm.TOPIC_EXCITATION, "position", t0, muscles),
        _series(run, tm.TOPIC_ENERGY_RATE_TOTAL, "data", t0),
        _series(run, tm.TOPIC_ENERGY_TOTAL, "data", t0),
        diagnostics, validity)


def loop_numbers(log: LoopLog) -> dict:
    """The summary's numbers: range of motion per joint (deg for hinges, m for slides: ``unit``),
    peak |tau| (N m or N), energy (J),
    joint work (J), model time (s), muscle_node's step rate (Hz: median over its diagnostics
    windows while running, without the first, which holds the start) and skipped model time
    (s)."""
    q = log.q.values[log.q.time_s >= 0]
    q = np.where(log.rotational, np.degrees(q), q)
    running = [d for d in log.diagnostics if d.get("state") == "running"]
    running = running[1:] or running
    net, positive = log.joint_work_j()
    return {
        "unit": ["deg" if r else "m" for r in log.rotational],
        "q_min": np.nanmin(q, axis=0),
        "q_max": np.nanmax(q, axis=0),
        "range": np.nanmax(q, axis=0) - np.nanmin(q, axis=0),
        "peak_torque": np.nanmax(np.abs(log.tau.values), axis=0),
        "energy_j": float(log.energy.values[-1]) if len(log.energy.values) else float("nan"),
        "joint_work_net_j": net,
        "joint_work_positive_j": positive,
        "model_time_s": log.duration_s,
        "step_rate_hz": (float(np.median([diagnostics_number(d, "step rate (Hz)")
                                          for d in running]))
                         if running else float("nan")),
        "step_rate_windows": len(running),
        "skipped_s": log.validity.skipped_s,
    }


def format_loop_summary(log: LoopLog) -> str:
    n = loop_numbers(log)
    lines = [f"{log.duration_s:.2f} s of model time; {len(log.q.time_s)} joint_states in, "
             f"{len(log.tau.time_s)} joint_efforts out"]
    for j, name in enumerate(log.joints):
        unit = n["unit"][j]
        lines.append(f"{name}: {n['q_min'][j]:.1f} .. {n['q_max'][j]:.1f} {unit} (range of "
                     f"motion {n['range'][j]:.1f} {unit}), peak |torque| "
                     f"{n['peak_torque'][j]:.2f} {'N m' if unit == 'deg' else 'N'}")
    lines.append(f"muscle energy (energy_total) {n['energy_j']:.2f} J, mean "
                 f"{n['energy_j'] / max(log.duration_s, 1e-9):.2f} W; work of the torques on "
                 f"the joints {n['joint_work_positive_j']:.3f} J positive, "
                 f"{n['joint_work_net_j']:.3f} J net")
    windows = n["step_rate_windows"]
    lines.append(f"muscle_node: {n['step_rate_hz']:.0f} model steps/s (median of {windows} "
                 f"diagnostics window{'s' if windows != 1 else ''}), skipped model time "
                 f"{n['skipped_s']:.3g} s")
    return "\n".join(lines)


def _drive_groups(log: LoopLog) -> list[list[int]]:
    """Muscles with the same recorded drive throughout, in order of first appearance."""
    groups: list[list[int]] = []
    for i in range(len(log.muscles)):
        for group in groups:
            if np.array_equal(log.drive.values[:, i], log.drive.values[:, group[0]],
                              equal_nan=True):
                group.append(i)
                break
        else:
            groups.append([i])
    return groups


def plot_loop_log(log: LoopLog, path, title: str = "") -> Path:
    """PNG: joint angle, drive, joint torque, muscle forces, energy rate and cumulative energy
    over model time. Muscles with r > 0 on the moving joint (the flexors on an elbow) in reds,
    the others in blues; muscles driven alike share one drive line."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    colors = [None] * len(log.muscles)
    for group, cmap in ((np.flatnonzero(log.moment_arm_sign > 0), plt.get_cmap("Reds")),
                        (np.flatnonzero(log.moment_arm_sign <= 0), plt.get_cmap("Blues"))):
        for k, i in enumerate(group):
            colors[i] = cmap(0.45 + 0.5 * k / max(len(group) - 1, 1))
    side = {"loc": "upper left", "bbox_to_anchor": (1.01, 1.0), "fontsize": 8,
            "borderaxespad": 0.0}

    fig, axes = plt.subplots(5, 1, figsize=(11, 12), sharex=True,
                             gridspec_kw={"height_ratios": [2, 1.1, 1.5, 1.5, 1.5]})
    ax_q, ax_u, ax_tau, ax_f, ax_e = axes
    for j, name in enumerate(log.joints):
        values = np.degrees(log.q.values[:, j]) if log.rotational[j] else log.q.values[:, j]
        ax_q.plot(log.q.time_s, values, lw=1.6, label=f"{name}\n(joint_states)")
    ax_q.set_ylabel("joint angle (deg)" if log.rotational.all() else "joint (deg or m)")
    ax_q.legend(**side)
    if len(log.drive.time_s):
        for group in _drive_groups(log):
            ax_u.step(log.drive.time_s, log.drive.values[:, group[0]], where="post",
                      color=colors[group[-1]], lw=1.4,
                      label=", ".join(log.muscles[i] for i in group))
        ax_u.set_ylim(-0.03, max(0.1, float(np.nanmax(log.drive.values))) * 1.2)
        ax_u.legend(title="excitation", title_fontsize=8, **side)
    ax_u.set_ylabel("drive U")
    for j, name in enumerate(log.joints):
        ax_tau.plot(log.tau.time_s, log.tau.values[:, j], color="k", lw=1.0,
                    label=f"{name}\ntau = r^T F\n(joint_efforts)")
    ax_tau.axhline(0.0, color="0.6", lw=0.8)
    ax_tau.set_ylabel("joint torque (N m)")
    ax_tau.legend(**side)
    for i, name in enumerate(log.muscles):
        ax_f.plot(log.force.time_s, log.force.values[:, i], color=colors[i], lw=1.1, label=name)
    ax_f.set_ylabel("tendon force (N)")
    ax_f.legend(title="muscle_force\nr > 0 red, r < 0 blue", title_fontsize=8, **side)
    ax_e.plot(log.energy_rate.time_s, log.energy_rate.values, color="tab:orange", lw=1.0,
              label="energy rate (W)\nenergy_rate_total")
    ax_e.set_ylabel("energy rate (W)", color="tab:orange")
    ax_total = ax_e.twinx()
    ax_total.plot(log.energy.time_s, log.energy.values, color="tab:purple", lw=1.8,
                  label="cumulative (J)\nenergy_total")
    ax_total.set_ylabel("cumulative energy (J)", color="tab:purple")
    lines = ax_e.get_lines() + ax_total.get_lines()
    ax_e.legend(lines, [line.get_label() for line in lines],
                **{**side, "bbox_to_anchor": (1.08, 1.0)})
    ax_e.set_xlabel("time from the model start (s, ROS clock: outputs at model time, inputs "
                    "when received)")
    for ax in axes:
        ax.grid(alpha=0.3)
    ax_e.set_xlim(0.0, max(log.duration_s, 1e-3))
    n = loop_numbers(log)
    moving = int(np.argmax(n["range"]))
    unit = n["unit"][moving]
    fig.suptitle((title or "closed loop over ROS 2") + "\n"
                 f"{log.joints[moving]}: range of motion {n['range'][moving]:.1f} {unit}, "
                 f"peak |torque| {n['peak_torque'][moving]:.2f} {'N m' if unit == 'deg' else 'N'}"
                 "; muscle energy "
                 f"{n['energy_j']:.1f} J over {log.duration_s:.1f} s", fontsize=11)
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


__all__ = ["LoopLog", "Series", "format_loop_summary", "loop_numbers", "plot_loop_log",
           "read_loop_log"]
