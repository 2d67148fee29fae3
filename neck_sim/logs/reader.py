"""Read a contract log into numpy arrays, validating the contract on the way.

``read_log(path)`` returns a :class:`Log` with one samples object per topic (time vector ``t``
(T,) s plus the fields as (T, n) arrays).  A time window (``start``/``end``, s) is served from
the MCAP chunk index: chunks outside it are never read.  Within a chunk, the message index gives
each message's offset, so decoding is vectorised:

* all payloads of a topic are joined and, when every message has the layout the writer produces
  (checked by comparing the number-free skeleton of all messages with the expected one), the
  numbers are parsed in one ``np.fromstring`` call;
* otherwise (another producer, other key order, whitespace) the payloads are parsed with
  ``json.loads``, which also locates the first bad message when the data is wrong.

Files without a summary or message index are read through the ``mcap`` library's reader.
Collecting the payloads is :mod:`neck_sim.logs.payloads`; decoding and checking them is here.
Every problem (missing topic/field/record, wrong array length, non-finite number, time not
increasing, t != log_time, truncated or corrupt file) raises :class:`LogError` naming it.
"""

from __future__ import annotations

import json
import os
import warnings
from dataclasses import dataclass, field
from typing import Any, Iterable

import numpy as np
from mcap.reader import SeekingReader

from neck_sim.logs.contract import (MIN_CAMERA_FRAMES, record_value, NECK_RECORD, RUN_RECORD, TOPIC_BY_NAME, TOPICS, LogError,
                                    TopicSpec, check_plausible, params_from_metadata, resolve_topic)
from neck_sim.logs.payloads import READ_ERRORS, Payloads, collect_indexed, collect_linear
from neck_sim.params import NeckParams

__all__ = ["read_log", "require_camera_frames",
           "Log", "MotorSamples", "CameraSamples", "ReferenceSamples", "EstimateSamples",
           "TruthSamples"]

_MAGIC = b"\x89MCAP0\r\n"
_NUMBER_CHARS = b"0123456789.+-eE"
_MAX_NS = 2**63 - 1
_T_TOLERANCE_NS = 1000          # |t * 1e9 - log_time| allowed (the contract: the same instant)


@dataclass(frozen=True)
class MotorSamples:
    """``/neck/motors``: t (T,) s, theta (T, N+1) rad, force (T, N+1) N."""
    t: np.ndarray
    theta: np.ndarray
    force: np.ndarray


@dataclass(frozen=True)
class CameraSamples:
    """``/neck/camera``: t (T,) s, alpha (T, N) rad."""
    t: np.ndarray
    alpha: np.ndarray


@dataclass(frozen=True)
class ReferenceSamples:
    """``/neck/reference``: t (T,) s, alpha_d (T, N) rad."""
    t: np.ndarray
    alpha_d: np.ndarray


@dataclass(frozen=True)
class EstimateSamples:
    """``/neck/estimate``: t (T,) s, alpha_hat (T, N) rad."""
    t: np.ndarray
    alpha_hat: np.ndarray


@dataclass(frozen=True)
class TruthSamples:
    """``/neck/truth`` (simulation only): t, alpha, alpha_dot (T, N), tension, elongation (T, N+1)."""
    t: np.ndarray
    alpha: np.ndarray
    alpha_dot: np.ndarray
    tension: np.ndarray
    elongation: np.ndarray


_SAMPLES = {"motors": MotorSamples, "camera": CameraSamples, "reference": ReferenceSamples,
            "estimate": EstimateSamples, "truth": TruthSamples}


@dataclass(frozen=True)
class Log:
    """A contract log read into numpy. Topics absent from the file (or not asked for) are None.

    ``metadata`` is the ``neck`` record, ``params`` the NeckParams it describes (defaults for
    everything it does not hold), ``run_info`` the ``run`` record (versions, seed, command line,
    plant settings: never to be used by analyses of measured data), ``message_counts`` the number
    of messages per topic in the whole file, ``warnings`` what was accepted on request (out-of-range
    forces): every analysis of the log must repeat them in its output.
    """

    path: str
    params: NeckParams
    metadata: dict[str, str]
    run_info: dict[str, str]
    attachments: dict[str, bytes]
    message_counts: dict[str, int]
    motors: MotorSamples | None = None
    camera: CameraSamples | None = None
    reference: ReferenceSamples | None = None
    estimate: EstimateSamples | None = None
    truth: TruthSamples | None = None
    window: tuple[float | None, float | None] = field(default=(None, None))
    warnings: tuple[str, ...] = ()

    @property
    def n_joints(self) -> int:
        return self.params.n_joints

    def run_value(self, key: str) -> Any:
        """A ``run`` record value decoded from JSON (the raw string when it is not JSON; None if absent)."""
        return record_value(self.run_info.get(key))


