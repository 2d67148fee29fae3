"""Fault injection: hypothesis corrupts MCAP logs, CSV files and parameter
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

Round two adds generators for the kinds of path a command is given (device nodes, FIFOs, sockets,
symlinks, read-only files, long names, an output that is an input), unit mistakes in measured
data and parameter files (degrees, encoder counts, kN, mN, ms, mm, grams, gravity), and stale or
stuck sensors.  Every case is counted by class and outcome; with ``NECK_SIM_WRITE_RELIABILITY=1`` a
full run of this file writes the table of ``docs/reliability.md`` (atomically).
"""

from __future__ import annotations

import collections
import json
import math
import os
import shutil
import socket
import stat

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from blocking import bounded
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


# class -> Counter(outcome): what the test run tried, for docs/reliability.md
OUTCOMES: dict[str, collections.Counter] = collections.defaultdict(collections.Counter)


def record(klass: str, outcome: str) -> str:
    """Count one case of ``klass`` ("refused" or "done"); returns ``outcome``."""
    OUTCOMES[klass][outcome] += 1
    return outcome


# class -> (input and command, what is tried); the rows of docs/reliability.md in this order
CLASSES = {
    "log bytes": ("MCAP log (`replay --json -o`)", "truncation at any byte, 1-3 byte flips"),
    "log content": ("MCAP log", "dropped topic or field, NaN/inf, a string/bool/list for a number, a short array, "
                                "two messages swapped, t != log_time, times x1e3/x1e6, camera in degrees, "
                                "forces < 0 or > f_max"),
    "csv": ("CSV files (`import`)", "truncation, byte flips, a non-UTF-8 byte, an empty file, a bad cell (empty, "
                                    "text, nan, inf, 1e400, 0x10), a dropped column or cell, swapped rows, times "
                                    "in ms, degrees, mN"),
    "params values": ("parameter file (`params --load -o`)", "truncation, byte flips, a dropped line, "
                                                              "nan/inf/-1/0/1e400/3.5e9 values"),
    "params types": ("parameter file", "a string, list, bool, table or inf as the value of every scalar key "
                                       "(all cases)"),
    "output path kinds": ("output path (`params -o`, also with `--load`)",
                          "new, regular (mode kept), symlink to a regular file, dangling symlink, 245-character "
                          "name: written; FIFO, socket, copy of /dev/null, /dev/full, symlink to /dev/full, "
                          "to a FIFO or to /proc/self/fd/N of a pipe, directory, read-only file, 256-character "
                          "name, the input itself: refused and left as they were"),
    "input path kinds": ("input path (LOG, `--params`, `--motors`, `--camera`, `--load`, `--model`)",
                         "FIFO, socket, copy of /dev/null, symlink to a FIFO: refused at once (no blocking open)"),
    "unit mistakes": ("motors/camera CSV (`import`), MCAP log (reader), parameter file",
                      "encoders in degrees or counts (12-40 rad moves), forces in kN or mN, times in ms, camera "
                      "in degrees, lengths in mm, masses in g, gravity x10; the same data in SI units"),
    "stale and stuck sensors": ("motors/camera CSV (`import`)",
                                "a force frozen inside (f_min, f_max) for 1.2 s while its motor turns, a camera "
                                "frozen at 0 rad; a force held at 0, f_min or f_max and a noise-free camera "
                                "record (accepted)"),
}
_CPU_START = __import__("time").process_time()


def write_reliability_page() -> str | None:
    """docs/reliability.md from ``OUTCOMES`` (only after a run that tried every class); returns the path."""
    import time

    from neck_sim.atomic import atomic_write_bytes
    if any(not OUTCOMES[k] for k in CLASSES):
        return None
    rows = ["| input | tried | cases | refused (exit 2, one line) | correct result |", "|---|---|---|---|---|"]
    for klass, (what, tried) in CLASSES.items():
        c = OUTCOMES[klass]
        rows.append(f"| {what} | {tried} | {sum(c.values())} | {c['refused']} | {c['done']} |")
    total = sum(sum(c.values()) for c in OUTCOMES.values())
    cpu = time.process_time() - _CPU_START
    page = RELIABILITY_PAGE.format(table="\n".join(rows), total=total, cpu=cpu)
    path = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "docs", "reliability.md")
    atomic_write_bytes(path, page.encode())
    return path


