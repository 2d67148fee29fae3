"""Structure left in the residuals: does anything beyond noise remain after the last finding?

Pure functions of residual and feature arrays, then :func:`leftover_structure`, which applies
them to a fitted model.  Two tests per residual channel (joint torque j, N m; cable elongation i,
m; alpha_hat against the camera j, deg):

* **correlation with the state**: the correlation rho of the cross-validated residual with each
  state feature (motor speeds, their signs and accelerations; joint angles, speeds, their signs
  and accelerations; tension estimates and motor angles; time), every feature but the joint
  angle from the encoders (see :func:`state_features`).  Noise is uncorrelated with the
  state: under it, rho sqrt(n_eff) ~ N(0, 1) with n_eff the independent samples at the filter's
  bandwidth (one per 1 / (2 f_c) s).  Significant when |z| beats a Bonferroni bound over every
  (channel, feature) pair *and* |rho| >= ``min_rho`` (a model is never perfect: a tiny but
  certain correlation is not an effect);
* **whiteness at the filter's bandwidth**: the residual sampled every 1 / (2 f_c) s is white
  under noise; its lag-one autocorrelation rho_1 sqrt(n_eff) ~ N(0, 1).  Significant under the
  same two conditions (``min_rho_white``).

The size of a structure against the noise is |rho| / sqrt(1 - rho^2): the RMS of the part that
follows the feature over the RMS of the rest.

A leftover beside a name counts only when it is larger than the mismatch the name's own fitted
form can leave (:data:`FORM_MISMATCH`): on at least one channel the structure's RMS (|rho| x the
channel's residual RMS) must reach that fraction of the RMS the findings removed from the
channel (sqrt(RMS_base^2 - RMS_final^2), cross-validated).  A fitted form that differs from the
true one leaves a residual in proportion to the effect it explains; an effect of its own leaves
one in proportion to itself.

A name beside a leftover must stand on its own (:func:`borrowed_names`): each finding is tested
again against its step's baseline after the leftover's structure (the features each residual
channel follows) is regressed out of both models' residuals.  An effect outside the vocabulary
lends a look-alike name part of its gain (creep: a rest elongation soaks up the mean of the
drift); once the drift is removed from both sides that gain is gone, and the verdict is
``unexplained`` without the borrowed name.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy import stats

from identification.diagnosis.settings import StructureSettings
from identification.diagnosis.statistics import effective_samples

__all__ = ["StructureSettings", "Structure", "Leftover", "correlations", "lag_one", "bonferroni_z", "state_features",
           "leftover_structure", "test_margin", "remove_structure", "borrowed_names"]


#: The share of what the findings removed from a channel that a leftover on it must reach to be
#: more than their fitted forms' mismatch, calibrated on the open-world generator's forms at
#: their test level (seeds 1-3, the §5.2.2 sequences and the 12 s random multisine): the largest
#: a vocabulary effect leaves is 0.55 (the generator's smooth gear play, fitted by the backlash
#: candidate's play operator with a band 42 % short: joint torque 2, multisine seed 2; on the
#: sequences a damping on the soft left cable fitted as viscous friction leaves 0.11); creep, a
#: camera scale error and a cable's own hysteresis leave 0.99 and more on the sequences, 19 and
#: more on the multisine.  0.74: the geometric mean of 0.55 and 0.99.
FORM_MISMATCH = 0.74


# ------------------------------------------------------------------------------ pure functions

def correlations(res: np.ndarray, feats: np.ndarray) -> np.ndarray:
    """(K, F) Pearson correlations of each residual channel (S, K) with each feature (S, F),
    over the samples where the channel is finite (NaN: a slack cable); 0 for constant series."""
    out = np.zeros((res.shape[1], feats.shape[1]))
    for k in range(res.shape[1]):
        ok = np.isfinite(res[:, k])
        if ok.sum() < 3:
            continue
        r = res[ok, k] - res[ok, k].mean()
        f = feats[ok] - feats[ok].mean(0)
        den = np.sqrt((r @ r) * (f * f).sum(0))
        out[k] = np.where(den > 0, (r @ f) / np.where(den > 0, den, 1.0), 0.0)
    return out


def lag_one(res: np.ndarray, step: int) -> np.ndarray:
    """(K,) lag-one autocorrelation of each channel (S, K) sampled every ``step`` samples (NaN
    samples and the pairs they break left out)."""
    r = res[::max(int(step), 1)]
    out = np.zeros(r.shape[1])
    for k in range(r.shape[1]):
        x = r[:, k] - np.nanmean(r[:, k])
        a, b = x[:-1], x[1:]
        ok = np.isfinite(a) & np.isfinite(b)
        den = np.sqrt((a[ok] ** 2).sum() * (b[ok] ** 2).sum())
        out[k] = (a[ok] @ b[ok]) / den if den > 0 else 0.0
    return out


def bonferroni_z(alpha: float, n_tests: int) -> float:
    """Two-sided normal quantile at family-wise level ``alpha`` over ``n_tests`` tests."""
    return float(stats.norm.isf(alpha / (2 * max(n_tests, 1))))


def _sign(v: np.ndarray) -> np.ndarray:
    """A smooth sign at a tenth of each column's RMS (a Coulomb-like feature)."""
    scale = 0.1 * np.sqrt(np.mean(v * v, axis=0)) + 1e-300
    return np.tanh(v / scale)


