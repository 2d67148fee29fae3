"""Atomic file output: a file appears under its final name complete, or not at all.

Everything neck-sim writes (parameter files, JSON results, figures, MJCF, MCAP logs) goes through
here: data goes to a temporary file beside the target, which is synced and renamed over it.
Published files get the permissions a plain ``open`` would give (0666 minus the umask), not the
0600 of ``mkstemp``.

Temporary files are named ``.neck-sim-tmp-<host>-<pid>-<random>-<target name>``: a file of a run
that was killed (SIGKILL, power loss) is recognisable, and the next run that writes into the same
folder on the same host removes those whose process no longer exists.  Errors name the user's
path, never the temporary one.
"""

from __future__ import annotations

import json
import math
import os
import re
import socket
import tempfile
from typing import Any

import numpy as np

__all__ = ["temp_file_beside", "publish", "discard", "output_error", "remove_stale_temp_files",
           "atomic_write_bytes", "atomic_write_json", "jsonable", "TEMP_PREFIX"]

TEMP_PREFIX = ".neck-sim-tmp-"
# the host name keeps a run on one machine from judging the processes of another (shared folders)
_HOST = re.sub(r"[^A-Za-z0-9_.]", "_", socket.gethostname())[:40] or "host"
_STALE = re.compile(re.escape(TEMP_PREFIX) + r"(?P<host>.+)-(?P<pid>\d+)-[^-]+-")
_swept: set[str] = set()


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def output_error(path: str | os.PathLike, exc: OSError) -> OSError:
    """An OSError whose message names the user's ``path`` (not a temporary file) and the reason."""
    reason = exc.strerror or str(exc)
    if os.path.isdir(path):
        reason = "it is a directory"
    err = OSError(f"cannot write {os.fspath(path)}: {reason}")
    err.errno = exc.errno
    return err


def _process_gone(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    except OSError:             # exists but belongs to another user
        return False
    return False


def remove_stale_temp_files(directory: str | os.PathLike) -> list[str]:
    """Delete the temporary files of killed neck-sim runs of this host in ``directory``; returns them."""
    removed = []
    try:
        entries = list(os.scandir(directory))
    except OSError:
        return removed
    for entry in entries:
        m = _STALE.match(entry.name)
        if m and m["host"] == _HOST and int(m["pid"]) != os.getpid() and _process_gone(int(m["pid"])):
            try:
                os.unlink(entry.path)
                removed.append(entry.path)
            except OSError:
                pass
    return removed


def temp_file_beside(path: str | os.PathLike) -> tuple[int, str]:
    """(fd, temp path) of a new file in the target's directory (created if needed).

    The first time a process writes into a directory, temporary files left there by killed runs
    are removed (:func:`remove_stale_temp_files`).  OSError names ``path``.
    """
    path = os.fspath(path)
    directory = os.path.dirname(os.path.abspath(path))
    try:
        os.makedirs(directory, exist_ok=True)
        if directory not in _swept:
            _swept.add(directory)
            remove_stale_temp_files(directory)
        return tempfile.mkstemp(prefix=f"{TEMP_PREFIX}{_HOST}-{os.getpid()}-",
                                suffix="-" + os.path.basename(path), dir=directory)
    except OSError as exc:
        raise output_error(path, exc) from None


def publish(tmp: str, path: str | os.PathLike) -> None:
    """Give the finished temporary file normal permissions and move it over ``path``."""
    try:
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, os.fspath(path))
    except OSError as exc:
        raise output_error(path, exc) from None


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
        try:
            with os.fdopen(fd, "wb") as fh:
                fh.write(payload)
                fh.flush()
                os.fsync(fh.fileno())
        except OSError as exc:
            raise output_error(path, exc) from None
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
