"""The message payloads of an MCAP log, per topic, without decoding them: from the chunk and
message indexes (a time window reads only its chunks; each message is found by its offset, so
gathering is vectorised), or through the ``mcap`` library's reader for files without them.

Damage (a truncated file, a corrupt chunk, an index that does not point at its messages) raises
:class:`~neck_sim.logs.contract.LogError` naming it.  :mod:`neck_sim.logs.reader` decodes and
validates what is collected here.
"""

from __future__ import annotations

import struct
import zlib

import numpy as np
from mcap.exceptions import McapError

from neck_sim.logs.contract import LogError

__all__ = ["Payloads", "collect_indexed", "collect_linear", "READ_ERRORS"]

_OP_CHUNK, _OP_MESSAGE_INDEX, _OP_MESSAGE = 0x06, 0x07, 0x05
READ_ERRORS = (McapError, struct.error, ValueError, KeyError, IndexError, EOFError, OSError)
"""What the mcap library and the byte parsing raise on a damaged file."""


def collect_linear(reader, path, topics, start_ns, end_ns) -> dict:
    """topic -> (log_times, payloads) through the mcap library (files without message index)."""
    out: dict[str, tuple[list, list]] = {}
    try:
        for _, channel, message in reader.iter_messages(topics=topics, log_time_order=False,
                                                        starting_at=start_ns, ending_before=end_ns):
            times, data = out.setdefault(channel.topic, ([], []))
            times.append(message.log_time)
            data.append(bytes(message.data))
    except READ_ERRORS as exc:
        raise LogError(f"{path}: corrupt MCAP data [{exc}]") from None
    return {topic: (np.array(t, dtype=np.int64), Payloads.from_list(d)) for topic, (t, d) in out.items()}


def _decompress(path, compression: str, data: bytes, size: int) -> bytes:
    try:
        if compression == "zstd":
            import zstandard
            return zstandard.ZstdDecompressor().decompress(data, max_output_size=size)
        if compression == "lz4":
            import lz4.frame
            return lz4.frame.decompress(data)
        if compression == "":
            return data
    except Exception as exc:       # zstd/lz4 raise their own error types on corrupt data
        raise LogError(f"{path}: corrupt chunk: {compression} decompression failed ({exc})") from None
    raise LogError(f"{path}: unsupported chunk compression {compression!r}")


def _gather_u(arr: np.ndarray, offsets: np.ndarray, nbytes: int) -> np.ndarray:
    """Little-endian unsigned integers of ``nbytes`` bytes at ``offsets`` of a uint8 array."""
    idx = offsets[:, None] + np.arange(nbytes)
    return arr[idx].copy().view(f"<u{nbytes}").ravel()


