"""Write one run as an MCAP file following the contract (:mod:`neck_sim.logs.contract`).

The file is written to a temporary name in the target directory and renamed on a successful
``close`` (atomic: a crash or an exception leaves no file under the final name).  Chunks are
zstd-compressed.  Alongside the contract topics the writer publishes Foxglove's
``foxglove.FrameTransforms`` on ``/tf`` and ``foxglove.SceneUpdate`` on ``/neck/scene`` (at
``visualization_rate_hz``) so the neck moves in Foxglove's 3D panel.  These are written when the
log is closed (MCAP readers order messages by log_time through the index), so their chunks never
mix with the contract topics' and cost the reader nothing.

Simulated runs reach this writer through :class:`neck_sim.recorder.Recorder`, which hands it
each topic's arrays at once (:meth:`LogWriter.write_batch`); the per-sample methods are for
code that produces samples one at a time (a logger on hardware, a hand-written test log).
"""

from __future__ import annotations

import datetime
import functools
import importlib.metadata
import json
import math
import os
import platform
import sys
import types
import weakref

import numpy as np
import zstandard
from mcap.opcode import Opcode
from mcap.records import MessageIndex
from mcap.writer import CompressionType, Writer

from neck_sim.atomic import discard, output_error, publish, temp_file_beside
from neck_sim.logs import foxglove, jsonrecords
from neck_sim.logs.contract import (NECK_RECORD, RUN_RECORD, TOPIC_BY_NAME, TopicSpec, neck_metadata,
                                    topic_schema)
from neck_sim.params import NeckParams, default_params

__all__ = ["LogWriter", "MJCF_ATTACHMENT", "topic_layout"]

MJCF_ATTACHMENT = "neck.xml"
_MAX_NS = 2 ** 63 - 1            # readers hold log_time as int64 (MCAP: uint64 ns)
_PENDING_ROWS = 256          # samples buffered by the per-sample methods before encoding


@functools.lru_cache(maxsize=None)     # reading a package's metadata costs about 1 ms; it cannot change in a run
def _version(package: str) -> str:
    try:
        return importlib.metadata.version(package)
    except importlib.metadata.PackageNotFoundError:
        return "not installed"


def _run_record(run_info: dict | None) -> dict[str, str]:
    rec = {"neck_sim_version": _version("neck-sim"), "mujoco_version": _version("mujoco"),
           "numpy_version": np.__version__, "mcap_version": _version("mcap"),
           "python_version": platform.python_version(),
           "command_line": json.dumps(sys.argv),
           "created_utc": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
           "seed": "none"}
    for key, value in (run_info or {}).items():
        rec[str(key)] = value if isinstance(value, str) else json.dumps(value, default=_jsonable)
    return rec


def _jsonable(value):
    """numpy scalars/arrays as numbers/lists, anything else by its str()."""
    return value.tolist() if hasattr(value, "tolist") else str(value)


def _chunk_parts(writer: Writer):
    """(chunk builder, statistics, maybe-finalize) of an mcap Writer, or None if its internals differ."""
    parts = tuple(getattr(writer, f"_Writer__{name}", None)
                  for name in ("chunk_builder", "statistics", "maybe_finalize_chunk"))
    return None if any(p is None for p in parts) else parts


class _Zstd1:
    """The ``zstandard`` module as mcap's chunk writer sees it, compressing at level 1: on these
    JSON logs faster (0.10 against 0.18 s for an 85 s run) and smaller (11.2 against 12.9 MB) than
    the module's default level 3, which mcap's Writer offers no way to change."""

    @staticmethod
    def compress(data, level: int = 1):
        return zstandard.ZstdCompressor(level=level).compress(data)   # a compressor per chunk: thread-safe

    def __getattr__(self, name):
        return getattr(zstandard, name)


def _writer_class() -> type:
    """mcap's Writer whose chunk finalisation (the library's own code) sees :class:`_Zstd1`; the
    plain Writer if that code no longer calls ``zstandard``."""
    finalize = getattr(Writer, "_Writer__finalize_chunk", None)
    if finalize is None or "zstandard" not in finalize.__code__.co_names:
        return Writer
    code = types.FunctionType(finalize.__code__, {**finalize.__globals__, "zstandard": _Zstd1()},
                              finalize.__name__, finalize.__defaults__, finalize.__closure__)
    return type("Level1Writer", (Writer,), {"_Writer__finalize_chunk": code})