def _to_ns(value: float | None, name: str) -> int | None:
    if value is None:
        return None
    v = float(value)
    if not np.isfinite(v) or v < 0:
        raise LogError(f"read_log: {name} must be a finite time >= 0 s, got {value!r}")
    # beyond MCAP's time range (2^63 ns = 292 years) means "after every message"
    return min(int(round(min(v, 1e12) * 1e9)), _MAX_NS)


def read_log(path: str | os.PathLike, *, start: float | None = None, end: float | None = None,
             topics: Iterable[str] | None = None, require: Iterable[str] = ("motors",),
             accept_out_of_range_forces: bool = False) -> Log:
    """Read a contract log into numpy arrays.

    Args:
      path: the ``.mcap`` file.
      start, end: time window [start, end) in s since the start of the run (None: open end);
        served from the chunk index, so a short window of a long log reads only its chunks.
      topics: short names (``"motors"``) or MCAP topics to read; None reads every contract topic
        present.  Required topics are always read.
      require: topics that must be present (LogError naming the first one missing); with a window,
        each must have at least two samples in it.
      accept_out_of_range_forces: keep commanded forces outside [0, f_max] (listed in
        ``Log.warnings``) instead of refusing the log.

    Measured topics are checked against the ``neck`` record (:func:`check_plausible`: sample
    rates, joint range, force range), so a unit mistake is refused rather than analysed.

    Raises:
      LogError (a ValueError) naming the problem: unreadable, truncated or corrupt file, missing
      ``neck`` record or key, missing required topic, missing field, wrong array length,
      non-finite value, t not matching log_time, time not increasing, implausible values (times
      in ms, angles in degrees, out-of-range forces), a window with no data of a required topic.
    """
    path = os.fspath(path)
    start_ns, end_ns = _to_ns(start, "start"), _to_ns(end, "end")
    if start_ns is not None and end_ns is not None and end_ns < start_ns:
        raise LogError(f"read_log: end = {end} s is before start = {start} s")
    required = [resolve_topic(r) for r in require]
    wanted = list(TOPICS) if topics is None else [resolve_topic(x) for x in topics]
    wanted += [r for r in required if r not in wanted]
    try:
        fh = open(path, "rb")
    except OSError as exc:
        raise LogError(f"{path}: cannot open log ({exc.strerror})") from None
    with fh:
        if fh.read(len(_MAGIC)) != _MAGIC:
            raise LogError(f"{path}: not an MCAP file (wrong magic bytes)")
        fh.seek(0)
        reader = SeekingReader(fh, validate_crcs=True)
        try:
            summary = reader.get_summary()
        except READ_ERRORS as exc:
            raise LogError(f"{path}: truncated or corrupt MCAP file: no valid footer/summary at the end "
                           f"(was the run interrupted before the log was closed?) [{exc}]") from None
        try:
            metadata = {m.name: dict(m.metadata) for m in reader.iter_metadata()}
            attachments = {a.name: bytes(a.data) for a in reader.iter_attachments()}
        except READ_ERRORS as exc:
            raise LogError(f"{path}: corrupt MCAP file: cannot read metadata/attachments [{exc}]") from None
        if NECK_RECORD not in metadata:
            raise LogError(f"{path}: missing metadata record {NECK_RECORD!r} (the neck's nominal constants)")
        neck = metadata[NECK_RECORD]
        try:
            params = params_from_metadata(neck)
        except LogError as exc:
            raise LogError(f"{path}: {exc}") from None
        n = params.n_joints

        channels: dict[str, Any] = {} if summary is None else {c.topic: c for c in summary.channels.values()}
        counts = {}
        if summary is not None and summary.statistics is not None:
            by_id = summary.statistics.channel_message_counts
            counts = {c.topic: int(by_id.get(cid, 0)) for cid, c in summary.channels.items()}
        if summary is None:          # a valid MCAP without summary: scan it (counts are the window's)
            payloads = collect_linear(reader, path, None, start_ns, end_ns)
            channels = {topic: None for topic in payloads}
            counts = {topic: len(data) for topic, (_, data) in payloads.items()}
        for spec in required:
            if spec.topic not in channels:
                raise LogError(f"{path}: missing required topic {spec.topic} ({spec.description})")
            if counts.get(spec.topic, 1) == 0:
                raise LogError(f"{path}: the required topic {spec.topic} ({spec.description}) is in the log but "
                               "holds no messages: its recorder wrote nothing; record it for the whole run")
        present = [s for s in wanted if s.topic in channels]
        for spec in present:
            ch = channels[spec.topic]
            if ch is not None and ch.message_encoding != "json":
                raise LogError(f"{path}: topic {spec.topic} has message encoding {ch.message_encoding!r}; "
                               "the contract says 'json'")
        if summary is not None:
            ids = {channels[s.topic].id: s.topic for s in present}
            indexed = collect_indexed(fh, path, summary, ids, start_ns, end_ns)
            # None: no message index, so the mcap reader walks the chunks
            payloads = indexed if indexed is not None else collect_linear(reader, path, [s.topic for s in present],
                                                                          start_ns, end_ns)

        samples = {}
        notes: tuple[str, ...] = ()
        for spec in present:
            log_times, data = payloads.get(spec.topic) or Payloads.concat([], [])
            samples[spec.name] = _decode(path, spec, n, params.n_cables, log_times, data)
            if spec in required and (start is not None or end is not None) and len(samples[spec.name].t) < 2:
                raise LogError(f"{path}: {_window_text(start, end)} holds {len(samples[spec.name].t)} sample(s) of "
                               f"{spec.topic} (at least 2 needed){_span_text(summary)}")
            fields = {f: getattr(samples[spec.name], f) for f in ("t", *spec.field_names)}
            try:
                notes += check_plausible(spec, fields, params, accept_out_of_range_forces=accept_out_of_range_forces,
                                         simulated=TOPIC_BY_NAME["truth"].topic in channels)
            except LogError as exc:
                raise LogError(f"{path}: {exc}") from None
    return Log(path=path, params=params, metadata=neck, run_info=metadata.get(RUN_RECORD, {}),
               attachments=attachments, message_counts=counts, window=(start, end), warnings=notes, **samples)


