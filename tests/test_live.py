"""The live view: a WebSocket client on loopback receives a run's topics from `simulate --live`
and from the dm_control environment, the same samples as the run's MCAP log."""

import asyncio
import json
import os
import struct
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

pytest.importorskip("foxglove")
websockets = pytest.importorskip("websockets")

from neck_sim.logs import read_log  # noqa: E402

SUBPROTOCOL = "foxglove.sdk.v1"       # what foxglove-sdk's server speaks (the successor of foxglove.websocket.v1)
TOPICS = {"/neck/motors", "/neck/reference", "/neck/estimate", "/neck/truth", "/neck/camera", "/neck/scene", "/tf"}


def receive(url: str, *, seconds: float = 60):
    """Connect to ``url``, subscribe to every advertised channel and collect messages until the
    server closes the connection (or ``seconds`` pass).

    Returns (channels by topic, {topic: [(arrival s, log time ns, payload dict), ...]}).
    """
    async def run():
        channels, got, by_sub = {}, {}, {}
        deadline = time.monotonic() + seconds
        async with websockets.connect(url, subprotocols=[SUBPROTOCOL], max_size=None) as ws:
            while time.monotonic() < deadline:
                try:
                    msg = await asyncio.wait_for(ws.recv(), 0.5)
                except asyncio.TimeoutError:
                    continue
                except websockets.ConnectionClosed:
                    break
                if isinstance(msg, str):
                    m = json.loads(msg)
                    if m["op"] == "advertise":
                        subs = []
                        for c in m["channels"]:
                            channels[c["topic"]] = c
                            by_sub[len(by_sub) + 1] = c["topic"]
                            subs.append({"id": len(by_sub), "channelId": c["id"]})
                        await ws.send(json.dumps({"op": "subscribe", "subscriptions": subs}))
                elif msg[0] == 1:                          # message data: sub id u32, log time u64, payload
                    sub, log_ns = struct.unpack_from("<IQ", msg, 1)
                    got.setdefault(by_sub[sub], []).append((time.monotonic(), log_ns, msg[13:]))
        return channels, {topic: [(a, ns, json.loads(m)) for a, ns, m in msgs] for topic, msgs in got.items()}

    return asyncio.run(run())


