"""One BLAS thread for the OpenBLAS libraries loaded in this process (NumPy's and SciPy's wheels
each bundle one), as threadpoolctl does, without the dependency.

Why: live coordination (vm_ros.coordination.receding) does small dense linear algebra every
publish period inside muscle_node, which is one thread. With OpenBLAS's default of one thread per
core, on a 2-core machine under load (load average 10-13) the 80-muscle solve took 290-470 ms
wall and 27-36 cores' worth of CPU time per simulated second instead of 25-39 ms and 0.7-1.1 of a
core (vm-ros bench --only coordination, OPENBLAS_NUM_THREADS=1 against the default, measured once
on 2026-12-02). Setting OPENBLAS_NUM_THREADS works only before NumPy is imported.
"""

from __future__ import annotations

import ctypes
import re

# the set-threads entry points of the OpenBLAS builds NumPy and SciPy ship (scipy-openblas) and
# of a plain OpenBLAS
_SETTERS = ("scipy_openblas_set_num_threads64_", "scipy_openblas_set_num_threads",
            "openblas_set_num_threads64_", "openblas_set_num_threads")


def loaded_openblas() -> list[str]:
    """Paths of the OpenBLAS shared libraries mapped into this process (Linux; [] elsewhere)."""
    try:
        with open("/proc/self/maps", encoding="utf-8") as maps:
            text = maps.read()
    except OSError:
        return []
    return sorted(set(re.findall(r"(/\S*openblas\S*\.so\S*)", text)))


def limit_blas_threads(threads: int = 1) -> list[str]:
    """Set every loaded OpenBLAS to ``threads`` threads; returns the libraries set (a library
    without a known entry point is left as it is)."""
    done = []
    for path in loaded_openblas():
        try:
            library = ctypes.CDLL(path)
        except OSError:
            continue
        for name in _SETTERS:
            setter = getattr(library, name, None)
            if setter is not None:
                setter(ctypes.c_int(threads))
                done.append(path)
                break
    return done


__all__ = ["limit_blas_threads", "loaded_openblas"]