def require_camera_frames(log: "Log", minimum: int = MIN_CAMERA_FRAMES) -> None:
    """LogError saying what is missing and what to record when ``log`` (its window) holds fewer than
    ``minimum`` camera frames: identification and diagnosis need the joint angles through the run."""
    frames = 0 if log.camera is None else len(log.camera.t)
    if frames >= minimum:
        return
    start, end = log.window
    where = _window_text(start, end) if start is not None or end is not None else "the log"
    rate = log.params.sensors.camera_rate_hz
    raise LogError(f"{log.path}: {where} holds {frames} frame(s) of /neck/camera: identification and diagnosis "
                   f"need the camera's joint angles through the run (at least {minimum} frames, "
                   f"{minimum / rate:.2g} s at the record's camera_rate_hz = {rate:g} Hz); record the camera "
                   "topic for the whole run")


def _window_text(start, end) -> str:
    return f"the window start = {start} s, end = {end} s" if end is not None and start is not None else (
        f"the window from start = {start} s" if start is not None else f"the window up to end = {end} s")


def _span_text(summary) -> str:
    stats = None if summary is None else summary.statistics
    if stats is None or not stats.message_count:
        return ""
    return f"; the log's messages span t = {stats.message_start_time * 1e-9:.6g} .. {stats.message_end_time * 1e-9:.6g} s"


# -- decoding --------------------------------------------------------------------------------------

_TEMPLATES: dict[tuple[str, int, int], tuple[bytes, bool, int]] = {}
# Structure characters and key letters become spaces; digits, signs, '.', 'e', 'E' and ',' stay.
_TO_NUMBERS = bytes(c if chr(c) in "0123456789.+-eE," else ord(" ") for c in range(256))


def _template(spec: TopicSpec, n: int, m: int):
    """(number-free skeleton of one message as the writer lays it out, whether a key holds an 'e',
    numbers per message)."""
    key = (spec.name, n, m)
    if key not in _TEMPLATES:
        lengths = spec.lengths(n, m)
        msg = {"t": 0, **{f: [0] * k for f, k in zip(spec.field_names, lengths)}}
        text = json.dumps(msg, separators=(",", ":")).encode()
        keys_have_e = any(set(f) & set("eE") for f in spec.field_names)
        _TEMPLATES[key] = (text.translate(None, _NUMBER_CHARS), keys_have_e, 1 + sum(lengths))
    return _TEMPLATES[key]