RELIABILITY_PAGE = """# Reliability

<!-- written by tests/test_faults.py (NECK_SIM_WRITE_RELIABILITY=1); edit the template there -->

`tests/test_faults.py` feeds the command line (in-process) bad inputs generated by hypothesis
(derandomized: the same cases on every run) and holds one property: exit status 2 with one line
naming the file (and the corrupted topic, channel or unit), or a correct result (the same output as
a clean file holding the values read; the CSV cells; the parameters read; the file written where
the path allows it), never a traceback, a hang, a partial output, a temporary file left behind, a
modified input or a non-regular file replaced; data that break the contract (NaN, a dropped field,
a unit mistake, a stuck sensor, ...) must be refused.

{table}

This run: {total} cases in {cpu:.0f} s of CPU.

What the refusals look like (from the same checks):

```text
neck-sim params: error: -o /dev/full: is a character device, not a regular file; refusing to replace it
neck-sim import: error: m.csv: /neck/motors: encoder theta3 reaches 1718.87 at sample 99 (t = 0.198 s): looks like degrees (1718.87 deg = 30 rad), expected rad; R/r_d x N (L + b + pi r) = 616.7 rad would wind a whole neck's height of cable
neck-sim params: error: p.json: inertia.gravity = 98.1 m/s^2 is 10x Earth's (9.81 m/s^2); use --accept-implausible-params if intended
```

Unit mistakes are named only where the magnitudes make them unambiguous: a motor angle beyond
R/r_d x N (L + b + pi r) (a whole neck's height of cable wound; 617 rad for the paper's neck) reads
as degrees, or as encoder counts when every value is a whole number; forces all below f_max / 1000
as kN; lengths above 5 m in a parameter file as mm, masses above 10 kg as grams, gravity above
25 m/s^2 as implausible (`--accept-implausible-params` loads such a file with a warning).  A small
move in degrees (a few hundred) stays undetectable from the encoders alone.  A force channel is
stale when it stays bit-identical for a second while its motor turns by 20 encoder counts or more
(0, f_min and f_max are exempt: a motor off or saturated); a camera is stuck when all its frames
are identical although the record declares camera noise.

`tests/test_paths.py` holds the targeted cases, one test per reproduced problem: an output equal
to an input (also through a symlink, or a file a command writes inside its output directory, such
as `diagnose --report .` next to `--model model.json`), two outputs on one path (`--json
report.md` with `--report .`), read-only outputs (refused also for root) and kept modes, device
nodes / FIFOs / sockets / symlinks to them as outputs and as inputs, long file names, directory /
missing / non-directory output folders checked before the computation, write errors naming the
user's path, option values naming the option, `--start`/`--end` past the log or at 1e308, the
signed `--shift-time`, times beyond MCAP's range, non-UTF-8 CSV, Ctrl-C / SIGTERM / internal error,
a closed standard output, an environment dropped without `close()`, a neck with b = 0.12 m and
L = 0.2 m reading its own log back, a Python-backend plant beside native plants (bit-identical),
the plausibility checks (ms, µs, camera rate, degrees, counts, kN, negative forces, 1e6 N spikes,
accepted forces reported, replay's clipping note, parameter files in mm/g/10 g), stale forces, a
stuck camera, an empty camera topic, too few camera frames and negative identified friction reported
as unphysical.

To regenerate this page:

<!-- doc-test: skip (runs the fault-injection tests and rewrites this page) -->
```bash
NECK_SIM_WRITE_RELIABILITY=1 python -m pytest tests/test_faults.py -q
```
"""


