"""Solve the drives of a geometry's muscles over a motion so that the joint moments of a forward
run of the full model (drive filter, activation, fascicle mass, tendon) reproduce target joint
moments at least cost (docs/coordination.md), and write:

  drives.sto      drive per muscle at the drive nodes (OpenSim storage, the motion's time axis;
                  `vm-ros simulate --excitations` and OpenSim read it)
  forces.sto      tendon force per muscle (N) at the target frames
  reserves.sto    reserve moment per coordinate (N m or N) at the target frames
  coordination.mcap  the run log of the drives (as `vm-ros simulate --motion` writes it, the
                  activation starting at the steady state of the first drive, the solver's
                  lead-in first; `vm-ros recompute` reproduces its forces and energy)
  motion.sto      with a lead-in (--lead-in, config/coordination.yaml drives.lead_in; the
                  receding method's receding.lead_in): the run log's motion, the first pose
                  held from the lead-in's start
  coordination.png   drives over time (heat map), forces, target and muscle moments with the
                  reserves, mean metabolic rate per muscle

--out FILE.mcap instead of a folder (as a study runs it, vm_ros.study): the run log alone, at
FILE.mcap, with drives.sto, forces.sto, reserves.sto (and motion.sto) attached to it and named
in its metadata by attachment, so that the log is one file and its bytes do not depend on where
the solve wrote them; no figure. --start-time, --flush-interval and --log-writer are the run
log's, as for `vm-ros simulate`.

and print per coordinate the reserves (RMS, peak, % of the target's peak), the frames where the
target exceeds what the muscles can give (with the moment they lack), muscles at their limit,
whole-body metabolic rate and, with --speed and --body-mass, the cost of transport.

Targets (--targets): an inverse-dynamics .sto (OpenSim's ID output names), mujoco[:MODEL] or
opensim-id:MODEL.osim[,LOADS.xml][,lowpass=HZ] (vm_ros.coordination.targets). Coordinates of the
targets no muscle crosses (pelvis, lumbar) are left to the reserves and listed.
Costs (--cost): tsianos2012 (VM's metabolic energy, default), drive2, or a published energetics
model's name (vm_ros.coordination.costs).

Every input is checked before the solve, by `vm-ros simulate --motion`'s rules
(docs/geometry.md): an input that would change the result without a word is an error (one line,
exit 2, nothing written), e.g. a motion whose header says inDegrees=no with angles beyond a full
turn; one a user may mean is a warning, printed when found and repeated after the summary
(a motion whose header says degrees but whose angles all stay within +-3.14, motion frames
outside the geometry's box, clamped; a dependent coordinate's column that disagrees with the
geometry's coupling); --strict makes every warning an error.
"""

from __future__ import annotations

import argparse
import contextlib
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from vm_ros.errors import VmRosError

# metadata entries of the run log
COST_KEY, SOLVE_KEY = "coordination_cost", "coordination_solve"
LEAD_IN_KEY = "lead_in_s"   # s of the run log before the motion's first frame (first pose held)
LIMIT_DRIVE = 0.99          # a muscle whose drive reaches this is "at its limit"
GRAVITY_M_PER_S2 = 9.81     # cost of transport: P / (m g v)
METHOD_KEY = "coordination_method"
# What a method gives up, printed beside its name (measured in docs/coordination.md, "Receding
# horizon over a whole motion")
METHOD_CAVEATS = {"receding": ": the live horizon, fast, but its cost weighs less and its drives "
                  "are rougher than the three stages' (docs/coordination.md); --method "
                  "trajectory for the whole-trajectory optimum"}
