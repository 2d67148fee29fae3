"""JSON messages of a fixed shape, encoded as MCAP Message records in bulk.

A log holds tens of thousands of messages whose JSON differs only in its numbers.  A
:class:`Template` is such a message written once, with :class:`Slot` placeholders where numbers
vary; :func:`message_records` then writes T messages (their numbers a (T, V) array) as MCAP Message
records in one compiled pass, numbers by orjson (shortest round-trip text, what ``json.dumps``
writes up to exponent style).  Timestamps of Foxglove's ``{"sec": ..., "nsec": ...}`` form are
slots filled from each message's log time, as integers.
"""

from __future__ import annotations

import dataclasses
import re

import numpy as np
import orjson

from neck_sim.jit import kernel

__all__ = ["Slot", "SEC", "NSEC", "Template", "template", "message_records", "render", "MESSAGE_HEADER"]

MESSAGE_HEADER = 31          # opcode (1) + record length (8) + channel, sequence, log and publish time (22)
_FLOAT, _SEC, _NSEC = 0, 1, 2


class Slot:
    """A number of a message: column ``index`` of the message's value row.

    (Not a dataclass: orjson would write a dataclass as an object instead of asking ``default``.)
    """
    __slots__ = ("index",)

    def __init__(self, index: int):
        self.index = int(index)


SEC = object()     # the seconds of the message's log time (integer)
NSEC = object()    # its nanoseconds below the second (integer)


@dataclasses.dataclass(frozen=True)
class Template:
    """A message's constant text cut at its numbers.

    pieces: the constant text, (P,) uint8, piece i being ``pieces[starts[i]:starts[i + 1]]``;
    kinds: (S,) int8, what fills each of the S = P - 1 gaps (0 a value column, 1 seconds,
    2 nanoseconds of the log time); columns: (F,) int64, the value column of each kind-0 gap, in
    text order.
    """
    pieces: np.ndarray
    starts: np.ndarray
    kinds: np.ndarray
    columns: np.ndarray


_MARK = re.compile(rb'"@@(\d+|S|N)@@"')


def _mark(value):
    if isinstance(value, Slot):
        return f"@@{value.index}@@"
    if value is SEC:
        return "@@S@@"
    if value is NSEC:
        return "@@N@@"
    raise TypeError(f"not a JSON value: {value!r}")


def template(document) -> Template:
    """The :class:`Template` of a JSON document (dicts keep their order) holding Slots, SEC, NSEC."""
    text = orjson.dumps(document, default=_mark)
    pieces, kinds, columns, last = [], [], [], 0
    for m in _MARK.finditer(text):
        pieces.append(text[last:m.start()])
        tag = m.group(1)
        kinds.append(_SEC if tag == b"S" else _NSEC if tag == b"N" else _FLOAT)
        if kinds[-1] == _FLOAT:
            columns.append(int(tag))
        last = m.end()
    pieces.append(text[last:])
    if not columns:
        raise ValueError("a template needs at least one value slot")
    starts = np.cumsum([0] + [len(p) for p in pieces]).astype(np.int64)
    return Template(np.frombuffer(b"".join(pieces), np.uint8), starts, np.array(kinds, np.int8),
                    np.array(columns, np.int64))


@kernel
def _write_int(out, w, value) -> int:
    digits = 1
    v = value
    while v >= 10:
        v //= 10
        digits += 1
    for d in range(digits - 1, -1, -1):
        out[w + d] = 48 + value % 10
        value //= 10
    return w + digits


@kernel
def _records(numbers, pieces, piece_start, kinds, channel, log_ns, out, offsets) -> int:
    """MCAP Message records of T payloads into ``out``; returns the bytes written.

    ``numbers`` is the JSON text of a (T, F) array (``[[a,b],[c,d]]``), F the kind-0 gaps; record
    r starts at ``offsets[r]`` and its payload interleaves pieces and gap fillers.
    """
    n_gaps = kinds.shape[0]
    pos = 2                                   # after "[["
    w = 0
    for r in range(log_ns.shape[0]):
        offsets[r] = w
        head = w
        out[w] = 0x05                         # opcode: Message
        w += 9                                # record length filled in below
        out[w] = channel & 0xFF
        out[w + 1] = (channel >> 8) & 0xFF
        for b in range(4):                    # sequence 0
            out[w + 2 + b] = 0
        t = log_ns[r]
        for b in range(8):                    # log_time, publish_time (= log_time)
            byte = (t >> (8 * b)) & 0xFF
            out[w + 6 + b] = byte
            out[w + 14 + b] = byte
        w += 22
        for g in range(n_gaps + 1):
            for i in range(piece_start[g], piece_start[g + 1]):
                out[w] = pieces[i]
                w += 1
            if g == n_gaps:
                break
            if kinds[g] == 1:
                w = _write_int(out, w, t // 1_000_000_000)
            elif kinds[g] == 2:
                w = _write_int(out, w, t % 1_000_000_000)
            else:
                while numbers[pos] != 44 and numbers[pos] != 93:     # up to "," or "]"
                    out[w] = numbers[pos]
                    w += 1
                    pos += 1
                pos += 1
        pos += 2                              # "],[" between rows: "]" was taken, skip ",["
        length = w - head - 9
        for b in range(8):
            out[head + 1 + b] = (length >> (8 * b)) & 0xFF
    return w


def message_records(tmpl: Template, values: np.ndarray, log_ns: np.ndarray, channel: int):
    """T messages of ``tmpl`` as MCAP Message records: (bytes (B,) uint8, record offsets (T,) int64).

    values: (T, V) float, the value rows the template's Slots index; log_ns: (T,) int64 ns >= 0.
    """
    numbers = np.ascontiguousarray(np.asarray(values, dtype=float)[:, tmpl.columns])
    text = np.frombuffer(orjson.dumps(numbers, option=orjson.OPT_SERIALIZE_NUMPY), np.uint8)
    n_time = int(np.count_nonzero(tmpl.kinds))
    out = np.empty(len(text) + len(log_ns) * (MESSAGE_HEADER + len(tmpl.pieces) + 19 * n_time), np.uint8)
    offsets = np.empty(len(log_ns), np.int64)
    size = _records(text, tmpl.pieces, tmpl.starts, tmpl.kinds, channel, np.asarray(log_ns, np.int64), out, offsets)
    return out[:size], offsets


def render(tmpl: Template, values, log_ns: int) -> bytes:
    """One message's JSON payload (bytes): ``values`` (V,) float, at log time ``log_ns``."""
    records, _ = message_records(tmpl, np.asarray(values, dtype=float)[None, :], np.array([log_ns]), 0)
    return records[MESSAGE_HEADER:].tobytes()
