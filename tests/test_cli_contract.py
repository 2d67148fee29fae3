"""The command line's contract with its user (``neck_sim.cli``): ``--version``; every user error on
exactly one line with exit status 2; help that documents every option and states its true default;
a quiet exit when the reader of standard output goes away; one line, never a traceback, on an early
Ctrl-C."""

from __future__ import annotations

import argparse
import json
import os
import re
import signal
import subprocess
import sys
import time
import tomllib

import pytest

from interrupts import sigint_as_from_a_terminal
from neck_sim.cli import COMMANDS, DefaultsFormatter, build_parser, main

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
CLI = [sys.executable, "-m", "neck_sim.cli"]


def _subparsers() -> dict[str, argparse.ArgumentParser]:
    parser = build_parser()
    action = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return dict(action.choices)


def _options(sub: argparse.ArgumentParser):
    return [a for a in sub._actions if not isinstance(a, (argparse._HelpAction, argparse._VersionAction))]


def _run(capsys, argv) -> tuple[int, str, str]:
    code = main(argv)
    out, err = capsys.readouterr()
    return code, out, err


# -- --version ----------------------------------------------------------------------------------

def test_version_is_the_project_version(capsys):
    with open(os.path.join(REPO, "pyproject.toml"), "rb") as fh:
        declared = tomllib.load(fh)["project"]["version"]
    code, out, err = _run(capsys, ["--version"])
    assert code == 0 and err == ""
    assert out.strip() == f"neck-sim {declared}"


# -- one-line errors ------------------------------------------------------------------------------

def _bad_value_cases():
    """Every option of every command that converts or restricts its value, given a value it refuses."""
    for name, sub in _subparsers().items():
        yield [name, "--no-such-option"]
        for a in _options(sub):
            if not a.option_strings or a.nargs == 0:
                continue
            if a.choices is not None:
                yield [name, a.option_strings[-1], "no-such-choice"]
            elif a.type not in (None, str):
                yield [name, a.option_strings[-1], "not-a-number"]


BAD_VALUES = list(_bad_value_cases())


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("cli-errors")
    good = d / "good.json"
    assert main(["params", "-o", str(good)]) == 0
    data = json.loads(good.read_text())
    data["geometry"]["L"] = -0.1
    (d / "bad-value.json").write_text(json.dumps(data))
    (d / "broken.json").write_text("{not json")
    mixed = d / "mixed4.json"
    assert main(["params", "--example", "mixed4", "-o", str(mixed)]) == 0
    (d / "empty.mcap").write_bytes(b"")
    (d / "motors.csv").write_text("not,a,motor,file\n1,2\n")
    return d


def _input_cases(d):
    missing = str(d / "missing")
    cases = [[], ["no-such-command"], ["--no-such-option"]]
    for cmd in ("check", "replay", "identify", "diagnose"):
        cases += [[cmd, missing + ".mcap"], [cmd, str(d / "empty.mcap")]]
    for cmd in ("crossval", "simulate", "design", "render", "replay", "diagnose", "import"):
        for bad in (missing + ".json", "broken.json", "bad-value.json"):
            path = bad if bad.startswith(missing) else str(d / bad)
            extra = {"replay": [str(d / "empty.mcap")], "diagnose": [str(d / "empty.mcap")],
                     "import": ["--motors", str(d / "motors.csv"), "-o", str(d / "out.mcap")]}.get(cmd, [])
            cases.append([cmd, *extra, "--params", path])
    cases += [
        ["params", "--load", missing + ".toml"], ["params", "--load", str(d / "bad-value.json")],
        ["params", "-o", str(d / "no-dir" / "p.json")], ["params", "-o", str(d / "p.csv")],
        ["pulleys", "--json", str(d / "no-dir" / "x.json")],
        ["crossval", "--json", str(d / "good.json"), "--params", str(d / "good.json")],
        ["crossval", "--n-joints", "0"],
        ["import", "--motors", missing + ".csv", "-o", str(d / "out.mcap")],
        ["import", "--motors", str(d / "motors.csv"), "-o", str(d / "out.mcap")],
        ["reproduce", "--out", str(d / "good.json")],
        ["design", "--samples", "0", "-o", str(d / "design")],
        ["render", "-o", str(d / "no-dir" / "x.png")],
        # identify's methods: several logs need output error; its options need it; a bad model file
        ["identify", missing + "-a.mcap", missing + "-b.mcap"],
        ["identify", str(d / "empty.mcap"), "--model", str(d / "good.json")],
        ["identify", str(d / "empty.mcap"), "--method", "output-error", "--model", str(d / "broken.json")],
        ["identify", str(d / "empty.mcap"), "--method", "output-error", "--model", str(d / "good.json")],
        ["identify", str(d / "empty.mcap"), "--method", "output-error", "--integrator", "euler-ish"],
        ["identify", str(d / "empty.mcap"), "--exact-jacobian"],
        ["identify", str(d / "empty.mcap"), str(d / "empty.mcap"), "--method", "output-error"],
        # a multi-line message from deep inside (the routing table of a neck the laws cannot drive)
        ["simulate", "--params", str(d / "mixed4.json"), "--law", "1", "--no-log", "--no-progress"],
    ]
    return cases