@pytest.fixture(scope="module", autouse=True)
def reliability_page():
    """After the module: write docs/reliability.md when asked and every class was tried."""
    yield
    if os.environ.get("NECK_SIM_WRITE_RELIABILITY") == "1":
        path = write_reliability_page()
        print(f"\nreliability table: {path or 'not written (not every class ran)'}")


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


def check_log_property(tmp_path, capsys, log_bytes: bytes, topics_named=(), must_refuse=False, klass=None):
    work = fresh_dir(tmp_path, "case")
    log = work / "in.mcap"
    log.write_bytes(log_bytes)
    out = fresh_dir(tmp_path, "out")
    code, err, js, mc = replay_outputs(log, out, capsys)
    if not assert_refused_or_done(code, err, {log: log_bytes}, [js, mc], log, topics_named, must_refuse):
        return record(klass, "refused") if klass else "refused"
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
    return record(klass, "done") if klass else "done"


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
    check_log_property(tmp_path, capsys, bytes(raw), klass="log bytes")


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
    check_log_property(tmp_path, capsys, encode(msgs), topics_named=topics, must_refuse=broken, klass="log content")


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
    record("csv", "done" if code != 2 else "refused")
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


def _params_property(tmp_path, capsys, payload: bytes, klass: str):
    work = fresh_dir(tmp_path, "case")
    src = work / "p.toml"
    src.write_bytes(payload)
    out = fresh_dir(tmp_path, "out") / "o.json"
    code, _, err = run_cli(["params", "--load", src, "-o", out], capsys)
    record(klass, "done" if code != 2 else "refused")
    if assert_refused_or_done(code, err, {src: payload}, [out], src):
        assert P.load(out) == P.load(src)


@settings(FAULTS, max_examples=50)
@given(data=st.data())
def test_corruptions_of_parameter_files(tmp_path, capsys, data):
    _params_property(tmp_path, capsys, _corrupt_toml(data, _clean_toml(tmp_path), NUMBER_TOKENS), "params values")


def test_parameters_of_the_wrong_type(tmp_path, capsys):
    """Every scalar key of a parameter file with a string, list, bool, table or infinity (all cases)."""
    lines = _clean_toml(tmp_path).splitlines()
    cases = [(k, token) for k in _scalar_lines(lines) for token in TYPE_TOKENS]
    for k, token in cases:
        corrupted = lines[:k] + [f"{lines[k].split(' = ')[0]} = {token}"] + lines[k + 1:]
        _params_property(tmp_path, capsys, ("\n".join(corrupted) + "\n").encode(), "params types")
    assert len(cases) >= 150


# -- round two: the kind of path a command is given ------------------------------------------------

SPECIAL_KINDS = ("fifo", "socket", "null copy", "/dev/full", "link to /dev/full", "link to fifo", "link to a pipe fd",
                 "directory")
REGULAR_KINDS = ("new", "regular", "link to regular", "dangling link", "long name")
REFUSED_KINDS = ("read-only", "too long", "same as input")


def make_path(kind: str, folder, keep: list, name="out.json"):
    """A path of ``kind`` in ``folder`` (sockets and pipe fds are appended to ``keep`` to close)."""
    path = folder / name
    if kind == "new":
        return path
    if kind in ("regular", "read-only"):
        path.write_text("old\n")
        path.chmod(0o444 if kind == "read-only" else 0o640)
    elif kind == "long name":
        return folder / ("x" * 240 + ".json")
    elif kind == "too long":
        return folder / ("x" * 251 + ".json")
    elif kind == "link to regular":
        (folder / "target.json").write_text("old\n")
        os.symlink(folder / "target.json", path)
    elif kind == "dangling link":
        os.symlink(folder / "later.json", path)
    elif kind in ("fifo", "link to fifo"):
        os.mkfifo(folder / "fifo.json")
        if kind == "fifo":
            return folder / "fifo.json"
        os.symlink(folder / "fifo.json", path)
    elif kind == "link to /dev/full":
        os.symlink("/dev/full", path)
    elif kind == "socket":
        s = socket.socket(socket.AF_UNIX)
        s.bind(str(path))
        keep.append(s)
    elif kind == "null copy":
        os.mknod(path, stat.S_IFCHR | 0o666, os.makedev(1, 3))
    elif kind == "/dev/full":
        return "/dev/full"
    elif kind == "link to a pipe fd":
        r, w = os.pipe()
        keep.extend([r, w])
        os.symlink(f"/proc/self/fd/{w}", path)
    elif kind == "directory":
        path.mkdir()
    return path