_Writer = _writer_class()


class _PackedMessageIndex(MessageIndex):
    """A MessageIndex record whose (log_time, offset) pairs are kept as (T, 2) arrays, one per
    batch, and serialised in one numpy call (the library keeps a tuple per message and packs each
    number separately: about 6 us per message).  A pair the library appends itself also works."""

    def write(self, stream) -> None:
        pairs = np.concatenate([np.asarray(r, dtype="<u8").reshape(-1, 2) for r in self.records])
        stream.start_record(Opcode.MESSAGE_INDEX)
        stream.write2(self.channel_id)
        stream.write4(len(pairs) * 16)
        stream.write(pairs.tobytes())
        stream.finish_record()


class LogWriter:
    """Record one run: ``with LogWriter(path, params) as w: w.motors(t, theta, force); ...``.

    Args:
      path: final file name (``.mcap``); its directory is created.
      params: the *nominal* parameters (what the experimenter knows); they fill the ``neck``
        metadata record (geometry, motors, rates, springs, masses; never friction or cables).
      mjcf_xml: the MJCF of the simulated plant, stored as the attachment ``neck.xml``.
      run_info: extra run metadata (seed, effects, command, ...); non-string values are stored as
        JSON.  Versions, the command line and the creation time are added automatically.
      visualization_rate_hz: rate of the ``/tf`` and ``/neck/scene`` messages (0 disables them).
      chunk_size: uncompressed bytes per MCAP chunk (the time-window granularity of the reader).

    Each method takes the sample time ``t`` (s, >= 0, strictly increasing per topic) and arrays of
    the contract's length; a wrong shape, a non-finite value or a time going backwards raises
    ValueError naming the topic and field.
    """

    def __init__(self, path, params: NeckParams | None = None, *, mjcf_xml: str | None = None,
                 run_info: dict | None = None, visualization_rate_hz: float = 30.0,
                 chunk_size: int = 512 * 1024):
        self.path = os.fspath(path)
        self.params = default_params(3) if params is None else params
        self._n = self.params.n_joints
        self._viz_period_ns = int(round(1e9 / visualization_rate_hz)) if visualization_rate_hz > 0 else None
        fd, self._tmp = temp_file_beside(self.path)
        self._fh = os.fdopen(fd, "wb")
        # a writer dropped without close() (an environment never closed) leaves no temporary file
        self._finalizer = weakref.finalize(self, _drop_file, self._fh, self._tmp)
        self._writer = _Writer(self._fh, chunk_size=chunk_size, compression=CompressionType.ZSTD)
        self._writer.start(profile="", library=f"neck-sim {_version('neck-sim')}")
        self._channels: dict[str, int] = {}
        self._layouts: dict[str, tuple] = {}
        self._last_ns: dict[str, int] = {}
        self._viz_next: dict[str, int] = {}
        self._viz: dict[str, list] = {"truth": [], "estimate": [], "camera": []}
        self._pending: dict[str, list] = {}
        self._pending_rows = 0
        self._chunk_size = chunk_size
        self._closed = False
        self.counts: dict[str, int] = {}
        self._writer.add_metadata(NECK_RECORD, neck_metadata(self.params))
        self._writer.add_metadata(RUN_RECORD, _run_record(run_info))
        if mjcf_xml is not None:
            self._writer.add_attachment(0, 0, MJCF_ATTACHMENT, "application/xml", mjcf_xml.encode())

    # -- context manager ---------------------------------------------------------------------
    def __enter__(self) -> "LogWriter":
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is None:
            self.close()
        else:
            self.abort()

    def close(self) -> None:
        """Finish the file and move it to its final name."""
        if self._closed:
            return
        self._closed = True
        self._finalizer.detach()
        try:
            try:
                for name in list(self._pending):
                    self._flush_pending(name)
                self._write_visualization()
                self._writer.finish()
                self._fh.flush()
                os.fsync(self._fh.fileno())
                self._fh.close()
            except OSError as exc:
                raise output_error(self.path, exc) from None
            publish(self._tmp, self.path)
        except BaseException:
            self._discard()
            raise

    def abort(self) -> None:
        """Drop the run: the temporary file is deleted and nothing appears under ``path``."""
        if not self._closed:
            self._closed = True
            self._discard()

    def _discard(self) -> None:
        self._finalizer.detach()
        _drop_file(self._fh, self._tmp)

    # -- contract topics ---------------------------------------------------------------------
    def motors(self, t: float, theta, force) -> None:
        """Encoder angles theta (m,) rad and commanded forces (m,) N at time t (s); m = params.n_cables."""
        self._write(TOPIC_BY_NAME["motors"], t, (theta, force))

    def camera(self, t: float, alpha) -> None:
        """Joint angles from video, alpha (N,) rad."""
        ns = self._write(TOPIC_BY_NAME["camera"], t, (alpha,))
        self._visualize("camera", ns, alpha)

    def reference(self, t: float, alpha_d) -> None:
        """Desired joint angles alpha_d (N,) rad."""
        self._write(TOPIC_BY_NAME["reference"], t, (alpha_d,))

    def estimate(self, t: float, alpha_hat) -> None:
        """Online estimate alpha_hat (N,) rad."""
        ns = self._write(TOPIC_BY_NAME["estimate"], t, (alpha_hat,))
        self._visualize("estimate", ns, alpha_hat)

    def truth(self, t: float, alpha, alpha_dot, tension, elongation) -> None:
        """Simulation truth: alpha, alpha_dot (N,), tension (m,) N, elongation (m,) m."""
        ns = self._write(TOPIC_BY_NAME["truth"], t, (alpha, alpha_dot, tension, elongation))
        self._visualize("truth", ns, alpha)

    # -- internals ---------------------------------------------------------------------------
    def _channel(self, topic: str, schema_name: str, schema) -> int:
        ch = self._channels.get(topic)
        if ch is None:
            schema = schema() if callable(schema) else schema
            sid = self._writer.register_schema(schema_name, "jsonschema", json.dumps(schema).encode())
            ch = self._writer.register_channel(topic, "json", sid)
            self._channels[topic] = ch
            self.counts[topic] = 0
        return ch

    def _layout(self, spec: TopicSpec):
        """(field lengths, payload template) of a topic, built once (:func:`topic_layout`)."""
        layout = self._layouts.get(spec.name)
        if layout is None:
            layout = self._layouts[spec.name] = topic_layout(spec, self._n, self.params.n_cables)
        return layout

    def _write(self, spec: TopicSpec, t: float, arrays) -> int:
        if self._closed:
            raise ValueError(f"{self.path}: log already closed")
        t = float(t)
        if not (t >= 0.0 and math.isfinite(t)):
            raise ValueError(f"{spec.topic}: time t must be finite and >= 0, got {t!r}")
        if t * 1e9 > _MAX_NS:
            raise ValueError(f"{spec.topic}: time t = {t!r} s is beyond MCAP's nanosecond timestamps (t < 9.2e9 s); "
                             "times are seconds since the start of the run")
        ns = int(round(t * 1e9))
        last = self._last_ns.get(spec.topic)
        if last is not None and ns <= last:
            raise ValueError(f"{spec.topic}: time must increase, got t = {t!r} s after t = {last * 1e-9!r} s")
        lengths = self._layout(spec)[0]
        values = [t]
        for name, n, value in zip(spec.field_names, lengths, arrays):
            arr = np.asarray(value, dtype=float)
            if arr.shape != (n,):
                raise ValueError(f"{spec.topic}: {name} must have shape ({n},), got {arr.shape}")
            row = arr.tolist()
            if not all(map(math.isfinite, row)):
                raise ValueError(f"{spec.topic}: {name} contains NaN or infinity at t = {t!r} s")
            values += row
        self._pending.setdefault(spec.name, []).append((ns, values))
        self._pending_rows += 1
        self._last_ns[spec.topic] = ns
        self.counts[self._register(spec)] += 1
        if self._pending_rows >= _PENDING_ROWS:     # all topics together: chunks stay short in time
            for pending in list(self._pending):
                self._flush_pending(pending)
        return ns

    def write_batch(self, name: str, t, *fields) -> None:
        """Many samples of one contract topic at once: ``t`` (T,) s increasing, then the topic's
        fields in contract order, each (T, n).  Same checks as the per-sample methods."""
        spec = TOPIC_BY_NAME[name]
        if self._closed:
            raise ValueError(f"{self.path}: log already closed")
        t = np.asarray(t, dtype=float)
        if t.ndim != 1:
            raise ValueError(f"{spec.topic}: t must have shape (T,), got {t.shape}")
        if not np.all(np.isfinite(t) & (t >= 0)):
            raise ValueError(f"{spec.topic}: time t must be finite and >= 0")
        if len(t) and t.max() * 1e9 > _MAX_NS:
            raise ValueError(f"{spec.topic}: time t = {float(t.max())!r} s is beyond MCAP's nanosecond timestamps")
        lengths = self._layout(spec)[0]
        if len(fields) != len(lengths):
            raise ValueError(f"{spec.topic}: expected fields {spec.field_names}, got {len(fields)} arrays")
        cols = [t[:, None]]
        for fname, n, value in zip(spec.field_names, lengths, fields):
            arr = np.asarray(value, dtype=float)
            if arr.shape != (len(t), n):
                raise ValueError(f"{spec.topic}: {fname} must have shape ({len(t)}, {n}), got {arr.shape}")
            if not np.all(np.isfinite(arr)):
                bad = int(np.argmax(~np.isfinite(arr).all(axis=1)))
                raise ValueError(f"{spec.topic}: {fname} contains NaN or infinity at t = {float(t[bad])!r} s")
            cols.append(arr)
        if len(t) == 0:
            return
        self._flush_pending(name)
        ns = np.rint(t * 1e9).astype(np.int64)
        last = self._last_ns.get(spec.topic)
        steps = np.diff(ns, prepend=ns[0] - 1 if last is None else last)
        if np.any(steps <= 0):
            i = int(np.argmax(steps <= 0))
            raise ValueError(f"{spec.topic}: time must increase, got t = {float(t[i])!r} s after an earlier sample")
        self._encode(spec, np.concatenate(cols, axis=1), ns)
        self._last_ns[spec.topic] = int(ns[-1])
        self.counts[spec.topic] += len(t)
        if spec.name in self._viz:
            first = cols[1]
            for i in self._visual_samples(spec.name, ns):
                self._viz[spec.name].append((int(ns[i]), first[i]))

    def _register(self, spec: TopicSpec) -> str:
        self._channel(spec.topic, spec.schema_name, lambda: topic_schema(spec, self._n, self.params.n_cables))
        return spec.topic

    def _flush_pending(self, name: str) -> None:
        rows = self._pending.pop(name, None)
        if rows:
            self._pending_rows -= len(rows)
            spec = TOPIC_BY_NAME[name]
            self._encode(spec, np.array([v for _, v in rows]), np.array([ns for ns, _ in rows], dtype=np.int64))

    def _encode(self, spec: TopicSpec, values: np.ndarray, ns: np.ndarray) -> None:
        """JSON payloads of (T, F) checked values as MCAP records, appended to the open chunk."""
        ch = self._channel(spec.topic, spec.schema_name, lambda: topic_schema(spec, self._n, self.params.n_cables))
        self._append_encoded(ch, self._layout(spec)[1], values, ns)

    def _append_encoded(self, ch: int, tmpl: jsonrecords.Template, values: np.ndarray, ns: np.ndarray) -> None:
        records, offsets = jsonrecords.message_records(tmpl, values, ns, ch)
        try:
            self._append_records(ch, records, offsets, ns)
        except OSError as exc:                  # a full chunk is written to the file here
            raise output_error(self.path, exc) from None

    def _append_records(self, ch: int, records: np.ndarray, offsets: np.ndarray, ns: np.ndarray) -> None:
        """Add encoded Message records to the writer's chunks, about ``chunk_size`` bytes at a time.

        The mcap Writer has no bulk call: its chunk builder and statistics are filled as
        ``add_message`` would (with an mcap whose internals differ, add_message is used).
        """
        w = self._writer
        ends = np.append(offsets[1:], len(records))
        parts = _chunk_parts(w)
        if parts is None:
            for off, end, t in zip(offsets.tolist(), ends.tolist(), ns.tolist()):
                w.add_message(ch, t, records[off + jsonrecords.MESSAGE_HEADER: end].tobytes(), t)
            return
        builder, stats, finalize = parts
        i = 0
        while i < len(ns):
            room = max(self._chunk_size - builder.count, 1)
            j = max(int(np.searchsorted(ends, offsets[i] + room, side="right")), i + 1)
            base = builder.count - int(offsets[i])
            builder.record_writer.write(records[offsets[i]: ends[j - 1]].tobytes())
            index = builder.message_indices.get(ch)
            if index is None:
                index = builder.message_indices[ch] = _PackedMessageIndex(channel_id=ch, records=[])
            index.records.append(np.column_stack((ns[i:j], offsets[i:j] + base)))
            lo, hi = int(ns[i:j].min()), int(ns[i:j].max())
            builder.message_start_time = lo if builder.num_messages == 0 else min(lo, builder.message_start_time)
            builder.message_end_time = max(hi, builder.message_end_time)
            builder.num_messages += j - i
            stats.message_start_time = lo if stats.message_count == 0 else min(lo, stats.message_start_time)
            stats.message_end_time = max(hi, stats.message_end_time)
            stats.channel_message_counts[ch] += j - i
            stats.message_count += j - i
            finalize()
            i = j

    def _visual_samples(self, source: str, ns: np.ndarray) -> list[int]:
        """Indices of the samples ``_visualize`` would keep, for a batch of times."""
        if self._viz_period_ns is None:
            return []
        out, nxt = [], self._viz_next.get(source, 0)
        i = int(np.searchsorted(ns, nxt))
        while i < len(ns):
            out.append(i)
            nxt = int(ns[i]) + self._viz_period_ns
            i = int(np.searchsorted(ns, nxt))
        self._viz_next[source] = nxt
        return out

    def _visualize(self, source: str, ns: int, alpha) -> None:
        # Poses are kept and drawn at close(), with one batched forward kinematics per source.
        if self._viz_period_ns is None or ns < self._viz_next.get(source, 0):
            return
        self._viz_next[source] = ns + self._viz_period_ns
        self._viz[source].append((ns, np.asarray(alpha, dtype=float)))

    def _write_visualization(self) -> None:
        # /tf follows the truth in simulations; measured logs (no truth) follow the camera.
        tf_source = "truth" if self._viz["truth"] else "camera"
        for source, samples in self._viz.items():
            if not samples:
                continue
            times = np.array([ns for ns, _ in samples], dtype=np.int64)
            alphas = np.stack([a for _, a in samples])
            for batch in foxglove.visualization_batches(times, alphas, self.params, source, tf=source == tf_source):
                ch = self._channel(batch.topic, batch.schema_name, batch.schema)
                self._append_encoded(ch, batch.template, batch.values, batch.log_ns)
                self.counts[batch.topic] += len(batch.log_ns)


def topic_layout(spec: TopicSpec, n_joints: int, n_cables: int) -> tuple[tuple[int, ...], jsonrecords.Template]:
    """(field lengths, payload template) of a contract topic: ``{"t": .., "theta": [..], ..}``, the
    values of a message being its row ``[t, *field 1, *field 2, ...]``."""
    lengths = spec.lengths(n_joints, n_cables)
    doc, column = {"t": jsonrecords.Slot(0)}, 1
    for f, k in zip(spec.field_names, lengths):
        doc[f] = [jsonrecords.Slot(column + i) for i in range(k)]
        column += k
    return lengths, jsonrecords.template(doc)


def _drop_file(fh, tmp: str) -> None:
    try:
        fh.close()
    except OSError:
        pass
    finally:
        discard(tmp)
