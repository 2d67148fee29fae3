"""Zero-phase filters of the pre-processing (:mod:`identification.preprocessing`, paper §5.2.1).

Winter's residual analysis for the cutoffs (:func:`residual_cutoff`), the zero-phase Butterworth
low-pass (:func:`lowpass`: ``scipy.signal.sosfiltfilt`` bit for bit, compiled) and the staged
zero-phase decimation (:func:`decimate`: ``scipy.signal.decimate`` bit for bit, its filter's
coefficients derived once); the module docstring of :mod:`identification.preprocessing` says
why each is chosen.  Frequencies in Hz, signals along ``axis`` (default 0).

Usage::

    from identification.filtering import decimate, lowpass, residual_cutoff
    cut = residual_cutoff(theta, 500.0)                  # theta (T, m) rad at 500 Hz
    slow = decimate(lowpass(theta, 500.0, cut.hz), 16)   # 31.25 Hz
"""

from __future__ import annotations

import functools
from typing import NamedTuple

import numpy as np
import numpy.typing as npt
from scipy import signal

from neck_sim.jit import kernel

__all__ = ["CutoffChoice", "residual_cutoff", "lowpass", "decimation_factor", "decimate"]


class CutoffChoice(NamedTuple):
    """A cutoff (Hz) with how it was chosen: per-channel cutoffs and noise rms (residual analysis)."""

    hz: float
    method: str                       # "residual analysis (Winter)" or "given"
    per_channel_hz: tuple = ()
    noise_rms: tuple = ()             # intercept a of the residual line, signal units


def lowpass(x: npt.ArrayLike, fs: float, cutoff_hz: float, order: int = 4, axis: int = 0) -> np.ndarray:
    """Zero-phase Butterworth low-pass (forward and reverse) along ``axis``: ``scipy.signal.
    sosfiltfilt``'s arithmetic bit for bit (odd extension of 3 x its taps at both ends, each pass
    started from ``sosfilt_zi`` times its first sample, sosfilt's direct form II transposed), in one
    compiled call with the design cached: the residual analysis filters a short signal at 120
    cutoffs on every bootstrap replicate, where scipy's per-call set-up cost more than the filtering."""
    nyq = 0.5 * fs
    if not 0 < cutoff_hz < nyq:
        raise ValueError(f"cutoff: {cutoff_hz:.4g} Hz must lie in (0, {nyq:.4g}) Hz (Nyquist at {fs:.4g} Hz)")
    sos, zi, edge = _butter_sos(int(order), float(cutoff_hz), float(fs))
    x0 = np.asarray(x, dtype=float)
    if axis != 0:           # the usual axis 0 skips moveaxis's checks: 120 calls per residual analysis
        x0 = np.moveaxis(x0, axis, 0)
    if x0.shape[0] <= edge:
        raise ValueError(f"lowpass: {x0.shape[0]} samples; an order-{order} zero-phase filter needs more than {edge}")
    y = _filtfilt(sos, zi, np.ascontiguousarray(x0.reshape(x0.shape[0], -1)), edge).reshape(x0.shape)
    return y if axis == 0 else np.moveaxis(y, 0, axis)


@kernel
def _filtfilt(sos, zi, x, edge):        # pragma: no cover  (compiled)
    # channels innermost: each channel's arithmetic is the same sequence as one channel alone (bit
    # for bit), and the independent channels vectorise (a 10-joint camera: 2.9x faster)
    T, C = x.shape
    S = sos.shape[0]
    L = T + 2 * edge
    out = np.empty((T, C))
    ext = np.empty((L, C))
    z0 = np.empty((S, C))
    z1 = np.empty((S, C))
    for k in range(edge):                   # odd extension, as scipy's odd_ext
        for c in range(C):
            ext[k, c] = 2 * x[0, c] - x[edge - k, c]
            ext[T + edge + k, c] = 2 * x[T - 1, c] - x[T - 2 - k, c]
    for k in range(T):
        for c in range(C):
            ext[edge + k, c] = x[k, c]
    for p in range(2):                      # forward, then over the reversed forward output
        first = 0 if p == 0 else L - 1
        for s in range(S):
            for c in range(C):
                z0[s, c] = zi[s, 0] * ext[first, c]
                z1[s, c] = zi[s, 1] * ext[first, c]
        for i in range(L):
            n = i if p == 0 else L - 1 - i
            for s in range(S):
                b0, b1, b2, a1, a2 = sos[s, 0], sos[s, 1], sos[s, 2], sos[s, 4], sos[s, 5]
                for c in range(C):
                    x_cur = ext[n, c]
                    x_new = b0 * x_cur + z0[s, c]
                    z0[s, c] = b1 * x_cur - a1 * x_new + z1[s, c]
                    z1[s, c] = b2 * x_cur - a2 * x_new
                    ext[n, c] = x_new
    for k in range(T):
        for c in range(C):
            out[k, c] = ext[edge + k, c]
    return out


