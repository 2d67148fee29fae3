"""The paper's identification (§5.3-5.5): Tables 1 and 2 and the reconstruction errors.

``identify`` runs, on the measured data only:

1. friction alone, rigid cables (eqs 46-47 as meant; Table 1, column 2);
2. the slack mask from eq (41)'s tension with that friction (``regressors.taut_samples``);
3. friction + linear stiffness + damping (eqs 44-45, W = 100; Table 1, columns 1, 3, 4);
4. variable stiffness k + lambda t with friction fixed at step 3's f_s (eqs 54-57; Table 2);
5. the torque reconstruction error of eqs (51)-(53) with and without friction (paper 0.18 vs
   0.55 N m), the tension reconstruction error of the constant and variable stiffness models
   (mean |RHS - LHS of eq 42| over taut samples; paper 6.88 vs 4.75 N), where the model's tension
   is eq (54) solved for t, t = (k x + c_a x_dot) / (1 - lambda x);
6. alpha_hat against the camera (§5.5) at the control rate, by eq (33) and eq (35), for the three
   cable models: inextensible, model 1 (Table 1 k, lambda = 0), model 2 (Table 2 k, lambda), with
   x_c from eq (58) (``controllers.estimators.ElongationEstimator``: tension f - friction,
   c_a = ``control.c_a_estimator``) -- paper 7.87/1.67/1.51 and 2.79/1.84/1.36 deg.

Two start-up choices keep the result independent of where the log starts: eq (58) starts from
its static solution x = t / (k + lambda t) for the first sample's force (the paper: from zero
at rest), and eq (35) starts from the filtered camera pose at the first slow-grid sample (the
paper: the straight pose).  Errors are means of absolute values over samples, joints or cables.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Sequence, cast

import numpy as np

from neck_sim.analytic import UnreachableError, estimate_alpha_pinv, estimate_alpha_triangular, static_elongation
from neck_sim.params import NeckParams

from identification import gaps as gaps_mod
from identification import regressors as reg
from identification import uncertainty as unc
from identification.least_squares import LSResult, solve_weighted
from identification.preprocessing import Measurements, PreprocessSettings, Prepared, prepare
from identification.uncertainty import N_BOOTSTRAP

if TYPE_CHECKING:
    from neck_sim.logs import Log

__all__ = ["PAPER", "IdentificationSettings", "IdentificationResult", "identify", "identify_log",
           "reconstruct_elongation", "format_tables", "paper_comparable", "CABLE_MODELS"]

#: The paper's published numbers (Tables 1, 2, §5.3-5.5), for side-by-side reports.
PAPER: dict[str, Any] = {
    "table1": {
        "f_s_elastic": [14.42, 17.65, 18.77, 16.18], "f_s_elastic_rel": [1.68, 1.38, 1.32, 0.88],
        "f_s_friction": [14.13, 17.70, 18.97, 16.29], "f_s_friction_rel": [2.52, 2.02, 1.88, 1.25],
        "k": [10454, 9256, 8319, 5336], "k_rel": [1.28, 1.37, 1.60, 1.85],
        "c_a": [805, 333, -218, 370], "c_a_rel": [30.5, 68.7, 94.3, 64.3],
    },
    "table2": {
        "k": [5378, 5364, 6231, 1908], "k_rel": [1.6, 1.7, 1.7, 5.0],
        "lambda": [103.3, 88.7, 53.2, 120.9], "lambda_rel": [1.5, 2.1, 4.8, 2.6],
        "c_a": [516.8, 185.9, -273.3, 241.5], "c_a_rel": [14.5, 37.8, 22.9, 30.7],
    },
    "torque_error": {"with_friction": 0.18, "without_friction": 0.55},
    "tension_error": {"constant": 6.88, "variable": 4.75},
    "alpha_error_deg": {"eq33": {"inextensible": 7.87, "constant": 1.67, "variable": 1.51},
                        "eq35": {"inextensible": 2.79, "constant": 1.84, "variable": 1.36}},
}

CABLE_MODELS = ("inextensible", "constant", "variable")
MODELS = ("friction", "elastic", "variable")


@dataclass(frozen=True)
class IdentificationSettings:
    """Method settings (not physical constants) of the identification; defaults are the paper's."""

    weight: float = 100.0              # W of eqs (44)-(45)
    slack_threshold: float = 2.0       # N: eq (41) tension below this = slack
    slack_margin_s: float = 0.1        # s added around every slack interval
    c_a_estimator: float | None = None  # N s/m for eq (58); None = params.control.c_a_estimator
    reconstruct_alpha: bool = True     # §5.5 (costs about 1 s per minute of log)
    preprocess: PreprocessSettings = field(default_factory=PreprocessSettings)
    bootstrap: int = N_BOOTSTRAP       # camera-noise replicates of the calibrated sigmas (0: HAC only)
    seed: int = 0                      # of the bootstrap's noise

    def __post_init__(self):
        for name in ("weight", "slack_margin_s"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v >= 0) or (name == "weight" and v == 0):
                raise ValueError(f"{name}: must be {'positive' if name == 'weight' else '>= 0'}, got {v!r}")
        if not np.isfinite(self.slack_threshold):
            raise ValueError(f"slack_threshold: must be finite, got {self.slack_threshold!r}")
        if not (isinstance(self.bootstrap, (int, np.integer)) and (self.bootstrap == 0 or self.bootstrap >= 2)):
            raise ValueError(f"bootstrap: must be 0 or an integer >= 2, got {self.bootstrap!r}")
        if self.c_a_estimator is not None and not self.c_a_estimator > 0:
            raise ValueError(f"c_a_estimator: must be positive, got {self.c_a_estimator!r}")


