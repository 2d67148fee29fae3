"""Candidate effects as regressors on measured data: one model, one weighted least-squares fit.

A diagnosis model is a set of :class:`Term` s, one per effect of the vocabulary
(:mod:`neck_sim.effects`) with its nonlinear shape parameters fixed (the Stribeck speed, a
smoothing, a delay).  The paper's model is ``dry_friction + cable_elasticity +
tension_stiffening``; the rigid frictionless model of eq (25) has no term at all.  Every model is
linear in its remaining parameters and is fitted to two blocks of equations sampled on the slow
grid of :func:`identification.preprocessing.prepare`:

**Torque block** (eq 51 on the joints, N rows per sample, N m).  With the sign convention of
:mod:`neck_sim.analytic.cables` the motor and joint equations (29), (30) give

    y_T = Z (f - (R/r_d) I_a theta_ddot) - M_m alpha_ddot - c_m - g  =  Z f_motor + Delta_linkage,

i.e. eq (51) with the motor terms written with the measured motor acceleration (the identity
(R/r_d) theta_ddot = (R/r_d)^2 (Z^T alpha_ddot + Zdot^T alpha_dot + x_c_ddot) turns it into the
paper's form, with the corrected sign of x_c_ddot, erratum 6).  f_motor is the sum of the
motor-side forces along the cables (dry, viscous, Stribeck, pulley friction), Delta_linkage the
torque of a payload or of spring errors.  Using the encoders' theta_ddot keeps the camera's noisy
second derivative out of the large reflected-inertia term; the block does not depend on the cable
model.

**Cable block** (eq 42/54 per taut cable, m rows per sample: the routing's cables).  Elastic models:

    y_C = f - (R/r_d) I_a theta_ddot  =  f_motor + k x_c + c_a x_c_dot + lambda x_c t + (k + lambda t) x_0,

with x_c from eq (27) corrected (camera angles and encoders) and t = y_C - f_motor the tension of
eq (41).  Its residual is reported in N (the paper's tension error, eq 42/54) and, divided by the
local stiffness k + lambda t, in m: the elongation error.  The fit weighs the rows by that
stiffness, so it minimises elongation errors.  A rigid model says x_c = 0: its cable residual is
x_c itself (m) and it has no cable-block parameters.  The elongation form makes rigid and elastic
models comparable.

**Parallel filtering** (:mod:`identification.diagnosis.measured`): motor-side regressors pass through the
observations' filter chain.  Regressors that need the tension (pulley friction, lambda, pretension) use the previous fit's
tension estimate, iterated to convergence (three passes).

**Actuation delay** shifts the commanded force: y(d) uses f(t - d) (linear interpolation between
control periods), d found by a 1-D search.  **Pretension** shifts the elongation of each cable by
its rest elongation x_0 (eq 54 with x_c + x_0): with k, lambda free the offset is nearly
collinear with them (a linear offset column lets the fit run to negative stiffness), so x_0 is a
bounded shape parameter per cable, searched on
:data:`identification.diagnosis.columns.PRETENSION_RANGE` ([-1, 5] mm).

Every effect-specific piece lives in the effect's own modules: its physics (parameters, force
law, prerequisites) in :mod:`neck_sim.effects`, its columns, shapes and the map back to the plant
in :mod:`identification.diagnosis.columns`; this module only loops over a model's terms.

Parameter vector layout (names as in reports): ``f_s(i)`` N, ``c_v(i)`` N s/rad, ``df(i)`` N,
``mu(i)``, ``k(i)`` N/m, ``c_a(i)`` N s/m, ``lambda(i)`` 1/m, ``payload`` kg,
``dk(j)`` N/m per joint's side springs; i = 1..m cables (the routing's), j = 1..N joints.
"""

from __future__ import annotations

from dataclasses import dataclass
import numpy as np

from neck_sim import effects as effect_registry
from neck_sim.effects import Effect, Effects
from neck_sim.params import NeckParams