# SolverOptions fields that only the three stages use, with their options: given to the
# receding-horizon method, an error rather than ignored
LOG_NAME = "coordination.mcap"   # the run log in an --out folder
LOG_SUFFIX = ".mcap"             # --out FILE.mcap: the run log alone, the outputs attached
TRAJECTORY_ONLY = {"lead_in_s": "--lead-in", "node_step_s": "--node-step",
                   "smoothness": "--smoothness", "reserve_weight": "--reserve-weight",
                   "iterations": "--iterations", "refine": "--refine"}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from vm_ros.cli.runs import LOG_WRITERS, add_strict_option, flush_interval_s
    from vm_ros.cli.simulate import start_time_ns
    from vm_ros.coordination.costs import COST_NAMES, DEFAULT_COST
    from vm_ros.coordination.solver import METHODS, SolverOptions, solver_settings
    from vm_ros.coordination.targets import SPEC_HELP
    from vm_ros.recording.writer import FLUSH_INTERVAL_S

    defaults, settings = SolverOptions(), solver_settings()
    parser.add_argument("--geometry", type=Path, required=True, metavar="GEOMETRY.yaml",
                        help="vm_ros.geometry file (vm-ros import-osim / import-mjcf)")
    parser.add_argument("--motion", type=Path, required=True, metavar="FILE.mot|.sto",
                        help="the motion (IK result); units from its header")
    parser.add_argument("--targets", required=True, metavar="SPEC", help=SPEC_HELP)
    parser.add_argument("--targets-lowpass", type=float, default=settings["targets"].lowpass,
                        metavar="HZ", help="low-pass the targets at HZ before the solve "
                        "(zero-phase Butterworth, config/coordination.yaml targets; 0: as "
                        "given, the default); for inverse dynamics with unfiltered ground "
                        "reaction forces, whose heel-strike transients no smooth drive "
                        "follows. The report's 'above' column says how much of each target "
                        "lies above the drives' smoothness cutoff")
    parser.add_argument("--library", type=Path, metavar="MUSCLES.yaml",
                        help="muscle library (e.g. the muscles.yaml of vm-ros import-osim)")
    parser.add_argument("--params", type=Path, metavar="MODEL.yaml", help="model parameters")
    parser.add_argument("--muscles", metavar="A,B", help="these muscles only (default: the "
                        "geometry's muscles in the library)")
    parser.add_argument("--cost", default=DEFAULT_COST, choices=COST_NAMES,
                        help=f"cost to minimise (default {DEFAULT_COST})")
    parser.add_argument("--muscle-weight", action="append", default=[], metavar="MUSCLE=W",
                        help="weight of a muscle's cost (default 1; repeatable)")
    parser.add_argument("--smoothness", type=float, default=defaults.smoothness, metavar="W",
                        help=f"weight of the drives' mean squared curvature, (tau^2 d2U/dt2)^2 "
                             f"with tau = 1 / (2 pi {defaults.smoothness_cutoff_hz:g} Hz) "
                             f"(default {defaults.smoothness:g})")
    parser.add_argument("--reserve-weight", type=float, default=defaults.reserve_weight,
                        help=f"weight of mean (reserve / peak)^2 (default "
                             f"{defaults.reserve_weight:g})")
    parser.add_argument("--node-step", type=float, default=defaults.node_step_s, metavar="S",
                        help=f"time between drive nodes (default {defaults.node_step_s:g} s)")
    parser.add_argument("--lead-in", type=float, default=defaults.lead_in_s, metavar="S",
                        help=f"start the forward runs S before the motion's first frame, first "
                             f"pose held, drives free (default {defaults.lead_in_s:g} s)")
    parser.add_argument("--iterations", type=int, default=defaults.iterations,
                        help=f"forward runs of the tracking stage at most (default "
                             f"{defaults.iterations})")
    parser.add_argument("--method", default="auto", choices=METHODS,
                        help="how to solve: trajectory (the three stages over the whole "
                             "motion), receding (the live node's receding horizon run over the "
                             "motion, then one forward run), auto (receding above "
                             f"{defaults.receding_above:g} muscles x target frames; default)")
    parser.add_argument("--refine", type=int, default=defaults.refine,
                        help=f"Gauss-Newton steps after it, each a QP solved by OSQP (default "
                             f"{defaults.refine})")
    parser.add_argument("--dt", type=float, default=0.001, metavar="S",
                        help="model step (default 0.001 s)")
    parser.add_argument("--speed", type=float, metavar="M/S",
                        help="walking speed, for the cost of transport")
    parser.add_argument("--body-mass", type=float, metavar="KG",
                        help="body mass, for W/kg and the cost of transport")
    parser.add_argument("--out", type=Path, default=Path("out/coordination"),
                        metavar="DIR|FILE.mcap",
                        help="output folder (default out/coordination); FILE.mcap: the run log "
                             "alone, the other outputs attached to it (no figure)")
    parser.add_argument("--override", action="append", default=[], metavar="MUSCLE.FIELD=VALUE",
                        help="change one muscle-library field, e.g. soleus_r.fpcsa_slow=0.6 "
                             "(repeatable; the solve and the run log)")
    log = parser.add_argument_group("run log (as vm-ros simulate's)")
    log.add_argument("--start-time", type=start_time_ns, metavar="NS",
                     help="log time of model time 0, integer ns since the Unix epoch (default: "
                          "the wall clock when the run log starts)")
    log.add_argument("--flush-interval", type=flush_interval_s, default=FLUSH_INTERVAL_S,
                     metavar="S", help=f"longest wall time (s) a message waits before its chunk "
                                       f"is written (default {FLUSH_INTERVAL_S:g})")
    log.add_argument("--log-writer", choices=LOG_WRITERS, default="thread",
                     help="who writes the log: a background thread (default) or the run's own "
                          "thread (caller)")
    parser.add_argument("--progress", action="store_true",
                        help="one line per iteration on stderr even when it is not a terminal")
    add_strict_option(parser)


