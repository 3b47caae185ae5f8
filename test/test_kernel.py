"""The compiled step (vm_ros.model.kernel) against the NumPy step: same equations, same numbers.

The NumPy step is the one test_integrator.py holds against the scipy Radau reference; the compiled
step calls the same equation functions in the same order, so the two must agree to rounding. The
kernel is compiled with fused multiply-adds (fast-math contraction) and its exp, expm1, log,
log1p and power are vm_ros.model.jit's arithmetic versions (within a few ulp of NumPy's, checked
below), so they differ in the last bits, and the stiff fascicle dynamics carry that on: measured
over these 1500 steps at most 8e-8 of the largest fascicle velocity (where FV is flat a
rounding-level force difference moves V most), 5e-10 of length, 4e-10 of force. Held here to
1e-5 of each field's scale; an error in an equation shows up at 1e-3 or more. Without Numba the
compiled step is unavailable, the bank falls back to NumPy, and the comparisons are skipped (they
are recorded as skips, so a Numba-less run shows them); the kernel's own code is still held to the
NumPy step, run as plain Python, by test_model_layout.py.
"""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest

from vm_ros.errors import InputError
from vm_ros.model import SCHEMES, MuscleBank, jit, kernel, layout, load_model_params
from vm_ros.model.compiled_step import CompiledStep, KernelConstants
from vm_ros.model.lumped_fit import with_drive_law
from vm_ros.model.params import DRIVE_LAWS
from vm_ros_bench import model_bench

DT = 1e-3
needs_numba = pytest.mark.skipif(not kernel.AVAILABLE, reason="numba not importable")


def library_bank(scheme, recovery_mode, backend, count=13, units_per_type=None, params=None):
    return model_bench.library_bank(count, scheme, backend, units_per_type, params=params,
                                    recovery_mode=recovery_mode)


def drive_and_path(k, n, lp0):
    """A drive sweeping 0..1 and a path moving +-1.5 cm at up to 0.3 m/s, phase-shifted."""
    phase = np.arange(n)
    u = 0.5 + 0.6 * np.sin(0.004 * k + phase)  # exceeds [0, 1]: tests the clipping too
    lp = lp0 + 0.015 * np.sin(0.02 * k + phase)
    vp = 0.015 * 0.02 / DT * np.cos(0.02 * k + phase)
    return u, lp, vp


FIELDS = ("force", "contractile_force", "fascicle_length", "fascicle_velocity",
          "effective_drive", "effective_drive_by_fibre", "effective_activation",
          "firing_rate_f05", "mechanical_power",
          "mechanical_work", "excitation")


TOLERANCE = 1e-5


def assert_close(a, b, name=""):
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    scale = max(float(np.max(np.abs(b))), 1e-300)
    # 1e-12 SI floor: a state at rest has velocities of 1e-15 m/s, numerically zero
    np.testing.assert_allclose(a, b, rtol=TOLERANCE, atol=TOLERANCE * scale + 1e-12,
                               err_msg=name)


def assert_outputs_equal(a, b):
    for name in FIELDS:
        assert_close(getattr(a, name), getattr(b, name), name)
    assert_close(a.energy_rate_by_fibre.as_array(), b.energy_rate_by_fibre.as_array(), "rates")
    assert_close(a.energy_by_fibre.as_array(), b.energy_by_fibre.as_array(), "energies")


def _compiled_math():
    """jit's exp, expm1, log, log1p and power compiled as the kernel compiles them."""
    import numba

    @numba.njit(fastmath=kernel.FASTMATH, error_model="numpy")
    def evaluate(x, y, exponent, out):
        for i in range(x.shape[0]):
            out[0, i] = jit.exp(x[i])
            out[1, i] = jit.expm1(x[i])
            out[2, i] = jit.log(y[i])
            out[3, i] = jit.log1p(x[i])
            out[4, i] = jit.power(y[i], exponent[i])

    return evaluate