FEATURE_UNITS = {"motor speed": "rad/s", "sign of motor speed": "-", "motor acceleration": "rad/s^2",
                 "joint angle": "rad", "joint speed": "rad/s", "sign of joint speed": "-",
                 "joint acceleration": "rad/s^2", "tension": "N", "elongation": "m", "time": "s"}
"""Unit of each state feature of :func:`state_features`, by name without its index."""


def feature_unit(name: str) -> str:
    """The unit of a feature named by :func:`state_features` ("motor speed 2" -> "rad/s")."""
    return FEATURE_UNITS.get(name.rstrip("0123456789 "), "-")


def state_features(data, tension: np.ndarray) -> tuple[tuple[str, ...], np.ndarray]:
    """(names, (S, F)) the state features on the slow grid of ``data`` (a MeasuredData):
    motor speed, its sign and acceleration per cable; joint angle, speed, its sign and
    acceleration per joint; tension (the model's eq 41 estimate) and motor angle per cable; time.

    Every feature but the joint angle comes from the encoders (joint speed by eq 35, its
    acceleration the time derivative of that), not from the camera: the residuals carry the
    camera's noise (the linkage torque through alpha_ddot, the elongation of eq 27 through alpha),
    so a camera-derived feature correlates with them by its own noise (errors in variables:
    rho = sd(noise) / sd(feature), 0.5-0.7 for the camera's alpha_ddot on slow moves), which is no
    structure of the model.  The joint angle's noise (about 1 deg against ranges of tens of
    degrees) leaves it a few hundredths."""
    from identification.diagnosis.columns.joint_friction import joint_speed_from_encoders

    p = data.prep
    C, n = data.C, data.n
    alpha_dot = joint_speed_from_encoders(data.theta_dot, data.alpha, data.params)
    alpha_ddot = np.gradient(alpha_dot, data.t, axis=0)
    groups = [("motor speed", data.theta_dot, C), ("sign of motor speed", _sign(data.theta_dot), C),
              ("motor acceleration", p.theta_ddot, C), ("joint angle", data.alpha, n),
              ("joint speed", alpha_dot, n), ("sign of joint speed", _sign(alpha_dot), n),
              ("joint acceleration", alpha_ddot, n), ("tension", tension, C), ("motor angle", p.theta, C)]
    names, cols = [], []
    for what, arr, count in groups:
        for i in range(count):
            names.append(f"{what} {i + 1}")
            cols.append(np.nan_to_num(arr[:, i]))
    names.append("time")
    cols.append(data.t - data.t[0])
    return tuple(names), np.stack(cols, axis=1)


# ------------------------------------------------------------------------------------ results

