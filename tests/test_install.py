"""Compiled kernels live in the user cache directory, never beside the sources, and a changed source
never loads an old entry (``neck_sim.jit``, ``neck_sim.cache``).

Each check runs a fresh interpreter on a copy of the packages, with its own ``NECK_SIM_CACHE``, and
reads numba's own hit/miss counters of the compiled function.
"""

from __future__ import annotations

import importlib
import json
import os
import pkgutil
import shutil
import subprocess
import sys

import pytest

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PACKAGES = ("neck_sim", "controllers", "identification")

# compile one small kernel and report numba's counters for it
PROBE = """
import json, numpy as np
from neck_sim.jit import solve_in_place, kernel_cache_root
A = np.array([[2.0, 1.0], [1.0, 3.0]]); y = np.array([[1.0], [2.0]])
assert solve_in_place(A, y)
s = solve_in_place.stats
print(json.dumps({"hits": sum(s.cache_hits.values()), "misses": sum(s.cache_misses.values()),
                  "root": kernel_cache_root(), "x": y.ravel().tolist()}))
"""


def _copy_tree(dest) -> str:
    """A copy of the packages' sources (no bytecode, no caches) under ``dest``."""
    for pkg in PACKAGES:
        shutil.copytree(os.path.join(REPO, pkg), os.path.join(dest, pkg),
                        ignore=shutil.ignore_patterns("__pycache__", "*.pyc", "*.nbi", "*.nbc"))
    return str(dest)


def _probe(tree: str, cache: str) -> dict:
    env = dict(os.environ, NECK_SIM_CACHE=cache, PYTHONPATH=tree, PYTHONDONTWRITEBYTECODE="1")
    env.pop("NUMBA_CACHE_DIR", None)
    out = subprocess.run([sys.executable, "-c", PROBE], env=env, cwd=tree, capture_output=True, text=True,
                         check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def _files(tree: str) -> dict[str, tuple[int, int]]:
    found = {}
    for folder, _, names in os.walk(tree):
        for name in names:
            path = os.path.join(folder, name)
            st = os.stat(path)
            found[os.path.relpath(path, tree)] = (st.st_mtime_ns, st.st_size)
    return found


def test_kernels_cached_in_user_cache_not_beside_sources(tmp_path):
    tree = _copy_tree(tmp_path / "src")
    cache = str(tmp_path / "cache")
    before = _files(tree)
    first = _probe(tree, cache)
    assert first["misses"] == 1 and first["hits"] == 0
    assert _files(tree) == before, "compiling wrote into the package folders"
    root = first["root"]
    assert os.path.commonpath([root, cache]) == cache
    written = os.listdir(os.path.join(root, "neck_sim.jit"))
    assert any(n.endswith(".nbi") for n in written) and any(n.endswith(".nbc") for n in written)
    second = _probe(tree, cache)            # the entry is really used by the next process
    assert second["hits"] == 1 and second["misses"] == 0
    assert second["x"] == pytest.approx([0.2, 0.6], abs=1e-15)


def test_changed_kernel_source_never_loads_old_entry(tmp_path):
    tree = _copy_tree(tmp_path / "src")
    cache = str(tmp_path / "cache")
    first = _probe(tree, cache)
    assert _probe(tree, cache)["hits"] == 1
    # params.py defines no kernel, but its constants are frozen into kernels that use them
    with open(os.path.join(tree, "neck_sim", "params.py"), "a") as fh:
        fh.write("\n# an edit\n")
    changed = _probe(tree, cache)
    assert changed["hits"] == 0 and changed["misses"] == 1
    assert changed["root"] != first["root"]


def test_kernel_sources_cover_every_compiled_function():
    """Every numba dispatcher the packages define (found by importing them) is in a listed file."""
    import numba.core.registry

    from neck_sim.jit import KERNEL_SOURCES
    dispatcher = numba.core.registry.CPUDispatcher
    defining = set()
    for pkg in PACKAGES:
        mod = importlib.import_module(pkg)
        for info in pkgutil.walk_packages(mod.__path__, pkg + "."):
            if info.name.endswith("__main__"):
                continue
            module = importlib.import_module(info.name)
            for value in vars(module).values():
                for obj in (value, getattr(value, "jit", None)):
                    if isinstance(obj, dispatcher) and obj.py_func.__module__ == info.name:
                        defining.add(os.path.relpath(obj.py_func.__code__.co_filename, REPO).replace(os.sep, "/"))
    assert len(defining) >= 8
    assert defining <= set(KERNEL_SOURCES), sorted(defining - set(KERNEL_SOURCES))
    assert "neck_sim/params.py" in KERNEL_SOURCES      # constants kernels freeze
