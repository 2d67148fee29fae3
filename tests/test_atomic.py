import os
import stat

import pytest

from neck_sim.atomic import atomic_write_bytes, atomic_write_json


def test_written_files_get_umask_permissions_and_no_temp_remains(tmp_path):
    old = os.umask(0o022)
    try:
        atomic_write_json(tmp_path / "sub" / "r.json", {"a": 1})
    finally:
        os.umask(old)
    path = tmp_path / "sub" / "r.json"
    assert path.read_text() == '{\n  "a": 1\n}\n'
    assert stat.S_IMODE(path.stat().st_mode) == 0o644
    assert [p.name for p in path.parent.iterdir()] == ["r.json"]


def test_failed_write_leaves_the_old_file(tmp_path):
    path = tmp_path / "r.json"
    atomic_write_bytes(path, b"old")
    with pytest.raises(TypeError):
        atomic_write_json(path, {"x": object()})
    assert path.read_bytes() == b"old"
    assert [p.name for p in tmp_path.iterdir()] == ["r.json"]


def test_json_is_strict_and_numpy_aware(tmp_path):
    import json

    import numpy as np

    from neck_sim.atomic import jsonable

    obj = {"a": np.arange(3), "b": np.float32(1.5), "c": float("nan"), "d": (np.int64(2), np.bool_(True)), 4: np.inf}
    assert jsonable(obj) == {"a": [0, 1, 2], "b": 1.5, "c": None, "d": [2, True], "4": None}
    atomic_write_json(tmp_path / "x.json", obj)
    assert json.loads((tmp_path / "x.json").read_text())["c"] is None