@dataclass(frozen=True)
class Structure:
    """One significant structure: residual ``channel`` (e.g. "joint torque 2", "cable 4",
    "alpha_hat 1"), the ``feature`` it follows ("whiteness": correlated in time at the filter's
    bandwidth), correlation ``rho``, its ``z`` against noise, ``size`` = RMS of the structure /
    RMS of the rest, and the residual RMS with its ``unit``."""

    channel: str
    feature: str
    rho: float
    z: float
    size: float
    rms: float
    unit: str

    def to_dict(self) -> dict:
        return {"channel": self.channel, "feature": self.feature, "rho": self.rho, "z": self.z,
                "size_vs_noise": self.size, "residual_rms": self.rms, "unit": self.unit}

    def describe(self) -> str:
        follows = "is correlated in time beyond noise" if self.feature == "whiteness" else f"follows {self.feature}"
        return (f"{self.channel} residual {follows} (rho = {self.rho:+.2f}, z = {self.z:.1f}; structure "
                f"{self.size:.2f} x the rest, residual RMS {self.rms:.3g} {self.unit})")


@dataclass(frozen=True, eq=False)
class Leftover:
    """The structure tests on one model's residuals: every significant :class:`Structure`
    (strongest first), the thresholds used, and for plots the residual and feature series of the
    strongest (``t``, ``residual``, ``feature``; None when nothing is left)."""

    found: tuple
    z_threshold: float
    n_tests: int
    settings: StructureSettings
    plot: tuple | None = field(default=None, repr=False)
    within_form: tuple = ()        # structures no larger than the findings' form mismatch (FORM_MISMATCH)
    closest: tuple = ()            # the tests nearest their decision: (margin in bands, Structure), largest first
    min_rho: float = float("nan")  # the |rho| a structure needed here (min_rho, or min_rho_named beside a name)
    features: tuple = field(default=(), repr=False)   # (names, (S, F) array) of the state features tested
    borrowed: tuple = ()           # names whose gain does not stand without the leftover (borrowed_names)
    retests: tuple = ()            # (name, Comparison) of borrowed_names, one per finding re-tested

    @property
    def significant(self) -> bool:
        return bool(self.found)

    def channels(self) -> tuple[str, ...]:
        return tuple(dict.fromkeys(s.channel for s in self.found))

    @property
    def margin(self) -> float:
        """The structure decision's margin in borderline bands: the test closest to (or furthest
        past) its thresholds, > 0 when structure is found (:func:`test_margin`)."""
        return self.closest[0][0] if self.closest else -np.inf

    def margin_dict(self) -> dict:
        if not self.closest:
            return {"margin_in_bands": -np.inf}
        m, top = self.closest[0]
        return {"margin_in_bands": m, "channel": top.channel, "feature": top.feature, "rho": top.rho, "z": top.z,
                "z_threshold": self.z_threshold, "min_rho": self.min_rho}

    def to_dict(self) -> dict:
        return {"significant": self.significant, "structures": [s.to_dict() for s in self.found[:10]],
                "n_structures": len(self.found), "z_threshold": self.z_threshold, "n_tests": self.n_tests,
                "min_rho": self.min_rho, "min_rho_white": self.settings.min_rho_white,
                "margin": self.margin_dict(), "borrowed": list(self.borrowed),
                "within_form_mismatch": [x.to_dict() for x in self.within_form[:5]],
                "retests": [{"effect": n, "improvement": c.improvement, "p_holdout": c.p_holdout,
                             "p_train": c.p_train} for n, c in self.retests],
                "closest": [{"margin_in_bands": m, **x.to_dict()} for m, x in self.closest[:5]]}


def test_margin(z: float, rho: float, z_threshold: float, min_rho: float, band: float) -> float:
    """Margin of one structure test in borderline bands: the smaller of |z| / z_threshold - 1 and
    |rho| / min_rho - 1, divided by ``band`` (> 0: both thresholds passed, a structure)."""
    return min(abs(z) / z_threshold - 1.0, abs(rho) / min_rho - 1.0) / band


def _channel_names(n: int, C: int) -> tuple[list[str], list[str]]:
    names = [f"joint torque {j + 1}" for j in range(n)] + [f"cable {i + 1}" for i in range(C)]
    units = ["N m"] * n + ["m"] * C
    return names, units