def _close(keep):
    for k in keep:
        k.close() if hasattr(k, "close") else os.close(k)


def _state(path) -> tuple:
    """What must not change on a refusal: the kind, mode and bytes (regular files) behind ``path``."""
    try:
        st = os.stat(path)
    except OSError:
        return ("missing",)
    data = open(path, "rb").read() if stat.S_ISREG(st.st_mode) else None
    return stat.S_IFMT(st.st_mode), stat.S_IMODE(st.st_mode), os.path.islink(path), data


@FAULTS
@given(kind=st.sampled_from(SPECIAL_KINDS + REGULAR_KINDS + REFUSED_KINDS), second=st.booleans())
def test_output_path_kinds(tmp_path, capsys, kind, second):
    """``params -o PATH`` (and ``--load`` of a file when ``kind`` is "same as input"): regular files
    and new paths are written (links followed, modes kept); anything else is refused in one line
    and left as it was."""
    work, keep = fresh_dir(tmp_path, "case"), []
    try:
        src = work / "in.json"
        P.save(PARAMS, src)
        path = src if kind == "same as input" else make_path(kind, work, keep)
        mode_before = stat.S_IMODE(os.stat(path).st_mode) if kind in ("regular", "link to regular") else None
        before = _state(path)
        argv = ["params", "--load", src, "-o", path] if second or kind == "same as input" else ["params", "-o", path]
        with bounded():
            code, _, err = run_cli(argv, capsys)
        if kind in REGULAR_KINDS:
            assert code == 0, err
            assert P.load(path) == PARAMS and stat.S_ISREG(os.stat(path).st_mode)
            assert os.path.islink(path) == (kind in ("link to regular", "dangling link"))
            if mode_before is not None:
                assert stat.S_IMODE(os.stat(path).st_mode) == mode_before
            record("output path kinds", "done")
        else:
            lines = err.strip().splitlines()
            assert code == 2 and len(lines) == 1 and f"-o {path}" in lines[0], err
            assert _state(path) == before
            record("output path kinds", "refused")
        assert not [n for n in os.listdir(work) if n.startswith(".")]
    finally:
        _close(keep)


@FAULTS
@given(kind=st.sampled_from(("fifo", "socket", "null copy", "link to fifo")),
       option=st.sampled_from(("LOG", "--params", "--motors", "--camera", "--load", "--model")))
def test_input_path_kinds(tmp_path, capsys, kind, option):
    """An input that is a FIFO, socket or device is refused at once, naming the option and the kind."""
    work, keep = fresh_dir(tmp_path, "case"), []
    try:
        path = make_path(kind, work, keep, name="in.dat")
        csv = work / "m.csv"
        csv.write_text(CSVS["motors"])
        argv = {"LOG": ["identify", path], "--params": ["simulate", "--params", path, "--no-log"],
                "--motors": ["import", "--motors", path, "-o", work / "o.mcap"],
                "--camera": ["import", "--motors", csv, "--camera", path, "-o", work / "o.mcap"],
                "--load": ["params", "--load", path],
                "--model": ["diagnose", csv, "--model", path]}[option]
        with bounded(5):
            code, _, err = run_cli(argv, capsys)
        lines = err.strip().splitlines()
        assert code == 2 and len(lines) == 1, err
        assert f"{path}" in lines[0] and "not a regular file" in lines[0], lines[0]
        record("input path kinds", "refused")
    finally:
        _close(keep)


# -- round two: unit mistakes where the magnitudes make them unambiguous ---------------------------

