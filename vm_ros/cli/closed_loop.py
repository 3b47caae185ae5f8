"""Drive a MuJoCo model with vm_ros muscle forces only, in one process, and check the energy.

MuJoCo's actuation is off; each step the muscle tendons' lengths and velocities go to a
MuscleBank and its tensions come back as generalized forces (qfrc_applied = -J^T F); see
vm_ros.closed_loop and docs/closed_loop.md. Muscle parameters: derived from the model the MuJoCo
way (as vm-ros import-mjcf does; unusable ones are listed loudly), entries of --library replacing
them by name; the library used is written to DIR/muscles.yaml.

--excitation:
  pulses[:POS,NEG,PERIOD]  alternating pulses about --coordinate (default: the first): muscles
                           with r > 1 mm at POS for the first half of each PERIOD s, those with
                           r < -1 mm at NEG for the second half, 0.05 otherwise
                           (default pulses:0.5,0.2,1)
  constant:U               U on every muscle
  FILE.csv|.sto            time_s and one column per muscle (NAME or NAME.excitation; an
                           OpenSim .sto as `vm-ros simulate --excitations` reads it), on the
                           run's time axis (0 s at its start); muscles without a column get 0

Drives are fractions in [0, 1]: a value outside is an error naming the muscle and time (percent:
divide by 100). A file that does not overlap the run [0, --duration] is an error; one that covers
only part of it holds its first or last row there: a warning, printed when found and repeated
after the summary (--strict makes it an error, exit 2).

The drive is VM's neural drive U, not a Hill model's activation: at the same number VM makes far
less force (docs/closed_loop.md).

Writes DIR/closed_loop.csv (per step: coordinates, velocities, torques r^T F, drives, forces,
path lengths, energies), DIR/closed_loop.png (with matplotlib) and DIR/muscles.yaml; prints the
energy balance and the wall time per simulated second.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

from vm_ros.errors import VmRosError

RUN_AXIS = "the run's time axis (0 s at its start)"   # where an excitation file's times lie


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from vm_ros.cli.runs import add_strict_option
    from vm_ros.importers.common import add_parameter_arguments

    parser.add_argument("--model", default="myoelbow", metavar="NAME|FILE.xml",
                        help="myo-sim model name or MJCF file (default myoelbow)")
    parser.add_argument("--duration", type=float, default=2.0, metavar="S",
                        help="simulated time (default 2 s)")
    parser.add_argument("--dt", type=float, default=0.001, metavar="S",
                        help="step of MuJoCo and of the muscles (default 0.001 s)")
    parser.add_argument("--excitation", default="pulses", metavar="SPEC",
                        help="pulses[:POS,NEG,PERIOD] | constant:U | FILE.csv|.sto (see "
                             "above)")
    parser.add_argument("--coordinate", metavar="NAME",
                        help="coordinate the pulses move (default: the first)")
    parser.add_argument("--q0", metavar="NAME=VALUE,...",
                        help="initial coordinates with their unit (r_elbow_flex=90deg, "
                             "1.2rad, 0.9m; inside the coordinate's range; default: the middle "
                             "of each range)")
    parser.add_argument("--library", metavar="FILE.yaml",
                        help="muscle library whose entries replace the derived ones by name")
    add_parameter_arguments(parser)
    parser.add_argument("--out", metavar="DIR",
                        help="output folder (default out/closed-loop-<model>-<date>-<time>)")
    parser.add_argument("--no-plot", action="store_true", help="no PNG")
    add_strict_option(parser)


def parse_q0(text, geometry) -> np.ndarray:
    """--q0 NAME=VALUE,...: each with its unit and inside the coordinate's range, as `vm-ros
    simulate --hold` (vm_ros.node.motion_inputs.parse_hold); the others at the middle of their
    range (rad or m)."""
    from vm_ros.node.motion_inputs import parse_hold

    q0 = (geometry.lower + geometry.upper) / 2
    items = [item.strip() for item in (text or "").split(",") if item.strip()]
    for name, value in parse_hold(items, geometry, "--q0").items():
        q0[geometry.coordinate_index(name)] = value
    return q0


def make_excitation(spec: str, geometry, q0, coordinate: str | None):
    from vm_ros.closed_loop import constant_excitation, pulse_excitation
    from vm_ros.offline.excitations import check_drive_range

    spec = spec.strip()
    if spec.startswith("constant:"):
        try:
            level = float(spec.split(":", 1)[1])
        except ValueError as exc:
            raise VmRosError(f"--excitation {spec!r}: constant:U with a number U") from exc
        check_drive_range([[level]], ["every muscle"], [0.0], f"--excitation {spec}")
        return constant_excitation(len(geometry.muscle_names), level)
    if spec == "pulses" or spec.startswith("pulses:"):
        name = coordinate or geometry.coordinate_names[0]
        if name not in geometry.coordinate_names:
            raise VmRosError(f"--coordinate {name!r} is not a coordinate (have: "
                             f"{', '.join(geometry.coordinate_names)})")
        values = spec.split(":", 1)[1].split(",") if ":" in spec else []
        try:
            numbers = [float(v) for v in values]
        except ValueError as exc:
            raise VmRosError(f"--excitation {spec!r}: pulses:POS,NEG,PERIOD") from exc
        if len(numbers) not in (0, 3):
            raise VmRosError(f"--excitation {spec!r}: pulses:POS,NEG,PERIOD (three numbers)")
        check_drive_range([numbers[:2]], ["POS", "NEG"], [0.0], f"--excitation {spec}")
        r = geometry.evaluate(q0).moment_arm[:, geometry.coordinate_index(name)]
        return pulse_excitation(r, name, *numbers)
    return file_excitation(spec, geometry.muscle_names)


def file_excitation(path, muscle_names):
    """The drives of a .csv/.sto file (vm_ros.offline.excitations.load_excitations, as `vm-ros
    simulate --excitations` reads them; muscles without a column at 0) on the run's time axis."""
    from functools import partial

    from vm_ros.closed_loop import Excitation
    from vm_ros.offline.excitations import load_excitations

    series = load_excitations(path, muscle_names, missing_drive=0.0)
    given = len(muscle_names) - len(series.absent)
    others = f"; the other {len(series.absent)} at 0" if series.absent else ""
    unused = f"; columns not used: {', '.join(series.ignored)}" if series.ignored else ""
    return Excitation(series.at, f"from {path} ({given} of {len(muscle_names)} muscles{others}"
                      f"{unused})", partial(series.coverage, axis=RUN_AXIS))


def run(args) -> int:
    from vm_ros.cli.runs import InputWarnings
    from vm_ros.closed_loop import ClosedLoop, plot_result
    from vm_ros.geometry.mujoco_backend import MujocoGeometry
    from vm_ros.importers import common, mjcf
    from vm_ros.model import MuscleBank

    if not (args.dt > 0 and args.duration >= args.dt):
        raise VmRosError(f"need --dt > 0 and --duration >= --dt (got {args.dt}, "
                         f"{args.duration})")
    geometry = MujocoGeometry(args.model)
    q0 = parse_q0(args.q0, geometry)  # options checked before anything is written
    excitation = make_excitation(args.excitation, geometry, q0, args.coordinate)
    warnings = InputWarnings("closed-loop", args.strict)
    warnings.extend(excitation.coverage(0.0, args.duration))
    out = Path(args.out or Path("out") / f"closed-loop-{Path(str(args.model)).stem}-"
               f"{time.strftime('%Y%m%d-%H%M%S')}")
    choices = common.choices_from_args(args)
    user = mjcf.load_user_library(args.library) if args.library else None
    path_min, path_max = mjcf.path_extremes(geometry)
    library = mjcf.derive_library(geometry, choices, path_min, path_max, user)
    mjcf.print_parameter_flags(library)
    if library.excluded:
        print(f"!! {len(library.excluded)} muscles have no usable parameters and apply no force: "
              f"{', '.join(library.excluded)}")
    if not library.entries:
        raise VmRosError("no muscle has usable parameters: give them with --library")
    library_path = common.write_library(
        out / "muscles.yaml", library.entries,
        f"Muscle library used by vm-ros closed-loop --model {args.model}\n"
        f"{choices.specific_tension.source}; --library {args.library or '-'}")
    bank = MuscleBank.from_config(list(library.entries), library=library_path)
    loop = ClosedLoop(geometry, bank, args.dt)
    loop.reset(q0, excitation(0.0)[loop.rows])
    result = loop.run(args.duration, excitation)
    csv_path = result.write_csv(out / "closed_loop.csv")
    print_report(args.model, excitation.description, result)
    print(f"wrote {csv_path}, {library_path}")
    if not args.no_plot:
        try:
            png = plot_result(result, out / "closed_loop.png",
                              f"{args.model}: vm_ros muscles driving MuJoCo, dt {args.dt:g} s")
            print(f"wrote {png}")
        except ModuleNotFoundError:
            print("matplotlib is not installed: no plot (pip install 'vm_ros[plot]')")
    for line in warnings.closing_lines():
        print(line)
    return 0


def print_report(model, description, result, file=None) -> None:
    file = file or sys.stdout
    e = result.ledger
    steps = len(result.force)
    print(f"model {model}: {len(result.muscle_names)} muscles, {len(result.coordinate_names)} "
          f"coordinates, {steps} steps of {result.dt_s:g} s", file=file)
    print(f"excitation: {description}", file=file)
    moved = np.ptp(result.q, axis=0)
    for j in np.argsort(-moved)[:6]:
        print(f"  {result.coordinate_names[j]:<24} {np.degrees(result.q[:, j].min()):8.2f} .. "
              f"{np.degrees(result.q[:, j].max()):8.2f} deg, |torque| max "
              f"{np.abs(result.torque[:, j]).max():7.3f} N m", file=file)
    print(f"muscle force max {result.force.max():.1f} N", file=file)
    change_k, change_p = e.kinetic_j - e.kinetic_start_j, e.potential_j - e.potential_start_j
    print(f"energy (J): muscle work W {e.muscle_work_j:.5f} = kinetic {change_k:+.5f} + potential "
          f"{change_p:+.5f} + damping loss {e.damping_loss_j:.5f} - constraint work "
          f"{e.constraint_work_j:.5f} - other passive work {e.other_passive_work_j:.5f}",
          file=file)
    print(f"energy residual {e.residual_j:.2e} J ({e.relative_residual:.3%} of W, "
          f"{e.residual_j / max(e.largest_term_j, 1e-12):.3%} of the largest term)", file=file)
    if result.limit_steps:
        print(f"joint limits active in {result.limit_steps} steps (their work is in the "
              "constraint work)", file=file)
    print(f"wall time {result.wall_s:.3f} s: {result.wall_per_sim_s:.3f} s per simulated s, "
          f"{result.wall_s / max(steps, 1) * 1e6:.1f} us per step", file=file)