@dataclass(frozen=True, eq=False)
class IdentificationResult:
    """Everything §5.3-5.5 reports, plus the series the figures need.

    ``friction``, ``elastic``, ``variable``: :class:`LSResult` of eqs (46-47), (44-45), (54-57)
    (None when not run).  Errors: ``torque_error`` N m {"with_friction", "without_friction"},
    ``tension_error`` N {"constant", "variable"}, ``alpha_error_deg`` {"eq33", "eq35"} x
    {"inextensible", "constant", "variable"}.  ``series`` holds arrays keyed by name.
    """

    friction: LSResult | None
    elastic: LSResult | None
    variable: LSResult | None
    torque_error: dict
    tension_error: dict
    alpha_error_deg: dict
    taut_fraction: np.ndarray | None
    prepared: Prepared
    settings: IdentificationSettings
    series: dict = field(default_factory=dict)
    notes: tuple = ()
    params: NeckParams | None = None   # the nominal constants identified with (their routing names the cables)
    uncertainty: dict = field(default_factory=dict)   # model name -> uncertainty.Uncertainty
    gaps: tuple = ()                                    # one line per parameter not identified

    @property
    def f_s(self) -> np.ndarray:
        """The friction the later models use: eqs (44)-(45)'s, else the friction-only model's."""
        return cast(LSResult, self.elastic or self.friction).group("f_s")     # identify fits one of them

    def to_dict(self) -> dict:
        """JSON-ready summary (no large arrays)."""
        prep = self.prepared
        out = {
            "samples": prep.n_samples, "rate_hz": prep.rate_hz, "decimation": prep.decimation,
            "duration_s": float(prep.t[-1] - prep.t[0]),
            "cutoffs_hz": {k: {"hz": c.hz, "method": c.method, "per_channel_hz": list(c.per_channel_hz)}
                           for k, c in prep.cutoffs.items()},
            "models": {name: (getattr(self, name).to_dict() if getattr(self, name) is not None else None)
                       for name in MODELS},
            "torque_error_Nm": self.torque_error, "tension_error_N": self.tension_error,
            "alpha_error_deg": self.alpha_error_deg,
            "taut_fraction": None if self.taut_fraction is None else self.taut_fraction.tolist(),
            "notes": list(self.notes),
            "paper": PAPER if self.params is None or paper_comparable(self.params) else None,
            "models_sigma": "eq (50), the paper's (independent residuals, exact regressors: 2-4x optimistic on "
                            "filtered logs); the calibrated values and sigmas are under 'uncertainty'",
            "uncertainty": {k: u.to_dict() for k, u in self.uncertainty.items()},
            "not_identified": sorted({f"{k}: {n}" for k, u in self.uncertainty.items()
                                      for n, ok in zip(u.names, u.identified) if not ok}),
            "gaps": list(self.gaps),
        }
        return out


def _mean_abs(x) -> float:
    x = np.asarray(x, dtype=float)
    return float(np.mean(np.abs(x))) if x.size else float("nan")