def _assert_one_line_error(code, err, argv):
    lines = err.splitlines()
    assert code == 2, (argv, code, err)
    assert len(lines) == 1, (argv, err)
    assert lines[0].startswith("neck-sim") and ": error: " in lines[0], (argv, err)
    assert "Traceback" not in err


@pytest.mark.parametrize("argv", BAD_VALUES, ids=[" ".join(a) for a in BAD_VALUES])
def test_bad_option_values_are_one_line(capsys, argv):
    code, _, err = _run(capsys, argv)
    _assert_one_line_error(code, err, argv)
    message = err.split(": error: ")[1]
    # names the option (argparse reports missing required arguments first)
    assert argv[1] in message or message.startswith("the following arguments are required"), err


def test_bad_inputs_are_one_line(capsys, files):
    cases = _input_cases(files)
    assert len(cases) >= 40
    for argv in cases:
        code, _, err = _run(capsys, argv)
        _assert_one_line_error(code, err, argv)


def test_multi_line_message_keeps_its_content(capsys, monkeypatch):
    """A library error whose message spans lines (a routing's description, one line per cable) is
    printed on one line with every part kept."""
    from neck_sim.cli import params_cmd
    from neck_sim.params import example_params

    routing = example_params("mixed4").routing.describe()
    assert routing.count("\n") >= 3

    def refuse(args):
        raise ValueError(f"this routing cannot be used here:\n{routing}")

    monkeypatch.setattr(params_cmd, "run", refuse)
    code, _, err = _run(capsys, ["params"])
    _assert_one_line_error(code, err, "params")
    for cable in ("c1:", "c2:", "c3:", "c4:"):      # every line of the routing table is still there
        assert cable in err


def test_bad_option_cases_cover_every_command():
    assert {argv[0] for argv in BAD_VALUES} == set(COMMANDS)
    assert len(BAD_VALUES) >= 2 * len(COMMANDS)


# -- help -------------------------------------------------------------------------------------------

def _stated_defaults(text: str) -> list[str]:
    return [t.rstrip(".,:") for t in re.findall(r"default:?\s+([^\s;)]+)", text)]


def _same(stated: str, value) -> bool:
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        try:
            return float(stated) == float(value)
        except ValueError:
            return False
    return stated.removeprefix("./") == str(value).removeprefix("./")


def test_every_option_has_help_and_true_defaults():
    checked = 0
    for name, sub in _subparsers().items():
        fmt = DefaultsFormatter(prog=sub.prog)
        for a in _options(sub):
            label = f"{name} {'/'.join(a.option_strings) or a.dest}"
            assert a.help and a.help.strip(), f"{label}: no help text"
            text = fmt._expand_help(a)
            if a.default in (None, False, []) or not a.option_strings:
                continue
            stated = _stated_defaults(text)
            assert stated, f"{label}: help does not state the default {a.default!r}: {text!r}"
            assert _same(stated[0], a.default), f"{label}: help states {stated[0]!r}, argparse default {a.default!r}"
            checked += 1
    assert checked >= 20