# room for both residual analyses' 120 candidates (motors and camera) and a bootstrap's new cutoffs:
# at 256 the motors' candidates were designed again for every log of a series
@functools.lru_cache(maxsize=4096)
def _butter_sos(order: int, cutoff_hz: float, fs: float) -> tuple[np.ndarray, np.ndarray, int]:
    """(sos, sosfilt_zi, pad length) of a Butterworth low-pass, as ``sosfiltfilt`` derives them."""
    sos = signal.butter(order, cutoff_hz, btype="low", fs=fs, output="sos")
    ntaps = 2 * sos.shape[0] + 1 - min(int((sos[:, 2] == 0).sum()), int((sos[:, 5] == 0).sum()))
    sos.flags.writeable = False
    zi = signal.sosfilt_zi(sos)
    zi.flags.writeable = False
    return sos, zi, 3 * ntaps


def residual_cutoff(x: npt.ArrayLike, fs: float, *, order: int = 4, n_candidates: int = 120,
                    fit_band: tuple[float, float] = (0.5, 0.95)) -> CutoffChoice:
    """Winter's residual analysis: the cutoff (Hz) of a zero-phase Butterworth for ``x`` (T, C).

    R(f_c) = rms(x - lowpass(x, f_c)) on candidates from 1 % to 95 % of Nyquist; a line fitted to
    R over ``fit_band`` (fractions of Nyquist, where only noise is left) gives the noise rms a as
    its value at f_c = 0; the cutoff is the lowest f_c with R(f_c) <= a (linear interpolation
    between candidates).  Channels whose residual never reaches a (noise-free data) get the top
    candidate.  Returns the largest channel cutoff, and each channel's cutoff and a.
    """
    x = np.asarray(x, dtype=float)
    if x.ndim == 1:
        x = x[:, None]
    if x.ndim != 2 or x.shape[0] < 32:
        raise ValueError(f"residual_cutoff: expected (T >= 32, C) samples, got shape {x.shape}")
    nyq = 0.5 * fs
    fc = np.linspace(0.01, 0.95, n_candidates) * nyq
    band = (fc >= fit_band[0] * nyq) & (fc <= fit_band[1] * nyq)
    res = np.full((n_candidates, x.shape[1]), np.nan)        # NaN: never read (below)
    res[band] = _residuals(x, fs, fc, order, np.nonzero(band)[0])
    slope, intercept = np.polyfit(fc[band], res[band], 1)
    # the other candidates from the lowest up, until every channel's first crossing is among them:
    # those between the crossings and the band are never read (a third of the camera's candidates),
    # nor those above a channel's own crossing (left NaN: the camera's 10 channels cross at 2-6 Hz)
    rest = np.nonzero(~band)[0]
    k = 0
    while k < rest.size:
        todo = ~((intercept <= 0) | np.any(res[: rest[k]] <= intercept, axis=0))
        if not todo.any():
            break
        step = max(1, _LANES // int(np.count_nonzero(todo)))
        rows = rest[k:k + step]
        res[np.ix_(rows, np.nonzero(todo)[0])] = _residuals(x, fs, fc, order, rows, todo)
        k += step
    chosen = np.empty(x.shape[1])
    for c in range(x.shape[1]):
        below = np.nonzero(res[:, c] <= intercept[c])[0]
        if below.size == 0 or intercept[c] <= 0:
            chosen[c] = fc[-1]
            continue
        i = below[0]
        if i == 0:
            chosen[c] = fc[0]
        else:                               # interpolate the crossing between candidates i-1, i
            r0, r1 = res[i - 1, c], res[i, c]
            w = (r0 - intercept[c]) / (r0 - r1) if r0 != r1 else 1.0
            chosen[c] = fc[i - 1] + w * (fc[i] - fc[i - 1])
    return CutoffChoice(float(chosen.max()), "residual analysis (Winter)", tuple(chosen.tolist()),
                        tuple(np.maximum(intercept, 0.0).tolist()))


def _residuals(x: np.ndarray, fs: float, fc: np.ndarray, order: int, rows: np.ndarray,
               channels: np.ndarray | None = None) -> np.ndarray:
    """R(f_c) = rms(x - lowpass(x, f_c)) per candidate ``fc[rows]`` and channel, (K, C), for x (T, C)
    (of the ``channels`` (C,) bool alone when given: (K, count)).

    ``np.sqrt(np.mean((x - lowpass(x, fs, f, order)) ** 2, axis=0))`` for every f in ``fc``, bit
    for bit: with two channels or more numpy sums a (T, C) array over axis 0 row after row, as the
    kernel does; one channel it sums pairwise, so that case keeps numpy.  One compiled call for all
    candidates, with their designs stacked once per (order, candidates, rate): a bootstrap replicate
    analyses its camera angles again, where 120 calls' set-up cost more than the filtering."""
    if x.shape[1] < 2:
        return np.stack([np.sqrt(np.mean((x - lowpass(x, fs, f, order)) ** 2, axis=0)) for f in fc[rows]])
    sos, zi, edge = _candidate_designs(int(order), tuple(fc.tolist()), float(fs))
    if x.shape[0] <= edge:
        raise ValueError(f"lowpass: {x.shape[0]} samples; an order-{order} zero-phase filter needs more than {edge}")
    # the kernel's channels are independent recursions: a subset gives the same numbers, even one
    # channel (where numpy's own mean would sum pairwise)
    x = x if channels is None else x[:, channels]
    return _residual_rms(sos[rows], zi[rows], np.ascontiguousarray(x), edge, _LANES)


#: Independent filter recursions :func:`_residual_rms` runs side by side (a few AVX registers' worth).
_LANES = 64


@functools.lru_cache(maxsize=16)
def _candidate_designs(order: int, fc: tuple, fs: float) -> tuple[np.ndarray, np.ndarray, int]:
    """:func:`_butter_sos` of every candidate cutoff stacked: sos (K, S, 6), zi (K, S, 2), pad length."""
    designs = []
    for f in fc:
        if not 0 < f < 0.5 * fs:
            raise ValueError(f"cutoff: {f:.4g} Hz must lie in (0, {0.5 * fs:.4g}) Hz (Nyquist at {fs:.4g} Hz)")
        designs.append(_butter_sos(order, f, fs))
    if len({d[2] for d in designs}) != 1:            # a Butterworth low-pass: one pad length for all
        raise ValueError("residual analysis: the candidate filters differ in pad length")
    sos, zi = np.stack([d[0] for d in designs]), np.stack([d[1] for d in designs])
    sos.flags.writeable = False
    zi.flags.writeable = False
    return sos, zi, designs[0][2]


@kernel
def _residual_rms(sos, zi, x, edge, lanes):       # pragma: no cover  (compiled)
    # per candidate and channel: _filtfilt's arithmetic, then the sum of squares row after row
    # (numpy's order for a (T, C >= 2) array over axis 0), divided by T, square root.  Blocks of
    # candidates run side by side as ~``lanes`` independent recursions (candidate, channel)
    # innermost: the same operations per recursion, but they vectorise (3 camera channels alone
    # would wait on each sample's recursion)
    T, C = x.shape
    K, S = sos.shape[0], sos.shape[1]
    B = max(1, min(K, lanes // C))
    W = B * C
    L = T + 2 * edge
    res = np.empty((K, C))
    ext = np.empty((L, W))
    coef = np.empty((S, 5, W))
    z0 = np.empty((S, W))
    z1 = np.empty((S, W))
    acc = np.empty(W)
    for k0 in range(0, K, B):
        nb = min(B, K - k0)
        w = nb * C
        for j in range(nb):
            for s in range(S):
                for c in range(C):
                    coef[s, 0, j * C + c] = sos[k0 + j, s, 0]
                    coef[s, 1, j * C + c] = sos[k0 + j, s, 1]
                    coef[s, 2, j * C + c] = sos[k0 + j, s, 2]
                    coef[s, 3, j * C + c] = sos[k0 + j, s, 4]
                    coef[s, 4, j * C + c] = sos[k0 + j, s, 5]
        for k in range(edge):                   # odd extension, as scipy's odd_ext
            for j in range(nb):
                for c in range(C):
                    ext[k, j * C + c] = 2 * x[0, c] - x[edge - k, c]
                    ext[T + edge + k, j * C + c] = 2 * x[T - 1, c] - x[T - 2 - k, c]
        for k in range(T):
            for j in range(nb):
                for c in range(C):
                    ext[edge + k, j * C + c] = x[k, c]
        for p in range(2):                      # forward, then over the reversed forward output
            first = 0 if p == 0 else L - 1
            for s in range(S):
                for j in range(nb):
                    for c in range(C):
                        z0[s, j * C + c] = zi[k0 + j, s, 0] * ext[first, j * C + c]
                        z1[s, j * C + c] = zi[k0 + j, s, 1] * ext[first, j * C + c]
            for i in range(L):
                n = i if p == 0 else L - 1 - i
                for s in range(S):
                    for q in range(w):
                        x_cur = ext[n, q]
                        x_new = coef[s, 0, q] * x_cur + z0[s, q]
                        z0[s, q] = coef[s, 1, q] * x_cur - coef[s, 3, q] * x_new + z1[s, q]
                        z1[s, q] = coef[s, 2, q] * x_cur - coef[s, 4, q] * x_new
                        ext[n, q] = x_new
        for q in range(w):
            acc[q] = 0.0
        for t in range(T):
            for j in range(nb):
                for c in range(C):
                    d = x[t, c] - ext[edge + t, j * C + c]
                    acc[j * C + c] += d * d
        for j in range(nb):
            for c in range(C):
                res[k0 + j, c] = np.sqrt(acc[j * C + c] / T)
    return res


def decimation_factor(fs: float, camera_rate_hz: float) -> int:
    """Largest integer q with fs / q >= the camera rate (500 Hz, 30 Hz -> 16, i.e. 31.25 Hz)."""
    if not (fs > 0 and camera_rate_hz > 0):
        raise ValueError(f"rates must be positive, got {fs}, {camera_rate_hz}")
    return max(1, int(np.floor(fs / camera_rate_hz + 1e-9)))


def _stages(q: int) -> list[int]:
    """Factors of q, each at most 13 (scipy's advice for IIR decimation), largest first."""
    stages, rest = [], q
    while rest > 1:
        f = next((d for d in range(min(rest, 13), 1, -1) if rest % d == 0), None)
        if f is None:
            raise ValueError(f"decimation factor {q} has a prime factor above 13; use a rate with "
                             f"small factors")
        stages.append(f)
        rest //= f
    return stages


@functools.lru_cache(maxsize=32)
def _antialias(q: int) -> signal.dlti:
    """scipy.signal.decimate's default filter (Chebyshev I, order 8, 0.05 dB, 0.8/q) with DC gain 1."""
    b, a = signal.cheby1(8, 0.05, 0.8 / q)
    return signal.dlti(b * (a.sum() / b.sum()), a)


@functools.lru_cache(maxsize=32)
def _antialias_coefficients(q: int) -> tuple[np.ndarray, ...]:
    """What ``scipy.signal.decimate`` and ``filtfilt`` derive from :func:`_antialias` (q) on every
    call, derived once: (b, a, lfilter_zi) when a pole is complex (scipy's transfer-function
    branch), else (sos,) (its second-order sections)."""
    f = _antialias(q)
    system = f._as_zpk()          # a polynomial root finding: the per-call cost saved here
    if any(np.iscomplex(system.poles)) or np.iscomplex(system.gain):
        tf = f._as_tf()
        b, a = np.atleast_1d(np.array(tf.num)), np.atleast_1d(np.array(tf.den))
        out: tuple[np.ndarray, ...] = (b, a, signal.lfilter_zi(b, a))
    else:
        out = (np.asarray(signal.zpk2sos(system.zeros, system.poles, system.gain), dtype=float),)
    for c in out:
        c.flags.writeable = False
    return out


def _filtfilt_tf(b: np.ndarray, a: np.ndarray, zi: np.ndarray, x: np.ndarray) -> np.ndarray:
    """``scipy.signal.filtfilt(b, a, x, axis=0)`` (odd extension of 3 max(len(a), len(b)) samples,
    each pass of ``lfilter`` started from ``zi`` times its first sample) with ``zi`` given."""
    edge = 3 * max(a.size, b.size)
    if x.shape[0] <= edge:
        raise ValueError(f"decimate: {x.shape[0]} samples; its zero-phase anti-aliasing filter needs more than {edge}")
    ext = np.concatenate((2 * x[:1] - x[edge:0:-1], x, 2 * x[-1:] - x[-2:-(edge + 2):-1]), axis=0)
    z = zi.reshape((zi.size,) + (1,) * (x.ndim - 1))
    y, _ = signal.lfilter(b, a, ext, axis=0, zi=z * ext[:1])
    y, _ = signal.lfilter(b, a, y[::-1], axis=0, zi=z * y[-1:])
    return y[::-1][edge:-edge]


def decimate(x: npt.ArrayLike, q: int, axis: int = 0) -> np.ndarray:
    """``scipy.signal.decimate`` by q in stages of at most 13, zero phase, unit DC gain.

    Output sample k is input sample k*q (the zero-phase filter does not shift the signal).  Each
    stage is scipy's zero-phase IIR decimation bit for bit, with what scipy derives from the filter
    on every call derived once (:func:`_antialias_coefficients`): the bootstrap decimates every
    replicate's signals again.
    """
    y = np.moveaxis(np.asarray(x, dtype=float), axis, 0)
    for f in _stages(q):
        c = _antialias_coefficients(f)
        y = (_filtfilt_tf(*c, y) if len(c) == 3 else signal.sosfiltfilt(c[0], y, axis=0))[::f]
    return np.moveaxis(y, 0, axis)