@needs_numba
def test_compiled_transcendentals_match_numpy_to_a_few_ulp():
    """The arithmetic exp, expm1, log, log1p and power the kernel uses (no libm calls, so that
    its loops vectorise) against NumPy's libm: within 2 ulp (log1p also where 1 + x rounds, and
    over (-1, 0)), power within its exp(y log x) error (2 + 2 |y log x| ulp), and NumPy's
    values at 0, infinity, NaN, negative, subnormal and overflowing arguments."""
    rng = np.random.default_rng(7)
    x = np.concatenate([rng.uniform(-700, 700, 20000), rng.uniform(-1, 1, 20000),
                        10.0 ** rng.uniform(-300, 0, 5000) * rng.choice([-1, 1], 5000),
                        [0.0, -0.0, 1e-320, 709.7, 710.0, -745.0, -746.0, -800.0, 800.0,
                         np.inf, -np.inf, np.nan]])
    y = np.concatenate([10.0 ** rng.uniform(-307, 307, 20000), rng.uniform(0, 3, 20000),
                        rng.uniform(-1, 1e-3, 5000),
                        [0.0, 1.0, 5e-324, 1e-310, 2.0, -1.0, -0.5, 3.0, 1e300, 1e-300,
                         np.inf, np.nan]])
    exponent = rng.uniform(-4, 4, x.size)
    out = np.empty((5, x.size))
    _compiled_math()(x, y, exponent, out)
    with np.errstate(all="ignore"):
        references = (np.exp(x), np.expm1(x), np.log(y), np.log1p(x),
                      np.power(y, exponent))
        error_bound = (2.0, 2.0, 2.0, 2.0, 2.0 + 2.0 * np.abs(exponent * np.log(y)))
    for name, got, expected, bound in zip(("exp", "expm1", "log", "log1p", "power"), out,
                                          references, error_bound, strict=True):
        finite = np.isfinite(expected)  # (subnormal results included: their ulp is 5e-324)
        ulp = np.spacing(np.abs(expected[finite]))
        bound = np.broadcast_to(bound, expected.shape)[finite]
        excess = np.abs(got[finite] - expected[finite]) / (bound * ulp)
        assert excess.max() <= 1.0, (name, float(excess.max()))
        np.testing.assert_array_equal(got[~finite], expected[~finite], err_msg=name)


@needs_numba
@pytest.mark.parametrize("recovery_mode", ["static", "dynamic"])
@pytest.mark.parametrize("scheme", SCHEMES)
def test_compiled_step_equals_numpy_step(scheme, recovery_mode):
    kwargs = {"units_per_type": 5} if scheme == "natural" else {}
    banks = [library_bank(scheme, recovery_mode, b, **kwargs) for b in ("numpy", "numba")]
    assert [b.backend for b in banks] == ["numpy", "numba"]
    lp0 = banks[0].l0_m + banks[0].l0t_m
    for b in banks:
        b.reset(lp0, excitation=np.full(b.n, 0.2))
    for k in range(1500):
        u, lp, vp = drive_and_path(k, banks[0].n, lp0)
        outs = [b.step(DT, u, lp, vp) for b in banks]
        if k % 50 == 0 or k > 1450:
            assert_outputs_equal(*outs)
    assert np.max(outs[0].force / banks[0].f0) > 0.3  # the comparison covered active states


@needs_numba
@pytest.mark.parametrize("law", DRIVE_LAWS)
def test_compiled_step_equals_numpy_step_for_each_drive_law(law):
    params = with_drive_law(load_model_params(), law)
    banks = [library_bank("lumped", "static", b, params=params) for b in ("numpy", "numba")]
    lp0 = banks[0].l0_m + banks[0].l0t_m
    for b in banks:
        b.reset(lp0)
    drive = np.repeat([0.0, 0.6, 0.2, 1.0, 0.0], 150)  # steps up and down, from and to rest
    lag = apart = 0.0
    for k, level in enumerate(drive):
        u = np.full(banks[0].n, level)
        outs = [b.step(DT, u, lp0) for b in banks]
        lag = max(lag, float(np.max(np.abs(outs[0].effective_drive - level))))
        ueff = outs[1].effective_drive_by_fibre
        apart = max(apart, float(np.max(np.abs(ueff[:, 1] - ueff[:, 0]))))
        if k % 25 == 0:
            assert_outputs_equal(*outs)
    assert lag > 0.1  # the filter's law was exercised, not bypassed
    # relative_drive holds the fast type's W once U is below U2 (0.6 -> 0.2 crosses it for most
    # library muscles), so the two types' Ueff part; the paper's law has one filter for both
    assert (apart > 0.05) if law == "relative_drive" else apart == 0.0


