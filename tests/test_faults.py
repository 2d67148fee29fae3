"""Fault injection (issue 14, item 9): hypothesis corrupts MCAP logs, CSV files and parameter
files, and runs the command line in-process on them.  One property for every case:

* exit status 2 and one line naming the file (and, for a corrupted topic, the topic), or
* a correct result: exit 0/1 with complete outputs equal to what the command gives on a clean
  file holding the same values (MCAP), to the values of the CSV cells (import), or to the
  parameters read (params);

never a traceback (status 70 or an exception escaping ``main``), never a partial output or a
temporary file left beside the outputs, never a modified input.

The clean data come from the analytic elastic model and are written with the ``mcap`` library
directly (not :class:`neck_sim.logs.LogWriter`), so the corruptions go through no neck-sim code.
Examples are derandomized (fixed seed) and bounded so CI is reproducible and fast.
"""

from __future__ import annotations

import json
import math
import os
import shutil

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from test_logs_fixtures import simulated_run, write_raw

from neck_sim import params as P
from neck_sim.cli import main
from neck_sim.logs import read_log

PARAMS = P.default_params(3)
FIELDS = {"/neck/motors": ("theta", "force"), "/neck/camera": ("alpha",),
          "/neck/truth": ("alpha", "alpha_dot", "tension", "elongation")}
SHORT = {"/neck/motors": "motors", "/neck/camera": "camera", "/neck/truth": "truth"}
FAULTS = settings(max_examples=30, derandomize=True, deadline=None, database=None,
                  suppress_health_check=list(HealthCheck))


def run_cli(argv, capsys):
    code = main([str(a) for a in argv])        # an exception escaping main fails the test
    out, err = capsys.readouterr()
    return code, out, err


def fresh_dir(root, name) -> "os.PathLike":
    d = root / name
    shutil.rmtree(d, ignore_errors=True)
    d.mkdir()
    return d


def assert_refused_or_done(code, err, inputs: dict, outputs: list, file, topics=(), must_refuse=False):
    """The common half of the property; returns True when the command succeeded.  A refusal must
    name ``file`` and, when given, one of ``topics``; ``must_refuse``: no correct result exists
    (the data break the contract), so status 2 is the only answer."""
    for path, data in inputs.items():
        assert path.read_bytes() == data, f"input {path} was modified"
    folder = {os.path.dirname(o) for o in outputs}
    leftovers = [n for d in folder for n in os.listdir(d) if n.startswith(".")]
    assert not leftovers, f"temporary files left: {leftovers}"
    assert code in (0, 1, 2), f"status {code}: {err}"
    assert code == 2 or not must_refuse, "data that break the contract were accepted"
    if code == 2:
        lines = err.strip().splitlines()
        assert len(lines) == 1 and ": error: " in lines[0], err
        assert str(file) in lines[0], f"the message does not name {file}: {lines[0]}"
        assert not topics or any(t in lines[0] for t in topics), f"the message names none of {topics}: {lines[0]}"
        assert not any(os.path.exists(o) for o in outputs), "partial output after an error"
        return False
    assert all(os.path.exists(o) for o in outputs), "missing output after success"
    return True


# -- MCAP logs ----------------------------------------------------------------------------------

def clean_messages() -> dict:
    """topic -> list of [log_time ns, message dict] of 0.1 s of an elastic-model run."""
    run = simulated_run(PARAMS, duration=0.1, seed=1)
    out = {}
    for topic, short in SHORT.items():
        arrays = run[short]
        out[topic] = [[int(round(t * 1e9)), {"t": float(t), **{f: arrays[f][i].tolist() for f in FIELDS[topic]}}]
                      for i, t in enumerate(arrays["t"])]
    return out


CLEAN = clean_messages()


def replay_outputs(log, folder, capsys):
    """(status, stderr, JSON without the output path) of ``replay`` on ``log``, outputs in folder."""
    js, mc = folder / "r.json", folder / "r.mcap"
    code, _, err = run_cli(["replay", log, "--no-progress", "--json", js, "-o", mc], capsys)
    return code, err, js, mc


def summary(js) -> dict:
    data = json.loads(js.read_text())
    data.pop("output")
    return data