def _decode_fast(spec: TopicSpec, n: int, m: int, data: "Payloads") -> np.ndarray | None:
    """(T, K) numbers when every message has the writer's layout, else None.

    The skeleton check (all messages, numbers deleted, equal the template) guarantees every number
    sits where the template puts it; the numbers are then parsed in one C call.
    """
    skeleton, keys_have_e, k = _template(spec, n, m)
    if data.blob.translate(None, _NUMBER_CHARS) != (skeleton + b",") * (len(data) - 1) + skeleton:
        return None
    text = data.blob.translate(_TO_NUMBERS)
    if keys_have_e:            # a key like "theta" is now " e " (numbers never have a lone e)
        text = text.replace(b" e ", b"   ")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        try:
            values = np.fromstring(text, sep=",")
        except (ValueError, DeprecationWarning):
            return None
    if values.size != k * len(data):
        return None
    return values.reshape(len(data), k)


def _decode_json(path, spec: TopicSpec, n: int, m: int, log_times: np.ndarray, data: "Payloads") -> dict:
    """Field arrays through json.loads, with errors locating the first bad message."""
    def where(i):
        return f"message {i} (log_time {int(log_times[i]) * 1e-9:.6f} s)"

    try:
        msgs = json.loads(b"[" + data.blob + b"]")
    except (json.JSONDecodeError, UnicodeDecodeError):
        for i in range(len(data)):
            try:
                json.loads(data[i])
            except (json.JSONDecodeError, UnicodeDecodeError) as exc:
                raise LogError(f"{path}: {spec.topic}: {where(i)} is not valid JSON ({exc})") from None
        raise LogError(f"{path}: {spec.topic}: messages are not valid JSON") from None
    out = {}
    for name, length, kind in (("t", None, None), *zip(spec.field_names, spec.lengths(n, m),
                                                        (k for _, k, _, _ in spec.fields))):
        for i, m in enumerate(msgs):
            if not isinstance(m, dict):
                raise LogError(f"{path}: {spec.topic}: {where(i)} is not a JSON object")
            if name not in m:
                raise LogError(f"{path}: {spec.topic}: missing field {name!r} in {where(i)}")
            v = m[name]
            if length is None:
                ok = isinstance(v, (int, float)) and not isinstance(v, bool)
                if not ok:
                    raise LogError(f"{path}: {spec.topic}: field 't' of {where(i)} is not a number: {v!r}")
            elif not isinstance(v, list) or len(v) != length:
                got = f"{len(v)} values" if isinstance(v, list) else repr(v)
                what = f"{kind}, N = {n}, m = {m} cables" if kind == "cables" else f"{kind}, N = {n}"
                raise LogError(f"{path}: {spec.topic}: field {name!r} of {where(i)} has {got}, expected "
                               f"{length} ({what} from the {NECK_RECORD!r} record)")
            elif not all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in v):
                raise LogError(f"{path}: {spec.topic}: field {name!r} of {where(i)} holds a non-number: {v!r}")
        out[name] = np.array([m[name] for m in msgs], dtype=float)
    return out


def _decode(path, spec: TopicSpec, n: int, m: int, log_times: np.ndarray, data: "Payloads"):
    lengths = spec.lengths(n, m)
    if len(data) == 0:
        fields = {"t": np.zeros(0)} | {f: np.zeros((0, k)) for f, k in zip(spec.field_names, lengths)}
    else:
        table = _decode_fast(spec, n, m, data)
        if table is None:
            fields = _decode_json(path, spec, n, m, log_times, data)
        else:
            fields, col = {"t": table[:, 0].copy()}, 1
            for f, k in zip(spec.field_names, lengths):
                fields[f] = table[:, col:col + k].copy()
                col += k
    for name, values in fields.items():
        bad = ~np.isfinite(values)
        if bad.any():
            i = int(np.flatnonzero(bad.reshape(len(values), -1).any(axis=1))[0])
            raise LogError(f"{path}: {spec.topic}: field {name!r} of message {i} holds NaN or infinity")
    t = fields["t"]
    mismatch = np.abs(t * 1e9 - log_times) > _T_TOLERANCE_NS
    if mismatch.any():
        i = int(np.flatnonzero(mismatch)[0])
        raise LogError(f"{path}: {spec.topic}: message {i} has t = {float(t[i])!r} s but log_time = {int(log_times[i])} ns "
                       "(the contract: log_time = round(t * 1e9))")
    back = np.flatnonzero(np.diff(t) <= 0)
    if back.size:
        i = int(back[0]) + 1
        raise LogError(f"{path}: {spec.topic}: time not increasing at message {i}: t = {float(t[i])!r} s after "
                       f"{float(t[i - 1])!r} s")
    return _SAMPLES[spec.name](**fields)