def reconstruct_elongation(force: np.ndarray, theta_dot: np.ndarray, params: NeckParams, *, k: np.ndarray,
                           lam: np.ndarray, f_s: np.ndarray, c_a: float, dt: float) -> np.ndarray:
    """x_c (T, m) m by eq (58) over logged forces (T, m) and motor speeds, from the static start.

    Each step is ``controllers.estimators.ElongationEstimator.step``; the first sample is the
    static solution t / (k + lambda t) of the first force.
    """
    from controllers.estimators import ElongationEstimator

    est = ElongationEstimator(k, lam, c_a, f_s, params.friction.c_s, dt)
    t0 = est.tension(force[0], theta_dot[0])
    est.reset(static_elongation(t0, est.k, est.lam))
    out = np.empty_like(np.asarray(force, dtype=float))
    out[0] = est.x
    for i in range(1, out.shape[0]):
        out[i] = est.step(force[i - 1], theta_dot[i - 1])
    return out


def _torque_errors(prep: Prepared, params: NeckParams, dyn: reg.Dynamics, f_s) -> tuple[dict, dict]:
    """Eqs (51)-(53) corrected: Gamma_m = Z f vs Z(a f_s + I_a (R/r_d)^2 x_c_ddot) + M alpha_ddot + c + g."""
    ia = params.actuation.reflected_inertia
    a = reg.slow_friction_basis(prep, params)
    inertial = np.einsum("sij,sj->si", dyn.M, reg._need_camera(prep, "joint torques").alpha_ddot) + dyn.c + dyn.g
    x_dd = prep.x_c_ddot if prep.x_c_ddot is not None else np.zeros_like(prep.force)
    gamma_m = np.einsum("sij,sj->si", dyn.Z, prep.force)
    gamma_r = np.einsum("sij,sj->si", dyn.Z, ia * x_dd) + inertial
    gamma_rf = gamma_r + np.einsum("sij,sj->si", dyn.Z, a * f_s)
    errs = {"with_friction": _mean_abs(gamma_m - gamma_rf), "without_friction": _mean_abs(gamma_m - gamma_r)}
    return errs, {"gamma_m": gamma_m, "gamma_rf": gamma_rf, "gamma_r": gamma_r}


def _model_tension(prep: Prepared, params: NeckParams, k, lam, c_a) -> np.ndarray:
    """Eq (54) solved for t: (k x + c_a x_dot) / (1 - lambda x) (no slack clipping), (S, m) N."""
    lam = np.asarray(lam, dtype=float)
    return (np.asarray(k) * prep.x_c + np.asarray(c_a) * prep.x_c_dot) / (1.0 - lam * prep.x_c)


def _alpha_reconstruction(prep: Prepared, params: NeckParams, models: dict, f_s, c_a: float, notes: list):
    """alpha_hat by eqs (33) and (35) for each cable model vs the camera; (errors, series)."""
    fast, camera, alpha_cam = prep.fast, prep.camera, prep.alpha
    if fast is None or camera is None or alpha_cam is None:
        raise ValueError("alpha_hat reconstruction: needs the control-rate signals and the camera frames")
    sel = (fast.t >= prep.t[0]) & (fast.t <= prep.t[-1])
    t, theta, theta_dot, force = fast.t[sel], fast.theta[sel], fast.theta_dot[sel], fast.force[sel]
    dt = float(np.median(np.diff(t)))
    x = {"inextensible": np.zeros_like(theta)}
    for name, (k, lam) in models.items():
        x[name] = reconstruct_elongation(force, theta_dot, params, k=k, lam=lam, f_s=f_s, c_a=c_a, dt=dt)
    names = list(x)
    xs = np.stack([x[n] for n in names])
    tc, ac = camera
    in_win = (tc >= t[0]) & (tc <= t[-1])
    tc, ac = tc[in_win], ac[in_win]
    errors: dict[str, dict[str, float]] = {"eq33": {}, "eq35": {}}
    series = {"t_fast": t[::4], "camera_t": tc, "camera_alpha": ac}

    def at_camera(a):
        return np.stack([np.interp(tc, t, a[:, j]) for j in range(a.shape[1])], axis=1)

    tri = None
    if not params.routing.is_paper_kind(params.n_joints):
        notes.append("eq (33) reconstruction skipped: it needs the paper's routing (cable j ends at joint j, one "
                     "long left cable); this neck's routing differs")
    else:
        try:
            tri = estimate_alpha_triangular(np.broadcast_to(theta, xs.shape), params, xs)
        except UnreachableError as exc:
            notes.append(f"eq (33) reconstruction failed: {exc}")
    alpha0 = np.broadcast_to(alpha_cam[0], (len(names), alpha_cam.shape[1]))
    pinv = estimate_alpha_pinv(np.broadcast_to(theta, xs.shape), params, xs, alpha0=alpha0)
    for i, n in enumerate(names):
        if tri is not None:
            errors["eq33"][n] = float(np.degrees(_mean_abs(at_camera(tri[i]) - ac)))
            series[f"alpha_eq33_{n}"] = tri[i][::4]
        else:
            errors["eq33"][n] = float("nan")
        errors["eq35"][n] = float(np.degrees(_mean_abs(at_camera(pinv[i]) - ac)))
        series[f"alpha_eq35_{n}"] = pinv[i][::4]
    return errors, series


