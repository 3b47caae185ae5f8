"""The ``vm-ros`` command: one module per verb under vm_ros.cli.

VERBS names each verb's module and its one-line help. A verb's module defines
``add_arguments(parser)`` and ``run(args) -> int`` (its docstring is the verb's description) and
is imported only when that verb is given: ``vm-ros --help`` imports none of them (nor NumPy's
heavy users: SciPy, Numba, rclpy). A verb whose module needs something not installed (rclpy,
matplotlib) says so when run, so the other verbs keep working.
"""

from __future__ import annotations

import argparse
import importlib
import importlib.util
import os
import sys

# verb name -> (module under vm_ros.cli, one-line help)
VERBS = {
    "simulate": ("simulate", "run the model offline on a scenario, CSV inputs or an OpenSim "
                             "motion (joint space); write MCAP and print a summary"),
    "replay": ("replay", "republish a log's topics over ROS 2 at the recorded pace"),
    "recompute": ("recompute", "re-run the model from a log's recorded inputs (other parameters "
                               "optional) into a new MCAP"),
    "report": ("report", "CSV tables and PNG plots of forces and partitioned energy from a run "
                         "log"),
    "validate": ("validate", "reproduce the paper's checks and figures; non-zero exit on a "
                             "failure that is not a known, explained gap"),
    "fit-w": ("fit_w", "refit the lumped weighting W (and drive filter) from natural units"),
    "bench": ("bench", "benchmark the model, offline runs and muscle_node; write JSON/CSV and "
                       "print a table"),
    "demo": ("demo", "run muscle_node with a knee-extension driver and print forces and "
                     "energies; --closed-loop: muscle_node driving a MuJoCo arm over ROS 2, "
                     "plotted"),
    "import-osim": ("import_osim", "import an OpenSim .osim model's muscle paths and parameters "
                                   "(needs the opensim extra)"),
    "import-mjcf": ("import_mjcf", "import a MuJoCo model's (MJCF or myo-sim name) muscle paths "
                                   "and parameters"),
    "closed-loop": ("closed_loop", "drive a MuJoCo model with vm_ros muscle forces (one "
                                   "process); energy balance, plot"),
    "params": ("params", "print the model's (or a muscle's) parameters: value in SI, unit as "
                         "written, tag, source"),
    "compare-energetics": ("compare_energetics", "every published muscle energetics model "
                                                 "against Tsianos 2012 on the same runs (table "
                                                 "and figures)"),
    "coordinate": ("coordinate", "solve the drives whose forward run reproduces a motion's joint "
                                 "moments at least cost; drives, forces, reserves, run log"),
    "study": ("study", "batch studies on Dask: many runs (inputs x parameter changes), one "
                       "results table (needs the study extra)"),
    "bag": ("bag", "bag directories: reindex (write metadata.yaml from the .mcap files, as "
                   "ros2 bag does)"),
}


def _module_name(verb: str) -> str:
    return f"vm_ros.cli.{VERBS[verb][0]}"


class OneLineParser(argparse.ArgumentParser):
    """argparse's parser whose usage errors are one line and exit 2, as every other bad input
    (argparse prints the whole usage first: 18 lines for `vm-ros simulate`); the verbs' parsers
    are of this class too (add_subparsers makes them of the parent's). An option is taken only
    by its whole name: argparse's prefix matching took a misspelt ``--body-mas`` for
    ``--body-mass`` and would take an abbreviation written today for another option added
    later."""

    def __init__(self, *args, **kwargs):
        kwargs.setdefault("allow_abbrev", False)
        super().__init__(*args, **kwargs)

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {message} (usage: {self.prog} --help)\n")


def build_parser(argv=None) -> argparse.ArgumentParser:
    """The parser with every verb in this version (its module present); the module of the verb
    that ``argv`` gives (its first argument that is not an option) is imported and adds its
    arguments, the others are named with their help only."""
    argv = sys.argv[1:] if argv is None else list(argv)
    given = next((a for a in argv if not a.startswith("-")), None)
    parser = OneLineParser(
        prog="vm-ros",
        description="Virtual Muscle force and fibre-type energetics: offline tools for vm_ros.",
    )
    sub = parser.add_subparsers(dest="verb", metavar="VERB", required=True)
    for verb, (_, help_line) in VERBS.items():
        if importlib.util.find_spec(_module_name(verb)) is None:
            continue  # verb not implemented in this version
        verb_parser = sub.add_parser(verb, help=help_line,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
        if verb == given:
            module = importlib.import_module(_module_name(verb))
            verb_parser.description = module.__doc__
            module.add_arguments(verb_parser)
            verb_parser.set_defaults(_run=module.run)
    return parser


def main(argv=None) -> int:
    args = build_parser(argv).parse_args(argv)
    from vm_ros.errors import VmRosError  # after parsing: --help needs none of vm_ros

    try:
        return int(args._run(args) or 0)
    except VmRosError as exc:
        print(f"vm-ros {args.verb}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"vm-ros {args.verb}: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        # a reader that closed the pipe (`| head`) ends the output quietly, for every verb;
        # Python flushes stdout again at exit: point it at /dev/null so that flush is silent
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0


if __name__ == "__main__":
    sys.exit(main())
