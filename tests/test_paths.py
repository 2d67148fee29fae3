"""Input and output paths: no command writes over an input or fails after the work on an
output path it could have checked first; user errors are one line with exit status 2; measured
data are checked against the ``neck`` record (units); Ctrl-C, SIGTERM and internal errors end in
one line with the temporary files gone.  Every command runs in-process through ``main``."""

from __future__ import annotations

import gc
import json
import math
import os
import signal
import socket as _socket
import stat

import numpy as np
import pytest
from blocking import bounded
from test_logs_fixtures import synthetic_arrays, write_arrays

from neck_sim.atomic import TEMP_PREFIX, atomic_write_json
from neck_sim.cli import main
from neck_sim.logs import LogError, LogWriter, read_log
from neck_sim.params import default_params, save


def run_cli(argv, capsys):
    """(exit status, stdout, stderr) of ``neck-sim argv`` run in this process."""
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def snapshot(folder) -> dict:
    """name -> bytes of every file in ``folder`` (hidden temporary files included)."""
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir()) if p.is_file()}


@pytest.fixture
def log(tmp_path):
    """A short, plausible measured log (0.2 s of motors at 500 Hz, camera at 30 Hz)."""
    p = default_params(3)
    arrays = synthetic_arrays(p, seconds=0.2, seed=3)
    path = tmp_path / "run.mcap"
    write_arrays(path, p, {k: arrays[k] for k in ("motors", "camera")})
    return path


def write_log(path, arrays, params=None):
    write_arrays(path, params or default_params(3), arrays)
    return path


def motors_csv(path, t, forces=None):
    forces = np.full((len(t), 4), 10.0) if forces is None else forces
    rows = ["t,theta1,theta2,theta3,theta4,force1,force2,force3,force4"]
    rows += [",".join(repr(float(v)) for v in (ti, 0.0, 0.0, 0.0, 0.0, *f)) for ti, f in zip(t, forces)]
    path.write_text("\n".join(rows) + "\n")
    return path


# -- item 1: nothing overwrites an input; outputs checked before the work -------------------------

@pytest.mark.parametrize("case", ["replay", "identify", "simulate", "import", "params", "diagnose", "symlink"])
def test_an_output_equal_to_an_input_is_refused_before_any_work(case, tmp_path, log, capsys):
    toml = tmp_path / "p.toml"
    save(default_params(3), toml)
    csv = motors_csv(tmp_path / "m.csv", np.arange(10) / 500)
    os.symlink(log, tmp_path / "link.mcap")
    argv, victim = {
        "replay": (["replay", log, "-o", log], log),
        "identify": (["identify", log, "--json", log], log),
        "simulate": (["simulate", "--params", toml, "--json", toml], toml),
        "import": (["import", "--motors", csv, "-o", csv], csv),
        "params": (["params", "--load", toml, "-o", toml], toml),
        "diagnose": (["diagnose", log, "--extended", log], log),
        "symlink": (["replay", log, "--json", tmp_path / "link.mcap"], log),
    }[case]
    before = snapshot(tmp_path)
    code, out, err = run_cli(argv, capsys)
    assert code == 2
    assert "refusing to write over an input" in err and str(victim) in err and len(err.splitlines()) == 1
    assert snapshot(tmp_path) == before


def test_two_outputs_on_one_path_are_refused(tmp_path, log, capsys):
    js = tmp_path / "d.json"
    code, _, err = run_cli(["diagnose", log, "--json", js, "--extended", js], capsys)
    assert code == 2 and "--extended" in err and "its own path" in err


@pytest.mark.parametrize("problem", ["directory", "missing folder", "folder is a file"])
def test_unwritable_output_paths_are_refused_before_the_computation(problem, tmp_path, log, capsys, monkeypatch):
    import neck_sim.replay

    def no_work(*a, **k):
        raise AssertionError("the replay ran before the output path was checked")

    monkeypatch.setattr(neck_sim.replay, "replay", no_work)
    (tmp_path / "adir").mkdir()
    (tmp_path / "afile").write_text("x")
    out = {"directory": tmp_path / "adir", "missing folder": tmp_path / "nope" / "r.mcap",
           "folder is a file": tmp_path / "afile" / "r.mcap"}[problem]
    code, _, err = run_cli(["replay", log, "-o", out], capsys)
    assert code == 2 and f"-o {out}:" in err
    assert {"directory": "is a directory", "missing folder": "does not exist",
            "folder is a file": "is not a directory"}[problem] in err


def test_write_errors_name_the_users_path_not_the_temporary_file(tmp_path):
    target = tmp_path / "result.json"
    target.mkdir()                      # os.replace over a directory fails
    with pytest.raises(OSError) as info:
        atomic_write_json(target, {"a": 1})
    assert str(info.value) == f"cannot write {target}: it is a directory"
    with pytest.raises(OSError) as info:      # refused when the writer opens, before any data
        LogWriter(target, default_params(3))
    assert str(target) in str(info.value) and TEMP_PREFIX not in str(info.value)
    assert [p.name for p in tmp_path.iterdir()] == ["result.json"]


