"""The published energetics models' compiled loops (energetics_models.compiled) give the NumPy
path's numbers to the bit: the same IEEE operations in the same order, the transcendental
functions by NumPy on both paths.

Independent numbers: the NumPy path is each model's function over arrays (rates_from_inputs on
vm_model_inputs), which the OpenSim-probe and second-implementation tests check; here the
compiled loops must reproduce every bit of it, NaN where it has NaN, over states that take every
branch (drive off and on, lengthening and shortening, exactly isometric and -0.0 velocities,
fibres shorter and longer than L0 and beyond Bhargava's curve's ends), for the shipped constants
and for every option set of the OpenSim-probe tests.
"""

from __future__ import annotations

import dataclasses
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from test_energetics_models import BHARGAVA_OPTIONS, UMBERGER_OPTIONS
from test_layout_digests import _skip_reason

from vm_ros.model import MuscleBank
from vm_ros.model.energetics_models import compiled
from vm_ros.model.energetics_models.constants import (
    load_bhargava_constants,
    load_houdijk_constants,
    load_lichtwark_constants,
    load_margaria_constants,
    load_umberger_constants,
)
from vm_ros.model.energetics_models.in_bank import COMPONENTS, BankModels
from vm_ros.model.energetics_models.vm_state import (
    MODEL_NAMES,
    VmMuscleConstants,
    published_model,
    rates_from_inputs,
    vm_model_inputs,
)

pytestmark = pytest.mark.skipif(not compiled.AVAILABLE, reason="needs Numba")

MUSCLES = ["vasti", "rectus_femoris", "soleus", "gastrocnemius_medialis", "tibialis_anterior"]


def _bank():
    return MuscleBank.from_config(MUSCLES, backend="numpy")


def _states(bank, steps=240, seed=7):
    """Outputs (k, n) that take every branch of the models (module docstring)."""
    rng = np.random.default_rng(seed)
    n = bank.n
    drive = np.clip(rng.uniform(-0.4, 1.0, (steps, n)), 0.0, 1.0)
    drive[40:60] = 0.0  # off for a while, then on again: the stimulation restarts
    activity = rng.uniform(0.0, 0.6, (steps, n, 2)) * (drive[..., None] > 0.0)
    activity[::17, :, 1] = 0.0
    length = bank.l0_m * rng.uniform(0.3, 2.2, (steps, n))
    velocity = bank.l0_m * rng.uniform(-6.0, 6.0, (steps, n))
    velocity[::5] = 0.0
    velocity[1::11] = -0.0
    time_s = 1e-3 * (1 + np.arange(steps))
    return time_s, drive, activity, length, velocity


def _bits(a):
    """The bytes of a float array, NaN payloads as NumPy left them."""
    return np.ascontiguousarray(a, dtype=np.float64).view(np.int64)


def test_a_bank_run_gives_the_numpy_paths_bits_with_every_model():
    bank = _bank()
    muscle = VmMuscleConstants.from_bank(bank)
    numpy_models = BankModels("all", muscle, compile_models=False)
    compiled_models = BankModels("all", muscle)
    assert compiled_models._compiled is not None and numpy_models._compiled is None
    time_s, drive, activity, length, velocity = _states(bank)
    for part in (slice(0, 100), slice(100, 101), slice(101, 240)):  # continued over calls
        expected = numpy_models.advance(1e-3, time_s[part], drive[part], activity[part],
                                        length[part], velocity[part])
        got = compiled_models.advance(1e-3, time_s[part], drive[part], activity[part],
                                      length[part], velocity[part])
        for a, b in zip(expected, got, strict=True):
            assert a.shape == b.shape
            np.testing.assert_array_equal(_bits(a), _bits(b))
        np.testing.assert_array_equal(_bits(numpy_models.onset_s),
                                      _bits(compiled_models.onset_s))
    assert np.isnan(got[0][..., MODEL_NAMES.index("margaria1968"), 0]).all()


def _variants():
    umberger = [(f"umberger {name}", "umberger2003",
                 dataclasses.replace(load_umberger_constants(variant), **overrides))
                for name, (variant, overrides) in UMBERGER_OPTIONS.items()]
    bhargava = [(f"bhargava {name}", "bhargava2004",
                 dataclasses.replace(load_bhargava_constants(), **overrides))
                for name, overrides in BHARGAVA_OPTIONS.items()]
    others = [
        ("bhargava heat rates off", "bhargava2004",
         dataclasses.replace(load_bhargava_constants(), maintenance_rate_on=False)),
        ("umberger no shortening heat", "umberger2003",
         dataclasses.replace(load_umberger_constants("umberger2010"), shortening_rate_on=False)),
        ("houdijk forbid negative", "houdijk2006",
         dataclasses.replace(load_houdijk_constants(), forbid_negative_total_power=True)),
        ("lichtwark constant gamma", "lichtwark2005",
         dataclasses.replace(load_lichtwark_constants(), maintenance_decay_constant=1.5,
                             maintenance_decay_fast_amplitude=0.0,
                             maintenance_decay_slow_amplitude=0.0,
                             include_negative_mechanical_work=False)),
        ("margaria positive work only", "margaria1968",
         dataclasses.replace(load_margaria_constants(), include_negative_mechanical_work=False)),
    ]
    return umberger + bhargava + others


@pytest.mark.parametrize(("label", "name", "constants"), _variants(),
                         ids=[v[0] for v in _variants()])