def _weights(texts) -> dict:
    weights = {}
    for text in texts:
        name, sep, value = text.partition("=")
        try:
            weights[name.strip()] = float(value)
        except ValueError:
            sep = ""
        if not sep:
            raise VmRosError(f"--muscle-weight {text!r}: give MUSCLE=WEIGHT, e.g. soleus_r=2")
    return weights


def write_storage(path: Path, title: str, times_s, labels, values) -> Path:
    """An OpenSim storage file (.sto): header, labels, one row per time."""
    lines = [title, "version=1", f"nRows={len(times_s)}", f"nColumns={len(labels) + 1}",
             "inDegrees=no", "endheader", "\t".join(["time", *labels])]
    lines += ["\t".join(f"{v:.9g}" for v in (t, *row)) for t, row in zip(times_s, values,
                                                                          strict=True)]
    path.write_text("\n".join(lines) + "\n")
    return path


def write_lead_in_motion(path: Path, motion, lead_s: float, dt_s: float) -> Path:
    """``motion`` (JointMotion) with its first pose held (speed 0) for ``lead_s`` before its
    first frame, values and speeds in rad or m (rad/s, m/s): the motion the solver's forward
    runs follow (vm_ros.coordination.forward, the lead-in). The held pose's last row is half
    a step before the first frame, so that every lead-in step samples it."""
    start = motion.start_s
    times = np.concatenate([[start - lead_s, start - dt_s / 2], start + motion.time_s])
    q = np.vstack([motion.q[:1], motion.q[:1], motion.q])
    qdot = np.vstack([np.zeros((2, q.shape[1])), motion.qdot])
    labels = [f"/jointset/motion/{c}/{kind}" for kind in ("value", "speed")
              for c in motion.coordinates]
    return write_storage(path, "vm_ros coordinate motion with lead-in", times, labels,
                         np.hstack([q, qdot]))


def _muscles(args, geometry) -> tuple:
    from vm_ros.model.params import load_muscle_library

    if args.muscles:
        chosen = tuple(m.strip() for m in args.muscles.split(",") if m.strip())
        unknown = [m for m in chosen if m not in geometry.muscle_names]
        if unknown:
            raise VmRosError(f"--muscles: {unknown[0]!r} has no path in {args.geometry}")
        return chosen
    library = load_muscle_library(args.library)
    chosen = tuple(m for m in geometry.muscle_names if m in library)
    if not chosen:
        raise VmRosError(f"none of the geometry's muscles is in the muscle library "
                         f"{args.library or 'shipped with vm_ros'}: give --library")
    return chosen