# -- item 6: option values name the option ---------------------------------------------------------

@pytest.mark.parametrize("argv, option", [
    (["pulleys", "--seed", "-1"], "--seed"),
    (["simulate", "--seed", "-1"], "--seed"),
    (["diagnose", "x.mcap", "--alpha", "2"], "--alpha"),
    (["identify", "x.mcap", "--start", "-3"], "--start"),
    (["crossval", "--samples", "0"], "--samples"),
])
def test_bad_option_values_name_the_option(argv, option, capsys):
    code, _, err = run_cli(argv, capsys)
    assert code == 2 and f"argument {option}: must be" in err


def test_a_start_past_the_end_of_the_log_says_so(log, capsys):
    code, _, err = run_cli(["identify", log, "--start", "100"], capsys)
    assert code == 2
    assert "start = 100" in err and "/neck/motors" in err and "span t = 0 .. 0.198 s" in err


def test_shift_time_prints_a_signed_shift(tmp_path, capsys):
    csv = motors_csv(tmp_path / "m.csv", -0.9665 + np.arange(20) / 500)
    code, out, _ = run_cli(["import", "--motors", csv, "--shift-time", "-o", tmp_path / "o.mcap"], capsys)
    assert code == 0 and "times shifted by +0.966500 s" in out


def test_times_beyond_mcap_range_are_a_clear_error(tmp_path, capsys):
    csv = motors_csv(tmp_path / "m.csv", 2e10 + np.arange(20) / 500)
    code, _, err = run_cli(["import", "--motors", csv, "-o", tmp_path / "o.mcap"], capsys)
    assert code == 2 and str(csv) in err and "--shift-time" in err and "9.2e9" in err
    assert not (tmp_path / "o.mcap").exists()
    code, _, _ = run_cli(["import", "--motors", csv, "--shift-time", "-o", tmp_path / "o.mcap"], capsys)
    assert code == 0 and read_log(tmp_path / "o.mcap").motors.t.size == 20
    with LogWriter(tmp_path / "w.mcap") as w, pytest.raises(ValueError, match="nanosecond timestamps"):
        w.motors(2e10, np.zeros(4), np.ones(4))


def test_a_non_utf8_csv_names_its_file(tmp_path, capsys):
    csv = tmp_path / "m.csv"
    motors_csv(csv, np.arange(5) / 500)
    csv.write_bytes(csv.read_bytes().replace(b"theta2", b"th\xe9ta2"))
    code, _, err = run_cli(["import", "--motors", csv, "-o", tmp_path / "o.mcap"], capsys)
    assert code == 2 and str(csv) in err and "not UTF-8" in err and "0xe9" in err


# -- item 4: Ctrl-C, SIGTERM and internal errors ---------------------------------------------------

@pytest.mark.parametrize("how, status, word", [("ctrl-c", 130, "interrupted"), ("sigterm", 143, "terminated"),
                                               ("bug", 70, "internal error")])
def test_interruptions_and_bugs_end_in_one_line_and_leave_no_temporary_file(how, status, word, tmp_path, capsys,
                                                                              monkeypatch):
    import neck_sim.logs.writer as writer

    calls = []
    original = writer.LogWriter.motors

    def motors(self, *a):
        calls.append(1)
        if len(calls) == 10:
            if how == "ctrl-c":
                raise KeyboardInterrupt
            if how == "sigterm":
                os.kill(os.getpid(), signal.SIGTERM)
            else:
                raise TypeError("a bug")
        return original(self, *a)

    monkeypatch.setattr(writer.LogWriter, "motors", motors)
    csv = motors_csv(tmp_path / "m.csv", np.arange(50) / 500)
    before = signal.getsignal(signal.SIGTERM)
    code, _, err = run_cli(["import", "--motors", csv, "-o", tmp_path / "o.mcap"], capsys)
    assert code == status and word in err and len(err.strip().splitlines()) == 1
    assert [p.name for p in tmp_path.iterdir()] == ["m.csv"]
    assert signal.getsignal(signal.SIGTERM) is before
    if how == "bug":
        trace = err.split("written to ")[1].strip().rstrip(")")
        assert "Traceback" in open(trace).read() and "TypeError: a bug" in open(trace).read()
        os.unlink(trace)


# -- item 5: temporary files -----------------------------------------------------------------------

def test_an_environment_dropped_without_close_leaves_no_temporary_file(tmp_path):
    from neck_sim import env as neck_env

    env = neck_env.load(seed=1, time_limit=0.1, log_path=str(tmp_path / "ep.mcap"))
    env.reset()
    for _ in range(3):
        env.step(np.full(4, 10.0))
    assert any(p.name.startswith(TEMP_PREFIX) for p in tmp_path.iterdir())
    del env
    gc.collect()
    assert list(tmp_path.iterdir()) == []