def motor_rows(seconds: float, amplitude: float, seed: int, *, stuck=None):
    """t, theta (T, 4) rad and force (T, 4) N of a plausible 500 Hz motor log, written here: smooth
    motor angles reaching +-``amplitude`` rad, forces in [5, 95] N.  ``stuck``: (cable, value)
    holds that force constant."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(round(seconds * 500))) / 500
    w, ph = rng.uniform(0.5, 2.0, 4), rng.uniform(0, 2 * np.pi, 4)
    theta = amplitude * np.sin(np.outer(t, 2 * np.pi * w) + ph)
    res = 2 * np.pi / 2048
    theta = np.round(theta / res) * res                            # quantised like the encoders
    force = 50.0 + 45.0 * np.sin(np.outer(t, 2 * np.pi * w[::-1]) + ph[::-1])
    if stuck is not None:
        force[:, stuck[0]] = stuck[1]
    return t, theta, force


def camera_rows(seconds: float, seed: int, *, stuck=None):
    """t, alpha (F, 3) rad at 30 Hz within +-0.8 rad with 1 degree of noise; ``stuck``: constant pose."""
    rng = np.random.default_rng(seed + 100)
    t = (np.arange(int(seconds * 30)) + 1) / 30
    alpha = 0.6 * np.sin(np.outer(t, [1.1, 1.7, 2.3])) + rng.normal(0, math.radians(1.0), (len(t), 3))
    if stuck is not None:
        alpha[:] = stuck
    return t, alpha


def write_csv(path, header, t, *blocks):
    rows = [",".join(header)]
    rows += [",".join(repr(float(v)) for v in (ti, *np.concatenate([b[i] for b in blocks])))
             for i, ti in enumerate(t)]
    path.write_text("\n".join(rows) + "\n")
    return path


MOTOR_HEADER = ["t", "theta1", "theta2", "theta3", "theta4", "force1", "force2", "force3", "force4"]
CAMERA_HEADER = ["t", "alpha1", "alpha2", "alpha3"]
# mistake -> (what is scaled, factor, words the refusal must hold); None: the data are plausible
UNIT_MISTAKES = {
    "encoders in degrees": ("theta", 180 / math.pi, ("theta", "looks like degrees")),
    "encoders in counts": ("theta", 2048 / (2 * math.pi), ("theta", "encoder counts")),
    "forces in kN": ("force", 1e-3, ("kilonewtons",)),
    "forces in mN": ("force", 1e3, ("mN",)),
    "times in ms": ("t", 1e3, ("milliseconds",)),
    "camera in degrees": ("alpha", 180 / math.pi, ("degrees",)),
    "none": None,
}
PARAM_MISTAKES = {
    "lengths in mm": ({"geometry": ("b", "L", "r"), "springs": ("rest_length",), "actuation": ("r_d",)}, 1e3,
                      "millimetres"),
    "masses in g": ({"inertia": ("bar_mass", "diagonal_mass")}, 1e3, "grams"),
    "gravity x10": ({"inertia": ("gravity",)}, 10.0, "Earth's"),
}


@FAULTS
@given(mistake=st.sampled_from(sorted(UNIT_MISTAKES)), amplitude=st.floats(12.0, 40.0), seed=st.integers(0, 99),
       via=st.sampled_from(("csv", "log")))
def test_unit_mistakes_in_measured_data(tmp_path, capsys, mistake, amplitude, seed, via):
    """A motor log reaching 12-40 rad (what the control test reaches) with one unit mistake is
    refused naming the unit, at import (CSV) and when a log is read; the same data in SI units pass."""
    from test_logs_fixtures import write_arrays
    work = fresh_dir(tmp_path, "case")
    t, theta, force = motor_rows(1.2, amplitude, seed)
    tc, alpha = camera_rows(1.2, seed)
    spec = UNIT_MISTAKES[mistake]
    if spec is not None:
        field, factor, _ = spec
        if field == "theta":
            theta = theta * factor
            if mistake == "encoders in counts":
                theta = np.round(theta)
        elif field == "force":
            force = force * factor
        elif field == "t":
            t, tc = t * factor, tc * factor
        else:
            alpha = alpha * factor
    if via == "csv":
        motors = write_csv(work / "m.csv", MOTOR_HEADER, t, theta, force)
        camera = write_csv(work / "c.csv", CAMERA_HEADER, tc, alpha)
        out = work / "o.mcap"
        code, _, err = run_cli(["import", "--motors", motors, "--camera", camera, "-o", out], capsys)
    else:
        from neck_sim.logs import LogError
        log = work / "in.mcap"
        write_arrays(log, PARAMS, {"motors": {"t": t, "theta": theta, "force": force},
                                   "camera": {"t": tc, "alpha": alpha}})
        try:
            read_log(log)
            code, err = 0, ""
        except LogError as exc:
            code, err = 2, f"read_log: error: {exc}"
    if spec is None:
        assert code == 0, err
        record("unit mistakes", "done")
        return
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1, err
    assert all(w in lines[0] for w in spec[2]), lines[0]
    record("unit mistakes", "refused")


@FAULTS
@given(mistake=st.sampled_from(sorted(PARAM_MISTAKES)), fmt=st.sampled_from((".json", ".toml")))
def test_unit_mistakes_in_parameter_files(tmp_path, capsys, mistake, fmt):
    fields, factor, word = PARAM_MISTAKES[mistake]
    data = P.to_dict(PARAMS)
    for grp, names in fields.items():
        for name in names:
            data[grp][name] = data[grp][name] * factor
    work = fresh_dir(tmp_path, "case")
    path = work / f"p{fmt}"
    if fmt == ".json":
        path.write_text(json.dumps(data))
    else:
        import tomli_w
        path.write_text(tomli_w.dumps(data))
    code, _, err = run_cli(["params", "--load", path], capsys)
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1 and str(path) in lines[0] and word in lines[0], err
    assert "--accept-implausible-params" in lines[0]
    record("unit mistakes", "refused")


# -- round two: stale and stuck sensors ------------------------------------------------------------

@FAULTS
@given(sensor=st.sampled_from(("force", "camera", "force at a limit", "camera at rest without noise")),
       cable=st.integers(0, 3), value=st.floats(3.0, 97.0), seed=st.integers(0, 99))
def test_stale_and_stuck_sensors(tmp_path, capsys, sensor, cable, value, seed):
    """A force channel frozen at a value inside (f_min, f_max) for 1.2 s while its motor turns, or a
    camera whose frames are all identical, is refused naming the channel; a force held at 0 or at
    f_min (a motor off or saturated) and a noise-free camera record are not."""
    work = fresh_dir(tmp_path, "case")
    stuck_force = {"force": (cable, value), "force at a limit": (cable, [0.0, 2.0, 100.0][seed % 3])}.get(sensor)
    t, theta, force = motor_rows(1.2, 20.0, seed, stuck=stuck_force)
    tc, alpha = camera_rows(1.2, seed, stuck=[0.0, 0.0, 0.0] if sensor.startswith("camera") else None)
    motors = write_csv(work / "m.csv", MOTOR_HEADER, t, theta, force)
    camera = write_csv(work / "c.csv", CAMERA_HEADER, tc, alpha)
    argv = ["import", "--motors", motors, "--camera", camera, "-o", work / "o.mcap"]
    if sensor == "camera at rest without noise":
        params = work / "p.json"
        P.save(PARAMS.replace(**{"sensors.camera_noise": 0.0}), params)
        argv += ["--params", params]
    code, _, err = run_cli(argv, capsys)
    lines = err.strip().splitlines()
    if sensor in ("force", "camera"):
        assert code == 2 and len(lines) == 1, err
        if sensor == "force":
            assert f"force{cable + 1} = " in lines[0] and "stale force logger" in lines[0] and str(motors) in lines[0]
        else:
            assert "camera is stuck" in lines[0] and str(camera) in lines[0] and "encoder" not in lines[0]
        record("stale and stuck sensors", "refused")
    else:
        assert code == 0, err
        record("stale and stuck sensors", "done")