def _report_lines(result, rate_w, body_mass, speed) -> list[str]:
    from vm_ros.coordination.targets import content_above

    p, s = result.problem, result.summary
    cutoff = result.options.smoothness_cutoff_hz
    above = content_above(p.frame_times_s, p.target, cutoff)
    above = (np.full(len(s.coordinates), np.nan) if above is None
             else 100 * above / np.maximum(s.target_peak, 1e-12))
    lines = [f"{'coordinate':<22} {'target peak':>11} {'reserve RMS':>11} {'peak':>9} "
             f"{'RMS %':>6} {'peak %':>7} {f'> {cutoff:g} Hz %':>9}"]
    for j, name in enumerate(s.coordinates):
        unit = "N m" if p.units[j] == "rad" else "N"
        lines.append(f"{name:<22} {s.target_peak[j]:>7.1f} {unit:<3} {s.rms[j]:>11.2f} "
                     f"{s.peak[j]:>9.2f} {s.rms_percent[j]:>6.2f} {s.peak_percent[j]:>7.1f} "
                     f"{above[j]:>9.2f}")
    lines.append(f"(> {cutoff:g} Hz %: RMS of the target's own content above the drives' "
                 f"smoothness cutoff, % of its peak; a reserve RMS below it needs drives "
                 f"faster than the cutoff; --targets-lowpass removes it)")
    if p.uncrossed:
        lines.append(f"crossed by no muscle, left to the reserves: {', '.join(p.uncrossed)}")
    if result.infeasible:
        shown = "; ".join(f"{f.coordinate} at {f.time_s:.3f} s lacks {f.lacking:.1f}"
                          for f in result.infeasible[:8])
        more = f" (+{len(result.infeasible) - 8} more)" if len(result.infeasible) > 8 else ""
        lines.append(f"beyond the muscles' capacity at {len(result.infeasible)} frame(s): "
                     f"{shown}{more}")
    else:
        lines.append("every target frame is within the muscles' capacity")
    limit = [m for m, u in zip(p.muscles, result.forward.drive_steps.max(axis=0), strict=True)
             if u >= LIMIT_DRIVE]
    lines.append(f"muscles at their limit (drive >= {LIMIT_DRIVE:g}): "
                 f"{', '.join(limit) if limit else 'none'}")
    mean = rate_w.mean(axis=0)
    total = float(mean.sum())
    per_kg = f", {total / body_mass:.2f} W/kg" if body_mass else ""
    lines.append(f"metabolic rate (Tsianos 2012), mean over the motion: {total:.1f} W{per_kg}; "
                 "per muscle: " + ", ".join(f"{m} {w:.1f}" for m, w in zip(p.muscles, mean,
                                                                       strict=True)))
    if body_mass and speed:
        lines.append(f"cost of transport: {total / (body_mass * GRAVITY_M_PER_S2 * speed):.3f} "
                     f"(P / (m g v), {total / (body_mass * speed):.2f} J/(kg m))")
    iterations = len(result.history)
    lines.append(f"solved in {iterations} iteration(s), {result.forward_runs} forward runs, "
                 f"{result.seconds:.1f} s ({result.options.cost} cost "
                 f"{result.cost_value:.4g} {_cost_unit(result.options.cost)})")
    return lines


def _cost_unit(name: str) -> str:
    from vm_ros.coordination.costs import cost_named

    return cost_named(name).unit


def _figure(path: Path, result, rate_w) -> Path | None:
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return None
    p = result.problem
    fig, axes = plt.subplots(2, 2, figsize=(14, 9))
    t = np.arange(p.n_steps) * p.dt_s
    ax = axes[0, 0]
    image = ax.imshow(result.forward.drive_steps.T, aspect="auto", origin="lower",
                      extent=(0, p.duration_s, -0.5, len(p.muscles) - 0.5), vmin=0, vmax=1,
                      cmap="viridis", interpolation="nearest")
    ax.set(yticks=range(len(p.muscles)), yticklabels=p.muscles, xlabel="time (s)",
           title="drive U")
    fig.colorbar(image, ax=ax)
    ax = axes[0, 1]
    ax.plot(np.arange(p.n_steps + 1) * p.dt_s, result.forward.force, lw=1)
    ax.set(xlabel="time (s)", ylabel="tendon force (N)", title="forces (forward run)")
    ax = axes[1, 0]
    for j, name in enumerate(p.coordinates):
        line, = ax.plot(p.frame_times_s, p.target[:, j], lw=1, label=name)
        ax.plot(p.frame_times_s, result.moments[:, j], "--", color=line.get_color(), lw=1)
        ax.fill_between(p.frame_times_s, 0, result.reserves[:, j], color=line.get_color(),
                        alpha=0.25)
    ax.set(xlabel="time (s)", ylabel="N m (N)",
           title="target (solid), muscles (dashed), reserve (shaded)")
    ax.legend(fontsize=7)
    ax = axes[1, 1]
    ax.barh(range(len(p.muscles)), rate_w.mean(axis=0))
    ax.set(yticks=range(len(p.muscles)), yticklabels=p.muscles,
           xlabel="mean metabolic rate (W, Tsianos 2012)", title="energy")
    del t
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def _refuse_trajectory_options(options, why: str) -> None:
    """VmRosError naming the first of TRAJECTORY_ONLY given a value other than its default:
    the receding-horizon method does not use it."""
    from vm_ros.coordination.solver import SolverOptions

    defaults = SolverOptions()
    for field, flag in TRAJECTORY_ONLY.items():
        if getattr(options, field) != getattr(defaults, field):
            raise VmRosError(f"{flag} does not act on the receding-horizon method ({why}); "
                             f"leave it out, or use --method trajectory")