# -- item 2: plausibility against the neck record --------------------------------------------------

def _measured(seconds=0.2, seed=3):
    a = synthetic_arrays(default_params(3), seconds=seconds, seed=seed)
    return {k: dict(a[k]) for k in ("motors", "camera")}


@pytest.mark.parametrize("unit, scale", [("milliseconds", 1e3), ("microseconds", 1e6)])
def test_times_in_another_unit_are_refused_naming_the_unit(unit, scale, tmp_path, capsys):
    a = _measured()
    for topic in a:
        a[topic]["t"] = a[topic]["t"] * scale
    path = write_log(tmp_path / "ms.mcap", a)
    code, _, err = run_cli(["identify", path], capsys)
    assert code == 2 and "/neck/motors" in err and f"times look like {unit}" in err and "control_rate_hz = 500" in err
    csv = motors_csv(tmp_path / "m.csv", np.arange(20) / 500 * scale)
    code, _, err = run_cli(["import", "--motors", csv, "-o", tmp_path / "o.mcap"], capsys)
    assert code == 2 and str(csv) in err and f"times look like {unit}" in err


def test_a_camera_at_the_wrong_rate_is_refused():
    p = default_params(3)
    a = _measured(seconds=1.0)
    a["camera"]["t"] = a["camera"]["t"] / 2         # 60 frames per second against the declared 30
    with pytest.raises(LogError, match="/neck/camera.*camera_rate_hz = 30"):
        from neck_sim.logs.contract import TOPIC_BY_NAME, check_plausible
        check_plausible(TOPIC_BY_NAME["camera"], a["camera"], p)


def test_camera_angles_in_degrees_are_refused(tmp_path, capsys):
    a = _measured()
    a["camera"]["alpha"] = np.degrees(a["camera"]["alpha"])
    path = write_log(tmp_path / "deg.mcap", a)
    code, _, err = run_cli(["diagnose", path], capsys)
    assert code == 2 and "/neck/camera" in err and "angles look like degrees" in err and "alpha_max" in err


def test_camera_angles_just_past_the_joint_range_are_not_called_degrees():
    """1.8 rad on one joint (a simulated neck that bent past alpha_max): refused as outside the
    joint range, and not mistaken for a log in degrees."""
    from neck_sim.logs.contract import TOPIC_BY_NAME, check_plausible

    a = _measured()
    a["camera"]["alpha"][5, 1] = -1.8
    with pytest.raises(LogError, match="alpha2 = -1.8 rad is outside the joint range") as info:
        check_plausible(TOPIC_BY_NAME["camera"], a["camera"], default_params(3))
    assert "bent past its joint range" in str(info.value) and "degrees" not in str(info.value)


@pytest.mark.parametrize("kind", ["negative", "spike"])
def test_out_of_range_forces_are_refused_or_accepted_and_reported(kind, tmp_path, capsys):
    a = _measured()
    force = a["motors"]["force"]
    k = 37
    force[k, 2] = -5.0 if kind == "negative" else 1e6
    path = write_log(tmp_path / "f.mcap", a)
    code, _, err = run_cli(["identify", path], capsys)
    assert code == 2 and f"sample {k}" in err and "force3" in err and "--accept-out-of-range-forces" in err
    log = read_log(path, accept_out_of_range_forces=True)
    assert len(log.warnings) == 1 and f"sample {k}" in log.warnings[0]
    assert log.motors.force[k, 2] == force[k, 2]


def test_replay_says_when_the_plant_clips_logged_forces(tmp_path, capsys):
    a = _measured(seconds=0.1)
    a["motors"]["force"][[5, 9], 1] = [-3.0, 250.0]
    path = write_log(tmp_path / "f.mcap", a)
    js = tmp_path / "r.json"
    code, out, _ = run_cli(["replay", path, "--no-output", "--no-progress", "--json", js,
                            "--accept-out-of-range-forces"], capsys)
    assert code == 0
    notes = json.loads(js.read_text())["notes"]
    clip = [n for n in notes if "clipped" in n]
    assert len(clip) == 1 and "2 of 50" in clip[0] and "largest excess 150 N" in clip[0] and clip[0] in out
    assert any("accepted out-of-range forces" in n for n in notes)


def test_plausible_logs_and_angles_near_the_joint_limit_pass(tmp_path):
    a = _measured()
    a["camera"]["alpha"][:, 0] = math.pi / 2 + 0.05      # camera noise just beyond the joint limit
    log = read_log(write_log(tmp_path / "ok.mcap", a))
    assert log.warnings == () and log.camera.alpha[0, 0] == a["camera"]["alpha"][0, 0]


# -- output and input path kinds: only regular files are written or read -------------------------