from identification.diagnosis import columns as effect_columns
from identification.diagnosis.columns import Design, EffectColumns, FitContext
from identification.diagnosis.measured import MeasuredData
from identification.least_squares import solve_weighted

__all__ = ["effect_names", "grid_of", "paper_model", "Term", "ModelSpec", "MeasuredData", "FitState", "FitContext",
           "Fit", "fit_model", "initial_state", "plant_model", "pretension_offsets", "elongation_offsets", "EFFECTS", "REQUIRES",
           "SHAPE_GRIDS", "PAPER_MODEL"]


def effect_names() -> tuple[str, ...]:
    """Candidate effects in report order: every registered effect with columns (the vocabulary
    without ``none``)."""
    return effect_columns.names()


def paper_model() -> tuple[str, ...]:
    """The paper's model: arctan friction + variable-stiffness cables."""
    return effect_registry.paper_model()


def grid_of(name: str) -> dict[str, tuple]:
    """Shape parameter -> the grid a candidate ``name`` is tried at (searched shapes only)."""
    return {sh.name: tuple(sh.grid) for sh in effect_columns.get(name).shapes if sh.grid and not sh.per_cable}


def __getattr__(name: str):
    # views of the registry under their former names, computed when asked (so they include effects
    # registered later)
    if name == "EFFECTS":
        return effect_names()
    if name == "PAPER_MODEL":
        return paper_model()
    if name == "REQUIRES":
        return {c.name: c.requires[0] for c in effect_registry.registered() if c.requires}
    if name == "SHAPE_GRIDS":
        return {n: grid_of(n) for n in effect_names() if grid_of(n)}
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


@dataclass(frozen=True)
class Term:
    """One effect of a model (its registered name) with its shape parameters fixed, e.g. the
    Stribeck friction with ``(("smoothing", 0.5), ("speed", 6.0))``."""

    name: str
    shape: tuple = ()

    def __post_init__(self):
        effect_registry.get(self.name)
        effect_columns.get(self.name)
        object.__setattr__(self, "shape", tuple(sorted((str(k), float(v)) for k, v in dict(self.shape).items())))

    @property
    def effect(self) -> type[Effect]:
        """The effect's physics (:mod:`neck_sim.effects`)."""
        return effect_registry.get(self.name)

    @property
    def identification(self) -> type[EffectColumns]:
        """The effect's columns, shapes and map back to the plant (:mod:`identification.diagnosis.columns`)."""
        return effect_columns.get(self.name)

    def get(self, key: str, default: float | None = None) -> float | None:
        return dict(self.shape).get(key, default)

    def label(self) -> str:
        if not self.shape:
            return self.name
        return self.name + "(" + ", ".join(f"{k}={v:g}" for k, v in self.shape) + ")"


@dataclass(frozen=True)
class ModelSpec:
    """A diagnosis model: its terms in the order they were added."""

    terms: tuple = ()

    def __post_init__(self):
        names = [t.name for t in self.terms]
        if len(set(names)) != len(names):
            raise ValueError(f"model: an effect appears twice in {names}")
        for t in self.terms:
            for need in t.effect.requires:
                if need not in names:
                    raise ValueError(f"model: {t.name} needs {need} in the model")

    @classmethod
    def of(cls, *names_or_terms) -> "ModelSpec":
        terms = []
        for x in names_or_terms:
            terms.append(x if isinstance(x, Term) else Term(x, effect_columns.get(x).default_shape()))
        return cls(tuple(terms))

    @property
    def names(self) -> tuple:
        return tuple(t.name for t in self.terms)

    def has(self, name: str) -> bool:
        return name in self.names

    def term(self, name: str) -> Term | None:
        return next((t for t in self.terms if t.name == name), None)

    @property
    def elastic(self) -> bool:
        """Elastic cables (eq 54) when a term makes them so; else rigid (eq 25)."""
        return any(t.identification.elastic_cables for t in self.terms)

    def plus(self, term: Term) -> "ModelSpec":
        return ModelSpec(self.terms + (term,))

    def without(self, name: str) -> "ModelSpec":
        return ModelSpec(tuple(t for t in self.terms if t.name != name))

    def describe(self) -> str:
        if not self.terms:
            return "rigid cables, no friction (eq 25)"
        return " + ".join(t.label() for t in self.terms) + ("" if self.elastic else " (rigid cables)")

    def to_list(self) -> list:
        return [{"effect": t.name, **dict(t.shape)} for t in self.terms]

    @classmethod
    def from_list(cls, items) -> "ModelSpec":
        terms = []
        for it in items:
            if isinstance(it, str):
                terms.append(Term(it, effect_columns.get(it).default_shape()))
                continue
            d = dict(it)
            name = d.pop("effect", None)
            if name is None:
                raise ValueError(f"model: a term without 'effect': {it!r}")
            terms.append(Term(name, d))
        return cls(tuple(terms))