@needs_numba
def test_compiled_step_after_set_state_and_reset():
    """FL/FV kept from the last step are reused only for the same (x, xdot): after set_state
    (going back in time) and after reset the compiled step still equals the NumPy step."""
    banks = [library_bank("lumped", "dynamic", b, count=4) for b in ("numpy", "numba")]
    lp0 = banks[0].l0_m + banks[0].l0t_m
    for b in banks:
        b.reset(lp0)
    saved = None
    for k in range(400):
        u, lp, vp = drive_and_path(k, 4, lp0)
        for b in banks:
            b.step(DT, u, lp, vp)
        if k == 150:
            saved = banks[1].state
    for b in banks:
        b.set_state(saved)
    for k in range(151, 300):
        u, lp, vp = drive_and_path(k, 4, lp0)
        outs = [b.step(DT, u, lp, vp) for b in banks]
    assert_outputs_equal(*outs)
    for b in banks:
        b.reset(lp0 * 1.01, excitation=np.full(4, 0.4))
    outs = [b.step(DT, 0.4, lp0 * 1.01) for b in banks]
    assert_outputs_equal(*outs)


@needs_numba
@pytest.mark.parametrize(
    "bad",
    [
        {"excitation": [0.1, np.nan, 0.2]},
        {"path_length": [0.3, 0.3, -0.1]},
        {"path_velocity": [0.0, np.inf, 0.0]},
        {"excitation": [0.1, 0.2]},
    ],
)
def test_compiled_step_rejects_bad_input_and_keeps_state(bad):
    bank = MuscleBank.from_config(["vasti", "soleus", "rectus_femoris"], backend="numba")
    lp = bank.l0_m + bank.l0t_m
    bank.reset(lp, excitation=0.3)
    bank.step(DT, 0.3, lp)
    before = bank.state
    inputs = {"excitation": [0.3] * 3, "path_length": lp, "path_velocity": None, **bad}
    with pytest.raises(InputError):
        bank.step(DT, **inputs)
    after = bank.state
    for name in ("fascicle_length_m", "effective_drive", "firing_rate_effective", "energy_j"):
        np.testing.assert_array_equal(getattr(after, name), getattr(before, name))
    assert after.time_s == before.time_s


@needs_numba
def test_outputs_are_independent_of_later_steps():
    """Fields computed on first access reflect the step that returned them."""
    bank = MuscleBank.from_config(["vasti"])
    lp = bank.l0_m + bank.l0t_m
    bank.reset(lp)
    first = bank.step(DT, 1.0, lp)
    length, energy = first.fascicle_length.copy(), first.energy.total.copy()
    for _ in range(100):
        bank.step(DT, 1.0, lp)
    late = first  # read only now
    np.testing.assert_array_equal(late.fascicle_length, length)
    np.testing.assert_array_equal(late.energy.total, energy)


