"""Which solver coordinates a problem: the three stages over the whole trajectory (solver.solve)
or the receding horizon over the whole motion (receding_offline.solve), by
SolverOptions.method; "auto" takes the receding horizon above ``receding_above`` muscles x
target frames (config/coordination.yaml receding.above, with its reason)."""

from __future__ import annotations

from vm_ros.coordination import receding_offline, solver
from vm_ros.coordination.problem import CoordinationProblem
from vm_ros.errors import VmRosError

SOLVERS = {"trajectory": solver.solve, "receding": receding_offline.solve}


def chosen_method(problem: CoordinationProblem, options: solver.SolverOptions) -> str:
    """The name in SOLVERS that ``options.method`` picks for ``problem``; VmRosError for a name
    that is neither "auto" nor in SOLVERS."""
    if options.method == "auto":
        size = len(problem.muscles) * len(problem.frame_times_s)
        return "receding" if size > options.receding_above else "trajectory"
    if options.method not in SOLVERS:
        raise VmRosError(f"method {options.method!r}: not one of auto, {', '.join(SOLVERS)}")
    return options.method


def solve(bank, problem: CoordinationProblem, options: solver.SolverOptions | None = None,
          progress=None) -> solver.CoordinationResult:
    """solver.solve's result by the method that ``options`` picks for ``problem``."""
    options = options or solver.SolverOptions()
    options.check(problem.muscles)
    return SOLVERS[chosen_method(problem, options)](bank, problem, options, progress)


__all__ = ["SOLVERS", "chosen_method", "solve"]