# ----------------------------------------------------------------------------------------- fits

@dataclass(frozen=True, eq=False)
class FitState:
    """What a fit needs from the previous one: tension estimate (T, C) N at the control rate and
    (S, C) on the slow grid, and the stiffness k (C,) N/m and lambda (C,) 1/m used to weigh the
    cable rows."""

    tension_fast: np.ndarray
    tension: np.ndarray
    k: np.ndarray
    lam: np.ndarray


@dataclass(frozen=True, eq=False)
class Fit:
    """One model fitted on the training samples, evaluated on every sample.

    ``value``, ``sigma`` (p,) in the order of ``names``/``units`` (eq 50's sigma, from the training
    rows); residuals on all S samples: ``torque`` (S, N) N m, ``cable`` (S, C) m (elongation error,
    NaN where a cable is slack), ``tension`` (S, C) N (eq 42/54 error; None for rigid models);
    ``tension_hat`` (S, C) N the model's eq (41) tension.  ``n_params`` counts the linear
    parameters (the diagnosis adds the searched shape parameters).
    """

    model: ModelSpec
    names: tuple
    units: tuple
    value: np.ndarray
    sigma: np.ndarray
    torque: np.ndarray
    cable: np.ndarray
    tension: np.ndarray | None
    tension_hat: np.ndarray
    state: FitState
    n_params: int
    delay: float = 0.0
    notes: tuple = ()
    rows: tuple | None = None      # (W (r, p), Y (r,)): the weighted training rows, when asked (keep_rows)

    def group(self, symbol: str) -> np.ndarray:
        idx = [i for i, n in enumerate(self.names) if n.split("(")[0] == symbol]
        return self.value[idx]

    def group_sigma(self, symbol: str) -> np.ndarray:
        idx = [i for i, n in enumerate(self.names) if n.split("(")[0] == symbol]
        return self.sigma[idx]

    def has(self, symbol: str) -> bool:
        return any(n.split("(")[0] == symbol for n in self.names)

    def residuals(self) -> np.ndarray:
        """(S, N + C) residuals of every channel: torque (N m) then elongation (m)."""
        return np.concatenate([self.torque, self.cable], axis=1)


def pretension_offsets(model: "ModelSpec", n_cables: int) -> np.ndarray:
    """(C,) m: the elongation at rest x_0 of each cable the model's terms impose (pretension),
    zeros without such a term.  The cable law then uses x_c + x_0 (the encoders were zeroed with
    the cables already stretched)."""
    out = np.zeros(n_cables)
    for t in model.terms:
        out = out + t.identification.fit_elongation_offset(dict(t.shape), n_cables)
    return out


def elongation_offsets(model: "ModelSpec", data: MeasuredData) -> np.ndarray:
    """(S, C) or (C,) m the model's terms add to the measured elongations: the rest elongations
    (:func:`pretension_offsets`) and the offsets that follow the motion (a dead band)."""
    out = pretension_offsets(model, data.C)
    for t in model.terms:
        series = t.identification.fit_elongation_series(data, dict(t.shape))
        if series is not None:
            out = out + series
    return out


