"""The published energetics models inside vm_ros: MuscleBank(energetics_models=...), the
energy_rate_models log channel of offline runs and recompute, and vm-ros report's totals.

Independent numbers: the bank's rates against published_rates / rates_from_inputs (the models
called on their own on the bank's outputs, stimulation duration from time_since_onset over the
whole series); cumulative energies against sums of rate * dt done here; logged values against
published_rates on a second bank stepped over the logged inputs.
"""

from __future__ import annotations

import numpy as np
import pytest

from vm_ros.energetics_models import MODEL_NAMES, published_rates
from vm_ros.energetics_models.in_bank import COMPONENTS
from vm_ros.energetics_models.vm_state import (
    rates_from_inputs,
    time_since_onset,
    vm_model_inputs_from_outputs,
)
from vm_ros.errors import InputError
from vm_ros.model import MuscleBank
from vm_ros.model import kernel as model_kernel

DT = 1e-3
MUSCLES = ["vasti", "rectus_femoris"]
BACKENDS = ["numpy"] + (["numba"] if model_kernel.AVAILABLE else [])


def _inputs(bank, steps=400):
    """Drive pulses (on and off, so that the stimulation duration restarts) and a moving path."""
    t = DT * np.arange(steps)
    u = np.clip(np.sin(2 * np.pi * 4 * t)[:, None] * np.array([0.8, 0.5]), 0.0, 1.0)
    rest = bank.l0_m + bank.l0t_m
    lp = rest + 0.01 * np.sin(2 * np.pi * 2 * t)[:, None]
    vp = 0.01 * 2 * np.pi * 2 * np.cos(2 * np.pi * 2 * t)[:, None] * np.ones(bank.n)
    return u, lp, vp


@pytest.mark.parametrize("backend", BACKENDS)
def test_step_by_step_equals_run_and_published_rates(backend):
    bank = MuscleBank.from_config(MUSCLES, backend=backend, energetics_models="all")
    assert bank.energetics_models == MODEL_NAMES
    u, lp, vp = _inputs(bank)
    bank.reset(lp[0])
    run = bank.run(DT, u, lp, vp)
    k, n, m = len(u), bank.n, len(MODEL_NAMES)
    assert run.energy_rate_models.shape == (k, n, m, len(COMPONENTS))
    assert run.energy_models.shape == (k, n, m)
    bank.reset(lp[0])
    outs = [bank.step(DT, u[j], lp[j], vp[j]) for j in range(k)]
    stepped = np.array([o.energy_rate_models for o in outs])
    np.testing.assert_allclose(stepped, run.energy_rate_models, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(np.array([o.energy_models for o in outs]), run.energy_models,
                               rtol=1e-12, atol=1e-12)
    # the models called on their own on the run's outputs
    reference = published_rates(bank, run)
    for j, name in enumerate(MODEL_NAMES):
        for c, component in enumerate(COMPONENTS):
            np.testing.assert_allclose(run.energy_rate_models[:, :, j, c],
                                       getattr(reference[name], component),
                                       rtol=1e-12, atol=1e-12, equal_nan=True)
    # ... and on each step's outputs, the stimulation duration counted over the series
    duration = time_since_onset(run.time_s, run.excitation)
    for row in (0, 57, k - 1):
        inputs = vm_model_inputs_from_outputs(bank, outs[row])
        inputs = type(inputs)(inputs.state, inputs.force_length_multiplier,
                              inputs.force_velocity_multiplier, inputs.passive_fibre_force,
                              duration[row])
        one = rates_from_inputs(inputs)
        for j, name in enumerate(MODEL_NAMES):
            np.testing.assert_allclose(outs[row].energy_rate_models[:, j, -1], one[name].total,
                                       rtol=1e-12, atol=1e-12)
    # the pulses switch the drive off and on: Lichtwark's duration restarted
    assert np.any(duration[1:] < duration[:-1])
    # cumulative energy = sum of total rate * dt since reset
    np.testing.assert_allclose(run.energy_models[-1],
                               (run.energy_rate_models[..., -1] * DT).sum(axis=0), rtol=1e-12)
    assert np.all(run.energy_models[-1] > 0)


def test_run_in_pieces_equals_one_run_and_reset_clears():
    bank = MuscleBank.from_config(MUSCLES, energetics_models=("umberger2010", "lichtwark_wilson"))
    u, lp, vp = _inputs(bank, 300)
    bank.reset(lp[0])
    whole = bank.run(DT, u, lp, vp)
    start = bank.reset(lp[0])
    assert start.energy_rate_models.shape == (2, 2, 5)
    assert np.all(start.energy_models == 0.0)
    first = bank.run(DT, u[:137], lp[:137], vp[:137])
    second = bank.run(DT, u[137:], lp[137:], vp[137:])
    np.testing.assert_allclose(np.concatenate([first.energy_rate_models,
                                               second.energy_rate_models]),
                               whole.energy_rate_models, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(second.last.energy_models, whole.last.energy_models, rtol=1e-12)


def test_no_models_by_default_and_bad_names():
    bank = MuscleBank.from_config(MUSCLES)
    assert bank.energetics_models == ()
    out = bank.reset(bank.l0_m + bank.l0t_m)
    assert out.energy_rate_models is None
    with pytest.raises(InputError, match="known: umberger2003"):
        MuscleBank.from_config(MUSCLES, energetics_models=["umberger2010", "nonsense"])
