"""Where neck-sim keeps what it compiles: one user cache directory, never beside the sources.

``$NECK_SIM_CACHE`` if set, else ``$XDG_CACHE_HOME/neck_sim``, else ``~/.cache/neck_sim``; when
that cannot be created or written, a per-user folder in the system's temporary directory.  It holds
the compiled plant callback (:mod:`neck_sim.native`) and the numba kernels (:mod:`neck_sim.jit`);
everything in it is rebuilt on demand, so deleting it is always safe.
"""

from __future__ import annotations

import os
import tempfile

__all__ = ["cache_dir"]


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
