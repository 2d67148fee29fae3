"""MCAP log writer and reader: the contract of docs/data-contract.md, round trips,
atomic writes, time windows through the index, and errors that name the problem."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest
from mcap.reader import make_reader
from test_logs_fixtures import motors_messages, synthetic_arrays, write_arrays, write_raw

from neck_sim import atomic
from neck_sim.atomic import TEMP_PREFIX
import neck_sim.logs.payloads as payloads_mod
import neck_sim.logs.reader as reader_mod
from neck_sim.logs import LogError, LogWriter, read_log
from neck_sim.params import default_params

CONTRACT_FIELDS = {  # written out from measured-data.md, independently of neck_sim.logs.contract
    "/neck/motors": {"theta": "c", "force": "c"},
    "/neck/camera": {"alpha": "j"},
    "/neck/reference": {"alpha_d": "j"},
    "/neck/estimate": {"alpha_hat": "j"},
    "/neck/truth": {"alpha": "j", "alpha_dot": "j", "tension": "c", "elongation": "c"},
}
NECK_KEYS = {"n_joints", "b", "L", "r", "r_d", "R", "I_a", "control_rate_hz", "camera_rate_hz",
             "encoder_counts_per_turn", "spring_stiffness", "spring_rest_length", "bar_mass",
             "diagonal_mass", "gravity", "f_min", "f_max", "n_cables"}


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    params = default_params(3)
    arrays = synthetic_arrays(params, seconds=2.0)
    path = tmp_path_factory.mktemp("logs") / "run.mcap"
    write_arrays(path, params, arrays, mjcf_xml="<mujoco model='neck'/>",
                 run_info={"seed": 7, "effects": {"dry_friction": True}, "gains": np.array([1.5, 2.0]),
                           "rate": np.float64(500.0)}, chunk_size=16 * 1024)
    return path, params, arrays


def raw_messages(path):
    with open(path, "rb") as fh:
        r = make_reader(fh)
        summary = r.get_summary()
        msgs = [(s, c, m) for s, c, m in r.iter_messages(log_time_order=False)]
        meta = {m.name: dict(m.metadata) for m in r.iter_metadata()}
    return summary, msgs, meta


def test_round_trip_is_exact(written):
    path, params, arrays = written
    log = read_log(path)
    for topic, fields in arrays.items():
        samples = getattr(log, topic)
        for name, values in fields.items():
            np.testing.assert_array_equal(getattr(samples, name), values, err_msg=f"{topic}.{name}")
    assert log.attachments == {"neck.xml": b"<mujoco model='neck'/>"}


def test_file_layout_follows_the_contract(written):
    path, params, arrays = written
    summary, msgs, meta = raw_messages(path)
    n = params.n_joints
    for chunk in summary.chunk_indexes:
        assert chunk.compression == "zstd"
    for schema, channel, message in msgs:
        if channel.topic not in CONTRACT_FIELDS:
            continue
        assert channel.message_encoding == "json" and schema.encoding == "jsonschema"
        body = json.loads(message.data)
        assert message.log_time == message.publish_time == round(body["t"] * 1e9)
        fields = CONTRACT_FIELDS[channel.topic]
        assert set(body) == {"t", *fields}
        for name, kind in fields.items():
            assert len(body[name]) == (n + 1 if kind == "c" else n)
        sch = json.loads(schema.data)          # each message satisfies its own schema
        assert set(sch["required"]) == {"t", *fields}
        for name in fields:
            assert sch["properties"][name]["minItems"] == sch["properties"][name]["maxItems"] == len(body[name])
    topics = {c.topic for c in summary.channels.values()}
    assert set(CONTRACT_FIELDS) <= topics
    schemas_per_topic = {c.topic: c.schema_id for c in summary.channels.values()}
    assert len(set(schemas_per_topic.values())) == len(schemas_per_topic)   # one schema per topic
    counts = {c.topic: summary.statistics.channel_message_counts[c.id] for c in summary.channels.values()}
    assert counts["/neck/motors"] == len(arrays["motors"]["t"])
    assert counts["/neck/camera"] == len(arrays["camera"]["t"])


def test_neck_record_holds_nominal_constants_only(written):
    path, params, _ = written
    _, _, meta = raw_messages(path)
    neck = meta["neck"]
    assert set(neck) == NECK_KEYS                     # no friction, cable or hidden parameters
    assert all(isinstance(v, str) for v in neck.values())
    assert json.loads(neck["spring_stiffness"]) == [600.0, 200.0, 200.0]
    assert float(neck["r_d"]) == 0.020 and float(neck["R"]) == 25.0 and int(neck["n_joints"]) == 3
    log = read_log(path)
    assert log.metadata == neck
    assert log.params == params


def test_run_record_has_versions_seed_and_command_line(written):
    path, _, _ = written
    run = read_log(path).run_info
    import mujoco
    assert run["mujoco_version"] == mujoco.__version__
    assert run["numpy_version"] == np.__version__
    assert run["seed"] == "7" and json.loads(run["effects"]) == {"dry_friction": True}
    assert json.loads(run["gains"]) == [1.5, 2.0] and json.loads(run["rate"]) == 500.0
    assert json.loads(run["command_line"]) == sys.argv
    assert run["neck_sim_version"]


def test_params_from_a_record_with_optional_keys_missing(tmp_path):
    p2 = default_params(2).replace(**{"geometry.b": 0.06, "actuation.I_a": 2e-5})
    neck = {k: v for k, v in __import__("neck_sim.logs", fromlist=["x"]).neck_metadata(p2).items()
            if k in {"n_joints", "b", "L", "r", "r_d", "R", "I_a", "control_rate_hz", "camera_rate_hz"}}
    neck["unknown_key"] = "kept and ignored"
    write_raw(tmp_path / "a.mcap", p2, {"/neck/motors": motors_messages(3, [0.0, 0.002])}, neck=neck)
    log = read_log(tmp_path / "a.mcap")
    assert log.params.n_joints == 2 and log.params.geometry.b == 0.06 and log.params.actuation.I_a == 2e-5
    assert log.params.springs.stiffness == default_params(2).springs.stiffness
    assert log.motors.theta.shape == (2, 3)


def test_fast_and_json_decoding_agree(written, monkeypatch):
    path, _, arrays = written
    fast = read_log(path)
    monkeypatch.setattr(reader_mod, "_decode_fast", lambda *a: None)
    slow = read_log(path)
    for topic in arrays:
        for name in arrays[topic]:
            np.testing.assert_array_equal(getattr(getattr(fast, topic), name), getattr(getattr(slow, topic), name))


def test_other_producers_layout_is_read(tmp_path):
    """Key order, whitespace and integers as another tool may write them (JSON path)."""
    p = default_params(3)
    msgs = [(0, b'{"force": [1, 2, 3, 4], "t": 0, "theta": [0.5, -1e-7, 2, 3]}'),
            (2_000_000, b'{ "theta" : [1,2,3,4] , "force":[5,6,7,8],"t":0.002 , "note": "extra"}')]
    write_raw(tmp_path / "a.mcap", p, {"/neck/motors": msgs, "/other/topic": [(0, b'{"x": 1}')]})
    log = read_log(tmp_path / "a.mcap")
    np.testing.assert_array_equal(log.motors.theta, [[0.5, -1e-7, 2, 3], [1, 2, 3, 4]])
    np.testing.assert_array_equal(log.motors.force, [[1, 2, 3, 4], [5, 6, 7, 8]])
    np.testing.assert_array_equal(log.motors.t, [0.0, 0.002])
    assert log.camera is None


def test_time_window_reads_only_its_chunks(written, monkeypatch):
    path, _, arrays = written
    calls = []
    real = payloads_mod._decompress
    monkeypatch.setattr(payloads_mod, "_decompress", lambda *a: calls.append(1) or real(*a))
    read_log(path)
    all_chunks = len(calls)
    calls.clear()
    log = read_log(path, start=0.5, end=0.7)
    assert all_chunks > 20 and 0 < len(calls) <= all_chunks // 4
    t = arrays["motors"]["t"]
    sel = (t >= 0.5) & (t < 0.7)
    np.testing.assert_array_equal(log.motors.t, t[sel])
    np.testing.assert_array_equal(log.motors.theta, arrays["motors"]["theta"][sel])
    tc = arrays["camera"]["t"]
    np.testing.assert_array_equal(log.camera.alpha, arrays["camera"]["alpha"][(tc >= 0.5) & (tc < 0.7)])


def test_topic_selection_and_required_topics(written):
    path, _, _ = written
    log = read_log(path, topics=("camera",), require=())
    assert log.motors is None and log.truth is None and log.camera is not None
    log = read_log(path, topics=("/neck/truth",))                  # motors required by default
    assert log.motors is not None and log.truth is not None and log.camera is None
    with pytest.raises(LogError, match="unknown topic 'cameras'"):
        read_log(path, topics=("cameras",))


@pytest.mark.parametrize("layout", ["no summary", "no chunks"])
def test_file_without_index_is_read_by_scanning(tmp_path, layout):
    p = default_params(3)
    path = tmp_path / "nosummary.mcap"
    from mcap.writer import IndexType, Writer
    with open(path, "wb") as fh:
        if layout == "no summary":
            w = Writer(fh, index_types=IndexType.NONE, repeat_channels=False, repeat_schemas=False,
                       use_statistics=False, use_summary_offsets=False)
        else:
            w = Writer(fh, use_chunking=False)
        w.start()
        from neck_sim.logs import neck_metadata
        w.add_metadata("neck", neck_metadata(p))
        sid = w.register_schema("x", "jsonschema", b"{}")
        ch = w.register_channel("/neck/motors", "json", sid)
        for ns, msg in motors_messages(4, [0.0, 0.002, 0.004]):
            w.add_message(ch, ns, json.dumps(msg).encode(), ns)
        w.finish()
    log = read_log(path)
    np.testing.assert_array_equal(log.motors.t, [0.0, 0.002, 0.004])


# -- errors that name the problem -------------------------------------------------------------------

def test_missing_required_topic(tmp_path):
    p = default_params(3)
    write_raw(tmp_path / "a.mcap", p, {"/neck/camera": [(0, {"t": 0.0, "alpha": [0, 0, 0]})]})
    with pytest.raises(LogError, match="missing required topic /neck/motors"):
        read_log(tmp_path / "a.mcap")
    with pytest.raises(LogError, match="missing required topic /neck/truth"):
        read_log(tmp_path / "a.mcap", require=("camera", "truth"))
    assert read_log(tmp_path / "a.mcap", require=("camera",)).camera.alpha.shape == (1, 3)


def test_missing_field(tmp_path):
    p = default_params(3)
    msgs = motors_messages(4, [0.0, 0.002, 0.004])
    del msgs[1][1]["force"]
    write_raw(tmp_path / "a.mcap", p, {"/neck/motors": msgs})
    with pytest.raises(LogError, match=r"/neck/motors: missing field 'force' in message 1"):
        read_log(tmp_path / "a.mcap")


def test_wrong_array_length(tmp_path):
    p = default_params(3)
    msgs = motors_messages(4, [0.0, 0.002, 0.004])
    msgs[2][1]["theta"] = [0.0, 1.0, 2.0]
    write_raw(tmp_path / "a.mcap", p, {"/neck/motors": msgs})
    with pytest.raises(LogError, match=r"field 'theta' of message 2 .* has 3 values, expected 4"):
        read_log(tmp_path / "a.mcap")


def test_non_numeric_and_non_finite_values(tmp_path):
    p = default_params(3)
    msgs = motors_messages(4, [0.0, 0.002])
    msgs[1][1]["force"] = [1.0, "x", 2.0, 3.0]
    write_raw(tmp_path / "a.mcap", p, {"/neck/motors": msgs})
    with pytest.raises(LogError, match="non-number"):
        read_log(tmp_path / "a.mcap")
    msgs = motors_messages(4, [0.0, 0.002])
    write_raw(tmp_path / "b.mcap", p, {"/neck/motors": [msgs[0], (msgs[1][0], b'{"t":0.002,"theta":[0,0,0,NaN],'
                                                                            b'"force":[1,1,1,1]}')]})
    with pytest.raises(LogError, match="'theta' of message 1 holds NaN"):
        read_log(tmp_path / "b.mcap")


def test_non_monotonic_time(tmp_path):
    p = default_params(3)
    write_raw(tmp_path / "a.mcap", p, {"/neck/motors": motors_messages(4, [0.0, 0.004, 0.002, 0.006])})
    with pytest.raises(LogError, match=r"/neck/motors: time not increasing at message 2: t = 0.002 s after 0.004 s"):
        read_log(tmp_path / "a.mcap")
    write_raw(tmp_path / "b.mcap", p, {"/neck/motors": motors_messages(4, [0.0, 0.002, 0.002])})
    with pytest.raises(LogError, match="time not increasing at message 2"):
        read_log(tmp_path / "b.mcap")


def test_t_must_match_log_time(tmp_path):
    p = default_params(3)
    msgs = motors_messages(4, [0.0, 0.002])
    msgs[1] = (3_000_000, msgs[1][1])
    write_raw(tmp_path / "a.mcap", p, {"/neck/motors": msgs})
    with pytest.raises(LogError, match="message 1 has t = 0.002 s but log_time = 3000000 ns"):
        read_log(tmp_path / "a.mcap")


def test_truncated_file(written, tmp_path):
    path, _, _ = written
    data = path.read_bytes()
    for cut in (len(data) // 2, len(data) - 10, 20):
        bad = tmp_path / f"cut{cut}.mcap"
        bad.write_bytes(data[:cut])
        with pytest.raises(LogError, match="truncated"):
            read_log(bad)


def test_corrupt_chunk(written, tmp_path):
    path, _, _ = written
    data = bytearray(path.read_bytes())
    with open(path, "rb") as fh:
        chunk = make_reader(fh).get_summary().chunk_indexes[3]
    mid = chunk.chunk_start_offset + chunk.chunk_length // 2
    data[mid:mid + 8] = bytes(8)
    bad = tmp_path / "corrupt.mcap"
    bad.write_bytes(bytes(data))
    with pytest.raises(LogError, match="corrupt chunk"):
        read_log(bad)


def test_not_an_mcap_file_and_missing_metadata(tmp_path):
    (tmp_path / "a.mcap").write_text("t,theta1\n0,0\n")
    with pytest.raises(LogError, match="not an MCAP file"):
        read_log(tmp_path / "a.mcap")
    with pytest.raises(LogError, match="cannot open log"):
        read_log(tmp_path / "missing.mcap")
    p = default_params(3)
    write_raw(tmp_path / "b.mcap", p, {"/neck/motors": motors_messages(4, [0.0])}, neck={"n_joints": "3"})
    with pytest.raises(LogError, match=r"missing required key\(s\) b, L, r, r_d, R, I_a"):
        read_log(tmp_path / "b.mcap")
    bad_neck = dict(__import__("neck_sim.logs", fromlist=["x"]).neck_metadata(p), r_d="twenty mm")
    write_raw(tmp_path / "c.mcap", p, {"/neck/motors": motors_messages(4, [0.0])}, neck=bad_neck)
    with pytest.raises(LogError, match="'r_d' = 'twenty mm' is not a number"):
        read_log(tmp_path / "c.mcap")


def test_log_error_is_a_value_error():
    assert issubclass(LogError, ValueError)


# -- writer ---------------------------------------------------------------------------------------

def test_writer_rejects_bad_samples(tmp_path):
    with LogWriter(tmp_path / "a.mcap", default_params(3)) as w:
        with pytest.raises(ValueError, match=r"/neck/motors: theta must have shape \(4,\), got \(3,\)"):
            w.motors(0.0, np.zeros(3), np.zeros(4))
        with pytest.raises(ValueError, match="force contains NaN"):
            w.motors(0.0, np.zeros(4), [0, 0, math.nan, 0])
        w.motors(0.0, np.zeros(4), np.zeros(4))
        with pytest.raises(ValueError, match="time must increase"):
            w.motors(0.0, np.zeros(4), np.zeros(4))
        with pytest.raises(ValueError, match="finite and >= 0"):
            w.camera(-1.0, np.zeros(3))
    assert read_log(tmp_path / "a.mcap").motors.t.tolist() == [0.0]


def test_exception_leaves_no_file(tmp_path):
    path = tmp_path / "a.mcap"
    with pytest.raises(RuntimeError):
        with LogWriter(path, default_params(3)) as w:
            w.motors(0.0, np.zeros(4), np.zeros(4))
            raise RuntimeError("simulation blew up")
    assert os.listdir(tmp_path) == []


def test_crash_mid_run_leaves_nothing_under_the_final_name(tmp_path):
    path = tmp_path / "run.mcap"
    code = textwrap.dedent(f"""
        import os, numpy as np
        from neck_sim.logs import LogWriter
        from neck_sim.params import default_params
        w = LogWriter({str(path)!r}, default_params(3))
        for k in range(3000):
            w.motors(k / 500, np.zeros(4), np.zeros(4))
        os._exit(3)          # a crash: no close, no finally
    """)
    assert subprocess.run([sys.executable, "-c", code]).returncode == 3
    assert not path.exists()
    leftovers = os.listdir(tmp_path)
    assert leftovers and all(name.startswith(TEMP_PREFIX) for name in leftovers)
    # the next run writing into that folder recognises the dead process's file and removes it
    atomic._swept.discard(str(tmp_path))
    with LogWriter(tmp_path / "next.mcap", default_params(3)) as w:
        w.motors(0.0, np.zeros(4), np.ones(4))
    assert sorted(os.listdir(tmp_path)) == ["next.mcap"]


def test_writing_over_an_existing_log_replaces_it_atomically(tmp_path):
    path = tmp_path / "a.mcap"
    p = default_params(3)
    with LogWriter(path, p) as w:
        w.motors(0.0, np.zeros(4), np.ones(4))
    with pytest.raises(KeyboardInterrupt):
        with LogWriter(path, p) as w:
            w.motors(0.0, np.zeros(4), 2 * np.ones(4))
            raise KeyboardInterrupt
    assert read_log(path).motors.force.tolist() == [[1.0] * 4]


# -- Foxglove ---------------------------------------------------------------------------------------

def test_foxglove_frames_follow_the_truth(tmp_path):
    p = default_params(3)
    alpha = np.array([[0.0, 0.0, 0.0], [0.3, -0.2, 0.5]])
    with LogWriter(tmp_path / "a.mcap", p, visualization_rate_hz=1000.0) as w:
        for k, a in enumerate(alpha):
            w.motors(k * 0.002, np.zeros(4), np.zeros(4))
            w.truth(k * 0.002, a, np.zeros(3), np.zeros(4), np.zeros(4))
    summary, msgs, _ = raw_messages(tmp_path / "a.mcap")
    tf = [(s, m) for s, c, m in msgs if c.topic == "/tf"]
    assert [s.name for s, _ in tf] == ["foxglove.FrameTransforms"] * 2
    assert tf[0][0].encoding == "jsonschema"
    h = math.sqrt(p.geometry.L ** 2 - p.geometry.b ** 2)     # straight X-joint: a rectangle b x h
    frames = {x["child_frame_id"]: x for x in json.loads(tf[0][1].data)["transforms"]}
    assert set(frames) == {"neck", "bar0", "bar1", "bar2", "bar3"}
    for i in range(4):
        tr = frames[f"bar{i}"]["translation"]
        assert frames[f"bar{i}"]["parent_frame_id"] == "neck"
        # drawn to 1e-6 m: the nearest micrometre
        assert tr["x"] == pytest.approx(0.0, abs=1e-12) and tr["y"] == pytest.approx(i * h, abs=5.000001e-7)
    bent = {x["child_frame_id"]: x for x in json.loads(tf[1][1].data)["transforms"]}
    for i, phi in enumerate(np.concatenate([[0.0], np.cumsum(alpha[1])])):
        q = bent[f"bar{i}"]["rotation"]
        half_digit = 5.000001e-7                      # drawn to 1e-6
        assert q["z"] == pytest.approx(math.sin(phi / 2), abs=half_digit)
        assert q["w"] == pytest.approx(math.cos(phi / 2), abs=half_digit)
    assert json.loads(tf[1][1].data)["transforms"][0]["timestamp"] == {"sec": 0, "nsec": 2_000_000}
    scenes = [(s, m) for s, c, m in msgs if c.topic == "/neck/scene"]
    assert scenes[0][0].name == "foxglove.SceneUpdate"
    entity = json.loads(scenes[0][1].data)["entities"][0]
    assert entity["id"] == "neck/truth" and entity["frame_id"] == "neck"
    bars, springs, *cables = entity["lines"]
    assert len(bars["points"]) == 2 * (1 + 3 * 3) and len(cables) == 4
    assert len(cables[2]["points"]) == 6          # c3: B1, C1, D1, C2, D2, D3
    assert len(cables[3]["points"]) == 4          # left: A1, C1, C2, C3


def test_foxglove_frames_follow_the_camera_without_truth(tmp_path):
    p = default_params(3)
    with LogWriter(tmp_path / "a.mcap", p) as w:
        for k in range(40):
            w.motors(k * 0.002, np.zeros(4), np.zeros(4))
            if k % 17 == 0:
                w.camera(k * 0.002, [0.1, 0.2, 0.3])
    _, msgs, _ = raw_messages(tmp_path / "a.mcap")
    assert sum(c.topic == "/tf" for _, c, _ in msgs) == 3
    ids = {json.loads(m.data)["entities"][0]["id"] for _, c, m in msgs if c.topic == "/neck/scene"}
    assert ids == {"neck/camera"}


def test_chunks_are_zstd_at_level_1(tmp_path):
    """Chunks are what zstandard writes at level 1 for their content (parsed from the file's bytes)."""
    import struct

    import zstandard

    p = default_params(3)
    path = tmp_path / "a.mcap"
    write_arrays(path, p, synthetic_arrays(p, seconds=3.0, seed=2), chunk_size=64 * 1024)
    buf = path.read_bytes()
    with open(path, "rb") as fh:
        chunks = make_reader(fh).get_summary().chunk_indexes
    assert len(chunks) >= 2
    for ci in chunks:
        pos = ci.chunk_start_offset + 9 + 28                       # opcode, length; times, size, crc
        (n,) = struct.unpack_from("<I", buf, pos)
        assert buf[pos + 4: pos + 4 + n] == b"zstd"
        pos += 4 + n
        (size,) = struct.unpack_from("<Q", buf, pos)
        data = buf[pos + 8: pos + 8 + size]
        plain = zstandard.ZstdDecompressor().decompress(data, max_output_size=ci.uncompressed_size)
        assert data == zstandard.ZstdCompressor(level=1).compress(plain)