def collect_indexed(fh, path, summary, ids: dict[int, str], start_ns, end_ns) -> dict | None:
    """topic -> (log_times, payloads) from the chunk and message indexes; None without them."""
    out: dict[str, tuple[list, list]] = {topic: ([], []) for topic in ids.values()}
    if not summary.chunk_indexes:          # unchunked file: messages sit in the data section
        return None
    chunks = sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset)
    for ci in chunks:
        if start_ns is not None and ci.message_end_time < start_ns:
            continue
        if end_ns is not None and ci.message_start_time >= end_ns:
            continue
        if not ci.message_index_offsets:
            return None
        wanted = [cid for cid in ids if cid in ci.message_index_offsets]
        if not wanted:
            continue
        fh.seek(ci.chunk_start_offset)
        raw = fh.read(ci.chunk_length + ci.message_index_length)
        if len(raw) != ci.chunk_length + ci.message_index_length:
            raise LogError(f"{path}: truncated file: chunk at byte {ci.chunk_start_offset} runs past the end")
        try:
            if raw[0] != _OP_CHUNK:
                raise LogError(f"{path}: corrupt index: no chunk at byte {ci.chunk_start_offset}")
            _, _, size, crc, clen = struct.unpack_from("<QQQII", raw, 9)
            compression = raw[41:41 + clen].decode()
            (rlen,) = struct.unpack_from("<Q", raw, 41 + clen)
            body = raw[49 + clen:49 + clen + rlen]
        except (struct.error, UnicodeDecodeError):
            raise LogError(f"{path}: corrupt chunk header at byte {ci.chunk_start_offset}") from None
        buf = _decompress(path, compression, body, size)
        if len(buf) != size or (crc != 0 and zlib.crc32(buf) != crc):
            raise LogError(f"{path}: corrupt chunk at byte {ci.chunk_start_offset}: CRC/size mismatch")
        arr = np.frombuffer(buf, dtype=np.uint8)
        for cid in wanted:
            topic = ids[cid]
            off = ci.message_index_offsets[cid] - ci.chunk_start_offset
            try:
                op, _, ch, nbytes = struct.unpack_from("<BQHI", raw, off)
            except struct.error:
                raise LogError(f"{path}: corrupt message index after chunk at byte {ci.chunk_start_offset}") from None
            if op != _OP_MESSAGE_INDEX or ch != cid or off + 15 + nbytes > len(raw) or nbytes % 16:
                raise LogError(f"{path}: corrupt message index for {topic} after chunk at byte {ci.chunk_start_offset}")
            entries = np.frombuffer(raw, dtype="<u8", count=nbytes // 8, offset=off + 15).reshape(-1, 2)
            entries = entries[np.argsort(entries[:, 1], kind="stable")]     # file order
            times, offsets = entries[:, 0].astype(np.int64), entries[:, 1].astype(np.int64)
            keep = np.ones(len(times), bool)
            if start_ns is not None:
                keep &= times >= start_ns
            if end_ns is not None:
                keep &= times < end_ns
            times, offsets = times[keep], offsets[keep]
            if len(offsets) == 0:
                continue
            if offsets.max() + 31 > len(buf):
                raise LogError(f"{path}: corrupt message index for {topic}: offset past the chunk end")
            lengths = _gather_u(arr, offsets + 1, 8).astype(np.int64)
            ok = ((arr[offsets] == _OP_MESSAGE) & (_gather_u(arr, offsets + 9, 2) == cid)
                  & (_gather_u(arr, offsets + 15, 8).astype(np.int64) == times)
                  & (offsets + 9 + lengths <= len(buf)) & (lengths >= 22))
            if not ok.all():
                raise LogError(f"{path}: corrupt message index for {topic}: it does not point at its messages")
            out[topic][0].append(times)
            out[topic][1].append(_gather_payloads(buf, offsets + 31, lengths - 22))
    return {topic: Payloads.concat(t, d) for topic, (t, d) in out.items()}


def _gather_payloads(buf: bytes, starts: np.ndarray, sizes: np.ndarray) -> "Payloads":
    """Payloads [starts, starts + sizes) of ``buf`` joined with commas (slicing is ~0.1 us each)."""
    first = np.zeros(len(starts), np.int64)
    first[1:] = np.cumsum(sizes[:-1] + 1)
    blob = b",".join([buf[a:b] for a, b in zip(starts.tolist(), (starts + sizes).tolist())])
    return Payloads(blob, first, sizes)


class Payloads:
    """Message payloads of one topic: ``blob`` = payloads joined by commas, with their bounds
    (``first`` (T,) offsets into ``blob``, ``sizes`` (T,) bytes)."""

    def __init__(self, blob: bytes, first: np.ndarray, sizes: np.ndarray):
        self.blob, self.first, self.sizes = blob, first, sizes

    def __len__(self) -> int:
        return len(self.first)

    def __getitem__(self, i: int) -> bytes:
        return self.blob[self.first[i]:self.first[i] + self.sizes[i]]

    @classmethod
    def from_list(cls, data: list) -> "Payloads":
        sizes = np.array([len(d) for d in data], dtype=np.int64)
        first = np.zeros(len(data), np.int64)
        first[1:] = np.cumsum(sizes[:-1] + 1)
        return cls(b",".join(data), first, sizes)

    @classmethod
    def concat(cls, times: list, parts: list) -> tuple[np.ndarray, "Payloads"]:
        if not parts:
            return np.zeros(0, np.int64), cls(b"", np.zeros(0, np.int64), np.zeros(0, np.int64))
        shift = np.cumsum([0] + [len(p.blob) + 1 for p in parts[:-1]])
        first = np.concatenate([p.first + d for p, d in zip(parts, shift)])
        sizes = np.concatenate([p.sizes for p in parts])
        return np.concatenate(times), cls(b",".join(p.blob for p in parts), first, sizes)
