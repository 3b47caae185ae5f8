"""Optional compilation of the model's equations with Numba (one source for both back ends).

Every equation of the model is a small pure function written once, over NumPy arrays. The ones the
fixed step needs are marked :func:`jitable`: called from Python they are the plain functions
(vectorised NumPy code); called from the compiled step kernel (``vm_ros.model.kernel``) Numba
compiles the same source for scalars. Without Numba (not installed, or ``VM_ROS_NUMBA=0``) the
decorator does nothing and the bank uses the NumPy step.

The two helpers below exist because NumPy's ``np.where`` and ``np.clip`` do not accept plain
scalars inside Numba: :func:`where` and :func:`clip` are ``np.where`` and ``np.clip`` from Python
and branch on scalars when compiled.

The transcendental functions :func:`exp`, :func:`expm1`, :func:`log`, :func:`log1p` and
:func:`power` are NumPy's from Python. Compiled for scalars they are written out in arithmetic
(no call into libm), so that LLVM can inline them and vectorise the kernel's loops over muscles
with SIMD instructions; libm's scalar calls were most of the kernel's time and cannot be
vectorised by this Numba (its LLVM has no vector maths library). exp and expm1: Cody & Waite's
reduction x = k ln2 + r and expm1(r) by its Taylor series to r^13; log and log1p: fdlibm's
(e_log.c). test_kernel.py holds them to 2 ulp of NumPy's, power to 2 + 2 |y log x| ulp, with
NumPy's values at 0, infinity, NaN and negative arguments.
"""

from __future__ import annotations

import functools
import hashlib
import importlib.metadata
import math
import os
import signal
import sys
import threading
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from vm_ros.resources import cache_home

ENV_SWITCH = "VM_ROS_NUMBA"
_MODEL_DIR = Path(__file__).resolve().parent


def _numba_wanted() -> bool:
    return os.environ.get(ENV_SWITCH, "1").strip().lower() not in ("0", "false", "no", "off")


numba = None
if _numba_wanted():
    try:
        import numba
        from numba.core import caching as _caching
        from numba.core import types as _nb_types
        from numba.extending import overload, register_jitable
    except ImportError:  # pragma: no cover - exercised where numba is absent
        numba = None

HAVE_NUMBA = numba is not None


# --- Numba's disk cache: one per machine, Python and vm_ros version ------------------------------


def cache_root() -> Path:
    """The folder of vm_ros's Numba cache: NUMBA_CACHE_DIR where it is set (Numba reads it when
    it is imported), else ``$XDG_CACHE_HOME/vm_ros/numba-py<X.Y>-<vm_ros version>`` (XDG_CACHE_HOME
    defaults to ~/.cache)."""
    if HAVE_NUMBA and numba.config.CACHE_DIR:
        return Path(numba.config.CACHE_DIR)
    try:
        version = importlib.metadata.version("vm_ros")
    except importlib.metadata.PackageNotFoundError:  # run from a source tree
        version = "source"
    return cache_home() / f"numba-py{sys.version_info[0]}.{sys.version_info[1]}-{version}"


