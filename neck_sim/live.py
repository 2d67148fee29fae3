"""A run served live to Foxglove over a WebSocket on the loopback address (``foxglove-sdk``).

:class:`LiveView` takes what a :class:`neck_sim.logs.LogWriter` takes (``write_batch`` of the
contract topics, or the per-sample ``motors``/``reference``/``estimate``/``truth``/``camera``) and
publishes it on the log's topics with the log's JSON schemas, plus the neck drawn as
``foxglove.SceneUpdate`` on ``/neck/scene`` and ``foxglove.FrameTransforms`` on ``/tf``
(:mod:`neck_sim.logs.foxglove`, at ``rate_hz``).  Payloads are the log's own (one template per
topic, :func:`neck_sim.logs.writer.topic_layout`), so a live message and the same sample in the MCAP
log are the same bytes.  Message log times are the wall clock at the start of the run plus the
simulated time (ns).

Pacing: ``"realtime"`` holds each batch until the wall clock has caught up with its simulated
time (the run plays at 1x); ``"fast"`` publishes as soon as the samples exist.  Nothing is encoded
for a topic no client subscribes to.

A closed-loop run (:func:`controllers.closed_loop.run_closed_loop`) feeds the view open around it
(``with LiveView(params): ...``; :func:`active`) between its compiled chunks; the dm_control
environment (``neck_sim.env.load(live=True)``) feeds it every control step.

Needs the ``foxglove-sdk`` package (``pip install 'neck-sim[live]'``).
"""

from __future__ import annotations

import contextvars
import json
import threading
import time

import numpy as np
import numpy.typing as npt

from neck_sim.params import NeckParams

# neck_sim.logs (mcap, zstandard) and foxglove are imported by LiveView only: a closed-loop run
# asks active() at every start, and most runs have no live view.

__all__ = ["LiveView", "active", "PACES", "DEFAULT_PORT"]

PACES = ("realtime", "fast")
DEFAULT_PORT = 8765                  # Foxglove's default for a WebSocket connection
# Messages queued per client before the SDK drops the oldest (its default is 1024): about 2 s of a
# `fast` run, some 20 MB at most, so that a viewer slower than the simulation loses nothing.
_BACKLOG = 65536
_ACTIVE: contextvars.ContextVar = contextvars.ContextVar("neck_sim_live_view", default=None)
_SOURCES = ("truth", "estimate", "camera")     # topics whose joint angles are drawn


def active() -> "LiveView | None":
    """The live view opened with ``with LiveView(...)`` around this call, if any."""
    return _ACTIVE.get()


def _listener(event: threading.Event):
    """A foxglove ServerListener that sets ``event`` at the first subscription of any client."""
    import foxglove

    class Subscribed(foxglove.ServerListener):
        def on_subscribe(self, client, channel) -> None:
            event.set()

    return Subscribed()