def test_backend_selection_and_numpy_fallback():
    """backend='numpy' always works; with VM_ROS_NUMBA=0 the package runs without Numba."""
    bank = MuscleBank.from_config(["soleus"], backend="numpy")
    assert bank.backend == "numpy"
    with pytest.raises(ValueError, match="backend must be one of"):
        MuscleBank.from_config(["soleus"], backend="fortran")
    code = (
        "import sys, numpy as np\n"
        "from vm_ros.model import MuscleBank, kernel\n"
        "assert not kernel.AVAILABLE and 'numba' not in sys.modules\n"
        "b = MuscleBank.from_config(['soleus'])\n"
        "assert b.backend == 'numpy'\n"
        "lp = b.l0_m + b.l0t_m\n"
        "b.reset(lp)\n"
        "out = [b.step(1e-3, 1.0, lp) for _ in range(300)][-1]\n"
        "assert out.force[0] > 0.3 * b.f0[0]\n"
        "try:\n"
        "    MuscleBank.from_config(['soleus'], backend='numba')\n"
        "    raise SystemExit('numba backend accepted without numba')\n"
        "except ValueError as e:\n"
        "    assert 'numba' in str(e)\n"
    )
    env = {**os.environ, "VM_ROS_NUMBA": "0"}
    result = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                            text=True, timeout=120)
    assert result.returncode == 0, result.stderr


@pytest.mark.parametrize("backend", ["numpy", "numba"])
def test_run_equals_repeated_steps(backend):
    """MuscleBank.run (one call for k steps) gives what k calls of step give."""
    if backend == "numba" and not kernel.AVAILABLE:
        pytest.skip("numba not importable")
    banks = [library_bank("lumped", "dynamic", backend, count=3) for _ in range(2)]
    lp0 = banks[0].l0_m + banks[0].l0t_m
    rows = [drive_and_path(k, 3, lp0) for k in range(600)]
    u, lp, vp = (np.array([r[i] for r in rows]) for i in range(3))
    for b in banks:
        b.reset(lp0)
    trajectory = banks[0].run(DT, u, lp, vp)
    outs = [banks[1].step(DT, u[k], lp[k], vp[k]) for k in range(600)]
    assert_close(trajectory.force, [o.force for o in outs], "force")
    assert_close(trajectory.fascicle_length, [o.fascicle_length for o in outs], "length")
    assert_close(trajectory.energy_rate.total, [o.energy_rate.total for o in outs], "energy")
    np.testing.assert_allclose(trajectory.time_s, [o.time_s for o in outs], rtol=1e-12)
    assert_outputs_equal(trajectory.last, outs[-1])
    assert banks[0].time_s == pytest.approx(0.6)
    # a bad row: InputError naming the step, state as before the call
    before = banks[0].state
    u_bad = u.copy()
    u_bad[250, 1] = np.nan
    with pytest.raises(InputError, match="at step 250"):
        banks[0].run(DT, u_bad, lp, vp)
    np.testing.assert_array_equal(banks[0].state.fascicle_length_m, before.fascicle_length_m)
    assert banks[0].time_s == before.time_s


def test_set_state_checks_shapes_and_converts_to_float():
    bank = MuscleBank.from_config(["vasti", "soleus", "rectus_femoris"])
    other = MuscleBank.from_config(["vasti", "soleus"])
    lp = bank.l0_m + bank.l0t_m
    bank.reset(lp)
    other.reset(other.l0_m + other.l0t_m)
    with pytest.raises(ValueError, match="shape"):
        bank.set_state(other.state)
    state = bank.state
    state.energy_j = state.energy_j.astype(np.int64)
    state.mechanical_work_j = state.mechanical_work_j.astype(np.int64)
    bank.set_state(state)
    for _ in range(100):
        out = bank.step(DT, 1.0, lp)
    assert np.all(out.energy.total > 1.0)  # not truncated to whole joules per step
    assert bank.state.energy_j.dtype == np.float64


@needs_numba
def test_unusual_input_arrays_do_not_recompile_the_kernel():
    bank = MuscleBank.from_config(["vasti", "soleus"])
    lp = bank.l0_m + bank.l0t_m
    bank.reset(lp)
    signatures = len(kernel.advance_series.signatures)
    table = np.column_stack([lp, lp, lp])  # a column of it is a strided view
    frozen = lp.copy()
    frozen.flags.writeable = False
    bank.step(DT, np.array([0.3, 0.3]), table[:, 1])
    bank.step(DT, [0.3, 0.3], frozen)
    bank.step(DT, np.array([1, 0]), lp)  # integers
    bank.run(DT, np.full((3, 2), 0.3), np.tile(lp, (3, 1)))
    assert len(kernel.advance_series.signatures) == signatures