def check_log_property(tmp_path, capsys, log_bytes: bytes, topics_named=(), must_refuse=False):
    work = fresh_dir(tmp_path, "case")
    log = work / "in.mcap"
    log.write_bytes(log_bytes)
    out = fresh_dir(tmp_path, "out")
    code, err, js, mc = replay_outputs(log, out, capsys)
    if not assert_refused_or_done(code, err, {log: log_bytes}, [js, mc], log, topics_named, must_refuse):
        return "refused"
    # correct result: the same as on a clean file holding the values that were read
    read = read_log(log, topics=tuple(SHORT))
    twin = work / "twin.mcap"
    topics = {}
    for topic, short in SHORT.items():
        samples = getattr(read, short)
        if samples is not None:
            topics[topic] = [(int(round(t * 1e9)), {"t": float(t), **{f: getattr(samples, f)[i].tolist()
                                                                      for f in FIELDS[topic]}})
                             for i, t in enumerate(samples.t)]
    write_raw(twin, PARAMS, topics, neck=read.metadata)
    twin_out = fresh_dir(tmp_path, "twin_out")
    code2, err2, js2, _ = replay_outputs(twin, twin_out, capsys)
    assert code2 == code and summary(js2) == summary(js)
    assert read_log(mc).motors.t.size == read.motors.t.size
    return "done"


def encode(messages: dict) -> bytes:
    import tempfile
    with tempfile.TemporaryDirectory() as d:
        path = os.path.join(d, "x.mcap")
        write_raw(path, PARAMS, {topic: [(ns, m if isinstance(m, bytes) else
                                          json.dumps(m).encode()) for ns, m in msgs]
                                 for topic, msgs in messages.items()}, chunk_size=4096)
        with open(path, "rb") as fh:
            return fh.read()


CLEAN_BYTES = encode(CLEAN)


def test_the_clean_log_replays(tmp_path, capsys):
    assert check_log_property(tmp_path, capsys, CLEAN_BYTES) == "done"


@FAULTS
@given(data=st.data())
def test_byte_level_corruptions_of_a_log(tmp_path, capsys, data):
    raw = bytearray(CLEAN_BYTES)
    kind = data.draw(st.sampled_from(["truncate", "flip"]))
    if kind == "truncate":
        raw = raw[:data.draw(st.integers(0, len(raw) - 1))]
    else:
        for _ in range(data.draw(st.integers(1, 3))):
            i = data.draw(st.integers(0, len(raw) - 1))
            raw[i] ^= data.draw(st.integers(1, 255))
    check_log_property(tmp_path, capsys, bytes(raw))


def _corrupt_messages(data) -> tuple[dict, tuple, bool]:
    """(messages, topics corrupted, whether the result breaks the contract)."""
    msgs = json.loads(json.dumps(CLEAN))
    topic = data.draw(st.sampled_from(sorted(msgs)))
    series = msgs[topic]
    kind = data.draw(st.sampled_from(["drop topic", "drop field", "non-finite", "not a number", "short array",
                                      "time order", "t != log_time", "time unit", "degrees", "force range"]))
    i = data.draw(st.integers(0, len(series) - 1))
    field = data.draw(st.sampled_from(FIELDS[topic]))
    if kind == "drop topic":
        del msgs[topic]
    elif kind == "drop field":
        del series[i][1][data.draw(st.sampled_from(["t", field]))]
    elif kind in ("non-finite", "not a number", "short array"):
        values = series[i][1][field]
        j = data.draw(st.integers(0, len(values) - 1))
        if kind == "short array":
            del values[j]
        else:
            values[j] = (data.draw(st.sampled_from([math.nan, math.inf, -math.inf])) if kind == "non-finite"
                         else data.draw(st.sampled_from(["1.0", None, True, [1.0]])))
    elif kind == "time order":
        i = min(i, len(series) - 2)
        series[i], series[i + 1] = series[i + 1], series[i]
    elif kind == "t != log_time":
        series[i][1]["t"] += data.draw(st.sampled_from([1e-3, -1e-5, 1.0]))
    elif kind == "time unit":
        scale = data.draw(st.sampled_from([1e3, 1e6]))
        for topic_msgs in msgs.values():
            for m in topic_msgs:
                m[0] = int(round(m[0] * scale))
                m[1]["t"] = m[0] * 1e-9
        return msgs, tuple(msgs), True
    elif kind == "degrees":
        topic = "/neck/camera"
        for m in msgs[topic]:
            m[1]["alpha"] = [math.degrees(a) + 90.0 for a in m[1]["alpha"]]
    elif kind == "force range":
        topic = "/neck/motors"
        m = msgs[topic][i][1]
        m["force"][data.draw(st.integers(0, 3))] = data.draw(st.sampled_from([-1.0, -50.0, 1e6, 100.5]))
    # only an optional topic may go missing (the replay then starts from the other one's pose)
    return msgs, (topic,), not (kind == "drop topic" and topic != "/neck/motors")