def identify(meas: Measurements | Prepared, params: NeckParams, settings: IdentificationSettings | None = None,
             *, models: Sequence[str] = MODELS) -> IdentificationResult:
    """The paper's identification on measured data (see the module docstring).

    ``params`` supplies the nominal constants only (geometry, drive, inertia, springs, c_s, and
    ``control.c_a_estimator``); its friction and cable fields are never used.  ``models`` is a
    subset of ("friction", "elastic", "variable"); "variable" needs "elastic" (for f_s) or
    "friction".  Raises ValueError naming the problem, e.g. a log without camera frames for the
    models that need the camera (all three: the joint angles enter every model).
    """
    s = settings or IdentificationSettings()
    models = tuple(models)
    unknown = [m for m in models if m not in MODELS]
    if unknown or not models:
        raise ValueError(f"models: unknown {unknown} (known: {', '.join(MODELS)})" if unknown
                         else "models: choose at least one")
    prep = meas if isinstance(meas, Prepared) else prepare(meas, params, s.preprocess)
    if not prep.has_camera:
        raise ValueError(f"camera: this log has no /neck/camera frames; the models {', '.join(models)} "
                         f"need the camera's joint angles (joint torques of eq 38, elongations of eq 27)")
    notes: list[str] = []
    dyn = reg.joint_dynamics(prep, params)
    # friction alone is cheap and gives the slack mask its tension estimate (eq 41)
    friction_fit = solve_weighted(*reg.friction_model(prep, params, dyn))
    taut = reg.taut_samples(prep, params, friction_fit.group("f_s"), threshold=s.slack_threshold,
                            margin_s=s.slack_margin_s)
    elastic: LSResult | None = None
    variable: LSResult | None = None
    if "elastic" in models:
        elastic = solve_weighted(*reg.elastic_model(prep, params, weight=s.weight, taut=taut, dyn=dyn))
    f_s = (elastic or friction_fit).group("f_s")
    if "variable" in models:
        variable = solve_weighted(*reg.variable_stiffness_model(prep, params, f_s, taut=taut))
    friction = friction_fit if "friction" in models else None
    notes += _unphysical_notes({"(44),(45)": elastic, "(46),(47)": friction, "Table 2": variable})

    torque_error, series = _torque_errors(prep, params, dyn, f_s)
    t_rhs = reg.tension_from_forces(prep, params, f_s)
    series.update(t=prep.t, tension_rhs=t_rhs, taut=taut, force=prep.force)
    tension_error = {}
    for name, res, lam in (("constant", elastic, None), ("variable", variable, "lambda")):
        if res is None:
            continue
        lam_v = res.group(lam) if lam else np.zeros(params.n_cables)
        t_lhs = _model_tension(prep, params, res.group("k"), lam_v, res.group("c_a"))
        series[f"tension_{name}"] = t_lhs
        tension_error[name] = _mean_abs((t_rhs - t_lhs)[taut])
    alpha_error = {}
    if s.reconstruct_alpha and params.n_cables < params.n_joints:
        notes.append(f"alpha_hat (§5.5) not reconstructed: eq (35) needs at least as many cables as joints (this "
                     f"neck: {params.n_cables} cables, {params.n_joints} joints)")
    elif s.reconstruct_alpha and (elastic is not None or variable is not None):
        cable_models = {}
        if elastic is not None:
            cable_models["constant"] = (elastic.group("k"), np.zeros(params.n_cables))
        if variable is not None:
            cable_models["variable"] = (variable.group("k"), np.maximum(variable.group("lambda"), 0.0))
        c_a = s.c_a_estimator or params.control.c_a_estimator
        alpha_error, a_series = _alpha_reconstruction(prep, params, cable_models, f_s, c_a, notes)
        series.update(a_series)
    fits = {"friction": friction, "elastic": elastic, "variable": variable}
    uncertainty, gap_lines = calibrated_uncertainty(prep, params, s, fits, dyn, taut, f_s, t_rhs)
    return IdentificationResult(friction, elastic, variable, torque_error, tension_error, alpha_error,
                                taut.mean(axis=0), prep, s, series, tuple(notes), params, uncertainty=uncertainty,
                                gaps=tuple(gap_lines))