def initial_state(data: MeasuredData) -> FitState:
    """Before any fit: tension = y_C (no friction), the nominal cable stiffness for the weights."""
    y_fast, y_slow = data.observations(0.0)
    return FitState(y_fast, y_slow, np.asarray(data.params.cables.k, dtype=float), np.zeros(data.C))


def fit_model(data: MeasuredData, model: ModelSpec, train: np.ndarray, scales: np.ndarray,
              state: FitState | None = None, *, iterations: int = 3, keep_rows: bool = False) -> Fit:
    """Fit ``model`` on the training samples ``train`` (S,) bool by weighted least squares.

    ``scales`` (N + C,): the residual scale of each channel (torque N m per joint, elongation m per
    cable); every channel's rows are weighted by 1 / (scale sqrt(2 rows channels-of-its-type)) so
    that the fit minimises the diagnosis' score: the normalised mean squares averaged within
    each residual type, then over the two types.
    ``state`` seeds the tension and stiffness estimates (default :func:`initial_state`).  Raises
    ValueError (from :func:`identification.least_squares.solve_weighted`) when a parameter is not
    identifiable on these data.  ``keep_rows``: the fit keeps the weighted rows (W, Y) of its last
    pass (``Fit.rows``), e.g. to measure how its columns overlap.
    """
    n, C, S = data.n, data.C, data.S
    scales = np.asarray(scales, dtype=float)
    if scales.shape != (n + C,) or not np.all(scales > 0):
        raise ValueError(f"scales: expected {n + C} positive values, got {scales!r}")
    train = np.asarray(train, bool)
    state = state or initial_state(data)
    delay = float(sum(t.identification.fit_delay(dict(t.shape)) for t in model.terms))
    data = data.camera_shifted(sum(t.identification.fit_camera_shift(dict(t.shape)) for t in model.terms))
    motor_delays = sum((t.identification.fit_motor_delays(dict(t.shape), data.C) for t in model.terms),
                       np.zeros(data.C))
    y_fast, y_slow = (data.observations_per_motor(delay + motor_delays) if np.any(motor_delays)
                      else data.observations(delay))
    for term in model.terms:
        offset = term.identification.fit_force_offset(data, dict(term.shape))
        if offset is not None:
            y_fast, y_slow = y_fast + offset[0], y_slow + offset[1]
    yT = data.torque_observation(y_slow)
    elastic = model.elastic
    taut = data.taut
    x = data.x + elongation_offsets(model, data)
    iters = iterations if (elastic or any(t.identification.uses_tension for t in model.terms)) else 1
    t_fast, t_slow = state.tension_fast, state.tension
    k_hat = np.maximum(np.asarray(state.k, dtype=float), 1.0)
    lam_hat = np.maximum(np.asarray(state.lam, dtype=float), 0.0)
    n_train_T = max(int(train.sum()), 1)
    n_train_C = np.maximum((taut & train[:, None]).sum(0), 1)
    # each residual type weighs one half, shared by its channels (the diagnosis' score)
    wT = 1.0 / (scales[:n] * np.sqrt(n_train_T * 2 * n))
    wC = 1.0 / (scales[n:] * np.sqrt(n_train_C * 2 * C))
    fit = None
    notes = []
    for _ in range(iters):
        designs, names, units, motor_fast = [], [], [], []
        ctx = FitContext(x, t_fast, t_slow)
        for term in model.terms:
            eff = term.identification
            design = eff.design(data, dict(term.shape), ctx)
            named = eff.column_names(n, C, dict(term.shape))
            cols = [nm for nm, _ in named]
            if design.torque.shape[2] != len(cols) or design.cable.shape[2] != len(cols):
                raise RuntimeError(f"{term.name}.design: {design.torque.shape[2]} torque and {design.cable.shape[2]} "
                                   f"cable columns for {len(cols)} names {cols}")
            if not cols:
                continue                                                        # acts on the observations
            if design.motor is not None:
                motor_fast.append((len(names), len(cols), *design.motor))
            designs.append(design)
            names += cols
            units += [u for _, u in named]
        p = len(names)
        stiff = k_hat + lam_hat * np.maximum(t_slow, 0.0)                       # (S, C) N/m
        AT, AC = Design.concat(designs, n, C, S)                                 # (S, N, p), (S, C, p)
        if p:
            rowsT = (AT[train] * wT[None, :, None]).reshape(-1, p)
            YT = (yT[train] * wT).reshape(-1)
            if elastic:
                sel = taut & train[:, None]
                wc = (wC[None, :] / stiff)[sel]
                rowsC = AC[sel] * wc[:, None]
                YC = y_slow[sel] * wc
                W = np.concatenate([rowsT, rowsC])
                Y = np.concatenate([YT, YC])
            else:
                W, Y = rowsT, YT
            ls = solve_weighted(W, Y, names, units, condition=False)     # value and sigma only
            value, sigma = ls.value, ls.sigma
        else:
            value = sigma = np.zeros(0)
            W, Y = np.zeros((0, 0)), np.zeros(0)
        # tension estimate for the next pass: y_C minus the fitted motor forces (the filter chain
        # is linear, so the slow-grid tension is the same combination of the slow columns)
        t_fast, t_slow = y_fast.copy(), y_slow.copy()
        for start, width, fast, slow in motor_fast:        # width: C, or 1 for a term on one cable
            t_fast = t_fast - fast * value[start:start + width]
            t_slow = t_slow - slow * value[start:start + width]
        if elastic:
            k_hat = np.maximum(_pick(names, value, "k", C), 1.0)
            lam_hat = np.maximum(_pick(names, value, "lambda", C, 0.0), 0.0)
        fit = (value, sigma, names, units, AT, AC, stiff, t_fast, t_slow, (W, Y))
    value, sigma, names, units, AT, AC, stiff, t_fast, t_slow, rows = fit
    res_T = yT - AT @ value if len(value) else yT.copy()
    if elastic:
        res_t = y_slow - AC @ value
        res_C = np.where(taut, res_t / stiff, np.nan)
        tension = np.where(taut, res_t, np.nan)
    else:
        res_C = np.where(taut, data.x, np.nan)
        tension = None
    new_state = FitState(t_fast, t_slow, k_hat, lam_hat)
    return Fit(model, tuple(names), tuple(units), value, sigma, res_T, res_C, tension, t_slow, new_state,
               len(value), delay, tuple(notes), rows if keep_rows else None)