@needs_numba
def test_step_and_run_share_one_compiled_kernel():
    """A step is a series of one: the single-step function is never compiled by a bank."""
    code = (
        "import numpy as np\n"
        "from vm_ros.model import MuscleBank, kernel\n"
        "b = MuscleBank.from_config(['vasti'])\n"
        "lp = b.l0_m + b.l0t_m\n"
        "b.reset(lp)\n"
        "b.step(1e-3, 0.5, lp)\n"
        "b.run(1e-3, np.full((4, 1), 0.5), np.tile(lp, (4, 1)), snapshot_every=2)\n"
        "assert len(kernel.advance_series.signatures) == 1, kernel.advance_series.signatures\n"
        "assert not hasattr(kernel, 'advance') and not kernel.advance_series_parallel.signatures\n"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                            timeout=300)
    assert result.returncode == 0, result.stderr


def _series_inputs(bank, k):
    lp0 = bank.l0_m + bank.l0t_m
    rows = [drive_and_path(j, bank.n, lp0) for j in range(k)]
    return lp0, [np.array([r[i] for r in rows]) for i in range(3)]


@needs_numba
@pytest.mark.parametrize("chunk", [1, 5, 13])
def test_parallel_kernel_equals_serial_kernel_bit_for_bit(chunk):
    """The parallel build over blocks of ``chunk`` muscles gives the serial kernel's numbers to
    the bit (every output and state array, snapshots included), and stops at the same bad
    input."""
    bank = library_bank("lumped", "dynamic", "numba", count=13)
    lp0, (u, lp, vp) = _series_inputs(bank, 300)
    results = []
    for function, block in ((kernel.advance_series, 0), (kernel.advance_series_parallel, chunk)):
        bank.reset(lp0, excitation=np.full(bank.n, 0.2))
        step = CompiledStep(KernelConstants.from_bank(bank), bank.n)
        step._advance_series, step.parallel_chunk = function, block
        status, new, record, length, velocity, snapshots = step.series(
            bank.state, DT, u, lp, vp, snapshot_every=7)
        assert status == 0
        step_state, step_record = step.step(new, DT, u[-1], lp[-1], vp[-1])
        bad = u.copy()
        bad[40, 11] = np.nan
        bad[40, 3] = np.inf
        first_bad = step.series(new, DT, bad, lp, vp)[0]
        arrays = [*record, length, velocity, *snapshots, *step_record,
                  *(getattr(step_state, name) for name in layout.STATE_NAMES)]
        results.append(([a.copy() for a in arrays], first_bad))
    (serial, serial_bad), (parallel, parallel_bad) = results
    for a, b in zip(serial, parallel, strict=True):
        np.testing.assert_array_equal(a, b)
    assert serial_bad == parallel_bad == 40 * bank.n + 3 + 1


@needs_numba
def test_parallel_switch_and_threshold(monkeypatch):
    """Off by default; VM_ROS_PARALLEL=1 (or parallel=True) switches it on for banks of
    PARALLEL_MIN_MUSCLES or more; below that the step stays serial."""
    monkeypatch.delenv(kernel.PARALLEL_ENV, raising=False)
    assert not kernel.parallel_wanted()
    assert kernel.parallel_wanted(True) and not kernel.parallel_wanted(False)
    monkeypatch.setenv(kernel.PARALLEL_ENV, "1")
    assert kernel.parallel_wanted()
    assert kernel.parallel_chunk(kernel.PARALLEL_MIN_MUSCLES - 1, threads=2) == 0
    assert kernel.parallel_chunk(1001, threads=2) == 501
    assert kernel.parallel_chunk(1001, threads=1) == 0