def form_share(base_cv: np.ndarray, final_cv: np.ndarray, k: int, rho: float) -> float:
    """The structure's RMS (|rho| x the final residual RMS of channel ``k``) over the RMS the
    findings removed from it (sqrt(RMS_base^2 - RMS_final^2)); inf when they removed nothing."""
    rb = float(np.sqrt(np.nanmean(base_cv[:, k] ** 2)))
    rf = float(np.sqrt(np.nanmean(final_cv[:, k] ** 2)))
    removed = np.sqrt(max(rb * rb - rf * rf, 0.0))
    return abs(rho) * rf / removed if removed > 0 else np.inf


def leftover_structure(data, fit, cv_residuals: np.ndarray, alpha_hat=None,
                       settings: StructureSettings | None = None, *, named: bool = False,
                       band: float = 0.1, base_cv: np.ndarray | None = None) -> Leftover:
    """The structure tests on the cross-validated residuals (S, N + C) of ``fit`` on ``data``
    (and on its alpha_hat errors against the camera, an :class:`~identification.diagnosis.gains.
    AlphaHatErrors`, when given).  ``named``: the model holds effects the diagnosis found, whose
    fitted forms may differ from the true ones (``min_rho_named`` then applies); ``band``: the
    borderline band of the margins (relative); ``base_cv``: the cross-validated residuals of the
    model before the findings (given with ``named``: a leftover must then exceed their forms'
    mismatch, :data:`FORM_MISMATCH`, on at least one residual channel)."""
    s = settings or StructureSettings()
    min_rho = s.min_rho_named if named else s.min_rho
    shift = sum(t.identification.fit_camera_shift(dict(t.shape)) for t in fit.model.terms)
    d = data.camera_shifted(shift)
    names, feats = state_features(d, fit.tension_hat)
    ch_names, ch_units = _channel_names(d.n, d.C)
    res = np.asarray(cv_residuals, dtype=float)
    fc, rate = d.prep.cutoffs["common"].hz, d.prep.rate_hz
    step = max(int(round(rate / (2 * fc))), 1)
    n_eff = np.array([effective_samples(int(np.isfinite(res[:, k]).sum()), fc, rate) for k in range(res.shape[1])])
    rho = correlations(res, feats)
    white = lag_one(res, step)
    series = [(res, d.t, feats)]
    if s.alpha_hat and alpha_hat is not None and alpha_hat.t.size > 10:
        # alpha_hat errors at the camera frames: features interpolated there; the errors are
        # integrated (eq 35) and smooth, one independent sample per 1 / (2 f_c) s as well
        tc = alpha_hat.t
        fa = np.stack([np.interp(tc, d.t, feats[:, i]) for i in range(feats.shape[1])], axis=1)
        err = alpha_hat.error_deg
        rate_c = 1.0 / float(np.median(np.diff(tc)))
        rho = np.concatenate([rho, correlations(err, fa)])
        white = np.concatenate([white, lag_one(err, max(int(round(rate_c / (2 * fc))), 1))])
        n_eff = np.concatenate([n_eff, [effective_samples(tc.size, fc, rate_c)] * err.shape[1]])
        ch_names += [f"alpha_hat {j + 1}" for j in range(err.shape[1])]
        ch_units += ["deg"] * err.shape[1]
        series.append((err, tc, fa))
    K = rho.shape[0]
    n_tests = K * (feats.shape[1] + 1)
    zc = bonferroni_z(s.alpha, n_tests)
    z = rho * np.sqrt(n_eff)[:, None]
    zw = white * np.sqrt(np.maximum(n_eff // 1, 1))
    all_res = [res[:, k] for k in range(res.shape[1])] + ([series[1][0][:, j] for j in range(series[1][0].shape[1])]
                                                          if len(series) > 1 else [])
    found, near = [], []

    def structure(k, feature, r, zz, rms):
        return Structure(ch_names[k], feature, float(r), float(abs(zz)), float(abs(r) / np.sqrt(max(1 - r * r, 1e-12))),
                         rms, ch_units[k])

    for k in range(K):
        rms = float(np.sqrt(np.nanmean(all_res[k] ** 2)))
        m = np.minimum(np.abs(z[k]) / zc - 1.0, np.abs(rho[k]) / min_rho - 1.0) / band    # test_margin, vectorised
        for f in np.argsort(-m)[:3]:
            near.append((float(m[f]), structure(k, names[f], rho[k, f], z[k, f], rms)))
        for f in np.nonzero(m > 0)[0]:
            found.append(structure(k, names[f], rho[k, f], z[k, f], rms))
        mw = test_margin(zw[k], white[k], zc, s.min_rho_white, band) if white[k] > 0 else -np.inf
        near.append((mw, structure(k, "whiteness", white[k], zw[k], rms)))
        if mw > 0:
            found.append(structure(k, "whiteness", white[k], zw[k], rms))
    found.sort(key=lambda x: -abs(x.rho))
    within: list = []
    if named and base_cv is not None and found:
        K0 = res.shape[1]
        share = [form_share(base_cv, res, ch_names.index(x.channel), x.rho) if ch_names.index(x.channel) < K0
                 else np.inf for x in found]          # alpha_hat channels: no residual to compare, kept
        if max(share) < FORM_MISMATCH:
            within, found = found, []
    near.sort(key=lambda e: -e[0])
    plot = None
    feature_found = [x for x in found if x.feature != "whiteness"]
    if feature_found:
        top = feature_found[0]
        k, f = ch_names.index(top.channel), names.index(top.feature)
        block = 0 if k < res.shape[1] else 1
        arr, t, fa = series[block]
        col = k if block == 0 else k - res.shape[1]
        plot = (top, t, arr[:, col], fa[:, f])
    return Leftover(tuple(found), zc, n_tests, s, plot, tuple(within), tuple(near[:10]), min_rho, (names, feats))


# ------------------------------------------------------------------------- borrowed names

def remove_structure(res: np.ndarray, feats: np.ndarray, by_channel: dict) -> np.ndarray:
    """``res`` (S, K) with, on each channel k of ``by_channel`` (k -> feature indices), its least-
    squares fit on those features and a constant removed (over its finite samples)."""
    out = np.array(res, dtype=float, copy=True)
    for k, cols in by_channel.items():
        ok = np.isfinite(out[:, k])
        if ok.sum() <= len(cols) + 1:
            continue
        X = np.column_stack([np.ones(int(ok.sum())), feats[ok][:, cols]])
        coef, *_ = np.linalg.lstsq(X, out[ok, k], rcond=None)
        out[ok, k] -= X @ coef
    return out


class _Cleaned:
    """A fit seen through its residuals with the leftover's structure removed (what
    :meth:`~identification.diagnosis.fitting.StepContext.compare` reads of a fit)."""

    def __init__(self, fit, residuals: np.ndarray):
        self.n_params, self._res = fit.n_params, residuals

    def residuals(self) -> np.ndarray:
        return self._res


def borrowed_names(data, split, settings, steps, leftover: Leftover) -> tuple[tuple, tuple]:
    """(names, retests): the findings of ``steps`` (forward-selection steps of a diagnosis with
    ``settings`` on ``split``) whose gain does not stand once the structure ``leftover`` found
    is regressed out, on each residual channel, of both the step's baseline and the extended
    model (their cross-validated and training residuals); ``retests`` the comparisons, one per
    finding.  Whiteness and the alpha_hat channels carry no feature of the residuals: only the
    residual channels' feature structures are removed."""
    from identification.diagnosis.fitting import Evaluated, StepContext

    if not leftover.significant or not leftover.features:
        return (), ()
    names, feats = leftover.features
    K = data.n + data.C
    ch_names, _ = _channel_names(data.n, data.C)
    by_channel: dict = {}
    for x in leftover.found:
        if x.feature == "whiteness" or x.channel not in ch_names[:K]:
            continue
        by_channel.setdefault(ch_names.index(x.channel), []).append(names.index(x.feature))
    if not by_channel:
        return (), ()
    out, retests = [], []
    for st in steps:
        c = st.chosen
        if c is None:
            continue
        ctx = StepContext(data, split, settings, st.base, st.scales, family=len(st.candidates))

        def clean(ev):
            cv = remove_structure(ev.cv, feats, by_channel)
            return Evaluated(_Cleaned(ev.fit, remove_structure(ev.fit.residuals(), feats, by_channel)), cv)

        cmp = ctx.compare(clean(st.base), clean(c.model), c.added_params)
        retests.append((c.term.name, cmp))
        if not ctx.candidate_significant(cmp):
            out.append(c.term.name)
    return tuple(out), tuple(retests)
