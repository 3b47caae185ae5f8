"""The phases of one fixed step, numbered once.

The step is written twice, as speed asks: over arrays (vm_ros.model.numpy_step.NumpyStep.step) and
as compiled loops over muscles (vm_ros.model.kernel.PHASE_LOOPS). Both mark where each phase starts
with a comment ``# Phase <number>, <NAME>: ...`` in this order; test_model_layout.py checks that the
two executors carry every phase, once each, in this order. The energetic phases carry the names of
Tsianos, Rustin & Loeb 2012 (STEPs 1-7).

| phase | what it advances or computes | source |
| 1 DRIVE | filtered drive Ueff and the pool weights it sets (recruited fraction x weighting) | Tsianos 2012 App. A; Song 2008; Cheng 2000 |
| 2 FIRING | per pool: firing envelope, rise/fall cascade f_int, f_eff, sag S, yield Y (exact lag updates, rates at the start of the step) | Brown & Loeb 2000 |
| 3 ACTIVATION | Acteff per fibre type = weight x Af(f_eff, L, Y, S); stimulation = weight x Af(f_eff, 1, 1, S) | Brown & Loeb 2000; Tsianos 2012 STEPs 4-5 |
| 4 MECHANICS | fascicle length and velocity by ROS2, activation held; length floor | Cheng 2000; Verwer 1999 |
| 5 INITIAL_ENERGY | E_a and E_xb at the step's end state | Tsianos 2012 STEPs 1-5 |
| 6 RECOVERY | E_rec = R E_i (static) or the recovery filter (dynamic) | Tsianos 2012 STEP 6, App. B |
| 7 TOTALS | rates summed over components and fibre types; energies and work integrated | Tsianos 2012 STEP 7 |
"""  # noqa: E501

from __future__ import annotations

from enum import IntEnum


class Phase(IntEnum):
    """Phases of the fixed step, in execution order (see the module docstring)."""

    DRIVE = 1
    FIRING = 2
    ACTIVATION = 3
    MECHANICS = 4
    INITIAL_ENERGY = 5
    RECOVERY = 6
    TOTALS = 7


PAPER_STEPS = {
    Phase.ACTIVATION: "Tsianos 2012 STEPs 4-5 (what activation and stimulation enter)",
    Phase.INITIAL_ENERGY: "Tsianos 2012 STEPs 1-5",
    Phase.RECOVERY: "Tsianos 2012 STEP 6 (static), Appendix B (dynamic)",
    Phase.TOTALS: "Tsianos 2012 STEP 7",
}

__all__ = ["PAPER_STEPS", "Phase"]
