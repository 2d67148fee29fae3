"""Where neck-sim keeps what it compiles or plans: one user cache directory, never beside the sources.

``$NECK_SIM_CACHE`` if set, else ``$XDG_CACHE_HOME/neck_sim``, else ``~/.cache/neck_sim``; when
that cannot be created or written, a per-user folder in the system's temporary directory.  It holds
the compiled plant callback (:mod:`neck_sim.native`), the numba kernels (:mod:`neck_sim.jit`) and
the results of :func:`memo` (``memo/<digest>/``: the paths planned for necks the paper's laws cannot
move, seconds of static solves each); everything in it is rebuilt on demand, so deleting it is
always safe.

Usage::

    from neck_sim.cache import memo
    path = memo("shapes_tour", (params, 0.25), lambda: plan(params, 0.25))
"""

from __future__ import annotations

import functools
import hashlib
import os
import pickle
import tempfile
from typing import Callable, Hashable, Iterable, TypeVar

__all__ = ["cache_dir", "package_sources", "files_digest", "source_digest", "memo"]

T = TypeVar("T")
_PACKAGES = ("neck_sim", "controllers", "identification")      # pyproject's packages
_ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
_MEMORY: dict[tuple[str, str], bytes] = {}


def _configured() -> str:
    explicit = os.environ.get("NECK_SIM_CACHE")
    if explicit:
        return os.path.abspath(os.path.expanduser(explicit))
    xdg = os.environ.get("XDG_CACHE_HOME")
    base = xdg if xdg and os.path.isabs(xdg) else os.path.join(os.path.expanduser("~"), ".cache")
    return os.path.join(base, "neck_sim")


def cache_dir() -> str:
    """The writable cache directory (created when missing); see the module docstring."""
    d = _configured()
    try:
        os.makedirs(d, exist_ok=True)
        if os.access(d, os.W_OK | os.X_OK):
            return d
    except OSError:
        pass
    d = os.path.join(tempfile.gettempdir(), f"neck_sim_cache_{os.getuid() if hasattr(os, 'getuid') else 0}")
    os.makedirs(d, exist_ok=True)
    return d


def package_sources(root: str = _ROOT) -> tuple[str, ...]:
    """Every ``.py`` file of the three packages under ``root``, relative to it ('/'-separated),
    sorted."""
    out = []
    for pkg in _PACKAGES:
        for folder, dirs, files in os.walk(os.path.join(root, pkg)):
            dirs[:] = [d for d in dirs if d != "__pycache__"]
            out += [os.path.relpath(os.path.join(folder, f), root).replace(os.sep, "/") for f in files if f.endswith(".py")]
    return tuple(sorted(out))


def files_digest(sources: Iterable[str], root: str = _ROOT) -> str:
    """sha256 (hex) of the files ``sources`` (relative to ``root``), names and texts, in that order."""
    h = hashlib.sha256()
    for rel in sources:
        h.update(rel.encode() + b"\0")
        with open(os.path.join(root, rel), "rb") as fh:
            h.update(fh.read())
        h.update(b"\0")
    return h.hexdigest()


@functools.lru_cache(maxsize=1)
def source_digest(root: str = _ROOT) -> str:
    """:func:`files_digest` of every source of the three packages (:func:`package_sources`): any
    change to the code gives a new digest, so :func:`memo` never returns what older code made."""
    return files_digest(package_sources(root), root)


def memo(kind: str, key: Hashable, compute: Callable[[], T]) -> T:
    """``compute()``, computed once per (``kind``, ``key``) for this version of the code: kept in this
    process and in ``<cache_dir>/memo/<source digest>/`` (shared by processes), as a pickle, so
    every caller gets its own copy.  ``key`` must have a ``repr`` that determines the result (frozen
    dataclasses of floats and tuples, such as :class:`neck_sim.params.NeckParams`, do).  A cache file
    that cannot be read or written is ignored: the result is computed."""
    name = f"{kind}-{hashlib.sha256(repr((key, _versions())).encode()).hexdigest()[:32]}.pkl"
    blob = _MEMORY.get((kind, name))
    if blob is not None:
        return pickle.loads(blob)
    folder = os.path.join(cache_dir(), "memo", source_digest()[:20])
    path = os.path.join(folder, name)
    try:
        with open(path, "rb") as fh:
            blob = fh.read()
        return _remember(kind, name, blob, pickle.loads(blob))
    except Exception:            # missing, torn or written by an incompatible interpreter: computed
        pass
    value = compute()
    blob = pickle.dumps(value, protocol=pickle.HIGHEST_PROTOCOL)
    try:
        from neck_sim.atomic import atomic_write_bytes

        os.makedirs(folder, exist_ok=True)
        atomic_write_bytes(path, blob)
    except OSError:
        pass
    return _remember(kind, name, blob, value)


@functools.lru_cache(maxsize=1)
def _versions() -> tuple:
    """Python's and the numerical libraries' versions: a new release can move a result's last bits."""
    import sys
    from importlib.metadata import PackageNotFoundError, version

    out = [sys.version]
    for dist in ("numpy", "scipy", "mujoco"):
        try:
            out.append(f"{dist} {version(dist)}")
        except PackageNotFoundError:
            out.append(f"{dist} -")
    return tuple(out)


def _remember(kind: str, name: str, blob: bytes, value: T) -> T:
    _MEMORY[kind, name] = blob
    return value
