"""Pre-processing of measured data for identification (paper §5.2.1).

From the measured topics only (encoders and commanded forces at the control rate, joint angles
from the camera at about 30 Hz) to synchronised, filtered signals and their derivatives on one
slow grid:

1. **Cutoff frequencies, chosen automatically** by Winter's residual analysis (D. A. Winter,
   *Biomechanics and Motor Control of Human Movement*, 4th ed., 2009, §3.4.4.3). For a cutoff
   f_c the residual R(f_c) = rms(x - filtfilt_{f_c}(x)); above the signal's band R falls
   linearly with f_c (what is left is noise), and the straight line fitted to the upper half of
   the band meets f_c = 0 at the noise rms a.  The chosen cutoff is the lowest f_c where
   R(f_c) <= a: below it the filter starts to remove signal, above it it lets noise through.
   Per group of channels the largest cutoff wins, so no channel loses its signal.  (The paper
   cites "the method of [37]" without detail; this is the standard automatic choice.)
2. **Zero-phase Butterworth filtering** (``scipy.signal.sosfiltfilt``, forward and reverse like
   Matlab's ``filtfilt``) of theta and f at the control rate, then **central differences**
   (``numpy.gradient``) for theta_dot, theta_ddot.
3. **Decimation** by the largest integer factor q that keeps the rate at or above the camera's
   (500 Hz / 16 = 31.25 Hz for the paper's 30 Hz video), with ``scipy.signal.decimate``
   (order-8 Chebyshev type I anti-aliasing, zero phase) in stages of at most 13.  The filter's DC
   gain is normalised to 1: scipy's default even-order Chebyshev I sits at the bottom of its
   0.05 dB ripple at DC, and the forward-reverse pass squares that, so every stage would scale
   the signal by 0.9886 -- 2.3 % of a 28 rad motor angle (0.5 mm of elongation) over two stages.
4. **Camera angles linearly interpolated** onto that grid, filtered with their own automatic cutoff,
   differentiated by central differences.
5. **Common bandwidth** ("parallel filtering", as in Gautier's inverse-dynamics identification):
   every slow-grid signal that enters one regression equation is filtered with the same cutoff,
   the lower of the motor and camera cutoffs, so both sides of each equation see the same band.
6. **Elongations** by the corrected eq (27), x_c = l_c(alpha_camera) - l_c0 + (r_d/R) theta
   (sign convention of :mod:`neck_sim.analytic.cables`), and their first and second derivatives
   by central differences on the slow grid (eq 44 needs the second, erratum 4).

``fast`` keeps the control-rate signals (raw encoder angles, filtered motor speeds, commanded
forces) for the online-estimator reconstructions of §5.5 (eq 58 with a 2 ms step).

Times are used only relative to each other: a log cut at any start time gives the same result.
Shapes: T control-rate samples, K camera frames, S slow-grid samples, N joints, m cables (the
routing's, ``params.n_cables``; N + 1 on the paper's routing).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, NamedTuple

import numpy as np
import numpy.typing as npt

from identification.filtering import CutoffChoice, decimate, decimation_factor, lowpass, residual_cutoff
from neck_sim.analytic import cable_kinematics, elongation
from neck_sim.params import NeckParams

if TYPE_CHECKING:
    from neck_sim.logs import Log

__all__ = ["Measurements", "PreprocessSettings", "CutoffChoice", "FastSignals", "Prepared",
           "residual_cutoff", "lowpass", "decimation_factor", "decimate", "SlowChain", "prepare"]


def _as_series(name: str, t, x, width: int | None, *, min_len: int = 2):
    t = np.asarray(t, dtype=float)
    x = np.asarray(x, dtype=float)
    if t.ndim != 1 or t.size < min_len:
        raise ValueError(f"{name}.t: expected a 1-D time vector with at least {min_len} samples, got shape {t.shape}")
    if x.ndim != 2 or x.shape[0] != t.size or (width is not None and x.shape[1] != width):
        w = "W" if width is None else width
        raise ValueError(f"{name}: expected shape ({t.size}, {w}), got {x.shape}")
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(x))):
        raise ValueError(f"{name}: contains NaN or infinity")
    if np.any(np.diff(t) <= 0):
        k = int(np.argmax(np.diff(t) <= 0))
        raise ValueError(f"{name}.t: times must increase strictly (sample {k + 1} at {t[k + 1]!r} s "
                         f"follows {t[k]!r} s)")
    return t, x


@dataclass(frozen=True, eq=False)
class Measurements:
    """What the prototype measures (the log contract's measured topics), SI units.

    t_motor (T,) s, theta (T, m) rad motor-shaft angles (> 0 winds up), force (T, m) N
    commanded; t_camera (K,) s and alpha_camera (K, N) rad, or both None without a camera.  The
    widths m and N are the log's own: :func:`prepare` checks them against the routing.
    """

    t_motor: np.ndarray
    theta: np.ndarray
    force: np.ndarray
    t_camera: np.ndarray | None = None
    alpha_camera: np.ndarray | None = None

    def __post_init__(self):
        t, th = _as_series("motors.theta", self.t_motor, self.theta, None, min_len=64)
        _, f = _as_series("motors.force", t, self.force, th.shape[1])
        if th.shape[1] < 1:
            raise ValueError(f"motors.theta: expected at least one motor per sample, got {th.shape[1]}")
        object.__setattr__(self, "t_motor", t)
        object.__setattr__(self, "theta", th)
        object.__setattr__(self, "force", f)
        if (self.t_camera is None) != (self.alpha_camera is None):
            raise ValueError("camera: t_camera and alpha_camera must both be given or both be None")
        if self.t_camera is not None:
            tc, a = _as_series("camera.alpha", self.t_camera, self.alpha_camera, None, min_len=8)
            object.__setattr__(self, "t_camera", tc)
            object.__setattr__(self, "alpha_camera", a)

    @property
    def n_cables(self) -> int:
        """m, the number of motors (one per cable)."""
        return self.theta.shape[1]

    @property
    def n_joints(self) -> int | None:
        """N from the camera's width, None without a camera."""
        return None if self.alpha_camera is None else self.alpha_camera.shape[1]

    def check_shapes(self, params: NeckParams) -> None:
        """Raise ValueError naming the field, the expected and the found shape when these
        measurements do not fit the neck of ``params`` (m = ``params.n_cables`` motors, N joints)."""
        m, n = params.n_cables, params.n_joints
        for name, x, width, what in (("motors.theta", self.theta, m, f"{m} cables"),
                                     ("motors.force", self.force, m, f"{m} cables"),
                                     ("camera.alpha", self.alpha_camera, n, f"{n} joints")):
            if x is not None and x.shape[1] != width:
                raise ValueError(f"{name}: expected shape ({x.shape[0]}, {width}) for the routing's {what}, "
                                 f"got {x.shape}")

    @property
    def has_camera(self) -> bool:
        return self.t_camera is not None

    @classmethod
    def from_log(cls, log: Log) -> "Measurements":
        """The measured topics of a :class:`neck_sim.logs.Log` (never its simulation-truth topics)."""
        motors, cam = log.motors, getattr(log, "camera", None)
        if motors is None:
            raise ValueError(f"{log.path}: no /neck/motors samples: identification needs the encoders and forces")
        if cam is None or getattr(cam, "t", None) is None:
            return cls(motors.t, motors.theta, motors.force, None, None)
        return cls(motors.t, motors.theta, motors.force, cam.t, cam.alpha)


@dataclass(frozen=True)
class PreprocessSettings:
    """Choices of the pre-processing; None cutoffs are chosen by residual analysis."""

    filter_order: int = 4                 # Butterworth order (doubled by the forward-reverse pass)
    motor_cutoff_hz: float | None = None
    camera_cutoff_hz: float | None = None
    trim_s: float = 0.5                   # s dropped at both ends (filter and interpolation edges)
    common_bandwidth: bool = True         # filter all slow-grid signals with the lower cutoff

    def __post_init__(self):
        if int(self.filter_order) != self.filter_order or not 1 <= self.filter_order <= 10:
            raise ValueError(f"filter_order: expected an integer in 1..10, got {self.filter_order!r}")
        for name in ("motor_cutoff_hz", "camera_cutoff_hz"):
            v = getattr(self, name)
            if v is not None and not (np.isfinite(v) and v > 0):
                raise ValueError(f"{name}: must be positive, got {v!r}")
        if not (np.isfinite(self.trim_s) and self.trim_s >= 0):
            raise ValueError(f"trim_s: must be >= 0, got {self.trim_s!r}")


class FastSignals(NamedTuple):
    """Control-rate signals for the online-estimator reconstructions (§5.5), over the whole log."""

    t: np.ndarray          # (T,) s
    theta: np.ndarray      # (T, m) rad, as measured (quantised)
    theta_dot: np.ndarray  # (T, m) rad/s, filtered, central differences
    force: np.ndarray      # (T, m) N, as commanded


class SlowChain(NamedTuple):
    """How ``prepare`` takes a control-rate signal to the slow grid, to apply to any other signal.

    Motor-cutoff low-pass at ``motor_rate_hz``, decimation by q (first ``n_grid`` samples), the
    camera window ``idx``, the common-bandwidth low-pass (``common_hz``, None when not applied),
    the trimming mask ``keep``.
    """

    motor_rate_hz: float
    motor_hz: float
    q: int
    n_grid: int
    idx: np.ndarray
    common_hz: float | None
    keep: np.ndarray
    order: int

    def to_decimation(self, v: npt.ArrayLike) -> np.ndarray:
        """The chain up to the common bandwidth: motor-cutoff low-pass, decimation, camera window."""
        return self.decimated(lowpass(np.asarray(v, dtype=float), self.motor_rate_hz, self.motor_hz, self.order))

    def decimation_key(self) -> tuple:
        """What :meth:`to_decimation` depends on besides its signal."""
        return (self.motor_rate_hz, self.motor_hz, self.order, self.q, self.n_grid, self.idx.tobytes())

    def decimated(self, v: npt.ArrayLike) -> np.ndarray:
        """Decimation and the camera window: the part of the chain the common bandwidth does not change."""
        return decimate(v, self.q)[: self.n_grid][self.idx]

    def after_decimation(self, slow: np.ndarray) -> np.ndarray:
        """The rest of the chain: the common-bandwidth low-pass and the trimming."""
        if self.common_hz is not None:
            slow = lowpass(slow, self.motor_rate_hz / self.q, self.common_hz, self.order)
        return slow[self.keep]

    def __call__(self, v: npt.ArrayLike) -> np.ndarray:
        """A control-rate signal (T, ...) to the slow grid (S, ...), exactly as theta and f are."""
        return self.after_decimation(self.to_decimation(v))


@dataclass(frozen=True, eq=False)
class Prepared:
    """Synchronised slow-grid signals for the identification models (all arrays (S, ...), SI).

    alpha* and x_c* are None when the log has no camera.  ``cutoffs`` maps "motors", "camera",
    "common" to a :class:`CutoffChoice`; ``fast`` holds control-rate signals, ``camera`` the raw
    frames (t (K,), alpha (K, N)) or None; ``chain`` (a :class:`SlowChain`) takes any other
    control-rate signal to this grid the way theta and f were taken.
    """

    t: np.ndarray
    theta: np.ndarray
    theta_dot: np.ndarray
    theta_ddot: np.ndarray
    force: np.ndarray
    alpha: np.ndarray | None
    alpha_dot: np.ndarray | None
    alpha_ddot: np.ndarray | None
    x_c: np.ndarray | None
    x_c_dot: np.ndarray | None
    x_c_ddot: np.ndarray | None
    motor_rate_hz: float
    rate_hz: float
    decimation: int
    cutoffs: dict = field(default_factory=dict)
    fast: FastSignals | None = None
    camera: tuple | None = None
    chain: SlowChain | None = None
    # theta, theta_dot, theta_ddot and force decimated, before the common bandwidth: ``prepare``'s
    # ``reuse`` takes them instead of filtering and decimating the same motor samples again
    _decimated: dict | None = field(default=None, repr=False)
    # (routing, geometry, CableKinematics of alpha, alpha_dot): eq (27)'s lengths came with Z and
    # Zdot, which the joint dynamics take (``transmission_for``) instead of evaluating them again
    _cables: tuple | None = field(default=None, repr=False)
    # control-rate signals derived from the encoders, through the chain up to the common bandwidth
    # (``SlowChain.to_decimation``), by key: shared with every preparation that ``reuse``s this one
    # (the camera-noise bootstrap's replicates), whose motors and chain up to there are these
    _memo: dict = field(default_factory=dict, repr=False)

    def transmission_for(self, params: NeckParams) -> tuple[np.ndarray, np.ndarray] | None:
        """(Z, Zdot) (S, N, m) at ``alpha``, ``alpha_dot`` when prepared with the routing and
        geometry of ``params``; None otherwise (the caller evaluates them)."""
        if self._cables is None:
            return None
        routing, geometry, kin = self._cables
        if routing is not params.routing or geometry != _geometry_key(params):
            return None
        return kin.Z, kin.Zdot

    @property
    def has_camera(self) -> bool:
        return self.alpha is not None

    @property
    def n_samples(self) -> int:
        return int(self.t.size)


def _uniform_rate(t: np.ndarray, name: str) -> float:
    dt = np.diff(t)
    med = float(np.median(dt))
    bad = np.abs(dt - med) > 0.1 * med
    if np.any(bad):
        k = int(np.argmax(bad))
        raise ValueError(f"{name}: samples are not evenly spaced (gap of {dt[k]:.6g} s after t = {t[k]:.6g} s, "
                         f"typical {med:.6g} s); identification needs a uniform control-rate log")
    return 1.0 / med


def _cutoff(given: float | None, x: np.ndarray, fs: float, order: int) -> CutoffChoice:
    if given is not None:
        if not given < 0.5 * fs:
            raise ValueError(f"cutoff: {given} Hz is above the Nyquist frequency {0.5 * fs:.4g} Hz")
        return CutoffChoice(float(given), "given")
    return residual_cutoff(x, fs, order=order)


def prepare(meas: Measurements, params: NeckParams, settings: PreprocessSettings | None = None,
            *, camera_rate_hz: float | None = None, reuse: Prepared | None = None,
            transmission: bool = False) -> Prepared:
    """Filter, differentiate, decimate and synchronise ``meas`` (see the module docstring).

    ``params`` gives the nominal geometry and drive (for eq 27); ``camera_rate_hz`` (default
    ``params.sensors.camera_rate_hz``) sets the decimation factor.  ``reuse``: a preparation of the
    very same motor arrays (``reuse.fast.theta is meas.theta``, likewise the forces) with the motor
    cutoff given here, whose filtered and decimated motor signals are taken instead of computed
    again (the camera-noise bootstrap prepares the same motors with new camera frames; the result
    is the same bit for bit).  ``transmission``: eq (27)'s cable lengths in one pass with Z and
    Zdot at the camera angles, kept for the joint dynamics (``Prepared.transmission_for``; the
    camera-noise bootstrap computes both on every replicate).  Raises ValueError naming the problem
    for a log that is too short, unevenly sampled, or whose camera does not overlap it, and for a
    ``reuse`` of other motors.
    """
    s = settings or PreprocessSettings()
    n = params.n_joints
    meas.check_shapes(params)
    fs = _uniform_rate(meas.t_motor, "motors.t")
    cam_rate = camera_rate_hz or params.sensors.camera_rate_hz
    q = decimation_factor(fs, cam_rate)
    rate = fs / q
    order = s.filter_order

    motor_cut = _cutoff(s.motor_cutoff_hz, meas.theta, fs, order)
    t_grid = meas.t_motor[::q]
    cutoffs = {"motors": motor_cut}
    lo, hi = t_grid[0], t_grid[-1]
    cam: tuple[np.ndarray, np.ndarray] | None = None
    if meas.t_camera is not None and meas.alpha_camera is not None:       # both or neither (Measurements)
        tc, ac = meas.t_camera, meas.alpha_camera
        lo, hi = max(lo, tc[0]), min(hi, tc[-1])
        if hi - lo < 4 * s.trim_s + 64 / rate:
            raise ValueError(f"camera: its frames ({tc[0]:.3f}..{tc[-1]:.3f} s) overlap the motor samples "
                             f"({t_grid[0]:.3f}..{t_grid[-1]:.3f} s) for too short a time: "
                             f"{max(hi - lo, 0.0):.1f} s together, at least {4 * s.trim_s + 64 / rate:.1f} s needed; "
                             f"record a longer run (`neck-sim simulate --trajectory identification` runs 85 s)")
        cam = (tc, ac)
    idx = np.nonzero((t_grid >= lo) & (t_grid <= hi))[0]
    if idx.size < 64:
        raise ValueError(f"motors: only {idx.size} samples at {rate:.4g} Hz; identification needs a longer log")
    t = t_grid[idx]
    keep = (t >= t[0] + s.trim_s) & (t <= t[-1] - s.trim_s)
    if np.count_nonzero(keep) < 32:
        raise ValueError(f"log: {t[-1] - t[0]:.2f} s of usable data is too short after trimming "
                         f"{s.trim_s} s at both ends")
    alpha: np.ndarray | None = None
    alpha_dot: np.ndarray | None = None
    alpha_ddot: np.ndarray | None = None
    common = motor_cut.hz
    if cam is not None:
        a_grid = np.stack([np.interp(t, cam[0], cam[1][:, j]) for j in range(n)], axis=1)
        cam_cut = _cutoff(s.camera_cutoff_hz, a_grid, rate, order)
        cutoffs["camera"] = cam_cut
        alpha = lowpass(a_grid, rate, cam_cut.hz, order)
        common = min(common, cam_cut.hz)
    cutoffs["common"] = CutoffChoice(float(common), "min(motors, camera)" if cam is not None else "motors")
    refilter = s.common_bandwidth and common < 0.5 * rate * 0.95
    chain = SlowChain(fs, motor_cut.hz, q, t_grid.size, idx, common if refilter else None, keep, order)

    if reuse is not None:
        decimated, theta_dot = _reused(reuse, meas, chain)
    else:
        theta_f = lowpass(meas.theta, fs, motor_cut.hz, order)
        theta_dot = np.gradient(theta_f, 1.0 / fs, axis=0)
        theta_ddot = np.gradient(theta_dot, 1.0 / fs, axis=0)
        decimated = {"theta": chain.decimated(theta_f), "theta_dot": chain.decimated(theta_dot),
                     "theta_ddot": chain.decimated(theta_ddot),
                     "force": chain.decimated(lowpass(meas.force, fs, motor_cut.hz, order))}
    fast = FastSignals(meas.t_motor, meas.theta, theta_dot, meas.force)
    slow = {k: chain.after_decimation(v) for k, v in decimated.items()}
    h = 1.0 / rate
    x_c: np.ndarray | None = None
    x_c_dot: np.ndarray | None = None
    x_c_ddot: np.ndarray | None = None
    cables: tuple | None = None
    if alpha is not None:
        if refilter and common < cutoffs["camera"].hz:
            alpha = lowpass(alpha, rate, common, order)
        alpha = alpha[keep]
        alpha_dot = np.gradient(alpha, h, axis=0)
        alpha_ddot = np.gradient(alpha_dot, h, axis=0)
        if transmission:
            kin = cable_kinematics(alpha, alpha_dot, params)
            cables = (params.routing, _geometry_key(params), kin)
            x_c = elongation(slow["theta"], alpha, params, lengths=kin.lengths)
        else:
            x_c = elongation(slow["theta"], alpha, params)
        x_c_dot = np.gradient(x_c, h, axis=0)
        x_c_ddot = np.gradient(x_c_dot, h, axis=0)

    return Prepared(t=t[keep], **slow, alpha=alpha, alpha_dot=alpha_dot, alpha_ddot=alpha_ddot,
                    x_c=x_c, x_c_dot=x_c_dot, x_c_ddot=x_c_ddot, motor_rate_hz=fs, rate_hz=rate, decimation=q,
                    cutoffs=cutoffs, fast=fast, camera=cam, chain=chain, _decimated=decimated, _cables=cables,
                    _memo={} if reuse is None else reuse._memo)


def _geometry_key(params: NeckParams) -> tuple:
    """What Z depends on besides the routing and the angles."""
    g = params.geometry
    return (params.n_joints, g.b, g.L, g.r)


def _reused(reuse: Prepared, meas: Measurements, chain: SlowChain) -> tuple[dict, np.ndarray]:
    """(decimated motor signals, control-rate motor speeds) of ``reuse``, checked to be those of
    ``meas``'s motor arrays through the same chain up to its common bandwidth."""
    old, decimated, fast = reuse.chain, reuse._decimated, reuse.fast
    if (decimated is None or fast is None or old is None or fast.theta is not meas.theta
            or fast.force is not meas.force):
        raise ValueError("reuse: not a preparation of these motor samples (the same theta and force arrays)")
    same = (old.motor_rate_hz, old.motor_hz, old.order, old.q, old.n_grid) == (
        chain.motor_rate_hz, chain.motor_hz, chain.order, chain.q, chain.n_grid)
    if not (same and np.array_equal(old.idx, chain.idx)):
        raise ValueError(f"reuse: prepared with motor cutoff {old.motor_hz:.6g} Hz and decimation {old.q} on its own "
                         f"camera window, here {chain.motor_hz:.6g} Hz and {chain.q}: give the same motor cutoff "
                         "and camera times")
    return decimated, fast.theta_dot