def test_every_option_set_gives_the_numpy_paths_bits(label, name, constants):
    bank = _bank()
    muscle = VmMuscleConstants.from_bank(bank)
    time_s, drive, activity, length, velocity = _states(bank, seed=len(label))
    duration = np.abs(np.sin(time_s))[:, None] * np.ones(bank.n)
    heat = rates_from_inputs(vm_model_inputs(muscle, drive, activity, length, velocity,
                                             duration), [name], {name: constants})[name]
    models = compiled.CompiledModels([published_model(name)], [constants], muscle)
    out = np.full((1, len(COMPONENTS), *length.shape), 123.0)
    models.fill(out, drive, activity, length, velocity, duration)
    for c, component in enumerate(COMPONENTS):
        np.testing.assert_array_equal(_bits(out[0, c]), _bits(getattr(heat, component)),
                                      err_msg=f"{label}: {component}")


def test_the_compiled_loops_do_not_fuse_multiply_adds():
    """A product added to a third number rounds twice in NumPy: compiled with the contract flag
    it would round once, and the bits would differ (this test fails there)."""
    bank = _bank()
    muscle = VmMuscleConstants.from_bank(bank)
    constants = load_margaria_constants()
    models = compiled.CompiledModels([published_model("margaria1968")], [constants], muscle)
    rng = np.random.default_rng(3)
    shape = (50, bank.n)
    velocity = bank.l0_m * rng.uniform(-3.0, 3.0, shape)
    activity = rng.uniform(0.0, 1.0, (*shape, 2))
    length = bank.l0_m * rng.uniform(0.6, 1.4, shape)
    out = np.empty((1, len(COMPONENTS), *shape))
    models.fill(out, np.full(shape, 0.5), activity, length, velocity, None)
    inputs = vm_model_inputs(muscle, np.full(shape, 0.5), activity, length, velocity)
    np.testing.assert_array_equal(_bits(out[0, COMPONENTS.index("mechanical_work")]),
                                  _bits(-inputs.state.active_fibre_force * velocity))


ORDER_CHECK = """
import sys
import numpy as np
sys.path.insert(0, {test_dir!r})
from test_energetics_compiled import _bank, _bits, _states
from test_layout_digests import DIGESTS, bank_digest, simd_level
from vm_ros.model import kernel
from vm_ros.model.energetics_models.in_bank import BankModels
from vm_ros.model.energetics_models.vm_state import VmMuscleConstants

def models_match_numpy():
    bank = _bank()
    muscle = VmMuscleConstants.from_bank(bank)
    states = _states(bank)
    expected = BankModels("all", muscle, compile_models=False).advance(1e-3, *states)
    got = BankModels("all", muscle).advance(1e-3, *states)
    return all(np.array_equal(_bits(a), _bits(b)) for a, b in zip(expected, got))

if {models_first!r}:
    assert models_match_numpy(), "models compiled first differ from NumPy"
    assert bank_digest("auto") == DIGESTS[simd_level()]["bank_auto"], \
        "kernel compiled after the models differs"
else:
    kernel.warm_up()
    assert bank_digest("auto") == DIGESTS[simd_level()]["bank_auto"], \
        "kernel compiled first differs"
    assert models_match_numpy(), "models compiled after the kernel differ from NumPy"
"""


@pytest.mark.parametrize("models_first", [True, False])
def test_numbers_do_not_depend_on_which_compiles_first(tmp_path, models_first):
    """Numba keeps one compile of a shared helper per process, with its first caller's flags:
    the kernel (fused multiply-adds allowed) and the models' loops (not) must share none. Each
    order in a fresh process with an empty cache: the kernel's bank digest (test_layout_digests)
    and the models' bits against NumPy."""
    if _skip_reason():
        pytest.skip(_skip_reason())
    code = ORDER_CHECK.format(test_dir=str(Path(__file__).parent), models_first=models_first)
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "numba")}
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                            env=env, timeout=600)
    assert result.returncode == 0, result.stderr[-2000:]


def test_the_compiled_sine_and_cosine_are_numpys():
    """The recruitment's sin and cos of pi u / 2 in a compiled loop are NumPy's, bit for bit,
    over a dense grid of the scaled excitation and beyond it (NumPy's float64 sin and cos call
    libm, which the loop calls; a machine where NumPy's are its own SIMD code fails here)."""
    from vm_ros.model.energetics_models.bhargava import recruitment_sin_cos

    u = np.concatenate([np.linspace(0.0, 1.0, 200_001), np.linspace(-3.0, 3.0, 100_001),
                        [-0.0, 1e-300, np.inf, np.nan]])
    out = np.empty((2, u.size))
    compiled._sin_cos_loop(1.0, u, out)
    with np.errstate(invalid="ignore"):  # sin and cos of infinity: NaN
        numpy_values = recruitment_sin_cos(u)
    for got, expected in zip(out, numpy_values, strict=True):
        np.testing.assert_array_equal(_bits(got), _bits(expected))


def test_the_loops_warm_up_compiles_are_the_ones_a_series_calls():
    """warm_up compiles the loops on a one-step block; a series of several steps (blocks of
    many rows, one row, and the energies summed chunk by chunk) must call those same
    compiles, not compile others in its first block (read-only or differently laid out
    arrays would type otherwise)."""
    bank = _bank()
    models = BankModels("all", VmMuscleConstants.from_bank(bank))
    compiled_before = {loop.__name__: len(loop.signatures) for loop in compiled.LOOPS}
    time_s, drive, activity, length, velocity = _states(bank, steps=30)
    for part in (slice(0, 29), slice(29, 30)):
        models.advance(1e-3, time_s[part], drive[part], activity[part], length[part],
                       velocity[part])
    assert {loop.__name__: len(loop.signatures) for loop in compiled.LOOPS} == compiled_before