class LiveView:
    """Serve one or more runs to Foxglove at ``ws://host:port`` (port 0: a free port, see ``url``).

    ``params``: the neck (its joint and cable counts shape the topics; its geometry draws the
    scene).  ``pace``: ``"realtime"`` or ``"fast"``.  ``rate_hz``: scene and transform messages
    per simulated second.  ``host`` is the loopback address unless you mean otherwise.
    """

    def __init__(self, params: NeckParams, *, port: int = DEFAULT_PORT, pace: str = "realtime",
                 rate_hz: float = 30.0, host: str = "127.0.0.1") -> None:
        if pace not in PACES:
            raise ValueError(f"pace: expected one of {', '.join(PACES)}, got {pace!r}")
        if not (isinstance(port, int) and 0 <= port <= 65535):
            raise ValueError(f"port: expected a TCP port 0..65535, got {port!r}")
        if not rate_hz > 0:
            raise ValueError(f"rate_hz: expected a positive rate, got {rate_hz!r}")
        try:
            import foxglove
        except ImportError as exc:
            raise RuntimeError(f"the live view needs foxglove-sdk ({exc}); pip install 'neck-sim[live]'") from None
        from neck_sim.logs import foxglove as fox
        from neck_sim.logs.contract import TOPIC_BY_NAME, topic_schema
        from neck_sim.logs.writer import topic_layout

        self.params, self.pace = params, pace
        self._n, self._m = params.n_joints, params.n_cables
        self.rate_hz = float(rate_hz)
        self._viz_period = 1.0 / rate_hz
        self._subscribed = threading.Event()
        self._context = foxglove.Context()
        self._server: foxglove.WebSocketServer | None
        try:
            self._server = foxglove.start_server(name="neck-sim", host=host, port=port, context=self._context,
                                                 server_listener=_listener(self._subscribed),
                                                 message_backlog_size=_BACKLOG)
        except Exception as exc:       # the SDK's error for a port in use or a bad host
            raise OSError(f"live view: cannot listen on {host}:{port} ({exc})") from None
        self.url = f"ws://{host}:{self._server.port}"
        self._layouts = {name: topic_layout(spec, self._n, self._m) for name, spec in TOPIC_BY_NAME.items()}
        # every topic advertised from the start: a client subscribes before the first sample
        self._channels = {spec.topic: _channel(self._context, spec.topic, spec.schema_name,
                                               topic_schema(spec, self._n, self._m))
                          for spec in TOPIC_BY_NAME.values()}
        self._channels[fox.SCENE_TOPIC] = _channel(self._context, fox.SCENE_TOPIC, "foxglove.SceneUpdate",
                                                   fox.SCENE_UPDATE_SCHEMA)
        self._channels[fox.TF_TOPIC] = _channel(self._context, fox.TF_TOPIC, "foxglove.FrameTransforms",
                                                fox.FRAME_TRANSFORMS_SCHEMA)
        self._wall0: float | None = None       # monotonic s at the run's first sample
        self._t0 = 0.0                         # the run's first simulated time, s
        self._ns0 = 0                          # log time (ns) of simulated time t0
        self._last_ns = 0
        self._viz_next = {source: -np.inf for source in _SOURCES}
        self._token: contextvars.Token | None = None

    # -- the view's life --------------------------------------------------------------------
    def __enter__(self) -> "LiveView":
        self._token = _ACTIVE.set(self)
        return self

    def __exit__(self, *exc) -> None:
        if self._token is not None:
            _ACTIVE.reset(self._token)
            self._token = None
        self.close()

    def close(self) -> None:
        """Stop the server (clients see the connection close)."""
        if self._server is not None:
            self._server.stop()
            self._server = None

    def wait_for_client(self, poll: float = 0.2) -> None:
        """Block until a client subscribes to a topic (Ctrl-C interrupts)."""
        while not self._subscribed.wait(poll):
            pass

    def new_run(self) -> None:
        """The next samples start a new run (simulated time restarts): log times keep increasing."""
        self._wall0 = None
        self._viz_next = {source: -np.inf for source in self._viz_next}

    # -- the LogWriter interface --------------------------------------------------------------
    def motors(self, t: float, theta: np.ndarray, force: np.ndarray) -> None:
        self.write_batch("motors", [t], [theta], [force])

    def reference(self, t: float, alpha_d: np.ndarray) -> None:
        self.write_batch("reference", [t], [alpha_d])

    def estimate(self, t: float, alpha_hat: np.ndarray) -> None:
        self.write_batch("estimate", [t], [alpha_hat])

    def truth(self, t: float, alpha: np.ndarray, alpha_dot: np.ndarray, tension: np.ndarray,
              elongation: np.ndarray) -> None:
        self.write_batch("truth", [t], [alpha], [alpha_dot], [tension], [elongation])

    def camera(self, t: float, alpha: np.ndarray) -> None:
        self.write_batch("camera", [t], [alpha])

    def write_batch(self, name: str, t: npt.ArrayLike, *fields: npt.ArrayLike) -> None:
        """Samples of contract topic ``name``: times ``t`` (T,) s, then its fields (T, n) in
        contract order (as :meth:`neck_sim.logs.LogWriter.write_batch`); realtime pacing first
        waits until the wall clock reaches the last of them."""
        from neck_sim.logs.contract import TOPIC_BY_NAME

        spec = TOPIC_BY_NAME[name]
        t = np.asarray(t, dtype=float).reshape(-1)
        if len(t) == 0 or self._server is None:
            return
        lengths, tmpl = self._layouts[name]
        values = np.concatenate([t[:, None]] + [np.asarray(f, dtype=float).reshape(len(t), k)
                                                 for f, k in zip(fields, lengths)], axis=1)
        ns = self._log_ns(t)
        self._pace(float(t[-1]))
        channel = self._channels[spec.topic]
        if channel.has_sinks():
            _publish(channel, tmpl, values, ns)
        if name in _SOURCES:
            self._draw(name, t, ns, values[:, 1:1 + self._n])

    # -- internals -----------------------------------------------------------------------------
    def _log_ns(self, t: np.ndarray) -> np.ndarray:
        if self._wall0 is None:
            self._wall0, self._t0 = time.monotonic(), float(t[0])
            self._ns0 = max(time.time_ns(), self._last_ns + 1)
        ns = self._ns0 + np.rint((t - self._t0) * 1e9).astype(np.int64)
        self._last_ns = max(self._last_ns, int(ns[-1]))
        return ns

    def _pace(self, t_last: float) -> None:
        if self.pace == "realtime" and self._wall0 is not None:     # set by the first sample's _log_ns
            delay = self._wall0 + (t_last - self._t0) - time.monotonic()
            if delay > 0:
                time.sleep(delay)

    def _draw(self, source: str, t: np.ndarray, ns: np.ndarray, alpha: np.ndarray) -> None:
        """Scene (and, for the truth, transform) messages of the samples due at ``rate_hz``."""
        from neck_sim.logs import foxglove as fox

        keep, nxt = [], self._viz_next[source]
        for i, ti in enumerate(t.tolist()):
            if ti >= nxt:
                keep.append(i)
                nxt = ti + self._viz_period
        self._viz_next[source] = nxt
        scene, tf = self._channels[fox.SCENE_TOPIC], self._channels[fox.TF_TOPIC]
        if not keep or not (scene.has_sinks() or tf.has_sinks()):
            return
        for batch in fox.visualization_batches(ns[keep], alpha[keep], self.params, source, tf=source == "truth"):
            channel = scene if batch.topic == fox.SCENE_TOPIC else tf
            if channel.has_sinks():
                _publish(channel, batch.template, batch.values, batch.log_ns)


def _channel(context, topic: str, schema_name: str, schema: dict):
    """A JSON channel with the log's JSON schema (Foxglove recognises its foxglove.* names)."""
    import foxglove

    return foxglove.Channel(topic, schema=foxglove.Schema(name=schema_name, encoding="jsonschema",
                                                          data=json.dumps(schema).encode()),
                            message_encoding="json", context=context)


def _publish(channel, tmpl, values: np.ndarray, ns: np.ndarray) -> None:
    """T messages of ``tmpl`` on a foxglove channel: the MCAP log's payload bytes, at log times ns."""
    from neck_sim.logs import jsonrecords

    records, offsets = jsonrecords.message_records(tmpl, values, ns, 0)
    ends = np.append(offsets[1:], len(records))
    data = records.tobytes()
    for start, end, t in zip((offsets + jsonrecords.MESSAGE_HEADER).tolist(), ends.tolist(), ns.tolist()):
        channel.log(data[start:end], log_time=t)