@functools.cache
def sources_hash(py_file: str) -> str:
    """A hash of every model source file, of ``py_file`` and of Numba's version: Numba checks a
    cached function against its own file only, not against the modules whose functions it
    inlines; and two Numba versions (a venv's, a ROS workspace's) would each find the other's
    index stale and compile again, over and over. For a file in a folder below the model's
    (energetics_models), that folder's sources too."""
    digest = hashlib.sha256(numba.__version__.encode() if HAVE_NUMBA else b"")
    folder = Path(py_file).resolve().parent
    below = folder.glob("*.py") if folder.parent == _MODEL_DIR else ()
    for path in sorted({*_MODEL_DIR.glob("*.py"), *below, Path(py_file).resolve()}):
        digest.update(path.name.encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()[:16]


@contextmanager
def model_cache_directory():
    """Functions decorated with ``cache=True`` inside this block cache in
    ``cache_root()/<sources_hash>/<folder of their file>`` (``model`` or ``geometry``): the same
    folder for every install of the same sources (Numba's own folder is keyed by the absolute
    path of the installed file, one compile per install location), and a fresh one after any edit
    to a model source. Numba picks the folder when a function is decorated, so this works
    whether or not numba was imported before. Where that folder cannot be written, Numba's own
    locations apply."""
    saved = _CacheImpl._locator_classes
    _CacheImpl._locator_classes = [_SourcesCacheLocator, *saved]
    try:
        yield
    finally:
        _CacheImpl._locator_classes = saved


def in_disk_cache(dispatcher) -> bool:
    """Whether Numba's disk cache holds a fresh compile of ``dispatcher`` (a function decorated
    with ``cache=True``): its index file exists, is of this Numba and of these sources. (Numba's
    cache classes have no public interface for this; False if theirs changed.)"""
    try:
        return bool(dispatcher._cache._cache_file._load_index())
    except Exception:  # noqa: BLE001 - any change in Numba's private classes: "not cached"
        return False


# The main thread's wait between two checks of a compiling thread (its signals are handled then)
COMPILE_POLL_S = 0.05


def compile_interruptibly(compile_now, what: str, expected: str) -> None:
    """Run ``compile_now()`` after one line on stderr (``what`` compiles, taking ``expected``,
    and where it is cached). On the main thread it runs in a worker thread while this thread
    waits, so that SIGINT or SIGTERM ends the process within COMPILE_POLL_S: one line on stderr
    and exit status 128 + the signal's number (``os._exit``: a compile cannot be stopped half
    way, and it has started nothing to finish). Numba's compile otherwise holds the main thread
    for its whole time, and a handler that only sets a flag (muscle_node's) is seen after it."""
    print(f"vm_ros: compiling {what} with Numba, once per machine, Python and vm_ros version "
          f"({expected}; cached in {cache_root()})", file=sys.stderr, flush=True)
    if threading.current_thread() is not threading.main_thread():
        compile_now()
        return
    outcome = []

    def work():
        try:
            compile_now()
        except BaseException as exc:  # noqa: BLE001 - raised again on the calling thread
            outcome.append(exc)

    def stop(signum, frame):
        print(f"vm_ros: {signal.Signals(signum).name} while compiling {what}: stopped",
              file=sys.stderr, flush=True)
        os._exit(128 + signum)

    previous = {sig: signal.getsignal(sig) for sig in (signal.SIGINT, signal.SIGTERM)}
    for sig, handler in previous.items():
        if handler is not None:  # None: a handler not set from Python, left alone
            signal.signal(sig, stop)
    try:
        worker = threading.Thread(target=work, name="vm_ros-compile", daemon=True)
        worker.start()
        while worker.is_alive():
            worker.join(COMPILE_POLL_S)
    finally:
        for sig, handler in previous.items():
            if handler is not None:
                signal.signal(sig, handler)
    if outcome:
        raise outcome[0]
# a loop over a tuple that Numba unrolls, each pass with its element as a constant
literal_unroll = numba.literal_unroll if HAVE_NUMBA else (lambda iterable: iterable)


# LLVM's limits, raised for the compiled kernel (vm_ros.model.kernel): each phase is a loop over
# muscles calling the model's equation functions, which LLVM must inline whole before it can
# vectorise the loop (default threshold 225), and whose rows it must check for overlap once per
# loop (default: at most 8 comparisons). With the defaults the phase loops keep calls and stay
# scalar, several times slower (docs/performance.md). These
# are options of the process's LLVM: other Numba code compiled in the same process after the
# kernel is imported sees them too (they change how much LLVM inlines and vectorises, never
# results).
LLVM_OPTIONS = (
    "-inline-threshold=3000",
    "-runtime-memory-check-threshold=4096",
    "-vectorize-memory-check-threshold=4096",
    "-memory-check-merge-threshold=4096",
)


def set_llvm_options() -> None:
    """Set :data:`LLVM_OPTIONS` in this process's LLVM (before the kernel compiles)."""
    if HAVE_NUMBA:
        import llvmlite.binding as llvm

        for option in LLVM_OPTIONS:
            llvm.set_option("vm_ros", option)


# Numba's options for every compiled function of the model: no C-callable ("cfunc") wrapper, which
# Numba otherwise builds, optimises and emits for every function and specialisation, for use as a
# first-class function value, which the model never makes; leaving them out shortens the
# kernel's first compile (docs/performance.md).
COMPILE_OPTIONS = {"no_cfunc_wrapper": True}


def jitable(func=None, *, inline=False):
    """Mark an equation as callable from the compiled kernel (no-op without Numba). With
    ``inline`` Numba inlines its body into every caller before typing (for a large function that
    a loop must have inlined to be vectorised); without it LLVM decides."""
    if func is None:
        return lambda func: jitable(func, inline=inline)
    if not HAVE_NUMBA:
        return func
    return register_jitable(inline="always" if inline else "never", **COMPILE_OPTIONS)(func)


def where(condition, if_true, if_false):
    """``np.where``; a plain branch when compiled for scalars."""
    return np.where(condition, if_true, if_false)


def power(base, exponent):
    """``base ** exponent`` (``np.power``). Compiled for scalars: ``exp(exponent * log(base))``
    for a positive base (a relative difference of a few 1e-16 per unit of
    ``|exponent * log(base)|``), ``base`` itself for an exponent of 1, 0 ** y as NumPy, and NaN
    for a negative base (the model raises only lengths, drives and fractions, all >= 0)."""
    return np.power(base, exponent)


def exp(x):
    """``np.exp``; arithmetic when compiled for scalars (module docstring)."""
    return np.exp(x)


def expm1(x):
    """``np.expm1``; arithmetic when compiled for scalars (module docstring)."""
    return np.expm1(x)


def log(x):
    """``np.log``; arithmetic when compiled for scalars (module docstring)."""
    return np.log(x)


def log1p(x):
    """``np.log1p``; arithmetic when compiled for scalars (module docstring)."""
    return np.log1p(x)


def maximum(a, b):
    """``np.maximum``; compiled for scalars, NumPy's result bit for bit: NaN if either is NaN,
    and ``b`` where a == b (so max(-0.0, 0.0) is 0.0, as NumPy's SIMD loops give it)."""
    return np.maximum(a, b)


def minimum(a, b):
    """``np.minimum``; compiled for scalars as :func:`maximum` (``b`` where a == b)."""
    return np.minimum(a, b)


def divide_where(numerator, denominator, condition, otherwise):
    """``numerator / denominator`` where ``condition``, else ``otherwise``, without dividing
    where not (``np.divide`` with ``out`` and ``where``); a branch when compiled for scalars."""
    shape = np.broadcast_shapes(np.shape(numerator), np.shape(denominator), np.shape(condition),
                                np.shape(otherwise))
    out = np.array(np.broadcast_to(otherwise, shape), dtype=float)
    return np.divide(numerator, denominator, out=out, where=condition)


def fixed_tuple(array, length):
    """The elements of a 1-d array of ``length`` elements as a tuple (Numba's
    ``to_fixed_tuple`` when compiled, which needs ``length`` to be a constant); ValueError for
    an array of another length."""
    if len(array) != length:
        raise ValueError(f"an array of {len(array)} elements, {length} expected")
    return tuple(array)


def clip(value, lower, upper):
    """``min(max(value, lower), upper)`` elementwise (``np.clip`` for scalars and arrays)."""
    return np.minimum(np.maximum(value, lower), upper)


if HAVE_NUMBA:

    def _compiled_overload(function):
        """Numba's ``overload`` with the model's COMPILE_OPTIONS (as :func:`jitable` gives)."""
        return overload(function, jit_options=COMPILE_OPTIONS)

    @_compiled_overload(where)
    def _where_compiled(condition, if_true, if_false):
        if isinstance(condition, _nb_types.Boolean):

            def scalar_where(condition, if_true, if_false):
                return if_true if condition else if_false

            return scalar_where

        def array_where(condition, if_true, if_false):
            return np.where(condition, if_true, if_false)

        return array_where

    from numba.np.unsafe.ndarray import to_fixed_tuple

    # CacheImpl and its list of locators: _CacheImpl before Numba 0.68
    _CacheImpl = getattr(_caching, "CacheImpl", None) or _caching._CacheImpl

    class _SourcesCacheLocator(_caching._SourceFileBackedLocatorMixin, _caching._CacheLocator):
        """Numba's cache locator for model_cache_directory: the folder there, and the sources'
        hash as the stamp that Numba checks the cached index against (Numba's is the file's
        own hash since 0.68, its time and size before, which every install changes)."""

        def __init__(self, py_func, py_file):
            self._py_file = py_file
            self._lineno = py_func.__code__.co_firstlineno
            self._stamp = sources_hash(py_file)
            self._cache_path = str(cache_root() / self._stamp / Path(py_file).parent.name)

        def get_cache_path(self):
            return self._cache_path

        def get_source_stamp(self):
            return self._stamp

    @jitable
    def _bits_as_float(bits):
        """The float64 whose IEEE 754 bits are the int64 ``bits`` (a bitcast)."""
        return np.int64(bits).view(np.float64)

    @jitable
    def _float_as_bits(value):
        """The IEEE 754 bits of the float64 ``value``, as an int64 (a bitcast)."""
        return np.float64(value).view(np.int64)

    # Cody & Waite's split of ln 2 (the high part has 20 trailing zero bits), as in fdlibm
    _LN2_HI, _LN2_LO = 6.93147180369123816490e-01, 1.90821492927058770002e-10
    _LOG2E = 1.4426950408889634
    # expm1(r) = r + r^2 (1/2! + r/3! + ... + r^11/13!) on |r| <= ln2/2: truncation below 1e-17
    _EXPM1_TAYLOR = tuple(1.0 / math.factorial(k) for k in range(13, 1, -1))
    # log(1+f) = f - f^2/2 + s (f^2/2 + R(s^2)), s = f/(2+f): fdlibm e_log.c's Lg1..Lg7
    _LG = (6.666666666666735130e-01, 3.999999999940941908e-01, 2.857142874366239149e-01,
           2.222219843214978396e-01, 1.818357216161805012e-01, 1.531383769920937332e-01,
           1.479819860511658591e-01)
    _SMALLEST_NORMAL = 2.2250738585072014e-308

    @jitable
    def _exp_parts(x):
        """(2^h, 2^(k-h), 2^-h, expm1(r)) with x = k ln2 + r, |r| <= ln2/2, h = floor(k / 2), x
        clamped to where exp is finite and not zero: exp(x) = 2^h (2^(k-h) (1 + expm1(r))),
        each power of 2 a normal float from k = -1076 to 1024."""
        x = min(max(x, -746.0), 710.0)
        kf = math.floor(x * _LOG2E + 0.5)
        r = (x - kf * _LN2_HI) - kf * _LN2_LO
        c = _EXPM1_TAYLOR
        p = c[0]
        for coefficient in c[1:]:
            p = p * r + coefficient
        k = np.int64(kf)
        half = k >> 1
        return (_bits_as_float((half + 1023) << 52), _bits_as_float((k - half + 1023) << 52),
                _bits_as_float((1023 - half) << 52), r + r * r * p)

    @jitable
    def _exp_scalar(x):
        scale_high, scale_low, _, p = _exp_parts(x)
        return x if x != x else scale_high * (scale_low + scale_low * p)

    @jitable
    def _expm1_scalar(x):
        # exp(x) - 1 = 2^h ((2^(k-h) - 2^-h) + 2^(k-h) expm1(r)): the difference of two powers
        # of 2 is exact where it matters (|k| small, where the 1 cancels), and no factor
        # overflows before the result does
        scale_high, scale_low, inverse_high, p = _exp_parts(x)
        return x if x != x else scale_high * ((scale_low - inverse_high) + scale_low * p)

    @jitable
    def _log_parts(x):
        """(k, f) with x = 2^k (1 + f), 1 + f in [sqrt(1/2), sqrt(2)), for a positive x."""
        subnormal = x < _SMALLEST_NORMAL
        normal = x * 18014398509481984.0 if subnormal else x  # 2^54
        bits = _float_as_bits(normal)
        e = (bits >> 52) - (1077 if subnormal else 1023)
        m = _bits_as_float((bits & 0x000FFFFFFFFFFFFF) | 0x3FF0000000000000)  # [1, 2)
        above = m > 1.4142135623730951
        return np.float64(e + 1 if above else e), (m * 0.5 if above else m) - 1.0

    @jitable
    def _log_from_parts(k, f):
        """k ln2 + log(1 + f) for |f| below about 0.41 (fdlibm's e_log.c)."""
        s = f / (2.0 + f)
        z = s * s
        w = z * z
        lg = _LG
        r = (w * (lg[1] + w * (lg[3] + w * lg[5]))
             + z * (lg[0] + w * (lg[2] + w * (lg[4] + w * lg[6]))))
        half_f2 = 0.5 * f * f
        return k * _LN2_HI - ((half_f2 - (s * (half_f2 + r) + k * _LN2_LO)) - f)

    @jitable
    def _log_special(x, y):
        """y where log(x) is finite; log's value at 0, infinity, negative numbers and NaN."""
        y = x if x == math.inf else y
        y = -math.inf if x == 0.0 else y
        return math.nan if (x < 0.0 or x != x) else y

    @jitable
    def _log_scalar(x):
        k, f = _log_parts(x)
        return _log_special(x, _log_from_parts(k, f))

    @jitable
    def _log1p_scalar(x):
        # where 1 + x needs no power of 2 (k = 0), f is x itself, without the rounding of 1 + x
        # (a correction term such as ((1 + x) - 1) - x would be reassociated to 0 under fast
        # maths); elsewhere |log1p(x)| > 0.29 and the rounding of 1 + x is below an ulp of it
        u = 1.0 + x
        k, f = _log_parts(u)
        f = x if k == 0.0 else f
        return _log_special(u, _log_from_parts(k, f))

    def _scalar_or_array(scalar_function, array_function):
        def choose(x):
            if isinstance(x, _nb_types.Float):
                return scalar_function
            return lambda x: array_function(x)

        return choose

    _compiled_overload(exp)(_scalar_or_array(_exp_scalar, np.exp))
    _compiled_overload(expm1)(_scalar_or_array(_expm1_scalar, np.expm1))
    _compiled_overload(log)(_scalar_or_array(_log_scalar, np.log))
    _compiled_overload(log1p)(_scalar_or_array(_log1p_scalar, np.log1p))

    def _scalars(*args):
        return all(isinstance(arg, (_nb_types.Number, _nb_types.Boolean)) for arg in args)

    @_compiled_overload(maximum)
    def _maximum_compiled(a, b):
        if _scalars(a, b):
            return lambda a, b: a if (a > b or a != a) else b
        return lambda a, b: np.maximum(a, b)

    @_compiled_overload(minimum)
    def _minimum_compiled(a, b):
        if _scalars(a, b):
            return lambda a, b: a if (a < b or a != a) else b
        return lambda a, b: np.minimum(a, b)

    @_compiled_overload(divide_where)
    def _divide_where_compiled(numerator, denominator, condition, otherwise):
        if _scalars(numerator, denominator, condition, otherwise):
            def scalar_divide_where(numerator, denominator, condition, otherwise):
                return numerator / denominator if condition else otherwise

            return scalar_divide_where
        return None

    @_compiled_overload(fixed_tuple)
    def _fixed_tuple_compiled(array, length):
        if not isinstance(length, _nb_types.IntegerLiteral):
            raise numba.errors.TypingError("fixed_tuple's length must be a constant")
        size = length.literal_value

        def constant_length_tuple(array, length):
            if array.shape[0] != size:  # to_fixed_tuple itself does not check
                raise ValueError("fixed_tuple: an array of another length than expected")
            return to_fixed_tuple(array, size)

        return constant_length_tuple

    @_compiled_overload(power)
    def _power_compiled(base, exponent):
        if isinstance(base, _nb_types.Float) and isinstance(exponent, (_nb_types.Float,
                                                                       _nb_types.Integer)):

            def scalar_power(base, exponent):
                y = _exp_scalar(exponent * _log_scalar(base))
                at_zero = 0.0 if exponent > 0.0 else (1.0 if exponent == 0.0 else math.inf)
                y = at_zero if base == 0.0 else y
                return base if exponent == 1.0 else y

            return scalar_power

        def array_power(base, exponent):
            return np.power(base, exponent)

        return array_power

    clip = jitable(clip)


__all__ = ["COMPILE_POLL_S", "ENV_SWITCH", "HAVE_NUMBA", "LLVM_OPTIONS", "cache_root", "clip",
           "compile_interruptibly", "divide_where", "exp", "expm1", "fixed_tuple", "in_disk_cache",
           "jitable", "literal_unroll", "log", "log1p", "maximum", "minimum",
           "model_cache_directory", "power", "set_llvm_options", "sources_hash", "where"]