def _simulate(*options):
    return subprocess.Popen([sys.executable, "-m", "neck_sim.cli", "simulate", "--live", "--live-port", "0",
                             "--duration-scale", "0.1", "--no-progress", *options],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _url(proc) -> str:
    line = proc.stdout.readline()
    assert line.startswith("live view: ws://127.0.0.1:"), line + proc.stderr.read()
    return line.split()[2]


def test_simulate_live_serves_the_logs_topics_and_samples_in_real_time(tmp_path):
    proc = _simulate("--live-pace", "realtime", "-o", str(tmp_path / "run.mcap"))
    try:
        channels, got = receive(_url(proc))
        out, err = proc.communicate(timeout=60)
    finally:
        proc.kill()
    assert proc.returncode == 0, err
    assert set(got) == TOPICS, set(got)
    # the same topics and schemas as the MCAP log of the same run
    from mcap.reader import make_reader

    with open(tmp_path / "run.mcap", "rb") as fh:
        summary = make_reader(fh).get_summary()
    logged = {c.topic: summary.schemas[c.schema_id] for c in summary.channels.values()}
    assert set(logged) == TOPICS
    for topic, schema in logged.items():
        assert channels[topic]["schemaName"] == schema.name and channels[topic]["encoding"] == "json"
        assert json.loads(channels[topic]["schema"]) == json.loads(schema.data), topic
    # every sample of the run, equal to the log's (read back by the log reader)
    log = read_log(tmp_path / "run.mcap", topics=("motors", "truth", "camera", "estimate"))
    truth = got["/neck/truth"]
    np.testing.assert_array_equal([m["t"] for _, _, m in truth], log.truth.t)
    np.testing.assert_array_equal([m["alpha"] for _, _, m in truth], log.truth.alpha)
    np.testing.assert_array_equal([m["force"] for _, _, m in got["/neck/motors"]], log.motors.force)
    np.testing.assert_array_equal([m["alpha"] for _, _, m in got["/neck/camera"]], log.camera.alpha)
    np.testing.assert_array_equal([m["alpha_hat"] for _, _, m in got["/neck/estimate"]], log.estimate.alpha_hat)
    # log times: one start plus the simulated time
    log_ns = np.array([ns for _, ns, _ in truth])
    np.testing.assert_array_equal(log_ns - log_ns[0], np.rint((log.truth.t - log.truth.t[0]) * 1e9))
    # the neck drawn: bars of the truth at about 30 Hz, the bar frames on /tf
    duration = log.truth.t[-1] - log.truth.t[0]
    truth_scenes = [m for _, _, m in got["/neck/scene"] if m["entities"][0]["id"] == "neck/truth"]
    assert abs(len(truth_scenes) - 30 * duration) <= 2
    assert len(truth_scenes[0]["entities"][0]["lines"][0]["points"]) == 2 + 6 * 3     # base bar + 3 joints
    assert {t["child_frame_id"] for t in got["/tf"][0][2]["transforms"]} == {"neck", "bar0", "bar1", "bar2", "bar3"}
    # paced: the samples arrive over the simulated duration, not at once.  Measured over the run's
    # second half: on a loaded machine the client may start reading late and catch up on the first
    # samples in one burst, which says nothing about the server's pacing.
    arrivals = np.array([a for a, _, _ in truth])
    mid = int(np.searchsorted(log.truth.t, log.truth.t[0] + duration / 2))
    second_half = log.truth.t[-1] - log.truth.t[mid]
    assert arrivals[-1] - arrivals[mid] >= 0.9 * second_half, (arrivals[-1] - arrivals[mid], second_half)


def test_simulate_live_fast_sends_every_sample():
    proc = _simulate("--live-pace", "fast", "--no-log")
    try:
        _, got = receive(_url(proc))
        out, err = proc.communicate(timeout=60)
    finally:
        proc.kill()
    assert proc.returncode == 0, err
    t = [m["t"] for _, _, m in got["/neck/motors"]]
    assert len(t) == round(t[-1] * 500) + 1 and t[-1] > 1.0         # every 2 ms period of the run
    assert "law 2" in out


def test_the_environment_serves_its_steps_live():
    from neck_sim import env as neck_env
    from neck_sim.live import LiveView
    from neck_sim.params import default_params

    p = default_params()
    with LiveView(p, port=0, pace="fast") as view:
        box = {}
        client = threading.Thread(target=lambda: box.update(zip(("channels", "got"), receive(view.url, seconds=30))))
        client.start()
        view.wait_for_client()
        environment = neck_env.load(seed=1, live=view, time_limit=0.2)
        ts = environment.reset()
        steps = 0
        while not ts.last():
            ts = environment.step(np.full(p.n_cables, 20.0))
            steps += 1
        time.sleep(0.5)             # the last messages on their way before the server stops
    client.join(30)                 # the client ends when the server closes
    got = box["got"]
    motors = [m for _, _, m in got["/neck/motors"]]
    assert len(motors) == steps == 100
    np.testing.assert_allclose([m["force"] for m in motors][5:], 20.0)
    assert {"/neck/truth", "/neck/reference", "/neck/camera", "/neck/scene", "/tf"} <= set(got)


def test_live_options_are_checked():
    from neck_sim import env as neck_env
    from neck_sim.live import LiveView
    from neck_sim.params import default_params

    with pytest.raises(ValueError, match="pace"):
        LiveView(default_params(), port=0, pace="slow")
    with LiveView(default_params(), port=0) as first:
        taken = int(first.url.rsplit(":", 1)[1])
        with pytest.raises(OSError, match=f"live view: cannot listen on 127.0.0.1:{taken} "):
            LiveView(default_params(), port=taken)
    with pytest.raises(ValueError, match="live: expected True or a neck_sim.live.LiveView"):
        neck_env.load(live="yes")
    r = subprocess.run([sys.executable, "-m", "neck_sim.cli", "simulate", "--live", "--live-port", "70000"],
                       capture_output=True, text=True, timeout=60)
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "--live-port" in r.stderr, r.stderr