@FAULTS
@given(data=st.data())
def test_content_corruptions_of_a_log(tmp_path, capsys, data):
    msgs, topics, broken = _corrupt_messages(data)
    check_log_property(tmp_path, capsys, encode(msgs), topics_named=topics, must_refuse=broken)


# -- CSV files ------------------------------------------------------------------------------------

def clean_csvs() -> dict:
    run = simulated_run(PARAMS, duration=0.1, seed=2)
    m, c = run["motors"], run["camera"]
    motors = ["t,theta1,theta2,theta3,theta4,force1,force2,force3,force4"]
    motors += [",".join(repr(float(v)) for v in (t, *th, *f)) for t, th, f in zip(m["t"], m["theta"], m["force"])]
    camera = ["t,alpha1,alpha2,alpha3"] + [",".join(repr(float(v)) for v in (t, *a)) for t, a in zip(c["t"], c["alpha"])]
    return {"motors": "\n".join(motors) + "\n", "camera": "\n".join(camera) + "\n"}


CSVS = clean_csvs()


def parse_csv(path) -> dict:
    """Column -> values, written for this test: header names lower-cased and stripped."""
    lines = [ln for ln in path.read_text(encoding="utf-8-sig").splitlines() if ln.strip() and not ln.lstrip().startswith("#")]
    header = [h.strip().lower() for h in lines[0].split(",")]
    rows = [[float(c) for c in ln.split(",")] for ln in lines[1:]]
    return {h: np.array([r[k] for r in rows]) for k, h in enumerate(header)}


def _corrupt_csv(data, text: str, kind_of_file: str) -> tuple[bytes, bool]:
    """(file content, whether it breaks the format so that no correct import exists)."""
    lines = text.splitlines()
    kind = data.draw(st.sampled_from(["truncate", "flip", "cell", "drop column", "drop cell", "swap rows",
                                      "time unit", "scale", "non-utf8", "empty"]))
    r = data.draw(st.integers(1, len(lines) - 1))
    c = data.draw(st.integers(0, len(lines[0].split(",")) - 1))
    if kind in ("truncate", "flip", "non-utf8"):
        raw = bytearray(text.encode())
        i = data.draw(st.integers(0, len(raw) - 1))
        if kind == "truncate":
            return bytes(raw[:i]), False
        raw[i] = 0xFF if kind == "non-utf8" else raw[i] ^ data.draw(st.integers(1, 255))
        return bytes(raw), kind == "non-utf8"
    rows = [ln.split(",") for ln in lines]
    broken = True
    if kind == "cell":
        rows[r][c] = data.draw(st.sampled_from(["", "abc", "nan", "inf", "1e400", "-5", "0x10", " 1 2"]))
        broken = rows[r][c] != "-5"
    elif kind == "drop column":
        for row in rows:
            del row[c]
    elif kind == "drop cell":
        del rows[r][c]
    elif kind == "swap rows":
        r = min(r, len(rows) - 2)
        rows[r], rows[r + 1] = rows[r + 1], rows[r]
    elif kind == "time unit":
        for row in rows[1:]:
            row[0] = repr(float(row[0]) * 1000)
    elif kind == "scale":         # degrees for the camera, mN for the forces
        cols = range(1, 4) if kind_of_file == "camera" else range(5, 9)
        for row in rows[1:]:
            for k in cols:
                row[k] = repr(float(row[k]) * (180 / math.pi if kind_of_file == "camera" else 1000) + 200)
    elif kind == "empty":
        return b"", True
    return ("\n".join(",".join(row) for row in rows) + "\n").encode(), broken