def test_params_help_states_the_neck_each_command_uses():
    """``--n-joints``' stated default is the neck the command really builds without options."""
    from neck_sim.cli import design_cmd
    from neck_sim.cli.common import params_from_args

    resolve = {"crossval": params_from_args, "render": params_from_args, "design": design_cmd.neck_params}
    subs = _subparsers()
    for name, fn in resolve.items():
        action = next(a for a in _options(subs[name]) if "--n-joints" in a.option_strings)
        stated = int(re.search(r"default (\d+)", action.help).group(1))
        args = subs[name].parse_args([] if name != "design" else ["-o", "x"])
        assert fn(args).n_joints == stated, name


# -- the process: closed pipe, early Ctrl-C -----------------------------------------------------------

def test_closed_stdout_exits_quietly():
    """The reader closes the pipe before the command writes (``neck-sim params | head -1`` with a
    fast reader): exit 141, nothing on stderr."""
    r, w = os.pipe()
    proc = subprocess.Popen(CLI + ["params"], stdout=w, stderr=subprocess.PIPE, text=True, cwd=REPO)
    os.close(w)
    os.close(r)
    err = proc.communicate(timeout=120)[1]
    assert err == ""
    assert proc.returncode == 141


def test_pipe_into_head():
    out = subprocess.run(["bash", "-c", f"'{sys.executable}' -m neck_sim.cli params | head -1; "
                                        "echo \"status ${PIPESTATUS[0]}\""],
                         capture_output=True, text=True, cwd=REPO, timeout=120)
    assert out.stderr == ""
    first, status = out.stdout.splitlines()
    assert first.startswith("geometry.n_joints")
    assert status in ("status 0", "status 141")


# the child has imported neck_sim.cli (the console script's first line) when it says so; main()
# then imports every command, numpy and MuJoCo: a Ctrl-C lands in those imports or in the run
_CHILD = ("import sys, neck_sim.cli as cli; sys.stdout.write('ready\\n'); sys.stdout.flush(); "
          "sys.exit(cli.main(['crossval', '--samples', '20']))")


@pytest.mark.parametrize("delay", [0.0, 0.02, 0.05, 0.1, 0.2, 0.4])
def test_early_ctrl_c_is_one_line(delay):
    proc = subprocess.Popen([sys.executable, "-c", _CHILD], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, cwd=REPO, preexec_fn=sigint_as_from_a_terminal)
    assert proc.stdout.readline() == "ready\n"
    time.sleep(delay)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    assert "Traceback" not in err
    assert proc.returncode in (130, -signal.SIGINT), (proc.returncode, err)
    lines = err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("neck-sim") and "interrupted (Ctrl-C)" in lines[0], err


def test_ctrl_c_inside_an_extension_import_is_an_interrupt(monkeypatch, capsys):
    """A Ctrl-C during ``import mujoco`` surfaces as ImportError("initialization failed") chained to
    the KeyboardInterrupt: exit 130 with the interrupt's one line, not an internal error."""
    import neck_sim.cli as cli

    def interrupted_import():
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt as exc:
            raise ImportError("initialization failed") from exc

    monkeypatch.setattr(cli, "_import_mujoco_without_opengl", interrupted_import)
    assert cli.main(["params"]) == 130
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "interrupted (Ctrl-C)" in err, err


def test_exact_jacobian_puts_every_column_on_the_fit_model():
    """`identify --exact-jacobian`: no Jacobian column on the cheaper model; without it, the
    settings' default cheaper model for f_s, k and lambda."""
    from identification.output_error.settings import OutputErrorSettings
    from neck_sim.cli import build_parser
    from neck_sim.cli.identify_cmd import output_error_settings

    def settings(*extra):
        return output_error_settings(build_parser().parse_args(["identify", "x.mcap", "--method", "output-error", *extra]))

    assert settings("--exact-jacobian").jacobian_timestep is None
    assert settings().jacobian_timestep == OutputErrorSettings().jacobian_timestep > 0
    assert settings("--exact-jacobian", "--max-evaluations", "3").max_evaluations == 3