def calibrated_uncertainty(prep: Prepared, params: NeckParams, s: IdentificationSettings, fits: dict,
                           dyn: reg.Dynamics, taut, f_s, tension) -> tuple[dict, list]:
    """:class:`~identification.uncertainty.Uncertainty` per fitted model, and the gap lines.

    ``fits`` maps model names to their :class:`LSResult` (or None); ``f_s`` (N+1,) N the friction
    the variable-stiffness model was fitted with; ``tension`` (S, N+1) N is eq (55)'s with it.  See :mod:`identification.uncertainty` and
    :mod:`identification.gaps`.
    """
    S, N = prep.n_samples, params.n_joints
    models = tuple(m for m in ("elastic", "variable") if fits.get(m) is not None)
    reps = (unc.camera_noise_bootstrap(prep, params, taut, weight=s.weight, models=models, settings=s.preprocess,
                                       n=s.bootstrap, seed=s.seed) if s.bootstrap else {})
    out: dict[str, unc.Uncertainty] = {}
    missing_by_model: list[tuple[str, Sequence[str], np.ndarray, np.ndarray, np.ndarray]] = []
    for name in ("friction", "elastic", "variable"):
        res = fits.get(name)
        if res is None:
            continue
        if name == "friction":
            W, rows = reg.friction_model(prep, params, dyn).W, unc.row_samples(S, N, tension=False)
        elif name == "elastic":
            W, rows = reg.elastic_model(prep, params, weight=s.weight, taut=taut, dyn=dyn).W, unc.row_samples(S, N, taut)
        else:
            W = reg.variable_stiffness_model(prep, params, f_s, taut=taut).W
            rows = unc.row_samples(S, N, taut, torque=False)
        u = unc.calibrate(res, W, rows, S, reps.get(name), camera_noise=params.sensors.camera_noise)
        if name == "elastic" and "friction" in out:
            # eqs (44)-(45) share f_s with tension rows whose constant stiffness does not fit a
            # tension-dependent cable, and the misfit leaks into f_s (0.1-0.4 N on a noise-free
            # 85 s log); the torque rows alone (friction model) do not carry it.  The two models'
            # disagreement on f_s measures that bias: it joins the elastic f_s sigma.
            fs = np.array([n.startswith("f_s(") for n in u.names])
            term = np.zeros(len(u.names))
            term[fs] = u.value[fs] - out["friction"].value
            u = u.with_model_term(term)
        missing = gaps_mod.not_identified(u.value, u.sigma)
        out[name] = u.with_identified(~missing)
        missing_by_model.append((name, u.names, u.value, u.sigma, missing))
    return out, gaps_mod.gap_lines(missing_by_model, tension=tension, theta_dot=prep.theta_dot, taut=taut,
                                   x_c_dot=reg._need_camera(prep, "parameters not identified").x_c_dot,
                                   f_max=params.actuation.f_max)


def _unphysical_notes(results: dict) -> list[str]:
    """A note for every identified friction f_s or stiffness k below zero: friction opposes motion
    (eq 37, f_s >= 0) and a cable pulls harder when stretched (eq 54, k > 0), so such a value is
    no result; it says the data do not hold this model (stale forces, too little motion, ...)."""
    notes = []
    for label, res in results.items():
        if res is None:
            continue
        for name, what in (("f_s", "friction"), ("k", "stiffness")):
            if not any(n.split("(")[0] == name for n in res.names):
                continue
            values = np.asarray(res.group(name), dtype=float)
            bad = np.flatnonzero(values < 0)
            if bad.size:
                listed = ", ".join(f"cable {j + 1}: {values[j]:.4g}" for j in bad)
                notes.append(f"UNPHYSICAL: identification with {label} gives a negative {what} {name} ({listed}); "
                             f"{what} cannot be negative, so the data do not support this model (stale or "
                             "stuck force logging? too little motion?): do not use these values")
    return notes


