import json

from neck_sim.cli import main


def test_params_prints_sources(capsys):
    assert main(["params"]) == 0
    out = capsys.readouterr().out
    assert "geometry.L" in out and "paper" in out


def test_params_round_trip_through_file(tmp_path, capsys):
    path = tmp_path / "p.toml"
    assert main(["params", "--n-joints", "5", "-o", str(path)]) == 0
    assert main(["params", "--load", str(path)]) == 0
    assert "5" in capsys.readouterr().out


def test_bad_file_is_a_clean_error(tmp_path, capsys):
    assert main(["params", "--load", str(tmp_path / "missing.toml")]) == 2
    assert "missing.toml" in capsys.readouterr().err


def test_pulleys_json(tmp_path):
    path = tmp_path / "p.json"
    assert main(["pulleys", "--samples", "2000", "--json", str(path)]) == 0
    data = json.loads(path.read_text())
    assert data["samples"] == 2000 and 0 < data["torque_rel_diff"] < 1


def test_top_level_help_lists_every_command(capsys):
    from neck_sim.cli import COMMANDS
    assert main(["--help"]) == 0
    out = capsys.readouterr().out
    for name in COMMANDS:
        assert name in out


def test_shared_params_options(tmp_path):
    import argparse

    import pytest

    from neck_sim import params as P
    from neck_sim.cli.common import add_params_arguments, params_from_args

    parser = argparse.ArgumentParser()
    add_params_arguments(parser)
    path = tmp_path / "five.toml"
    P.save(P.default_params(5), path)
    assert params_from_args(parser.parse_args([])).n_joints == 3
    assert params_from_args(parser.parse_args(["--n-joints", "4"])).n_joints == 4
    assert params_from_args(parser.parse_args(["--params", str(path)])).n_joints == 5
    with pytest.raises(ValueError, match="contradicts"):
        params_from_args(parser.parse_args(["--params", str(path), "--n-joints", "3"]))
    with pytest.raises(ValueError, match="n-joints"):
        params_from_args(parser.parse_args(["--n-joints", "0"]))


def test_commands_import_mujoco_without_opengl_and_leave_the_users_choice():
    """The CLI skips MuJoCo's GLFW probe (a subprocess at import) and restores MUJOCO_GL for children."""
    import os
    import subprocess
    import sys

    code = ("import os, sys\nfrom neck_sim.cli import main\nassert main(['params']) == 0\n"
            "import mujoco.rendering.classic.gl_context as gl\n"
            "print('RESULT', 'glfw' in sys.modules, hasattr(gl, 'GLContext'), os.environ.get('MUJOCO_GL'))")
    env = {k: v for k, v in os.environ.items() if k != "MUJOCO_GL"}
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True).stdout
    assert out.splitlines()[-1] == "RESULT False False None"
    env["MUJOCO_GL"] = "glfw"         # a user's choice is MuJoCo's choice (glfw: what plain mujoco loads)
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True).stdout
    assert out.splitlines()[-1] == "RESULT True True glfw"