def _pick(names, value, symbol, C, default=None):
    idx = [i for i, nm in enumerate(names) if nm.split("(")[0] == symbol]
    if not idx:
        if default is None:
            raise KeyError(symbol)
        return np.full(C, default)
    return np.asarray(value)[idx]


# ----------------------------------------------------------------------------- extended model

def plant_model(fit: Fit, nominal: NeckParams) -> tuple[NeckParams, Effects, bool]:
    """The fitted model as plant data: (parameters, effects, rigid cables).

    Each effect with columns maps its fitted values back (``to_plant``: constants it owns replaced,
    non-negative friction, stiffness and damping clipped at 0, stiffness at 1 N/m, or an extra
    effect) or says what the plant has without it (``when_absent``: zero friction when the model
    has none); rigid cables when no term makes them elastic.
    """
    m = fit.model
    params, extra = nominal, []
    for cls in effect_columns.registered():
        term = m.term(cls.effect)
        if term is None:
            params = cls.when_absent(params, m.elastic)
            continue
        shape = dict(term.shape)
        cable = cls.cable_of(shape)         # a term on one cable: its value there, zero elsewhere
        values = {col.symbol: col.expand(fit.group(col.symbol), nominal.n_joints, None, nominal.n_cables, cable)
                  for col in cls.columns}
        params, effect = cls.to_plant(params, values, cls.without_location(shape))
        if effect is not None:
            extra.append(effect)
    return params, Effects.of(*extra), not m.elastic
