"""Bulk-encoded JSON messages equal the documents they stand for, as json and MCAP read them."""

from __future__ import annotations

import json
import struct

import numpy as np
import pytest

from neck_sim.logs import jsonrecords
from neck_sim.logs.jsonrecords import NSEC, SEC, Slot


def _filled(document, row, log_ns):
    """The document with its placeholders replaced in plain Python (independent of the kernel)."""
    if isinstance(document, Slot):
        return float(row[document.index])
    if document is SEC:
        return log_ns // 1_000_000_000
    if document is NSEC:
        return log_ns % 1_000_000_000
    if isinstance(document, dict):
        return {k: _filled(v, row, log_ns) for k, v in document.items()}
    if isinstance(document, list):
        return [_filled(v, row, log_ns) for v in document]
    return document


def _records(buf: bytes):
    """(opcode, channel, sequence, log_time, publish_time, payload) of consecutive MCAP records."""
    out, pos = [], 0
    while pos < len(buf):
        opcode, length = struct.unpack_from("<BQ", buf, pos)
        channel, seq, log_time, pub_time = struct.unpack_from("<HIQQ", buf, pos + 9)
        out.append((opcode, channel, seq, log_time, pub_time, buf[pos + 31: pos + 9 + length]))
        pos += 9 + length
    return out


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_records_parse_to_the_document(seed):
    rng = np.random.default_rng(seed)
    doc = {"t": Slot(0), "stamp": {"sec": SEC, "nsec": NSEC}, "name": "a,b]\"c",
           "xs": [Slot(3), Slot(1), Slot(3)], "nested": [{"y": Slot(2), "z": 0.0, "flag": False}], "empty": []}
    tmpl = jsonrecords.template(doc)
    T = 50
    values = rng.standard_normal((T, 4)) * 10.0 ** rng.integers(-12, 12, (T, 4))
    values[0] = [0.0, -0.0, 1e300, 5e-324]
    log_ns = np.sort(rng.integers(0, 2 ** 62, T))
    log_ns[0] = 0
    buf, offsets = jsonrecords.message_records(tmpl, values, log_ns, channel=7)
    recs = _records(buf.tobytes())
    assert len(recs) == T
    assert list(offsets) == list(np.cumsum([0] + [31 + len(r[5]) for r in recs[:-1]]))
    for (opcode, channel, seq, log_time, pub_time, payload), row, ns in zip(recs, values, log_ns):
        assert (opcode, channel, seq, log_time, pub_time) == (5, 7, 0, ns, ns)
        got = json.loads(payload)
        assert got == _filled(doc, row, int(ns))
        assert isinstance(got["stamp"]["sec"], int) and isinstance(got["stamp"]["nsec"], int)


def test_contract_payload_is_what_json_dumps_writes():
    tmpl = jsonrecords.template({"t": Slot(0), "theta": [Slot(1), Slot(2)]})
    values = np.array([[0.002, 0.1 + 0.2, -3.0]])
    payload = jsonrecords.render(tmpl, values[0], 2_000_000)
    assert payload == json.dumps({"t": 0.002, "theta": [0.1 + 0.2, -3.0]}, separators=(",", ":")).encode()


def test_template_without_numbers_is_refused():
    with pytest.raises(ValueError, match="value slot"):
        jsonrecords.template({"a": 1})