def identify_log(log: Log, settings: IdentificationSettings | None = None, *, params: NeckParams | None = None,
                 models: Sequence[str] = MODELS) -> IdentificationResult:
    """:func:`identify` on a :class:`neck_sim.logs.Log` (measured topics and ``neck`` metadata only).

    ``params`` defaults to ``log.params`` (the nominal constants of the ``neck`` record).
    """
    meas = Measurements.from_log(log)
    p = params or log.params
    s = settings or IdentificationSettings()
    cam_rate = getattr(p.sensors, "camera_rate_hz", None)
    prep = prepare(meas, p, s.preprocess, camera_rate_hz=cam_rate)
    return identify(prep, p, s, models=models)


def paper_comparable(params: NeckParams) -> bool:
    """True when the paper's Tables 1-2 describe the same cables: its 3-joint neck and routing."""
    return params.n_joints == 3 and params.routing.is_paper_kind(3)


def _cell(v, rel, ref_v, ref_rel, fmt):
    """"ours (relative sigma) | paper (relative sigma)", or "| reference (our difference)" when
    ``ref_rel`` is None (a reference value without a sigma: the plant's or the nominal one)."""
    ours = f"{v:{fmt}} ({rel:.2f} %)"
    if ref_rel is not None:
        return f"{ours:>20} | {ref_v:{fmt}} ({ref_rel:.2f} %)"
    if ref_v is None or not np.isfinite(ref_v):
        return f"{ours:>20} | {'-':>6}"
    diff = 100.0 * (v - ref_v) / abs(ref_v) if ref_v else float("nan")
    return f"{ours:>20} | {ref_v:{fmt}} ({diff:+.1f} %)"


