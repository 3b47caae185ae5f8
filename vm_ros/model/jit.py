"""Optional compilation of the model's equations with Numba (one source for both back ends).

Every equation of the model is a small pure function written once, over NumPy arrays. The ones the
fixed step needs are marked :func:`jitable`: called from Python they are the plain functions
(vectorised NumPy code); called from the compiled step kernel (``vm_ros.model.kernel``) Numba
compiles the same source for scalars. Without Numba (not installed, or ``VM_ROS_NUMBA=0``) the
decorator does nothing and the bank uses the NumPy step.

The two helpers below exist because NumPy's ``np.where`` and ``np.clip`` do not accept plain
scalars inside Numba: :func:`where` and :func:`clip` are ``np.where`` and ``np.clip`` from Python
and branch on scalars when compiled.
"""

from __future__ import annotations

import hashlib
import math
import os
from contextlib import contextmanager
from pathlib import Path

import numpy as np

ENV_SWITCH = "VM_ROS_NUMBA"
_MODEL_DIR = Path(__file__).resolve().parent


def _numba_wanted() -> bool:
    return os.environ.get(ENV_SWITCH, "1").strip().lower() not in ("0", "false", "no", "off")


def _sources_hash() -> str:
    digest = hashlib.sha256()
    for path in sorted(_MODEL_DIR.glob("*.py")):
        digest.update(path.name.encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()[:16]


@contextmanager
def model_cache_directory():
    """Numba's on-disk cache is checked against the kernel module's own file only, not against the
    modules whose functions it inlines. Functions decorated with ``cache=True`` inside this block
    cache in ``<NUMBA_CACHE_DIR or ~/.cache/vm_ros/numba>/<hash of every model source file>``, so
    any edit to an equation starts a fresh cache. Numba picks the folder when a function is
    decorated, so this works whether or not numba was imported before."""
    saved = numba.config.CACHE_DIR
    home = Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache"))
    base = Path(saved) if saved else home / "vm_ros" / "numba"
    numba.config.CACHE_DIR = str(base / _sources_hash())
    try:
        yield
    finally:
        numba.config.CACHE_DIR = saved


numba = None
if _numba_wanted():
    try:
        import numba
        from numba.core import types as _nb_types
        from numba.extending import overload, register_jitable
    except ImportError:  # pragma: no cover - exercised where numba is absent
        numba = None

HAVE_NUMBA = numba is not None


def jitable(func):
    """Mark an equation as callable from the compiled kernel (no-op without Numba)."""
    return register_jitable(func) if HAVE_NUMBA else func


def where(condition, if_true, if_false):
    """``np.where``; a plain branch when compiled for scalars."""
    return np.where(condition, if_true, if_false)


def power(base, exponent):
    """``base ** exponent`` (``np.power``). Compiled for scalars: ``exp(exponent * log(base))``
    for a positive base and ``base`` itself for an exponent of 1, which costs about half of
    libm's correctly rounded pow (the kernel's largest single cost) for a relative difference
    of a few 1e-16 per unit of ``|exponent * log(base)|``; other bases as ``**``."""
    return np.power(base, exponent)


def clip(value, lower, upper):
    """``min(max(value, lower), upper)`` elementwise (``np.clip`` for scalars and arrays)."""
    return np.minimum(np.maximum(value, lower), upper)


if HAVE_NUMBA:

    @overload(where)
    def _where_compiled(condition, if_true, if_false):
        if isinstance(condition, _nb_types.Boolean):

            def scalar_where(condition, if_true, if_false):
                return if_true if condition else if_false

            return scalar_where

        def array_where(condition, if_true, if_false):
            return np.where(condition, if_true, if_false)

        return array_where

    @overload(power)
    def _power_compiled(base, exponent):
        if isinstance(base, _nb_types.Float) and isinstance(exponent, (_nb_types.Float,
                                                                       _nb_types.Integer)):

            def scalar_power(base, exponent):
                if exponent == 1.0:
                    return base
                if base > 0.0:
                    return math.exp(exponent * math.log(base))
                return base**exponent

            return scalar_power

        def array_power(base, exponent):
            return np.power(base, exponent)

        return array_power

    clip = register_jitable(clip)


__all__ = ["ENV_SWITCH", "HAVE_NUMBA", "clip", "jitable", "power", "where"]
