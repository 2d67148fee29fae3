"""The protocol every effect of the vocabulary answers (one module per effect in this package).

An effect is a frozen dataclass: its instance fields are its parameters (SI units, validated in
``__post_init__`` with the parameter named), its class attributes and methods say everything else
about it.  Three audiences read it:

**The plant** (:mod:`neck_sim.plant`) hides the effect in a simulation through whichever hooks the
effect overrides (the defaults do nothing):

* ``apply(params)`` -- the true constants (``"params"`` effects, baseline overrides);
* ``motor_force(theta_dot, tension)`` -- ``kind = "motor"``: an extra force (N) along the cable
  resisting the motor speed, added to eq (37): ``I_a theta_ddot = (r_d/R)(f - t - f_friction -
  extra)``.  ``native_fields(n_cables)`` hands the same law to the C callback (members of the
  ``neck_plant`` struct of ``neck_sim/native/plant_callback.c``); ``None`` = no native kernel (the
  plant then needs ``backend="python"``);
* ``elongation_offset(n_cables)`` -- m added to every cable elongation (pretension);
* ``encoder_band(n_cables)`` -- ``kind = "encoder"``: a dead band (m of cable) between each motor
  shaft, which carries the encoder, and its drum (backlash);
* ``command_delay`` (s) -- the commanded force acts that much later; ``camera_delay`` (s) -- a
  camera frame stamped t shows the neck at t - camera_delay;
* ``setup_mujoco(model, data, index)`` -- edit MuJoCo's compiled model or data directly
  (``dof_frictionloss``, ``qfrc_applied``, ...): MuJoCo-native mechanisms; called after every reset.

**The diagnosis** (:mod:`identification.diagnosis.candidates` and the diagnosis pipeline) fits the effect as
regressor columns, linear in the effect's magnitudes once its shape parameters are fixed:

* ``columns`` -- the :class:`Column` groups it adds to the parameter vector (symbol, unit, one per
  cable/joint or one in all, physical sign); ``design(data, shape, context)`` builds them;
* ``shapes`` -- the nonlinear :class:`Shape` parameters (default, search grid, refinement);
* ``requires`` -- effects that must already be in the model (Stribeck needs dry friction);
* ``fit_delay(shape)``, ``fit_camera_shift(shape)``, ``fit_elongation_offset(shape, n_cables)``,
  ``fit_elongation_series(data, shape)``, ``fit_force_offset(data, shape)`` -- effects that shift
  the observations, the camera or the elongations instead of adding columns (``fit_cable_offset`` the per-cable trial offset of
  a ``Shape.per_cable`` search);
* ``to_plant(params, values, shape)`` -- the fitted result back as plant constants and an effect;
  ``when_absent(params, elastic)`` -- the plant constants when a model lacks a baseline effect.

**The blind tests** (:mod:`identification.blind`): ``blind_forms()`` -- how to hide the effect in a
form that differs from the candidate's, at a test magnitude.

Indices of per-cable arrays follow the routing's cables (``params.routing.cables``, m of them; on
the paper's routing 0..N-1 the right cables c1..cN, N the long left cable); per-joint arrays have N.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import Any, Callable, ClassVar, NamedTuple

import numpy as np

from neck_sim.params import NeckParams

__all__ = ["Effect", "MotorEffect", "Column", "Shape", "Design", "Hidden", "clearly_nonzero", "finite", "indices",
           "per_item"]


# ------------------------------------------------------------------------------------ validation

def finite(name: str, v: float, *, positive: bool = False, non_negative: bool = False) -> float:
    """``v`` as a float; ValueError naming ``name`` if it is not a finite number (of that sign)."""
    try:
        v = float(v)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: not a number ({v!r})") from None
    if not math.isfinite(v):
        raise ValueError(f"{name}: must be finite, got {v!r}")
    if positive and v <= 0:
        raise ValueError(f"{name}: must be > 0, got {v!r}")
    if non_negative and v < 0:
        raise ValueError(f"{name}: must be >= 0, got {v!r}")
    return v


def indices(name: str, v) -> tuple[int, ...] | None:
    """Distinct non-negative 0-based indices (None = all)."""
    if v is None:
        return None
    try:
        out = tuple(int(i) for i in (v if hasattr(v, "__iter__") else [v]))
    except (TypeError, ValueError):
        raise ValueError(f"{name}: expected a list of 0-based indices, got {v!r}") from None
    if any(i < 0 for i in out) or len(set(out)) != len(out) or not out:
        raise ValueError(f"{name}: expected distinct non-negative 0-based indices, got {v!r}")
    return out


def per_item(name: str, v, *, positive=False, non_negative=False) -> tuple[float, ...] | float:
    """A scalar or a tuple of values (one per affected cable/joint)."""
    if np.ndim(v) == 0:
        return finite(name, v, positive=positive, non_negative=non_negative)
    return tuple(finite(f"{name}[{k}]", x, positive=positive, non_negative=non_negative) for k, x in enumerate(v))


def clearly_nonzero(value, sigma) -> np.ndarray:
    """Which fitted magnitudes are clearly non-zero: |z| >= 4 and at least 25 % of the largest.

    The one rule by which the diagnosis locates an effect (its cables or joints) and checks its
    physical sign.  ``value``, ``sigma`` (p,) -> (p,) bool.
    """
    v, s = np.asarray(value, dtype=float), np.asarray(sigma, dtype=float)
    return (np.abs(v) >= 4 * s) & (np.abs(v) >= 0.25 * np.abs(v).max(initial=0.0))


# ------------------------------------------------------------------------------- identification

@dataclass(frozen=True)
class Column:
    """A group of regressor columns: ``symbol`` (report name, ``symbol(i)`` per item, 1-based),
    ``unit``, ``per`` = ``"cable"`` (C columns), ``"joint"`` (N), ``"spring"`` (2N: joint 1 left,
    joint 1 right, ..., named ``symbol(1L)``, ``symbol(1R)``, ...) or ``"one"``; ``signed``: the
    physical value is >= 0 (a friction cannot push, a stiffness or a mass is > 0)."""

    symbol: str
    unit: str
    per: str = "cable"
    signed: bool = True

    def __post_init__(self):
        if self.per not in ("cable", "joint", "spring", "one"):
            raise ValueError(f"Column.per: 'cable', 'joint', 'spring' or 'one', got {self.per!r}")

    def names(self, n_joints: int, n_cables: int) -> tuple[str, ...]:
        """Column names for a neck of N = ``n_joints`` joints and m = ``n_cables`` cables."""
        if self.per == "one":
            return (self.symbol,)
        if self.per == "spring":
            return tuple(f"{self.symbol}({i + 1}{side})" for i in range(n_joints) for side in "LR")
        count = {"cable": n_cables, "joint": n_joints}[self.per]
        return tuple(f"{self.symbol}({i + 1})" for i in range(count))


@dataclass(frozen=True)
class Shape:
    """A nonlinear shape parameter of an effect, fixed inside each linear fit and searched around it.

    ``default`` -- the value when a model names the effect without a shape; ``grid`` -- the values
    a candidate is tried at; ``refine`` -- ``"log"`` or ``"linear"`` to refine the best grid point
    by a bounded 1-D search (None: grid only); ``span`` -- the later re-tuning range (factor for
    ``log``, +- units for ``linear``); ``profile_step`` -- step of the profile-likelihood sigma in
    reports (None: reported without sigma).  ``per_cable``: one value per cable, keys
    ``<name>_<i>`` (1-based), searched on ``bounds`` cable by cable.
    """

    name: str
    unit: str
    default: float | None = None
    grid: tuple = ()
    refine: str | None = None
    span: float = 2.0
    profile_step: float | None = None
    per_cable: bool = False
    bounds: tuple | None = None

    def __post_init__(self):
        if self.refine not in (None, "log", "linear"):
            raise ValueError(f"Shape.refine: None, 'log' or 'linear', got {self.refine!r}")


class Design(NamedTuple):
    """Regressor columns of one effect for one fit (S samples, N joints, C cables, p columns):
    ``torque`` (S, N, p) N m per unit parameter, ``cable`` (S, C, p) N per unit parameter, and for
    motor-side forces ``motor`` = (fast (T, C), slow (S, C)) force per unit magnitude (the fit
    subtracts them to estimate the tension)."""

    torque: np.ndarray
    cable: np.ndarray
    motor: tuple | None = None


class Hidden(NamedTuple):
    """A blind test's hidden effect: plant constants and effects, where it was hidden (0-based),
    the effect a correct diagnosis names, a description."""

    params: NeckParams
    effects: tuple
    cables: tuple
    joints: tuple
    description: str
    expect: str


# ------------------------------------------------------------------------------------- effects

@dataclass(frozen=True)
class Effect:
    """Base of every effect; see the module docstring for the protocol."""

    name: ClassVar[str] = ""
    description: ClassVar[str] = ""       # one line, the vocabulary table
    abbreviation: ClassVar[str] = ""      # a few letters for table columns (default: the name)
    kind: ClassVar[str] = ""              # motor | params | command | elongation | camera | mujoco
    baseline: ClassVar[bool] = False      # part of the paper's model (lives in NeckParams)
    magnitude_field: ClassVar[str] = ""   # the field the effect's force is linear in
    # plant
    acts_on_cable_law: ClassVar[bool] = False   # moot with rigid cables (refused there)
    command_delay: ClassVar[float] = 0.0
    camera_delay: ClassVar[float] = 0.0
    # diagnosis
    columns: ClassVar[tuple] = ()
    shapes: ClassVar[tuple] = ()
    requires: ClassVar[tuple] = ()
    elastic_cables: ClassVar[bool] = False      # in a model, makes its cables elastic (eq 54)
    uses_tension: ClassVar[bool] = False        # columns need the tension estimate (iterated fit)
    columns_exact: ClassVar[bool] = True        # columns x values = the plant's law exactly (False: the
    #                                             plant's law is a MuJoCo constraint the columns smooth)
    # blind tests
    blind_magnitude: ClassVar[float | None] = None
    blind_unit: ClassVar[str] = ""              # of blind_magnitude

    # -- parameters
    def parameter_names(self) -> tuple[str, ...]:
        """``"<name>.<field>"`` of every numeric parameter of the effect."""
        return tuple(f"{self.name}.{f.name}" for f in fields(self) if f.name not in ("cables", "joints"))

    def parameters(self, n_cables: int | None = None) -> dict[str, Any]:
        """Parameter name -> value (per-cable values expanded to (n_cables,) when given)."""
        out = {}
        for f in fields(self):
            if f.name in ("cables", "joints"):
                continue
            v = getattr(self, f.name)
            if n_cables is not None and f.name == self.magnitude_field and hasattr(self, "cables") and v is not None:
                v = self.per_cable(n_cables)
            out[f"{self.name}.{f.name}"] = v
        return out

    def check(self, params: NeckParams) -> None:
        """Raise ValueError naming the problem if the effect does not fit this neck."""
        n_c, n_j = params.n_cables, params.n_joints
        for attr, limit, what in (("cables", n_c, "cable"), ("joints", n_j, "joint")):
            idx = getattr(self, attr, None)
            if idx is not None and max(idx) >= limit:
                raise ValueError(f"{self.name}.{attr}: index {max(idx)} out of range for {limit} {what}s "
                                 f"(0-based; this neck has N = {n_j} joints)")
        mag = getattr(self, self.magnitude_field, None) if self.magnitude_field else None
        if isinstance(mag, tuple):
            want = len(self.cables) if getattr(self, "cables", None) is not None else n_c
            if len(mag) != want:
                raise ValueError(f"{self.name}.{self.magnitude_field}: {len(mag)} values for {want} affected cables")

    def per_cable(self, n_cables: int) -> np.ndarray:
        """The magnitude as an (n_cables,) array, zero on unaffected cables."""
        mag = getattr(self, self.magnitude_field)
        out = np.zeros(n_cables)
        idx = np.arange(n_cables) if self.cables is None else np.asarray(self.cables)
        out[idx] = mag
        return out

    def to_dict(self) -> dict[str, Any]:
        d = {"name": self.name}
        for f in fields(self):
            v = getattr(self, f.name)
            d[f.name] = list(v) if isinstance(v, tuple) else v
        return d

    # -- plant hooks (defaults: no action)
    def apply(self, params: NeckParams) -> NeckParams:
        """The plant's true constants with this effect."""
        return params

    def native_fields(self, n_cables: int) -> dict[str, np.ndarray] | None:
        """``neck_plant`` struct member -> (n_cables,) values of a motor effect; None: no native kernel."""
        return None

    def elongation_offset(self, n_cables: int) -> np.ndarray:
        """(n_cables,) m added to every elongation."""
        return np.zeros(n_cables)

    def encoder_band(self, n_cables: int) -> np.ndarray:
        """(n_cables,) m of cable: a dead band between each motor shaft (the encoder) and its drum
        (``kind = "encoder"``; the plant keeps the motor's lead, see :mod:`neck_sim.effects.backlash`)."""
        return np.zeros(n_cables)

    def setup_mujoco(self, model, data, index) -> None:
        """Edit the compiled MuJoCo model/data (``index``: :func:`neck_sim.mjcf.model_index`);
        called after every reset, so it must set values, not accumulate them."""

    # -- diagnosis hooks
    @classmethod
    def default_shape(cls) -> tuple:
        """((key, value), ...) sorted by key: the shape of a term named without one."""
        return tuple(sorted((s.name, float(s.default)) for s in cls.shapes if s.default is not None))

    @classmethod
    def design(cls, data, shape: dict, context) -> Design:
        """Regressor columns for one fit on the diagnosis' ``data`` (a
        :class:`identification.diagnosis.candidates.MeasuredData`); ``context`` carries the fit's current
        elongations ``x`` (S, C) m and tension estimates (``tension_fast`` (T, C), ``tension`` (S, C) N)."""
        S, n, C = data.S, data.n, data.C
        return Design(np.zeros((S, n, 0)), np.zeros((S, C, 0)))

    @classmethod
    def fit_delay(cls, shape: dict) -> float:
        """Delay (s) of the commanded force this term imposes on the observations."""
        return 0.0

    @classmethod
    def fit_camera_shift(cls, shape: dict) -> float:
        """s by which this term says the camera lags the encoders: the fit reads the camera's
        joint angles that much later (:meth:`identification.diagnosis.measured.MeasuredData.camera_shifted`)."""
        return 0.0

    @classmethod
    def fit_elongation_offset(cls, shape: dict, n_cables: int) -> np.ndarray:
        """(n_cables,) m this term adds to the measured elongations."""
        return np.zeros(n_cables)

    @classmethod
    def fit_elongation_series(cls, data, shape: dict) -> np.ndarray | None:
        """(S, C) m this term adds to the measured elongations sample by sample (None: nothing);
        for offsets that follow the motion (a dead band)."""
        return None

    @classmethod
    def fit_force_offset(cls, data, shape: dict) -> tuple[np.ndarray, np.ndarray] | None:
        """(fast (T, C), slow (S, C)) N this term adds to the cable-side observations
        y_C = f - (R/r_d) I_a theta_ddot (None: nothing); e.g. the inertia term read from the
        drum's acceleration where the encoders show the motor's."""
        return None

    @classmethod
    def fit_cable_offset(cls, data, cable: int, value: float) -> np.ndarray:
        """(S,) or scalar m added to cable ``cable``'s measured elongation when the per-cable shape
        (``Shape.per_cable``) of this effect is ``value``: the per-cable search's trial offset
        (default: ``value`` itself, a rest elongation)."""
        return value

    @classmethod
    def to_plant(cls, params: NeckParams, values: dict, shape: dict) -> tuple[NeckParams, "Effect | None"]:
        """The fitted term as plant data: ``values`` symbol -> fitted array (per :attr:`columns`),
        ``shape`` its shape; returns (constants, extra effect or None)."""
        return params, None

    @classmethod
    def when_absent(cls, params: NeckParams, elastic: bool) -> NeckParams:
        """Plant constants for a fitted model that lacks this (baseline) effect."""
        return params

    @classmethod
    def sign_violation(cls, values: dict, sigmas: dict) -> str:
        """'' when every clearly non-zero magnitude of a signed column is >= 0, else why not."""
        for col in cls.columns:
            if not col.signed or col.symbol not in values:
                continue
            v = np.asarray(values[col.symbol], dtype=float)
            bad = clearly_nonzero(v, sigmas[col.symbol]) & (v < 0)
            if bad.any():
                idx = ", ".join(str(i + 1) for i in np.nonzero(bad)[0])
                where = "the head" if col.per == "one" else col.per
                return f"fitted {col.symbol} < 0 on {where} {idx}: not a {cls.name}"
        return ""

    # -- blind tests
    @classmethod
    def blind_forms(cls) -> dict[str, tuple[float, Callable]]:
        """Blind case name -> (test magnitude, ``hide(params, rng, magnitude, cable, joint) -> Hidden``)."""
        if cls.blind_magnitude is None:
            return {}
        return {cls.name: (cls.blind_magnitude, cls.hide)}

    @classmethod
    def hide(cls, params: NeckParams, rng: np.random.Generator, magnitude: float, cable: int, joint: int) -> Hidden:
        raise NotImplementedError(f"{cls.name}: no blind form")