def _write_outputs(args, out: Path, log_path: Path, log_alone: bool, result, problem,
                   joint_motion, targets, muscles, warnings, motion_notes, method, started,
                   on_outcome) -> int:
    """Write the solve's outputs to ``out``, print the report and make the run log of the drives
    at ``log_path`` (``log_alone``: the outputs attached to it, no figure)."""
    from vm_ros.cli import simulate
    from vm_ros.coordination.costs import vm_rate
    from vm_ros.offline.runner import STEADY_START

    axis = joint_motion.start_s
    drives = write_storage(out / "drives.sto", "vm_ros coordinate drives",
                           axis + result.node_times_s, muscles, result.drives)
    written = [drives,
               write_storage(out / "forces.sto", "vm_ros coordinate forces (N)",
                             axis + problem.frame_times_s, muscles, result.forward.force_frames),
               write_storage(out / "reserves.sto", "vm_ros coordinate reserves (N m or N)",
                             axis + problem.frame_times_s, problem.coordinates,
                             result.reserves)]
    if result.unsolved_qps:
        print(f"warning: {result.unsolved_qps} periods' QPs were not solved by OSQP (their "
              "iterate, clipped to the drive box, was applied)")
    rate = result.forward.motion_rate(vm_rate)   # the lead-in's energy left out
    for line in _report_lines(result, rate, args.body_mass, args.speed):
        print(line)
    if targets.unmatched:
        print(f"targets {targets.source}: not coordinates of the motion, left to the reserves: "
              f"{', '.join(targets.unmatched)}")
    figure = None if log_alone else _figure(out / "coordination.png", result, rate)
    lead_s = len(result.forward.lead_in.drive) * args.dt
    motion_path = args.motion if lead_s == 0 else write_lead_in_motion(
        out / "motion.sto", joint_motion, lead_s, args.dt)
    written += [motion_path] if lead_s else []
    parser = argparse.ArgumentParser(prog="vm-ros coordinate")
    simulate.add_arguments(parser)
    argv = ["--motion", str(motion_path), "--geometry", str(args.geometry), "--excitations",
            str(drives), "--muscles", ",".join(muscles), "--dt", repr(args.dt),
            "--duration", repr(lead_s + problem.duration_s), "--out", str(log_path),
            "--flush-interval", repr(args.flush_interval), "--log-writer", args.log_writer]
    argv += [a for name in ("library", "params") if getattr(args, name)
             for a in (f"--{name}", str(getattr(args, name)))]
    argv += [a for text in args.override for a in ("--override", text)]
    argv += [] if args.start_time is None else ["--start-time", str(args.start_time)]
    extra = {STEADY_START: "yes", LEAD_IN_KEY: repr(lead_s), COST_KEY: args.cost,
             "targets": targets.source, METHOD_KEY: f"{method} (--method {args.method})",
             SOLVE_KEY: f"{len(result.history)} iterations, max reserve RMS "
                        f"{np.max(result.summary.rms_percent):.3f} % of peak, "
                        f"{result.unsolved_qps} unsolved QPs"}
    attachments = None
    if log_alone:   # the outputs travel in the log, named there by attachment, not by path
        attachments = {path.name: path.read_bytes() for path in written}
        extra["excitations"] = f"attachment {drives.name}"
        if lead_s:
            extra["motion_file"] = f"attachment {motion_path.name}"
    print(f"run log of the drives (vm-ros simulate --motion, steady start, lead-in {lead_s:g} s; "
          f"{time.perf_counter() - started:.1f} s so far):")
    code = simulate.run(parser.parse_args(argv), on_outcome=on_outcome, verb="coordinate",
                        extra=extra, checked=warnings, attachments=attachments)
    shown = [str(path) for path in written] + ([str(figure)] if figure else [])
    print(f"attached to the log: {', '.join(attachments)}" if log_alone
          else f"wrote {', '.join(shown)}")
    for line in [*motion_notes, *warnings.closing_lines()]:
        print(line)
    return code