def _no_diagnosis(monkeypatch):
    import identification.diagnosis

    class Reached(BaseException):      # not caught by main
        pass

    def stop(*a, **k):
        raise Reached
    monkeypatch.setattr(identification.diagnosis, "diagnose_log", stop)
    return Reached


def test_a_report_directory_holding_the_model_input_is_refused(tmp_path, log, capsys, monkeypatch):
    """``diagnose --model m.json --report .`` would write the report's model.json over m.json."""
    _no_diagnosis(monkeypatch)
    monkeypatch.chdir(tmp_path)
    (tmp_path / "model.json").write_text('{"model": ["dry_friction"]}\n')
    before = snapshot(tmp_path)
    code, _, err = run_cli(["diagnose", log, "--model", "model.json", "--report", "."], capsys)
    assert code == 2 and len(err.splitlines()) == 1
    assert "--report" in err and "model.json" in err and "refusing to write over an input" in err
    assert snapshot(tmp_path) == before


def test_an_output_file_inside_a_report_directory_is_refused(tmp_path, log, capsys, monkeypatch):
    """``diagnose --report . --json report.md``: the report would replace the JSON."""
    _no_diagnosis(monkeypatch)
    monkeypatch.chdir(tmp_path)
    code, _, err = run_cli(["diagnose", log, "--report", ".", "--json", "report.md"], capsys)
    assert code == 2 and "--json report.md" in err and "--report" in err and "its own path" in err


@pytest.mark.parametrize("argv, figure", [
    (["identify", "{log}", "--plots", ".", "--json", "fig4_torques.png"], "fig4_torques.png"),
    (["simulate", "--duration-scale", "0.05", "--plots", ".", "--json", "forces.png"], "forces.png"),
])
def test_an_output_file_where_a_plot_goes_is_refused(argv, figure, tmp_path, log, capsys, monkeypatch):
    """``--plots .`` writes its figures into the folder: ``--json`` on one of their names would be
    replaced by a PNG; refused in one line before any work, nothing written."""
    monkeypatch.chdir(tmp_path)
    before = snapshot(tmp_path)
    code, _, err = run_cli([a.format(log=log) for a in argv], capsys)
    assert code == 2 and len(err.splitlines()) == 1, err
    assert f"--json {figure}" in err and "--plots" in err and "its own path" in err
    assert snapshot(tmp_path) == before


def test_an_output_directory_holding_an_input_is_fine(tmp_path, capsys, monkeypatch):
    reached = _no_diagnosis(monkeypatch)
    log = write_log(tmp_path / "long.mcap", _measured(seconds=0.5))       # 15 camera frames
    with pytest.raises(reached):
        main(["diagnose", str(log), "--report", str(tmp_path), "--json", str(tmp_path / "d.json")])


@pytest.mark.parametrize("mode", [0o444, 0o400])
def test_a_read_only_output_is_refused_even_as_root(mode, tmp_path, capsys):
    out = tmp_path / "ro.toml"
    out.write_text("keep me\n")
    out.chmod(mode)
    code, _, err = run_cli(["params", "-o", out], capsys)
    assert code == 2 and f"-o {out}" in err and "read-only" in err
    assert out.read_text() == "keep me\n" and stat.S_IMODE(out.stat().st_mode) == mode
    with pytest.raises(OSError, match="read-only"):
        atomic_write_json(out, {"a": 1})
    assert out.read_text() == "keep me\n"


def test_an_existing_output_keeps_its_mode(tmp_path, capsys):
    out = tmp_path / "p.json"
    out.write_text("{}")
    out.chmod(0o640)
    code, _, _ = run_cli(["params", "-o", out], capsys)
    assert code == 0 and "geometry" in out.read_text() and stat.S_IMODE(out.stat().st_mode) == 0o640
    fresh = tmp_path / "new.json"
    atomic_write_json(fresh, {"a": 1})
    assert stat.S_IMODE(fresh.stat().st_mode) == 0o666 & ~_umask()


def _umask():
    mask = os.umask(0)
    os.umask(mask)
    return mask


def _special(kind, tmp_path, keep):
    """A path of ``kind`` (and the word the refusal must contain)."""
    if kind == "null copy":
        path = tmp_path / "null"
        os.mknod(path, stat.S_IFCHR | 0o666, os.makedev(1, 3))
        return path, "character device"
    if kind == "/dev/full":
        return "/dev/full", "character device"
    if kind == "fifo":
        path = tmp_path / "fifo"
        os.mkfifo(path)
        return path, "FIFO"
    if kind == "socket":
        path = tmp_path / "sock"
        s = _socket.socket(_socket.AF_UNIX)
        s.bind(str(path))
        keep.append(s)
        return path, "socket"
    if kind == "link to a pipe fd":
        r, w = os.pipe()
        keep.extend([r, w])
        path = tmp_path / "stdout.json"
        os.symlink(f"/proc/self/fd/{w}", path)
        return path, "FIFO"
    raise AssertionError(kind)


