"""Atomic file output: a file appears under its final name complete, or not at all.

Everything neck-sim writes (parameter files, JSON results, figures, MJCF, MCAP logs) goes through
here: data goes to a temporary file beside the target, which is synced and renamed over it.
Published files get the permissions a plain ``open`` would give (0666 minus the umask), not the
0600 of ``mkstemp``.
"""

from __future__ import annotations

import json
import math
import os
import tempfile
from typing import Any

import numpy as np

__all__ = ["temp_file_beside", "publish", "discard", "atomic_write_bytes", "atomic_write_json", "jsonable"]


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def temp_file_beside(path: str | os.PathLike) -> tuple[int, str]:
    """(fd, temp path) of a new file in the target's directory (created if needed)."""
    path = os.fspath(path)
    directory = os.path.dirname(os.path.abspath(path))
    os.makedirs(directory, exist_ok=True)
    return tempfile.mkstemp(prefix=".tmp-", suffix="-" + os.path.basename(path), dir=directory)


def publish(tmp: str, path: str | os.PathLike) -> None:
    """Give the finished temporary file normal permissions and move it over ``path``."""
    os.chmod(tmp, 0o666 & ~_umask())
    os.replace(tmp, os.fspath(path))


def discard(tmp: str) -> None:
    """Remove a temporary file that will not be published (no error if it is gone)."""
    try:
        os.unlink(tmp)
    except FileNotFoundError:
        pass


def atomic_write_bytes(path: str | os.PathLike, payload: bytes) -> None:
    """Write ``payload`` to ``path`` atomically."""
    fd, tmp = temp_file_beside(path)
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(payload)
            fh.flush()
            os.fsync(fh.fileno())
        publish(tmp, path)
    except BaseException:
        discard(tmp)
        raise


def jsonable(x: Any) -> Any:
    """``x`` with numpy arrays and scalars as plain Python values and NaN/inf as None (valid JSON)."""
    if isinstance(x, dict):
        return {str(k): jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [jsonable(v) for v in x]
    if isinstance(x, np.ndarray):
        return jsonable(x.tolist())
    if isinstance(x, (bool, np.bool_)):
        return bool(x)
    if isinstance(x, np.integer):
        return int(x)
    if isinstance(x, (float, np.floating)):
        v = float(x)
        return v if math.isfinite(v) else None
    return x


def atomic_write_json(path: str | os.PathLike, obj: Any, *, indent: int = 2, **dumps_kwargs) -> None:
    """Write ``obj`` (through :func:`jsonable`) as strict JSON with a final newline, atomically."""
    text = json.dumps(jsonable(obj), indent=indent, allow_nan=False, **dumps_kwargs)
    atomic_write_bytes(path, (text + "\n").encode())
