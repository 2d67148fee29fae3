"""Atomic file output: a file appears under its final name complete, or not at all.

Everything neck-sim writes (parameter files, JSON results, figures, MJCF, MCAP logs) goes through
here: data goes to a temporary file beside the target, which is synced and renamed over it.
Published files get the permissions a plain ``open`` would give (0666 minus the umask), not the
0600 of ``mkstemp``.

Temporary files are named ``.neck-sim-tmp-<host>-<pid>-<random>-<start of the target name>``: a
file of a run that was killed (SIGKILL, power loss) is recognisable, and the next run that writes
into the same folder on the same host removes those whose process no longer exists.  Only the
first characters of the target's name are used, so any legal target name (up to NAME_MAX) gets a
legal temporary name.  Errors name the user's path, never the temporary one.

Only regular files are written (:func:`output_refusal`): an existing device node, FIFO or socket
(or a symlink to one) is refused instead of being replaced by a regular file; a symlink to a
regular file is written through (the link stays); a read-only file is refused, also for root; an
existing file keeps its permission bits and owner.
"""

from __future__ import annotations

import json
import math
import os
import re
import socket
import stat
import tempfile
from typing import Any

import numpy as np

__all__ = ["temp_file_beside", "publish", "discard", "output_error", "remove_stale_temp_files",
           "atomic_write_bytes", "atomic_write_json", "jsonable", "TEMP_PREFIX", "path_kind", "output_target",
           "output_refusal"]

TEMP_PREFIX = ".neck-sim-tmp-"
# the host name keeps a run on one machine from judging the processes of another (shared folders)
_HOST = re.sub(r"[^A-Za-z0-9_.]", "_", socket.gethostname())[:40] or "host"
_STALE = re.compile(re.escape(TEMP_PREFIX) + r"(?P<host>.+)-(?P<pid>\d+)-[^-]+-")
_swept: set[str] = set()
_SPECIAL_TREES = ("/proc/", "/dev/", "/sys/")   # kernel file systems: nothing there is an output file ...
_REGULAR_TREES = ("/dev/shm/",)                  # ... but shared memory, a tmpfs of regular files
_NAME_IN_TEMP = 32        # characters of the target's name kept in the temporary name
_KINDS = {stat.S_IFCHR: "a character device", stat.S_IFBLK: "a block device", stat.S_IFIFO: "a FIFO (named pipe)",
          stat.S_IFSOCK: "a socket", stat.S_IFDIR: "a directory"}


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


def path_kind(path: str | os.PathLike) -> str | None:
    """What ``path`` is after following symlinks, when it is not a regular file ("a FIFO (named
    pipe)", "a character device", ...); None for a regular file or a missing path.  Uses ``stat``,
    never ``open``: a FIFO is recognised without blocking."""
    try:
        mode = os.stat(path).st_mode
    except OSError:
        return None
    if stat.S_ISREG(mode):
        return None
    return _KINDS.get(stat.S_IFMT(mode), "not a file")


def _name_max(directory: str) -> int:
    while not os.path.isdir(directory) and os.path.dirname(directory) != directory:
        directory = os.path.dirname(directory)
    try:
        return os.pathconf(directory, "PC_NAME_MAX")
    except (OSError, ValueError):
        return 255


def _special_hop(path: str | os.PathLike) -> str | None:
    """The first name in ``path``'s chain of symlinks inside /proc, /dev or /sys, or None.  (The
    kernel resolves /proc/self/fd/N of a redirected stdout to the regular file behind it, so the
    kind of the end of the chain does not tell.)"""
    p = os.path.abspath(path)
    for _ in range(40):
        if p.startswith(_SPECIAL_TREES) and not p.startswith(_REGULAR_TREES):
            return p
        if not os.path.islink(p):
            return None
        p = os.path.abspath(os.path.join(os.path.dirname(p), os.readlink(p)))
    return None


def output_target(path: str | os.PathLike) -> str:
    """The file an output ``path`` is written to: ``path`` itself or, for a symlink, the file it
    names (the link stays a link)."""
    path = os.fspath(path)
    return os.path.realpath(path) if os.path.islink(path) else path


def output_refusal(path: str | os.PathLike) -> str | None:
    """Why ``path`` must not be written as an output file, or None.

    Refused: an existing path that is not a regular file after following symlinks (a device node
    such as /dev/full or a copy of /dev/null, a FIFO, a socket, a directory), a read-only file (no
    write permission bit, or no write access; root is refused too), a name longer than the file
    system's NAME_MAX.
    """
    target = output_target(path)
    kind = path_kind(path)          # the kernel follows the links (/proc/self/fd/N names no path)
    if kind == "a directory":
        return "it is a directory"
    if kind is not None:
        return f"it is {kind}, not a regular file; refusing to replace it"
    special = _special_hop(path)                # /proc/self/fd/1 of a redirected stdout, /dev/stdout, ...
    if special is not None:
        return f"it leads to {special}, a special file, not a regular file; refusing to replace it"
    name_max = _name_max(os.path.dirname(os.path.abspath(target)))
    name_bytes = len(os.fsencode(os.path.basename(target)))
    if name_bytes > name_max:
        return f"the file name is too long ({name_bytes} bytes; the limit is {name_max})"
    try:
        st = os.stat(target)
    except OSError:
        return None
    if not st.st_mode & 0o222 or not os.access(target, os.W_OK):
        return "the file is read-only (refusing to replace it; make it writable or choose another path)"
    return None


def _refuse(path) -> str:
    """``output_target(path)``, or OSError naming ``path`` and :func:`output_refusal`'s reason."""
    reason = output_refusal(path)
    if reason is not None:
        raise OSError(f"cannot write {os.fspath(path)}: {reason}")
    return output_target(path)


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
    removed: list[str] = []
    try:
        entries = list(os.scandir(os.fspath(directory)))
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
    directory = os.path.dirname(os.path.abspath(_refuse(path)))
    try:
        os.makedirs(directory, exist_ok=True)
        if directory not in _swept:
            _swept.add(directory)
            remove_stale_temp_files(directory)
        return tempfile.mkstemp(prefix=f"{TEMP_PREFIX}{_HOST}-{os.getpid()}-",
                                suffix="-" + os.path.basename(path)[:_NAME_IN_TEMP], dir=directory)
    except OSError as exc:
        raise output_error(path, exc) from None


def publish(tmp: str, path: str | os.PathLike) -> None:
    """Move the finished temporary file over ``path`` (or the file a symlink ``path`` names).

    The file gets the permission bits and owner of the file it replaces, or those a plain ``open``
    would give a new file (0666 minus the umask).  OSError (naming ``path``) when ``path`` became
    something :func:`output_refusal` refuses since the temporary file was made."""
    target = _refuse(path)
    try:
        try:
            old = os.stat(target)
        except FileNotFoundError:
            os.chmod(tmp, 0o666 & ~_umask())
        else:
            if (old.st_uid, old.st_gid) != (os.getuid(), os.getgid()):
                try:
                    os.chown(tmp, old.st_uid, old.st_gid)
                except PermissionError:     # not root: the file becomes the writer's
                    pass
            os.chmod(tmp, stat.S_IMODE(old.st_mode))
        os.replace(tmp, target)
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


def atomic_write_json(path: str | os.PathLike, obj: Any, *, indent: int = 2, **dumps_kwargs: Any) -> None:
    """Write ``obj`` (through :func:`jsonable`) as strict JSON with a final newline, atomically."""
    text = json.dumps(jsonable(obj), indent=indent, allow_nan=False, **dumps_kwargs)
    atomic_write_bytes(path, (text + "\n").encode())
