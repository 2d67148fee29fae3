"""Compiled kernels: numba's ``njit`` with an on-disk cache in the user's cache directory.

The control path (estimator, dynamics, tension distribution) runs one small sample every 2 ms, where
numpy's per-call overhead on 3x4 arrays costs more than the arithmetic.  Each formula is written
once: either as a plain function of scalars or arrays that numpy runs on batches and numba compiles
for one sample (:func:`dual`), or as a loop kernel over one sample that the numpy API calls row by
row (:func:`kernel`).

Compiled machine code is reused across processes (compiling the control step takes seconds, loading
it tens of milliseconds).  numba's own ``cache=True`` writes into ``__pycache__`` beside the sources
(inside site-packages for an installed copy, where the folders outlive an uninstall and shadow a
later editable install) and only checks the file that *defines* a function, while a kernel compiled
into the control step inlines formulas and constants from other files.  Here every kernel is cached
under :func:`kernel_cache_root`: ``<cache_dir>/kernels/<version>-<digest>``, a folder named by the
package version, Python, numba and a digest of all :data:`KERNEL_SOURCES`, so a changed source,
upgrade or interpreter never meets an old entry (old folders are left for the user to delete; see
:mod:`neck_sim.cache`).
"""

from __future__ import annotations

import functools
import os
import re
import sys

import numba
import numpy as np
from numba.core.caching import CompileResultCacheImpl, FunctionCache, _CacheLocator

from neck_sim.cache import cache_dir, files_digest, package_sources

__all__ = ["KERNEL_SOURCES", "kernel_sources", "kernel_cache_root", "kernel", "dual", "solve_in_place"]

_ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
_USES_KERNELS = re.compile(r"^\s*(?:from|import)\s+(?:neck_sim\.jit|numba)\b", re.M)
_IMPORTS = re.compile(r"^\s*from\s+((?:neck_sim|controllers|identification)(?:\.\w+)*)\s+import\s+"
                      r"(?:\(([^)]*)\)|([^\n]*))", re.M)


def _module_file(module: str, root: str) -> str | None:
    """The source file (relative to ``root``, the packages' folder) of a module, if any."""
    base = module.replace(".", "/")
    for rel in (base + ".py", base + "/__init__.py"):
        if os.path.isfile(os.path.join(root, rel)):
            return rel
    return None


def kernel_sources(root: str = _ROOT) -> tuple[str, ...]:
    """Every file whose text can end up in a compiled kernel, relative to ``root``.

    The modules that compile (they import ``neck_sim.jit`` or numba) and the package modules they
    import from: numba freezes the functions and global constants a kernel uses (``params``'
    segment codes, another module's kernels) into its machine code.
    """
    texts = {}
    for rel in package_sources(root):
        with open(os.path.join(root, rel), encoding="utf-8") as fh:
            texts[rel] = fh.read()
    sources = {rel for rel, text in texts.items() if _USES_KERNELS.search(text)}
    for rel in list(sources):
        for module, grouped, names in _IMPORTS.findall(texts[rel]):
            names = re.findall(r"\w+", grouped or names.split("#")[0])
            for dep in [_module_file(module, root)] + [_module_file(f"{module}.{n}", root) for n in names]:
                if dep is not None and dep in texts:
                    sources.add(dep)
    return tuple(sorted(sources))


KERNEL_SOURCES = kernel_sources()


def _package_version() -> str:
    from importlib.metadata import PackageNotFoundError, version
    try:
        return version("neck-sim")
    except PackageNotFoundError:
        return "unknown"


_DIGEST = files_digest(KERNEL_SOURCES, _ROOT)


@functools.lru_cache(maxsize=1)
def kernel_cache_root() -> str:
    """The folder of this build's compiled kernels (see the module docstring); not created here."""
    key = (f"neck_sim-{_package_version()}-py{sys.version_info[0]}{sys.version_info[1]}"
           f"-numba{numba.__version__}-{_DIGEST[:20]}")
    return os.path.join(cache_dir(), "kernels", key)


class _KernelLocator(_CacheLocator):
    """numba cache locator: one folder per module under :func:`kernel_cache_root`; the source stamp
    is the digest of every kernel source (numba's own stamp covers one file)."""

    def __init__(self, py_func, py_file):
        self._py_file = py_file
        self._lineno = py_func.__code__.co_firstlineno
        self._cache_path = os.path.join(kernel_cache_root(), py_func.__module__)

    def get_cache_path(self):
        return self._cache_path

    def get_source_stamp(self):
        return _DIGEST

    def get_disambiguator(self):
        return str(self._lineno)

    @classmethod
    def from_function(cls, py_func, py_file):
        self = cls(py_func, py_file)
        try:
            self.ensure_cache_path()
        except OSError:               # no writable cache: compile in every process instead
            return None
        return self


class _KernelCacheImpl(CompileResultCacheImpl):
    _locator_classes = [_KernelLocator]


class _KernelCache(FunctionCache):
    _impl_class = _KernelCacheImpl


def kernel(fn):
    """``numba.njit`` cached under :func:`kernel_cache_root`, IEEE semantics (no fastmath, numpy errors)."""
    disp = numba.njit(nogil=True, error_model="numpy")(fn)
    try:
        disp._cache = _KernelCache(disp.py_func)       # what numba's enable_caching() does, relocated
    except (RuntimeError, OSError):                     # no writable cache folder: compile in every process
        pass
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
