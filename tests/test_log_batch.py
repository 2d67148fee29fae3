"""Bulk MCAP encoding: ``LogWriter.write_batch`` and the per-sample methods give
the same messages, read back exactly by our reader and by the mcap library's own reader, with the
bulk chunk path and with the library's add_message fallback."""

from __future__ import annotations

import json

import numpy as np
import pytest
from mcap.reader import make_reader
from test_logs_fixtures import synthetic_arrays, write_arrays

import neck_sim.logs.writer as writer_mod
from neck_sim.logs import LogWriter, read_log
from neck_sim.params import default_params


def write_batches(path, params, arrays, **kw):
    with LogWriter(path, params, **kw) as w:
        for topic, fields in arrays.items():
            w.write_batch(topic, fields["t"], *[v for k, v in fields.items() if k != "t"])


def library_messages(path) -> dict:
    """topic -> (log times, JSON bodies) through mcap's reader, in file order per topic."""
    out: dict = {}
    with open(path, "rb") as fh:
        reader = make_reader(fh)
        counts = reader.get_summary().statistics.channel_message_counts
        for _, channel, msg in reader.iter_messages(log_time_order=False):
            times, bodies = out.setdefault(channel.topic, ([], []))
            assert msg.publish_time == msg.log_time
            times.append(msg.log_time)
            bodies.append(json.loads(msg.data))
    return out, counts


@pytest.mark.parametrize("bulk", [True, False])
def test_batches_and_samples_write_the_same_log(tmp_path, monkeypatch, bulk):
    if not bulk:
        monkeypatch.setattr(writer_mod, "_chunk_parts", lambda w: None)
    p = default_params(3)
    arrays = synthetic_arrays(p, seconds=1.0, seed=4)
    write_batches(tmp_path / "batch.mcap", p, arrays, chunk_size=8 * 1024)
    write_arrays(tmp_path / "samples.mcap", p, arrays, chunk_size=8 * 1024)
    for name in ("batch.mcap", "samples.mcap"):
        log = read_log(tmp_path / name)
        msgs, counts = library_messages(tmp_path / name)
        assert sum(counts.values()) == sum(len(b) for _, b in msgs.values())
        for topic, fields in arrays.items():
            samples = getattr(log, topic)
            times, bodies = msgs[f"/neck/{topic}"]
            assert sorted(times) == np.rint(fields["t"] * 1e9).astype(np.int64).tolist()
            order = np.argsort(times)
            for key, values in fields.items():
                np.testing.assert_array_equal(getattr(samples, key), values, err_msg=f"{name} {topic}.{key}")
                np.testing.assert_array_equal(np.array([bodies[i][key] for i in order]), values)


def test_write_batch_checks_its_input(tmp_path):
    p = default_params(3)
    t = np.arange(4) * 0.002
    with LogWriter(tmp_path / "a.mcap", p) as w:
        with pytest.raises(ValueError, match=r"theta must have shape \(4, 4\)"):
            w.write_batch("motors", t, np.zeros((4, 3)), np.zeros((4, 4)))
        bad = np.zeros((4, 4))
        bad[2, 1] = np.inf
        with pytest.raises(ValueError, match="force contains NaN or infinity at t = 0.004"):
            w.write_batch("motors", t, np.zeros((4, 4)), bad)
        with pytest.raises(ValueError, match="time must increase"):
            w.write_batch("motors", t[::-1], np.zeros((4, 4)), np.zeros((4, 4)))
        w.write_batch("motors", t, np.zeros((4, 4)), np.ones((4, 4)))
        with pytest.raises(ValueError, match="time must increase"):
            w.motors(t[-1], np.zeros(4), np.zeros(4))
    np.testing.assert_array_equal(read_log(tmp_path / "a.mcap").motors.force, np.ones((4, 4)))
