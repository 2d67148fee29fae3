"""Compiled kernels: numba's ``njit`` with an on-disk cache that follows the model's source files.

The control path (estimator, dynamics, tension distribution) runs one small sample every 2 ms, where
numpy's per-call overhead on 3x4 arrays costs more than the arithmetic.  Each formula is written
once: either as a plain function of scalars or arrays that numpy runs on batches and numba compiles
for one sample (:func:`dual`), or as a loop kernel over one sample that the numpy API calls row by
row (:func:`kernel`).

numba's ``cache=True`` reuses machine code across processes (compiling the control step takes
seconds, loading it tens of milliseconds) but only checks the file that *defines* a function: a
kernel compiled into the control step keeps the old version of a formula edited in another file.
Every cache index here therefore also records a digest of all :data:`KERNEL_SOURCES`; when it
differs the index is flushed and the kernel compiled again.
"""

from __future__ import annotations

import hashlib
import os

import numba
import numpy as np

__all__ = ["KERNEL_SOURCES", "kernel", "dual", "solve_in_place"]

_ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

# Every file that defines a kernel (paths from the directory holding the packages).
KERNEL_SOURCES = ("neck_sim/jit.py", "neck_sim/analytic/geometry.py", "neck_sim/analytic/cables.py",
                  "neck_sim/analytic/dynamics.py", "neck_sim/analytic/estimation.py",
                  "controllers/tension.py", "controllers/estimators.py", "controllers/computed_torque.py",
                  "neck_sim/logs/jsonrecords.py", "neck_sim/plant.py", "controllers/closed_loop.py")


def _sources_digest() -> str:
    h = hashlib.sha1()
    for rel in KERNEL_SOURCES:
        path = os.path.join(_ROOT, rel)
        h.update(rel.encode())
        if os.path.exists(path):
            with open(path, "rb") as fh:
                h.update(fh.read())
    return h.hexdigest()


_DIGEST = _sources_digest()


def _follow_sources(dispatcher) -> None:
    """Flush ``dispatcher``'s cache index when any kernel source changed since it was written."""
    cache = getattr(dispatcher, "_cache", None)
    path = getattr(cache, "cache_path", None)
    if path is None:
        return
    stamp = os.path.join(path, f"{dispatcher.py_func.__module__}.{dispatcher.py_func.__qualname__}.sources")
    try:
        with open(stamp) as fh:
            if fh.read() == _DIGEST:
                return
    except OSError:
        pass
    cache.flush()
    try:
        os.makedirs(path, exist_ok=True)
        with open(stamp, "w") as fh:
            fh.write(_DIGEST)
    except OSError:                       # read-only install: numba then caches elsewhere or not at all
        pass


def kernel(fn):
    """``numba.njit`` with a source-following cache, IEEE semantics (no fastmath, numpy errors)."""
    disp = numba.njit(cache=True, nogil=True, error_model="numpy")(fn)
    _follow_sources(disp)
    return disp


def dual(fn):
    """Keep ``fn`` (numpy on arrays) and attach its compiled scalar twin as ``fn.jit``.

    ``fn`` must use only what both numpy and numba accept (``np.sin``, arithmetic, tuples).
    """
    fn.jit = kernel(fn)
    return fn


@kernel
def solve_in_place(A, y) -> bool:
    """Solve A X = Y for a small square A (Gaussian elimination with partial pivoting).

    A (n, n) is overwritten by its factors, Y (n, m) by X.  Returns False when A is singular (a zero
    or non-finite pivot); A and Y then hold garbage.
    """
    n = A.shape[0]
    m = y.shape[1]
    for col in range(n):
        piv = col
        big = abs(A[col, col])
        for r in range(col + 1, n):
            if abs(A[r, col]) > big:
                big = abs(A[r, col])
                piv = r
        if not (big > 0.0 and np.isfinite(big)):
            return False
        if piv != col:
            for k in range(n):
                A[col, k], A[piv, k] = A[piv, k], A[col, k]
            for k in range(m):
                y[col, k], y[piv, k] = y[piv, k], y[col, k]
        for r in range(col + 1, n):
            f = A[r, col] / A[col, col]
            for k in range(col + 1, n):
                A[r, k] -= f * A[col, k]
            for k in range(m):
                y[r, k] -= f * y[col, k]
    for col in range(n - 1, -1, -1):
        for k in range(m):
            acc = y[col, k]
            for j in range(col + 1, n):
                acc -= A[col, j] * y[j, k]
            y[col, k] = acc / A[col, col]
    return True