def run(args, on_outcome: Callable | None = None) -> int:
    """The verb; ``on_outcome`` (vm_ros.study) gets the RunOutcome of the run log of the drives
    (vm_ros.cli.runs) when it succeeded."""
    from vm_ros.cli.runs import InputWarnings
    from vm_ros.coordination.costs import COSTS
    from vm_ros.coordination.methods import chosen_method, solve
    from vm_ros.coordination.problem import build_problem
    from vm_ros.coordination.solver import SolverOptions
    from vm_ros.coordination.targets import load_targets, lowpass_targets
    from vm_ros.geometry import load_geometry
    from vm_ros.importers.motion import read_motion
    from vm_ros.model.run_config import RunConfig, parse_overrides
    from vm_ros.node.motion_inputs import JointMotion, motion_checks

    for name in ("speed", "body_mass", "dt"):
        value = getattr(args, name)
        if value is not None and not value > 0:
            raise VmRosError(f"--{name.replace('_', '-')} must be > 0 (got {value})")
    if not args.targets_lowpass >= 0:
        raise VmRosError(f"--targets-lowpass must be >= 0 Hz (0: off; got "
                         f"{args.targets_lowpass})")
    geometry = load_geometry(args.geometry)
    motion = read_motion(args.motion)
    muscles = _muscles(args, geometry)
    crossed = sorted({c for m in geometry.muscles if m.name in muscles for c in m.coordinates})
    joint_motion = JointMotion.from_motion(motion, geometry, crossed, {})
    warnings = InputWarnings("coordinate", args.strict)   # every input checked before the solve
    motion_warnings, motion_notes = motion_checks(motion, joint_motion, geometry)
    warnings.extend(motion_warnings)
    targets = load_targets(args.targets, geometry=geometry, motion=joint_motion)
    if args.targets_lowpass > 0:
        targets = lowpass_targets(targets, args.targets_lowpass)
        print(f"targets {targets.source}: {targets.notes[-1]}")
    options = SolverOptions(cost=args.cost, muscle_weights=_weights(args.muscle_weight),
                            node_step_s=args.node_step, reserve_weight=args.reserve_weight,
                            smoothness=args.smoothness, iterations=args.iterations,
                            lead_in_s=args.lead_in,
                            refine=args.refine, method=args.method)
    options.check(muscles)
    config = RunConfig(muscles, geometry=args.geometry, library=args.library,
                       params=args.params,
                       energetics_models=COSTS[args.cost].bank_models).with_overrides(
        parse_overrides(args.override))
    bank = config.make_bank()
    problem = build_problem(geometry, joint_motion, targets, muscles, dt_s=args.dt)
    verbose = args.progress or sys.stderr.isatty()

    def progress(it):
        if verbose:
            print(f"iteration {len(progress.seen)}: J {it.objective:.4g}, reserves RMS "
                  f"{np.max(it.rms_percent):.2f} % of peak at worst, {it.runs} runs, "
                  f"{it.seconds:.1f} s", file=sys.stderr)
        progress.seen.append(it)

    progress.seen = []
    method = chosen_method(problem, options)
    if method == "receding":
        _refuse_trajectory_options(options, f"--method {args.method}: {len(muscles)} muscles x "
                                   f"{len(problem.frame_times_s)} target frames")
    print(f"method: {method} ({len(muscles)} muscles x {len(problem.frame_times_s)} target "
          f"frames; --method {args.method}){METHOD_CAVEATS.get(method, '')}")
    started = time.perf_counter()
    result = solve(bank, problem, options, progress=progress)
    log_alone = args.out.suffix == LOG_SUFFIX
    with contextlib.ExitStack() as stack:
        out = (Path(stack.enter_context(tempfile.TemporaryDirectory(prefix="vm_ros-coordinate-")))
               if log_alone else args.out)
        out.mkdir(parents=True, exist_ok=True)
        code = _write_outputs(args, out, args.out if log_alone else out / LOG_NAME, log_alone,
                              result, problem, joint_motion, targets, muscles, warnings,
                              motion_notes, method, started, on_outcome)
    return code