KINDS = ["null copy", "/dev/full", "fifo", "socket", "link to a pipe fd"]


@pytest.mark.parametrize("kind", KINDS)
def test_outputs_that_are_not_regular_files_are_refused(kind, tmp_path, capsys):
    keep = []
    try:
        path, word = _special(kind, tmp_path, keep)
        before = os.stat(path).st_mode
        with bounded():
            code, _, err = run_cli(["params", "-o", path], capsys)
        assert code == 2 and f"-o {path}" in err and word in err and "not a regular file" in err
        assert os.stat(path).st_mode == before and os.path.islink(path) == (kind == "link to a pipe fd")
        with pytest.raises(OSError, match="not a regular file"):
            atomic_write_json(path, {"a": 1})
        assert os.stat(path).st_mode == before
        assert not [p for p in tmp_path.iterdir() if p.name.startswith(TEMP_PREFIX)]
    finally:
        for k in keep:
            k.close() if hasattr(k, "close") else os.close(k)


@pytest.mark.parametrize("kind", ["fifo", "null copy", "socket"])
@pytest.mark.parametrize("option", ["LOG", "--params", "--motors"])
def test_inputs_that_are_not_regular_files_are_refused_without_blocking(kind, option, tmp_path, capsys):
    keep = []
    try:
        path, word = _special(kind, tmp_path, keep)
        argv = {"LOG": ["identify", path], "--params": ["simulate", "--params", path, "--no-log"],
                "--motors": ["import", "--motors", path, "-o", tmp_path / "o.mcap"]}[option]
        with bounded(5):
            code, _, err = run_cli(argv, capsys)
        assert code == 2 and len(err.splitlines()) == 1
        assert f"{option} {path}" in err and word in err and "not a regular file" in err
    finally:
        for k in keep:
            k.close() if hasattr(k, "close") else os.close(k)


def test_a_link_to_a_redirected_standard_output_is_refused(tmp_path, capsys):
    """/proc/self/fd/N of a stdout redirected to a file resolves to that regular file: replacing it
    would cut the command's own output off, so links into /proc (and /dev) are refused."""
    redirected = tmp_path / "stdout.txt"
    fd = os.open(redirected, os.O_WRONLY | os.O_CREAT, 0o644)
    try:
        link = tmp_path / "out.json"
        os.symlink(f"/proc/self/fd/{fd}", link)
        code, _, err = run_cli(["params", "-o", link], capsys)
        assert code == 2 and f"-o {link}" in err and "special file" in err
        assert redirected.read_text() == "" and os.path.islink(link)
    finally:
        os.close(fd)


def test_a_symlink_to_a_regular_output_is_written_through(tmp_path, capsys):
    target = tmp_path / "real.json"
    target.write_text("{}")
    link = tmp_path / "link.json"
    os.symlink(target, link)
    code, _, _ = run_cli(["params", "-o", link], capsys)
    assert code == 0 and os.path.islink(link) and "geometry" in target.read_text()