@settings(FAULTS, max_examples=60)
@given(data=st.data())
def test_corruptions_of_csv_files(tmp_path, capsys, data):
    work = fresh_dir(tmp_path, "case")
    files = {kind: work / f"{kind}.csv" for kind in CSVS}
    which = data.draw(st.sampled_from(sorted(CSVS)))
    inputs, broken = {}, False
    for kind, path in files.items():
        payload, broken = _corrupt_csv(data, CSVS[kind], kind) if kind == which else (CSVS[kind].encode(), broken)
        path.write_bytes(payload)
        inputs[path] = payload
    out = fresh_dir(tmp_path, "out") / "o.mcap"
    code, _, err = run_cli(["import", "--motors", files["motors"], "--camera", files["camera"], "-o", out], capsys)
    if assert_refused_or_done(code, err, inputs, [out], files[which], must_refuse=broken):
        log = read_log(out, topics=("motors", "camera"))
        for kind, fields in (("motors", ("theta", "force")), ("camera", ("alpha",))):
            cells = parse_csv(files[kind])
            samples = getattr(log, kind)
            assert np.array_equal(samples.t, cells["t"])
            for f in fields:
                cols = [k for k in cells if k.startswith(f) and k[len(f):].isdigit()]
                expected = np.column_stack([cells[k] for k in sorted(cols, key=lambda k: int(k[len(f):]))])
                assert np.array_equal(getattr(samples, f), expected)


# -- parameter files ------------------------------------------------------------------------------

def _scalar_lines(lines) -> list[int]:
    """Indices of the ``key = value`` lines that are not lists."""
    return [k for k, ln in enumerate(lines) if " = " in ln and not ln.rstrip().endswith("[")]



def _clean_toml(tmp_path) -> str:
    P.save(PARAMS, tmp_path / "clean.toml")
    return (tmp_path / "clean.toml").read_text()


def _corrupt_toml(data, text: str, tokens) -> bytes:
    """Truncation, byte flips, a dropped line or one of ``tokens`` as the value of a scalar key."""
    lines = text.splitlines()
    kind = data.draw(st.sampled_from(["truncate", "flip", "drop line", "value"]))
    if kind in ("truncate", "flip"):
        raw = bytearray(text.encode())
        i = data.draw(st.integers(0, len(raw) - 1))
        if kind == "truncate":
            return bytes(raw[:i])
        raw[i] ^= data.draw(st.integers(1, 255))
        return bytes(raw)
    scalar = _scalar_lines(lines)
    k = data.draw(st.sampled_from(scalar))
    if kind == "drop line":
        del lines[k]
    else:
        key = lines[k].split(" = ")[0]
        lines[k] = f"{key} = {data.draw(st.sampled_from(tokens))}"
    return ("\n".join(lines) + "\n").encode()


NUMBER_TOKENS = ["nan", "inf", "-inf", "-1", "0", "1e400", "1e-300", "3.5e9"]
TYPE_TOKENS = ['"abc"', "[1, 2]", "true", "{}", "inf"]


def _params_property(tmp_path, capsys, payload: bytes):
    work = fresh_dir(tmp_path, "case")
    src = work / "p.toml"
    src.write_bytes(payload)
    out = fresh_dir(tmp_path, "out") / "o.json"
    code, _, err = run_cli(["params", "--load", src, "-o", out], capsys)
    if assert_refused_or_done(code, err, {src: payload}, [out], src):
        assert P.load(out) == P.load(src)


@settings(FAULTS, max_examples=50)
@given(data=st.data())
def test_corruptions_of_parameter_files(tmp_path, capsys, data):
    _params_property(tmp_path, capsys, _corrupt_toml(data, _clean_toml(tmp_path), NUMBER_TOKENS))


def test_parameters_of_the_wrong_type(tmp_path, capsys):
    """Every scalar key of a parameter file with a string, list, bool, table or infinity (all cases)."""
    lines = _clean_toml(tmp_path).splitlines()
    cases = [(k, token) for k in _scalar_lines(lines) for token in TYPE_TOKENS]
    for k, token in cases:
        corrupted = lines[:k] + [f"{lines[k].split(' = ')[0]} = {token}"] + lines[k + 1:]
        _params_property(tmp_path, capsys, ("\n".join(corrupted) + "\n").encode())
    assert len(cases) >= 150
