"""BLAS threads for the identification fits: one.

The least squares, the diagnosis and the output-error fit solve many small problems ((n, p) by
(p, p) products with p of a few tens), for which OpenBLAS threads only spin: 10x slower on a
loaded 2-core machine for the diagnosis, 0.44 s against 0.018 s of CPU for the output-error
sandwich.  MuJoCo's batch threads are its own and are not limited.

Usage::

    from identification.threads import single_thread

    with single_thread():
        ...   # numpy / scipy linear algebra on one thread
"""

from __future__ import annotations

import contextlib
from typing import Any

__all__ = ["single_thread"]


def single_thread() -> contextlib.AbstractContextManager[Any]:
    """BLAS limited to one thread inside the ``with`` block (module docstring)."""
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:              # pragma: no cover - threadpoolctl is a dependency
        return contextlib.nullcontext()
    return threadpool_limits(1)
