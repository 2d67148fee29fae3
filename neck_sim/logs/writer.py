"""Write one run as an MCAP file following the contract (:mod:`neck_sim.logs.contract`).

The file is written to a temporary name in the target directory and renamed on a successful
``close`` (atomic: a crash or an exception leaves no file under the final name).  Chunks are
zstd-compressed.  Alongside the contract topics the writer publishes Foxglove's
``foxglove.FrameTransforms`` on ``/tf`` and ``foxglove.SceneUpdate`` on ``/neck/scene`` (at
``visualization_rate_hz``) so the neck moves in Foxglove's 3D panel.  These are written when the
log is closed (MCAP readers order messages by log_time through the index), so their chunks never
mix with the contract topics' and cost the reader nothing.
"""

from __future__ import annotations

import datetime
import importlib.metadata
import json
import math
import os
import platform
import sys

import numpy as np
from mcap.writer import CompressionType, Writer

from neck_sim.atomic import discard, publish, temp_file_beside
from neck_sim.logs import foxglove
from neck_sim.logs.contract import (NECK_RECORD, RUN_RECORD, TOPIC_BY_NAME, TopicSpec, neck_metadata,
                                    topic_schema)
from neck_sim.params import NeckParams, default_params

__all__ = ["LogWriter", "MJCF_ATTACHMENT"]

MJCF_ATTACHMENT = "neck.xml"
_DUMPS = json.JSONEncoder(separators=(",", ":"), allow_nan=False).encode


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
        self._writer = Writer(self._fh, chunk_size=chunk_size, compression=CompressionType.ZSTD)
        self._writer.start(profile="", library=f"neck-sim {_version('neck-sim')}")
        self._channels: dict[str, int] = {}
        self._layouts: dict[str, tuple] = {}
        self._last_ns: dict[str, int] = {}
        self._viz_next: dict[str, int] = {}
        self._viz: dict[str, list] = {"truth": [], "estimate": [], "camera": []}
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
        try:
            self._write_visualization()
            self._writer.finish()
            self._fh.flush()
            os.fsync(self._fh.fileno())
            self._fh.close()
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
        try:
            self._fh.close()
        finally:
            discard(self._tmp)

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
        """(field lengths, %-format of one message) of a topic, built once."""
        layout = self._layouts.get(spec.name)
        if layout is None:
            lengths = spec.lengths(self._n, self.params.n_cables)
            # %r of a Python float is its shortest round-trip repr: the JSON number json.dumps writes.
            parts = ['{"t":%r'] + [f',"{f}":[' + ",".join(["%r"] * k) + "]" for f, k in zip(spec.field_names, lengths)]
            layout = self._layouts[spec.name] = (lengths, "".join(parts) + "}")
        return layout

    def _write(self, spec: TopicSpec, t: float, arrays) -> int:
        if self._closed:
            raise ValueError(f"{self.path}: log already closed")
        t = float(t)
        if not (t >= 0.0 and math.isfinite(t)):
            raise ValueError(f"{spec.topic}: time t must be finite and >= 0, got {t!r}")
        ns = int(round(t * 1e9))
        last = self._last_ns.get(spec.topic)
        if last is not None and ns <= last:
            raise ValueError(f"{spec.topic}: time must increase, got t = {t!r} s after t = {last * 1e-9!r} s")
        lengths, fmt = self._layout(spec)
        values = [t]
        for name, n, value in zip(spec.field_names, lengths, arrays):
            arr = np.asarray(value, dtype=float)
            if arr.shape != (n,):
                raise ValueError(f"{spec.topic}: {name} must have shape ({n},), got {arr.shape}")
            row = arr.tolist()
            if not all(map(math.isfinite, row)):
                raise ValueError(f"{spec.topic}: {name} contains NaN or infinity at t = {t!r} s")
            values += row
        ch = self._channel(spec.topic, spec.schema_name, lambda: topic_schema(spec, self._n, self.params.n_cables))
        self._writer.add_message(ch, ns, (fmt % tuple(values)).encode(), ns)
        self._last_ns[spec.topic] = ns
        self.counts[spec.topic] += 1
        return ns

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
            times = [ns for ns, _ in samples]
            alphas = np.stack([a for _, a in samples])
            for topic, ns, msg in foxglove.visualization_messages(times, alphas, self.params, source,
                                                                   tf=source == tf_source):
                if topic == foxglove.TF_TOPIC:
                    ch = self._channel(topic, "foxglove.FrameTransforms", foxglove.FRAME_TRANSFORMS_SCHEMA)
                else:
                    ch = self._channel(topic, "foxglove.SceneUpdate", foxglove.SCENE_UPDATE_SCHEMA)
                self._writer.add_message(ch, ns, _DUMPS(msg).encode(), ns)
                self.counts[topic] += 1
