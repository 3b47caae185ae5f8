"""Import an OpenSim model's muscle geometry and parameters for vm_ros.

Writes, in --out DIR: geometry.yaml (polynomial path lengths of the independent coordinates, with
each muscle's held-out fit errors), muscles.yaml (a VM muscle library from the model's muscle
parameters, every number with its source note) and summary.txt (the summary printed here).

Needs the opensim extra (pip install ".[opensim]"). With --function-based-paths FILE.xml the
polynomials are OpenSim's own (PolynomialPathFitter output) and the model supplies coordinates and
muscle parameters. Details and every parameter choice: docs/geometry.md.

Units and signs of the written geometry: coordinates in rad (rotational) or m (translational),
path lengths L in m; the moment arm is r = -dL/dq (m, or m/m), as OpenSim's, positive where the
muscle shortens as the coordinate grows, so that the joint torque is r * F.
"""

from __future__ import annotations

from pathlib import Path

from vm_ros.errors import VmRosError


def add_arguments(parser) -> None:
    from vm_ros.importers.common import add_fit_arguments, add_parameter_arguments

    parser.add_argument("model", type=Path, help="the OpenSim model (.osim)")
    parser.add_argument("--out", type=Path, required=True, help="output folder")
    parser.add_argument("--motion", type=Path, action="append", default=[], metavar="FILE",
                        help="a .mot/.sto motion (IK result); the box becomes the motions' range "
                             "plus --margin-deg, and half of the poses lie near its frames "
                             "(repeatable)")
    parser.add_argument("--margin-deg", type=float, default=10.0,
                        help="margin around the motions' range (default 10 deg; 1 cm for "
                             "translational coordinates)")
    add_fit_arguments(parser)
    add_parameter_arguments(parser)
    parser.add_argument("--muscle", action="append", default=[], metavar="NAME",
                        help="import only this muscle (repeatable; default all)")
    parser.add_argument("--function-based-paths", type=Path, default=None, metavar="FILE.xml",
                        help="take the polynomials from OpenSim's PolynomialPathFitter output")
    parser.add_argument("--seed", type=int, default=0, help="random seed of the poses")
    parser.add_argument("--progress", action="store_true",
                        help="progress lines on stderr even when it is not a terminal")


def run(args) -> int:
    from vm_ros.importers.common import choices_from_args
    from vm_ros.importers.osim import OsimOptions, import_function_based_paths, import_osim

    if not args.tolerance_mm > 0 or not args.margin_deg >= 0:
        raise VmRosError("--tolerance-mm must be > 0 and --margin-deg >= 0")
    options = OsimOptions(degree=args.degree, samples=args.samples, held_out=args.held_out,
                          motions=tuple(args.motion), margin_deg=args.margin_deg,
                          length_tolerance_m=args.tolerance_mm * 1e-3, seed=args.seed,
                          muscles=tuple(args.muscle))
    choices = choices_from_args(args)
    progress = True if args.progress else None
    if args.function_based_paths is not None:
        import_function_based_paths(args.model, args.function_based_paths, args.out, options,
                                    choices, progress=progress)
    else:
        import_osim(args.model, args.out, options, choices, progress=progress)
    return 0