def format_tables(result: IdentificationResult, truth: NeckParams | None = None, *,
                  reference: str | None = None) -> str:
    """Tables 1 and 2 per cable of the routing: "ours (relative sigma) | reference".

    The reference is the paper's published value (relative sigma) only when the neck is the
    paper's (3 joints, its routing: :func:`paper_comparable`); for any other neck it is the
    parameter values per cable with our relative difference: ``truth``'s (simulated data: the
    plant's) when given, else those of ``result.params`` (the nominal constants the
    identification was given), named ``reference`` in the header.  On the paper's neck ``truth``
    adds the plant's values in a line under each table.
    """
    p = result.params
    m = result.prepared.theta.shape[1]
    paper = p is None or paper_comparable(p)
    P1, P2 = PAPER["table1"], PAPER["table2"]
    if paper:
        ref_name = "paper"
        ref = {"f_s_e": (P1["f_s_elastic"], P1["f_s_elastic_rel"]), "f_s_f": (P1["f_s_friction"], P1["f_s_friction_rel"]),
               "k1": (P1["k"], P1["k_rel"]), "c_a1": (P1["c_a"], P1["c_a_rel"]), "k2": (P2["k"], P2["k_rel"]),
               "lambda": (P2["lambda"], P2["lambda_rel"]), "c_a2": (P2["c_a"], P2["c_a_rel"])}
    else:
        src = truth if truth is not None else cast(NeckParams, p)       # not None: else paper is True
        ref_name = "plant" if truth is not None else (reference or "nominal")
        none = [None] * m
        ref = {"f_s_e": (src.friction.f_s, none), "f_s_f": (src.friction.f_s, none),
               "k1": (src.cables.k_linear or none, none), "c_a1": (src.cables.c_a, none), "k2": (src.cables.k, none),
               "lambda": (src.cables.lam, none), "c_a2": (src.cables.c_a, none)}
    lines = [f"Table 1: identified parameters -- ours (relative sigma) | {ref_name}"
             + (" (relative sigma)" if paper else " (our difference)")]
    if not paper:
        lines.append(f"  {cast(NeckParams, p).n_joints} joints, {m} cables in the routing's order; the paper's "
                     f"Tables 1-2 are for its 3-joint routing and are not compared")
    head = f"{'':8}"
    cols = []
    if result.elastic is not None:
        cols.append(("Ident. with (44),(45): f_s (N)", result.elastic, "f_s", "f_s_e", ".2f"))
    if result.friction is not None:
        cols.append(("Ident. with (46),(47): f_s (N)", result.friction, "f_s", "f_s_f", ".2f"))
    if result.elastic is not None:
        cols.append(("Stiffness k (N/m)", result.elastic, "k", "k1", ".0f"))
        cols.append(("Damping c_a (N s/m)", result.elastic, "c_a", "c_a1", ".0f"))
    for title, *_ in cols:
        head += f"  {title:>40}"
    lines.append(head)
    for i in range(m):
        row = f"{'cable ' + str(i + 1):8}"
        for _, res, sym, key, fmt in cols:
            row += f"  {_cell(res.group(sym)[i], res.group_rel_sigma(sym)[i], ref[key][0][i], ref[key][1][i], fmt):>40}"
        lines.append(row)
    conds = []
    for name in ("elastic", "friction"):
        res = getattr(result, name)
        if res is not None:
            conds.append(f"{name}: cond(W) = {res.cond:.3g}, scaled {res.cond_scaled:.3g}, sigma_rho = {res.sigma_rho:.3g}")
    lines += ["  " + c for c in conds]
    if truth is not None and paper:
        lines.append(f"  plant: f_s = {', '.join(f'{v:.2f}' for v in truth.friction.f_s)} N")
    if result.variable is not None:
        v = result.variable
        lines += ["", f"Table 2: variable stiffness (friction fixed) -- ours (relative sigma) | {ref_name}"
                  + (" (relative sigma)" if paper else " (our difference)"),
                  f"{'':8}  {'k (N/m)':>40}  {'lambda (1/m)':>40}  {'c_a (N s/m)':>40}"]
        for i in range(m):
            lines.append(f"{'cable ' + str(i + 1):8}" + "".join(
                f"  {_cell(v.group(sym)[i], v.group_rel_sigma(sym)[i], ref[key][0][i], ref[key][1][i], fmt):>40}"
                for sym, key, fmt in (("k", "k2", ".0f"), ("lambda", "lambda", ".1f"), ("c_a", "c_a2", ".0f"))))
        lines.append(f"  cond(W) = {v.cond:.3g}, scaled {v.cond_scaled:.3g}, sigma_rho = {v.sigma_rho:.3g}")
        if truth is not None and paper:
            lines.append(f"  plant: k = {', '.join(f'{x:.0f}' for x in truth.cables.k)} N/m, "
                         f"lambda = {', '.join(f'{x:.1f}' for x in truth.cables.lam)} 1/m, "
                         f"c_a = {', '.join(f'{x:.0f}' for x in truth.cables.c_a)} N s/m")
    lines += ["", f"{'reconstruction error':44} {'ours':>8} {'paper':>8}"]
    te, pe = result.torque_error, PAPER["torque_error"]

    def paper_value(v: float) -> str:
        return f"{v:8.2f}" if paper else f"{'-':>8}"

    lines.append(f"{'torque, eqs (51)-(53), with friction (N m)':44} {te['with_friction']:8.3f} "
                 f"{paper_value(pe['with_friction'])}")
    lines.append(f"{'torque, without friction (N m)':44} {te['without_friction']:8.3f} "
                 f"{paper_value(pe['without_friction'])}")
    for name, label in (("constant", "tension, constant stiffness (N)"), ("variable", "tension, variable stiffness (N)")):
        if name in result.tension_error:
            lines.append(f"{label:44} {result.tension_error[name]:8.2f} {paper_value(PAPER['tension_error'][name])}")
    for eq in ("eq33", "eq35"):
        for name, val in result.alpha_error_deg.get(eq, {}).items():
            label = f"alpha_hat by eq ({eq[2:]}), {name} (deg)"
            lines.append(f"{label:44} {val:8.2f} {paper_value(PAPER['alpha_error_deg'][eq][name])}")
    c = result.prepared.cutoffs
    lines += ["", "cutoffs (residual analysis): " + ", ".join(f"{k} {v.hz:.2f} Hz" for k, v in c.items())
              + f"; {result.prepared.n_samples} samples at {result.prepared.rate_hz:.2f} Hz"]
    if result.taut_fraction is not None:
        lines.append("taut samples per cable: " + ", ".join(f"{100 * f:.1f} %" for f in result.taut_fraction))
    if result.uncertainty:
        lines += ["", unc.format_uncertainty(result.uncertainty)]
    if result.gaps:
        lines += ["", "Not identified by this log (what is missing, what to record):"] + [f"  {g}" for g in result.gaps]
    lines += list(result.notes)
    return "\n".join(lines)