@dataclass(frozen=True)
class MotorEffect(Effect):
    """An extra force along the cable, linear in ``magnitude_field`` (per cable): force =
    magnitude x ``regressor(theta_dot, tension)``; its diagnosis columns follow from that."""

    kind: ClassVar[str] = "motor"

    def regressor(self, theta_dot, tension=None):
        """d force / d magnitude, (..., C)."""
        raise NotImplementedError

    def motor_force(self, theta_dot, tension=None):
        """Force (N) along each cable resisting the motor speed ``theta_dot`` (..., C) rad/s."""
        td = np.asarray(theta_dot, dtype=float)
        return self.per_cable(td.shape[-1]) * self.regressor(td, tension)

    @classmethod
    def unit(cls, shape: dict) -> "MotorEffect":
        """The effect with magnitude 1 on every cable and the given shape."""
        return cls(**{cls.magnitude_field: 1.0}, **shape)

    @classmethod
    def design(cls, data, shape: dict, context) -> Design:
        fast, slow = data.motor_basis(cls, shape, context.tension_fast if cls.uses_tension else None)
        C = data.C
        return Design(data.Z * slow[:, None, :], slow[:, :, None] * np.eye(C), (fast, slow))

    @classmethod
    def to_plant(cls, params: NeckParams, values: dict, shape: dict):
        sym = cls.columns[0].symbol
        mag = np.asarray(values[sym], dtype=float)
        if cls.columns[0].signed:
            mag = np.clip(mag, 0.0, None)
        return params, cls(**{cls.magnitude_field: tuple(mag)}, **shape)
