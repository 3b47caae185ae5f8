"""Import a MuJoCo model's muscle geometry (and what parameters it has) for vm_ros.

MODEL is an MJCF file or a myo-sim model name (myoelbow, myoarm_r, myolegs, ...); a name myo-sim
knows wins over a file or folder of that name in the working directory (./NAME for the file).
Writes, in --out DIR: geometry.yaml (polynomial path lengths of the independent joints, fitted to
MuJoCo's exact tendon lengths and gradients, with each muscle's held-out errors), muscles.yaml (a
VM muscle library) and summary.txt (the summary printed here).

MuJoCo stores no optimal fibre length or tendon slack length: they are derived the MuJoCo way
from each muscle's operating range and compiled lengthrange, and are often unusable (tendons of a
few mm, or negative); such muscles are listed loudly. Give real parameters with --library FILE
(a VM muscle library; its entries replace the derived ones by name). Needs the mujoco extra.

Units and signs of the written geometry: coordinates in rad (hinge) or m (slide), path lengths L
in m; the moment arm is r = -dL/dq (m, or m/m), positive where the tendon shortens as the joint
coordinate grows, so that the joint torque is r * F (MuJoCo's actuator_moment is +dL/dq, with
negative muscle forces: the same torque).
"""

from __future__ import annotations


def add_arguments(parser) -> None:
    from vm_ros.importers.common import add_fit_arguments, add_parameter_arguments

    parser.add_argument("model", metavar="MODEL.xml|MYO_SIM_NAME",
                        help="MJCF file or myo-sim model name")
    parser.add_argument("--out", required=True, metavar="DIR", help="output folder")
    parser.add_argument("--library", metavar="FILE.yaml",
                        help="muscle library whose entries replace the derived ones by name")
    add_fit_arguments(parser)
    parser.add_argument("--max-terms", type=int, default=500,
                        help="largest polynomial tried per muscle, in terms (default 500: "
                             "degree 4 for a tendon crossing 8 joints; fit time grows with "
                             "the square)")
    add_parameter_arguments(parser)
    parser.add_argument("--muscle", action="append", default=[], metavar="NAME",
                        help="import only this muscle (repeatable; default all)")
    parser.add_argument("--seed", type=int, default=0, help="random seed of the poses")


def run(args) -> int:
    from vm_ros.importers.common import choices_from_args
    from vm_ros.importers.mjcf import MjcfOptions, import_mjcf

    options = MjcfOptions(degree=args.degree, samples=args.samples, held_out=args.held_out,
                          length_tolerance_m=args.tolerance_mm * 1e-3, seed=args.seed,
                          muscles=tuple(args.muscle), max_terms=args.max_terms)
    import_mjcf(args.model, args.out, options, choices_from_args(args),
                user_library=args.library)
    return 0