@needs_numba
def test_run_reuses_only_buffers_no_caller_holds():
    """A second run never writes into the arrays of a trajectory the caller still holds; once
    the caller lets them go, a run of the same size writes into them again."""
    bank = library_bank("lumped", "static", "numba", count=4)
    lp0, (u, lp, vp) = _series_inputs(bank, 50)
    bank.reset(lp0)
    first = bank.run(DT, u, lp, vp, snapshot_every=10)
    kept = {name: getattr(first, name).copy() for name in ("force", "fascicle_length")}
    kept_snapshot = first.snapshots.fascicle_length_m.copy()
    second = bank.run(DT, u[::-1].copy(), lp, vp, snapshot_every=10)
    for name, value in kept.items():
        np.testing.assert_array_equal(getattr(first, name), value)
        assert not np.shares_memory(getattr(first, name), getattr(second, name))
    np.testing.assert_array_equal(first.snapshots.fascicle_length_m, kept_snapshot)
    address = first.force.__array_interface__["data"][0]
    del first
    third = bank.run(DT, u, lp, vp, snapshot_every=10)
    assert third.force.__array_interface__["data"][0] == address
    assert not np.shares_memory(third.force, second.force)


def test_run_names_the_input_with_the_wrong_rows_and_adds_time_like_step():
    bank = MuscleBank.from_config(["vasti"])
    lp = bank.l0_m + bank.l0t_m
    bank.reset(lp)
    u = np.full((7, 1), 0.4)
    with pytest.raises(InputError, match="path_velocity"):
        bank.run(DT, u, np.tile(lp, (7, 1)), np.zeros((6, 1)))
    with pytest.raises(InputError, match="dt"):
        bank.step(True, 0.4, lp)
    trajectory = bank.run(DT, u, np.tile(lp, (7, 1)))
    t = 0.0
    for _ in range(7):
        t += DT
    assert trajectory.time_s[-1] == t == bank.time_s


@needs_numba
def test_numba_cache_folder_follows_the_model_sources_even_if_numba_came_first():
    code = (
        "import numba\n"
        "from vm_ros.model import kernel, jit\n"
        "path = kernel.advance_series.stats.cache_path\n"
        "assert jit.sources_hash(kernel.__file__) in path, path\n"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                            timeout=120)
    assert result.returncode == 0, result.stderr


_VECTORISED_LOOPS = """
import re
from vm_ros.model import kernel, layout
kernel.advance_series(*layout.dummy_arguments(0))
ir = kernel.advance_series.inspect_llvm(kernel.advance_series.signatures[0])
for loop in kernel.PHASE_LOOPS:
    bodies = [f for f in re.split(r"\\n(?=define )", ir)
              if re.match(r"define [^@]*@\\w*" + loop.__name__ + r"B", f)]
    vectors = sum(len(re.findall(r"<[2-9] x double>", f)) for f in bodies)
    calls = sum(len(re.findall(r"call [^@\\n]*@(?:_ZN|(?:llvm\\.(?:exp|log|pow)\\w*|exp|expm1"
                               r"|log|log1p|pow)\\b)", f)) for f in bodies)
    print(loop.__name__, len(bodies), vectors, calls)
"""


@needs_numba
def test_the_phase_loops_are_compiled_to_simd_code(tmp_path):
    """Each phase loop of the compiled kernel is vectorised: its LLVM IR works on vectors of
    doubles and calls no function (a call left in a loop, such as a libm function or an equation
    LLVM did not inline, keeps it scalar, about 8x slower). Compiled afresh in a child process
    (Numba does not show the IR of a kernel loaded from its cache)."""
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path)}
    result = subprocess.run([sys.executable, "-c", _VECTORISED_LOOPS], capture_output=True,
                            text=True, timeout=600, env=env, cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    rows = [line.split() for line in result.stdout.splitlines()]
    assert [row[0] for row in rows] == [loop.__name__ for loop in kernel.PHASE_LOOPS]
    for name, bodies, vectors, calls in rows:
        assert int(bodies) >= 1 and int(vectors) > 0 and int(calls) == 0, (name, bodies, vectors,
                                                                           calls)
