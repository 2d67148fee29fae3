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
