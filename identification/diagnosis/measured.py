"""The measured signals of one log, prepared once for every model fit of the diagnosis.

Observations and regressors on the slow grid of :func:`identification.preprocessing.prepare`
(the two blocks of equations are described in :mod:`identification.diagnosis.candidates`).

**Parallel filtering.** Motor-side regressors are nonlinear in the motor speed (a sign-like
friction), so they are computed at the control rate from the encoders' speed (filtered at the motor
cutoff only) and then pass through exactly the filter and decimation chain the observations pass
through (:meth:`MeasuredData.to_slow`): both sides of every equation see the same filter.
"""

from __future__ import annotations

import copy
import dataclasses
import math

import numpy as np

from neck_sim.analytic import cable_lengths, linkage_dynamics, transmission_matrix
from neck_sim.params import NeckParams

from identification import regressors as reg
from identification.preprocessing import Measurements, PreprocessSettings, Prepared, decimate, lowpass, prepare

__all__ = ["MeasuredData"]


class MeasuredData:
    """The measured signals of one log, prepared once for every model fit.

    Built from measured topics only (:class:`~identification.preprocessing.Measurements`) and the
    nominal constants ``params`` (geometry, drive, springs, masses; never friction or cables).
    Shapes: T control-rate samples, S slow-grid samples, N joints, C = m cables (the routing's).
    The effects' columns read it through :class:`identification.diagnosis.columns.ColumnData`.
    """

    def __init__(self, meas: Measurements, params: NeckParams, settings: PreprocessSettings | None = None,
                 *, slack_threshold: float = 2.0, slack_margin_s: float = 0.1, reuse: Prepared | None = None):
        self.params = params
        self.settings = settings or PreprocessSettings()
        # reuse: prepare()'s, a preparation of the same motor arrays whose motor signals are taken
        self.prep: Prepared = prepare(meas, params, self.settings, camera_rate_hz=params.sensors.camera_rate_hz,
                                      reuse=reuse)
        prep = self.prep
        if not prep.has_camera:
            raise ValueError("camera: the diagnosis needs the /neck/camera joint angles (torque block eq 51 and "
                             "elongations eq 27); this log has none")
        self.n = params.n_joints
        self.C = params.n_cables
        act = params.actuation
        self.ratio = act.R / act.r_d
        fast = prep.fast
        self.t_fast = fast.t
        self.dt = float(np.median(np.diff(fast.t)))
        self.theta_dot_fast = fast.theta_dot
        self.theta_ddot_fast = np.gradient(fast.theta_dot, self.dt, axis=0)
        self.force_fast = fast.force
        self._slow_index()
        self.t = prep.t
        self.S = prep.t.size
        # camera-side quantities on the slow grid
        self.alpha = prep.alpha
        self.Z = transmission_matrix(prep.alpha, params)
        lk = linkage_dynamics(prep.alpha, prep.alpha_dot, params)
        self.linkage = np.einsum("sij,sj->si", lk.M, prep.alpha_ddot) + lk.c + lk.g
        self.x = prep.x_c
        self.x_dot = prep.x_c_dot
        self.theta_dot = prep.theta_dot
        self._y_cache: dict[float, tuple[np.ndarray, np.ndarray]] = {}
        self._col_cache: dict = {}
        self._shifted: dict[float, "MeasuredData"] = {}
        self.camera_shift = 0.0
        y_fast, y = self.observations(0.0)
        # slack samples: eq (41) tension with a first friction estimate (torque rows), as in §5.  Not
        # x_c <= 0: with a pretension the measured elongation is negative on a taut cable
        a = reg.slow_friction_basis(prep, params)
        W = (self.Z * a[:, None, :]).reshape(-1, self.C)
        yT = (np.einsum("sij,sj->si", self.Z, y) - self.linkage).reshape(-1)
        try:
            fs0 = np.clip(np.linalg.lstsq(W, yT, rcond=None)[0], 0.0, None)
        except np.linalg.LinAlgError:
            fs0 = np.zeros(self.C)
        self.f_s0 = fs0
        t_est = y - a * fs0
        self.tension0 = t_est        # (S, C) N: that first tension estimate (what the log's tension ranges are read from)
        slack = t_est < slack_threshold
        pad = int(math.ceil(slack_margin_s * prep.rate_hz))
        if pad > 0 and slack.any():
            kernel = np.ones(2 * pad + 1)
            slack = np.stack([np.convolve(slack[:, i].astype(float), kernel, mode="same") > 0
                              for i in range(self.C)], axis=1)
        self.taut = ~slack
        self.activity = np.linalg.norm(self.theta_dot, axis=1)

    # -- the filter chain of prepare(), for any control-rate signal
    def _slow_index(self) -> None:
        prep, s = self.prep, self.settings
        q = prep.decimation
        t_grid = self.t_fast[::q]
        tc = prep.camera[0]
        lo, hi = max(t_grid[0], tc[0]), min(t_grid[-1], tc[-1])
        idx = np.nonzero((t_grid >= lo) & (t_grid <= hi))[0]
        tg = t_grid[idx]
        keep = (tg >= tg[0] + s.trim_s) & (tg <= tg[-1] - s.trim_s)
        if not (np.count_nonzero(keep) == prep.t.size and np.allclose(tg[keep], prep.t)):
            raise RuntimeError("diagnosis: cannot reproduce the slow grid of identification.preprocessing.prepare")
        self._grid = (t_grid.size, idx, keep)
        self._common = prep.cutoffs["common"].hz
        self._motor_cut = prep.cutoffs["motors"].hz

    def motor_lowpass(self, v: np.ndarray) -> np.ndarray:
        """A control-rate signal (T, ...) through the encoders' low-pass (the motor cutoff), still
        at the control rate: what theta_dot_fast went through."""
        return lowpass(v, self.prep.motor_rate_hz, self._motor_cut, self.settings.filter_order)

    def to_slow(self, v: np.ndarray) -> np.ndarray:
        """A control-rate signal (T, ...) through prepare()'s chain: motor-cutoff low-pass,
        decimation, camera window, common-bandwidth low-pass, trimming -> (S, ...)."""
        prep, s = self.prep, self.settings
        n_grid, idx, keep = self._grid
        v = self.motor_lowpass(v)
        v = decimate(v, prep.decimation)[:n_grid][idx]
        if s.common_bandwidth and self._common < 0.5 * prep.rate_hz * 0.95:
            v = lowpass(v, prep.rate_hz, self._common, s.filter_order)
        return v[keep]

    def delayed_force(self, delay: float) -> np.ndarray:
        """The force acting on the cables if it lags the command by ``delay`` s, (T, C) N.

        A command sampled at t_k acts over [t_k, t_k + dt] (zero-order hold): on average it is
        half a period late even without any delay, so the shift is ``delay + dt / 2``; linear
        interpolation between control periods.
        """
        tq = self.t_fast - (delay + 0.5 * self.dt)
        return np.stack([np.interp(tq, self.t_fast, self.force_fast[:, j]) for j in range(self.C)], axis=1)

    def observations(self, delay: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        """(y_C fast (T, C), y_C slow (S, C)): f(t - delay) - (R/r_d) I_a theta_ddot, N."""
        key = round(float(delay), 6)
        if key not in self._y_cache:
            ia = self.params.actuation.I_a
            y_fast = self.delayed_force(key) - self.ratio * ia * self.theta_ddot_fast
            self._y_cache[key] = (y_fast, self.to_slow(y_fast))
            if len(self._y_cache) > 24:
                self._y_cache.pop(next(iter(self._y_cache)))
        return self._y_cache[key]

    def observations_per_motor(self, delays: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`observations` with a delay (C,) s of its own on each motor's command: cable j's
        column is that of ``observations(delays[j])`` (the filter chain acts column by column)."""
        delays = np.asarray(delays, dtype=float)
        if delays.shape != (self.C,):
            raise ValueError(f"observations_per_motor: expected {self.C} delays, got shape {delays.shape}")
        if np.all(delays == delays[0]):
            return self.observations(float(delays[0]))
        cols = [self.observations(float(d)) for d in delays]
        return (np.stack([c[0][:, j] for j, c in enumerate(cols)], axis=1),
                np.stack([c[1][:, j] for j, c in enumerate(cols)], axis=1))

    def torque_observation(self, y_slow: np.ndarray) -> np.ndarray:
        """y_T = Z y_C - M_m alpha_ddot - c_m - g, (S, N) N m."""
        return np.einsum("sij,sj->si", self.Z, y_slow) - self.linkage

    def camera_shifted(self, shift: float) -> "MeasuredData":
        """These data with the camera read ``shift`` s later (a camera that lags the encoders by
        ``shift``: the frame stamped t + shift shows the neck at t).

        Every camera-side slow-grid quantity is re-evaluated at t + shift: alpha and its
        derivatives by linear interpolation of the filtered signals (they are band-limited at the
        common cutoff, a few Hz, so a shift of a fraction of a frame interpolates exactly enough;
        the last samples repeat the end value), then Z, the linkage torque (eq 30) and the
        elongations of eq (27).  The motor side, the slow grid, the slack mask and the
        observations are unchanged.  Cached per shift (rounded to 0.1 ms).
        """
        key = round(float(shift), 4)
        if key == 0.0:
            return self
        if key not in self._shifted:
            if len(self._shifted) > 8:
                self._shifted.pop(next(iter(self._shifted)))
            self._shifted[key] = self._shift_camera(key)
        return self._shifted[key]

    def _shift_camera(self, shift: float) -> "MeasuredData":
        prep, p = self.prep, self.params
        tq = self.t + shift

        def at(v):
            return np.stack([np.interp(tq, self.t, v[:, i]) for i in range(v.shape[1])], axis=1)

        alpha, alpha_dot, alpha_ddot = at(prep.alpha), at(prep.alpha_dot), at(prep.alpha_ddot)
        Z = transmission_matrix(alpha, p, allow_outside_range=True)
        # eq (27): x_c = l_c(alpha) - l_c0 + (r_d/R) theta; d l_c / dt = -Z^T alpha_dot
        x = self.x + cable_lengths(alpha, p, allow_outside_range=True) - cable_lengths(prep.alpha, p,
                                                                                         allow_outside_range=True)
        x_dot = self.x_dot - np.einsum("snc,sn->sc", Z, alpha_dot) + np.einsum("snc,sn->sc", self.Z, prep.alpha_dot)
        out = copy.copy(self)
        out.prep = dataclasses.replace(prep, alpha=alpha, alpha_dot=alpha_dot, alpha_ddot=alpha_ddot, x_c=x,
                                       x_c_dot=x_dot)
        lk = linkage_dynamics(alpha, alpha_dot, p)
        out.alpha, out.Z, out.x, out.x_dot = alpha, Z, x, x_dot
        out.linkage = np.einsum("sij,sj->si", lk.M, alpha_ddot) + lk.c + lk.g
        out._col_cache, out._shifted, out.camera_shift = {}, {}, shift
        return out

    # what the effects' columns read (:class:`identification.diagnosis.columns.ColumnData`)
    @property
    def alpha_dot(self) -> np.ndarray:
        """(S, N) rad/s, the camera's joint speeds on the slow grid (shifted with the camera)."""
        return self.prep.alpha_dot

    @property
    def alpha_ddot(self) -> np.ndarray:
        """(S, N) rad/s^2, the camera's joint accelerations on the slow grid (shifted with the camera)."""
        return self.prep.alpha_ddot

    @property
    def theta_fast(self) -> np.ndarray:
        """(T, C) rad, the encoders at the control rate."""
        return self.prep.fast.theta

    def cached(self, key, compute):
        """``compute()`` once per ``key`` for this log (regressor columns that do not depend on the fit)."""
        if key not in self._col_cache:
            self._col_cache[key] = compute()
        return self._col_cache[key]

    @classmethod
    def from_log(cls, log, params: NeckParams | None = None, settings: PreprocessSettings | None = None,
                 **kw) -> "MeasuredData":
        """From a :class:`neck_sim.logs.Log`: its measured topics and ``neck`` record only."""
        return cls(Measurements.from_log(log), params or log.params, settings, **kw)
