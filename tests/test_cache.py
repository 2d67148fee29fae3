"""neck_sim.cache.memo: computed once per key and code version, shared through the cache directory,
each caller given its own copy; the planners of controllers.reachable_paths go through it."""

import numpy as np
import pytest

from neck_sim import cache


@pytest.fixture
def fresh(tmp_path, monkeypatch):
    """An empty cache directory for memo (the compiled kernels stay where they are) and an empty
    in-process memo."""
    folder = tmp_path / "cache"
    monkeypatch.setattr(cache, "cache_dir", lambda: str(folder))
    monkeypatch.setattr(cache, "_MEMORY", {})
    return folder


def test_memo_computes_once_per_key_and_hands_out_copies(fresh, monkeypatch):
    calls = []

    def compute(x):
        calls.append(x)
        return {"x": np.arange(3.0) * x}

    a = cache.memo("t", ("k", 2.0), lambda: compute(2.0))
    a["x"][0] = 99.0                                       # the caller's copy only
    b = cache.memo("t", ("k", 2.0), lambda: compute(2.0))
    assert calls == [2.0] and b["x"].tolist() == [0.0, 2.0, 4.0]
    monkeypatch.setattr(cache, "_MEMORY", {})              # another process: read from the directory
    assert cache.memo("t", ("k", 2.0), lambda: compute(2.0))["x"].tolist() == [0.0, 2.0, 4.0]
    assert calls == [2.0]
    cache.memo("t", ("k", 3.0), lambda: compute(3.0))      # another key
    assert calls == [2.0, 3.0]
    assert len(list(fresh.glob("memo/*/t-*.pkl"))) == 2


def test_a_torn_cache_file_is_computed_again(fresh, monkeypatch):
    cache.memo("t", 1, lambda: [1, 2])
    (path,) = fresh.glob("memo/*/t-*.pkl")
    path.write_bytes(path.read_bytes()[:5])
    monkeypatch.setattr(cache, "_MEMORY", {})
    assert cache.memo("t", 1, lambda: [1, 2, 3]) == [1, 2, 3]


def test_the_source_digest_follows_every_package_file(tmp_path):
    for pkg in ("neck_sim", "controllers", "identification"):
        (tmp_path / pkg / "sub").mkdir(parents=True)
        (tmp_path / pkg / "sub" / "m.py").write_text("x = 1\n")
    (tmp_path / "notes.txt").write_text("not code")
    first = cache.source_digest.__wrapped__(str(tmp_path))
    (tmp_path / "notes.txt").write_text("changed")
    assert cache.source_digest.__wrapped__(str(tmp_path)) == first
    (tmp_path / "controllers" / "sub" / "m.py").write_text("x = 2\n")
    assert cache.source_digest.__wrapped__(str(tmp_path)) != first


def test_the_planners_plan_once_per_neck_and_request(fresh, monkeypatch):
    from controllers import reachable_paths as rp
    from neck_sim.params import default_params, example_params

    calls = []
    monkeypatch.setattr(rp, "_shapes_tour", lambda *key: calls.append(key) or key[1:])
    p10, p3 = example_params("neck10x4"), default_params(3)
    assert rp.shapes_tour(p10, 0.25) == (0.25, rp.BEND_DEG, rp.FORCE_MARGIN, 0.5)
    assert rp.shapes_tour(p10, 0.25) == (0.25, rp.BEND_DEG, rp.FORCE_MARGIN, 0.5)
    rp.shapes_tour(p10, 0.5)
    rp.shapes_tour(p10, 0.25, bend_deg=10.0)
    rp.shapes_tour(p3, 0.25)
    assert [k[1:3] for k in calls] == [(0.25, rp.BEND_DEG), (0.5, rp.BEND_DEG), (0.25, 10.0), (0.25, rp.BEND_DEG)]
    assert calls[-1][0] is p3


def test_a_path_read_back_is_the_path_stored(fresh, monkeypatch):
    """A short path of equilibria of the 10-joint, 4-cable neck, stored and read back by a fresh
    process's memo: the same waypoints, labels and grid of equilibria, bit for bit."""
    from controllers import reachable_paths as rp
    from controllers.underactuated import ReachablePath
    from neck_sim.params import example_params

    p = example_params("neck10x4")
    start = rp.straight_pretension(p)

    def plan():
        path = ReachablePath(p, [start.tensions, start.tensions + [4.0, -4.0, 3.0, -3.0]], move_time=0.2,
                             hold_time=0.05, alpha0=start.alpha)
        path.labels = ["start", "bent"]
        return path

    planned = cache.memo("path", (p, 1), plan)
    monkeypatch.setattr(cache, "_MEMORY", {})
    read = cache.memo("path", (p, 1), lambda: pytest.fail("read from the directory, not planned again"))
    assert read is not planned and read.labels == planned.labels
    assert np.array_equal(read.waypoints, planned.waypoints) and np.array_equal(read.grid_alpha, planned.grid_alpha)
    assert np.abs(planned.grid_alpha).max() > 1e-3                  # it bends
    t = np.linspace(0.0, planned.duration, 101)
    assert np.array_equal(read.sample(t).alpha, planned.sample(t).alpha)