def test_long_legal_output_names_work_and_too_long_ones_are_refused_before_the_work(tmp_path, log, capsys,
                                                                                    monkeypatch):
    long_name = tmp_path / ("p" * 240 + ".toml")          # 245 characters: legal (NAME_MAX 255)
    code, _, err = run_cli(["params", "-o", long_name], capsys)
    assert code == 0, err
    assert long_name.exists() and [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []
    import neck_sim.replay

    def no_work(*a, **k):
        raise AssertionError("the replay ran before the output path was checked")
    monkeypatch.setattr(neck_sim.replay, "replay", no_work)
    too_long = tmp_path / ("r" * 256 + ".mcap")
    code, _, err = run_cli(["replay", log, "-o", too_long], capsys)
    assert code == 2 and "name is too long" in err and "255" in err


# -- valid input refused ---------------------------------------------------------------------------

def test_a_neck_with_a_long_bar_reads_its_own_log_back(tmp_path):
    """b = 0.12 m, L = 0.2 m is valid; the log's record must read back whatever the field order."""
    from neck_sim.params import NeckParams
    p = default_params(3)
    wide = p.replace(**{"geometry.L": 0.2, "geometry.b": 0.12})
    assert wide.replace(**{"geometry.b": 0.12, "geometry.L": 0.2}) == wide
    assert (wide.geometry.b, wide.geometry.L) == (0.12, 0.2)
    with pytest.raises(ValueError, match="must be longer than the bar"):
        p.replace(**{"geometry.b": 0.12})
    path = tmp_path / "wide.mcap"
    with LogWriter(path, wide) as w:
        for k in range(5):
            w.motors(k / 500, np.zeros(4), np.full(4, 10.0))
    back = read_log(path).params
    assert isinstance(back, NeckParams) and (back.geometry.b, back.geometry.L) == (0.12, 0.2)


@pytest.mark.parametrize("option", ["--start", "--end"])
def test_huge_window_bounds_are_a_window_not_a_traceback(option, tmp_path, capsys, monkeypatch):
    import identification.paper

    log = write_log(tmp_path / "long.mcap", _measured(seconds=0.5))

    seen = {}

    class Reached(BaseException):
        pass

    def stop(log, *a, **k):
        seen["samples"] = log.motors.t.size
        raise Reached
    monkeypatch.setattr(identification.paper, "identify_log", stop)
    if option == "--start":
        code, _, err = run_cli(["identify", log, "--start", "1e308"], capsys)
        assert code == 2 and "start = 1e+308" in err and "/neck/motors" in err and len(err.splitlines()) == 1
    else:
        with pytest.raises(Reached):
            main(["identify", str(log), "--end", "1e308"])
        assert seen["samples"] == read_log(log).motors.t.size


# -- parameter files: unit mistakes and implausible values are named -------------------------------

@pytest.mark.parametrize("field, value, words", [
    ("inertia.gravity", 98.1, ["inertia.gravity = 98.1 m/s^2", "10x Earth's"]),
    ("geometry.b", 50.0, ["geometry.b = 50 m", "millimetres"]),
    ("springs.rest_length", 46.0, ["springs.rest_length = 46 m", "millimetres"]),
    ("inertia.bar_mass", 20.0, ["inertia.bar_mass = 20 kg", "grams"]),
])
def test_implausible_parameter_files_are_refused_naming_the_value(field, value, words, tmp_path, capsys):
    from neck_sim.params import to_dict
    data = to_dict(default_params(3))
    grp, fld = field.split(".")
    data[grp][fld] = value
    if field == "geometry.b":                      # the whole geometry in mm, as a user would write it
        data["geometry"].update(b=50.0, L=100.0, r=4.6)
    path = tmp_path / "p.json"
    path.write_text(json.dumps(data))
    code, _, err = run_cli(["simulate", "--params", path, "--no-log"], capsys)
    assert code == 2 and str(path) in err and len(err.splitlines()) == 1
    assert all(w in err for w in words) and "--accept-implausible-params" in err
    code, out, err = run_cli(["params", "--load", path, "--accept-implausible-params"], capsys)
    if field == "springs.rest_length":          # 46 m is also longer than a side can be: still refused
        assert code == 2 and "longer than a side" in err
    else:
        assert code == 0 and all(w in out for w in words) and "warning:" in out


# -- measured data: encoders in degrees or counts, forces in kN ------------------------------------

def _motor_table(seconds=0.2):
    """A plausible motors table: theta ramps to 30 rad on cable 3 (a large move), forces 5-60 N."""
    t = np.arange(int(seconds * 500)) / 500
    theta = np.zeros((len(t), 4))
    theta[:, 2] = 30.0 * t / t[-1]
    theta[:, 0] = -8.0 * t / t[-1]
    force = 5.0 + 55.0 * np.abs(np.sin(np.outer(t, [3.0, 5.0, 7.0, 11.0])))
    return t, theta, force


def _write_motor_csv(path, t, theta, force):
    rows = ["t,theta1,theta2,theta3,theta4,force1,force2,force3,force4"]
    rows += [",".join(repr(float(v)) for v in (ti, *th, *f)) for ti, th, f in zip(t, theta, force)]
    path.write_text("\n".join(rows) + "\n")
    return path


@pytest.mark.parametrize("mistake, words", [
    ("degrees", ["encoder theta3 reaches 1718.87", "looks like degrees", "expected rad"]),
    ("counts", ["encoder theta3 reaches 9778 ", "looks like encoder counts (2048 per turn"]),
    ("kN", ["forces look like kilonewtons", "expected N", "f_max = 100 N"]),
    ("none", []),
])
def test_unit_mistakes_in_measured_motors_are_named_at_import_and_in_logs(mistake, words, tmp_path, capsys):
    t, theta, force = _motor_table()
    if mistake == "degrees":
        theta = np.degrees(theta)
    elif mistake == "counts":
        theta = np.round(theta * 2048 / (2 * math.pi))
    elif mistake == "kN":
        force = force / 1000
    csv = _write_motor_csv(tmp_path / "m.csv", t, theta, force)
    code, _, err = run_cli(["import", "--motors", csv, "-o", tmp_path / "o.mcap"], capsys)
    if mistake == "none":
        assert code == 0, err
        return
    assert code == 2 and str(csv) in err and "/neck/motors" in err and all(w in err for w in words), err
    assert not (tmp_path / "o.mcap").exists()
    a = _measured()
    a["motors"] = {"t": t, "theta": theta, "force": force}
    a["camera"]["t"] = a["camera"]["t"][a["camera"]["t"] <= t[-1]]
    a["camera"]["alpha"] = a["camera"]["alpha"][: len(a["camera"]["t"])]
    path = write_log(tmp_path / "u.mcap", a)
    code, _, err = run_cli(["identify", path], capsys)
    assert code == 2 and str(path) in err and all(w in err for w in words), err


def test_the_encoder_bound_holds_simulated_runs():
    """The motor-angle bound sits above what the simulated neck reaches in its largest moves."""
    from neck_sim.logs.contract import max_motor_angle
    p = default_params(3)
    limit = max_motor_angle(p)
    # straight pose to alpha_max on every joint: the largest geometric winding of any cable
    from neck_sim.analytic import cable_lengths
    corners = np.array([[s * p.geometry.alpha_max] * 3 for s in (-1, 1)])
    wound = np.abs(cable_lengths(corners, p)).max() * p.actuation.R / p.actuation.r_d
    assert 2 * wound < limit < math.degrees(wound)


def test_a_closed_standard_output_is_an_error_not_a_silent_success(tmp_path):
    import subprocess
    import sys
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    run = subprocess.run(f"{sys.executable} -m neck_sim.cli params >&-", shell=True, cwd=root,
                         stderr=subprocess.PIPE, text=True, timeout=60)
    assert run.returncode == 2 and len(run.stderr.splitlines()) == 1 and "standard output is closed" in run.stderr
    ok = subprocess.run(f"{sys.executable} -m neck_sim.cli params >/dev/null", shell=True, cwd=root,
                        stderr=subprocess.PIPE, text=True, timeout=60)
    assert ok.returncode == 0 and ok.stderr == ""


# -- silent wrong results --------------------------------------------------------------------------

FORCES = 10.0 + 5.0 * np.sin(np.outer(np.arange(40) / 50.0, [1.0, 2.0, 3.0, 4.0]))


def _truth_row(plant):
    tr = plant.truth()
    return np.concatenate([tr.alpha, tr.alpha_dot, tr.tension])


def test_a_python_backend_plant_leaves_native_plants_bit_identical():
    from neck_sim import plant as P
    if not P.native_available():
        pytest.skip("no C compiler: only the Python backend exists here")
    previous = P.get_backend()
    try:
        P.set_backend("native")
        alone = P.Plant(default_params(3), seed=2)
        reference = []
        for f in FORCES:
            alone.step(f)
            reference.append(_truth_row(alone))
        del alone
        plant = P.Plant(default_params(3), seed=2)
        rows, slow = [], None
        for k, f in enumerate(FORCES):
            if k == 20:                 # a Python-backend plant appears half-way and steps in between
                slow = P.Plant(default_params(3), seed=9, backend="python")
            if slow is not None:
                slow.step(np.full(4, 12.0))
            plant.step(f)
            rows.append(_truth_row(plant))
        np.testing.assert_array_equal(np.array(rows), np.array(reference))
        assert plant.backend == "native" and slow.backend == "python" and P.get_backend() == "native"
    finally:
        P.set_backend(previous or "auto")


# -- stuck sensors and too little camera -----------------------------------------------------------

@pytest.fixture(scope="module")
def plant_log(tmp_path_factory):
    """5 s of the MuJoCo plant open loop (motors, camera, truth) as per-topic arrays."""
    from test_logs_fixtures import log_arrays, plant_run
    path = tmp_path_factory.mktemp("plant") / "run.mcap"
    plant_run(path, seconds=5.0, seed=4)
    return log_arrays(read_log(path))


def _measured_copy(arrays):
    return {k: {f: np.array(v) for f, v in arrays[k].items()} for k in ("motors", "camera")}


def test_a_stale_force_logger_is_refused_naming_the_cable(plant_log, tmp_path, capsys):
    a = _measured_copy(plant_log)
    a["motors"]["force"][:, 2] = a["motors"]["force"][0, 2]
    path = write_log(tmp_path / "stale.mcap", a)
    code, _, err = run_cli(["identify", path], capsys)
    assert code == 2 and len(err.splitlines()) == 1 and str(path) in err
    assert "force3 = " in err and "all 2500 samples" in err and "theta3 moves" in err and "stale force logger" in err
    t = a["motors"]["t"]
    csv = _write_motor_csv(tmp_path / "m.csv", t, a["motors"]["theta"], a["motors"]["force"])
    code, _, err = run_cli(["import", "--motors", csv, "-o", tmp_path / "o.mcap"], capsys)
    assert code == 2 and str(csv) in err and "stale force logger" in err
    clean = write_log(tmp_path / "clean.mcap", _measured_copy(plant_log))     # the same log, logger working
    assert read_log(clean).warnings == ()
    # a simulated log (with /neck/truth) holds what neck-sim commanded: a constant action is no logger fault
    simulated = write_log(tmp_path / "sim.mcap", {**a, "truth": plant_log["truth"]})
    assert np.all(read_log(simulated).motors.force[:, 2] == a["motors"]["force"][0, 2])


def test_a_stuck_camera_is_named_not_the_encoders(plant_log, tmp_path, capsys):
    a = _measured_copy(plant_log)
    a["camera"]["alpha"][:] = 0.0
    path = write_log(tmp_path / "cam0.mcap", a)
    for command in ("identify", "diagnose"):
        code, _, err = run_cli([command, path], capsys)
        assert code == 2 and len(err.splitlines()) == 1
        assert "/neck/camera" in err and "camera is stuck" in err and "alpha = [0, 0, 0] rad" in err
        assert "encoder" not in err


@pytest.mark.parametrize("frames", [1, 7])
def test_too_few_camera_frames_say_what_to_record(frames, plant_log, tmp_path, capsys):
    a = _measured_copy(plant_log)
    a["camera"] = {k: v[:frames] for k, v in a["camera"].items()}
    path = write_log(tmp_path / "few.mcap", a)
    for command in ("identify", "diagnose"):
        code, _, err = run_cli([command, path], capsys)
        assert code == 2 and len(err.splitlines()) == 1 and str(path) in err
        assert f"holds {frames} frame(s) of /neck/camera" in err and "at least 8 frames" in err
        assert "record the camera topic for the whole run" in err and "1-D time vector" not in err


def test_an_empty_camera_topic_says_it_holds_nothing(tmp_path, capsys):
    from test_logs_fixtures import motors_messages, write_raw
    t = np.arange(600) / 500
    motors = motors_messages(4, t, theta=[[0.0] * 4] * 600, force=[[10.0] * 4] * 600)
    path = tmp_path / "empty.mcap"
    write_raw(path, default_params(3), {"/neck/motors": motors, "/neck/camera": []})
    for command in ("identify", "diagnose"):
        code, _, err = run_cli([command, path], capsys)
        assert code == 2 and len(err.splitlines()) == 1 and str(path) in err
        assert "/neck/camera" in err and "holds no messages" in err and "record it for the whole run" in err


def test_negative_identified_friction_is_called_unphysical(plant_log, tmp_path):
    """Forces frozen at their first values (defeating the stale check by a jitter of 1e-9 N) make
    the friction regression return negative f_s: the result must say it is no result."""
    import dataclasses

    from identification.paper import IdentificationSettings, format_tables, identify_log
    from neck_sim.logs.reader import MotorSamples
    a = _measured_copy(plant_log)
    base = read_log(write_log(tmp_path / "run.mcap", a))
    settings = IdentificationSettings(reconstruct_alpha=False)
    honest = identify_log(base, settings, models=("friction",))
    assert np.all(honest.friction.group("f_s") > 0) and not any("UNPHYSICAL" in n for n in honest.notes)
    frozen = np.tile(a["motors"]["force"][0], (len(a["motors"]["t"]), 1))
    frozen[::300] += 1e-9
    log = dataclasses.replace(base, motors=MotorSamples(t=base.motors.t, theta=base.motors.theta, force=frozen))
    res = identify_log(log, settings, models=("friction",))
    negative = np.flatnonzero(res.friction.group("f_s") < 0)
    assert negative.size, res.friction.group("f_s")
    note = [n for n in res.notes if n.startswith("UNPHYSICAL")]
    assert len(note) == 1 and "negative friction f_s" in note[0] and f"cable {negative[0] + 1}:" in note[0]
    assert note[0] in format_tables(res) and note[0] in res.to_dict()["notes"]


@pytest.mark.parametrize("scale", [0.1, 0.2])
def test_check_passes_honest_logs_of_fast_control_tests(scale, tmp_path, capsys, monkeypatch):
    """``simulate --duration-scale 0.1/0.2`` moves fast with all cables near f_max: the torque
    relation's tolerance follows the gross cable torques, so the honest log passes; the same log
    with a 30 % error in the pulley radius of the check's model still fails."""
    from neck_sim.check import check_log
    path = tmp_path / "fast.mcap"
    code, out, err = run_cli(["simulate", "--duration-scale", scale, "-o", path, "--no-progress"], capsys)
    assert code == 0, err
    code, out, err = run_cli(["check", path], capsys)
    assert code == 0 and "all relations within tolerance" in out, out
    torque = next(r for r in check_log(path).relations if r.name == "joint torques")
    assert torque.max_error < 0.6 * torque.tolerance         # the margin measured: 0.39 (0.1), 0.24 (0.2)
    import neck_sim.check as check
    honest_model = check._model

    def wrong_pulleys(log):
        params, effects, rigid, source = honest_model(log)
        return params.replace(**{"geometry.r": params.geometry.r * 1.3}), effects, rigid, source
    monkeypatch.setattr(check, "_model", wrong_pulleys)
    wrong = next(r for r in check_log(path).relations if r.name == "joint torques")
    assert not wrong.passed, wrong
