"""The protocol of an effect's identification side: its regressor columns over a typed view of the data.

One class per effect (:mod:`identification.diagnosis.columns`, keyed by the effect's name in
:mod:`neck_sim.effects`) says how the diagnosis fits the effect, linear in its magnitudes once its
shape parameters are fixed; the effect's physics (parameters, force law, plant hooks) stays in its
own module of :mod:`neck_sim.effects`.  Every hook is a classmethod with a default that does
nothing, so a class overrides only what its effect needs:

* ``columns`` -- the :class:`Column` groups it adds to the parameter vector (symbol, unit, one per
  cable/joint or one in all, physical sign); ``design(data, shape, context)`` builds them from a
  :class:`ColumnData` (what the columns may read of the measured data, nothing else) and a
  :class:`FitContext` (the fit's current elongations and tension estimates);
* ``shapes`` -- the nonlinear :class:`Shape` parameters (default, search grid, refinement);
* ``fit_delay(shape)``, ``fit_motor_delays(shape, n_cables)``, ``fit_camera_shift(shape)``, ``fit_elongation_offset(shape, n_cables)``,
  ``fit_elongation_series(data, shape)``, ``fit_force_offset(data, shape)`` -- effects that shift
  the observations, the camera or the elongations instead of adding columns
  (``fit_cable_offset`` the per-cable trial offset of a ``Shape.per_cable`` search);
* ``to_plant(params, values, shape)`` -- the fitted result back as plant constants and an effect;
  ``when_absent(params, elastic)`` -- the plant constants when a model lacks a baseline effect;
* ``elastic_cables`` (a model with it has elastic cables, eq 54), ``uses_tension`` (its columns
  need the tension estimate: the fit iterates), ``columns_exact`` (columns x values are the plant's
  law exactly; False when the plant's law is a MuJoCo constraint the columns smooth).

Columns compose as pysindy's feature libraries do: a model's design is its terms' designs side by
side (:meth:`Design.concat`), in the model's order.

Indices of per-cable arrays follow the routing's cables (``params.routing.cables``, C of them),
per-joint arrays have N.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, ClassVar, Hashable, NamedTuple, Protocol, TypeVar, runtime_checkable

import numpy as np

from neck_sim import effects as effect_registry
from neck_sim.effects import Effect
from neck_sim.params import NeckParams

from identification.diagnosis.statistics import clearly_nonzero
from identification.preprocessing import Prepared

__all__ = ["ColumnData", "FitContext", "Column", "Shape", "Design", "EffectColumns", "MotorColumns"]

_T = TypeVar("_T")


@runtime_checkable
class ColumnData(Protocol):
    """What an effect's columns read of one log's measured data (:class:`MeasuredData
    <identification.diagnosis.measured.MeasuredData>` answers it), and nothing more.

    Shapes: T control-rate samples, S slow-grid samples, N joints, C cables (the routing's).
    Camera-side quantities are on the slow grid (shifted when the model has a camera delay).
    """

    params: NeckParams          # the nominal constants (geometry, drive, springs, masses)
    n: int                      # N joints
    C: int                      # C cables
    S: int                      # slow-grid samples
    t: np.ndarray               # (S,) s, the slow grid
    t_fast: np.ndarray          # (T,) s, the control rate
    dt: float                   # s, control period
    ratio: float                # R / r_d, rad of motor per m of cable (1/m)
    alpha: np.ndarray           # (S, N) rad, the camera's joint angles
    alpha_dot: np.ndarray       # (S, N) rad/s
    alpha_ddot: np.ndarray      # (S, N) rad/s^2
    Z: np.ndarray               # (S, N, C) m, transmission matrix at alpha (eq 28)
    x_dot: np.ndarray           # (S, C) m/s, elongation rate of eq (27)
    theta_fast: np.ndarray      # (T, C) rad, the encoders at the control rate
    theta_dot_fast: np.ndarray  # (T, C) rad/s, their speed (motor cutoff only)
    prep: Prepared              # the pre-processing's output (its rates and cutoffs)

    def motor_lowpass(self, v: np.ndarray) -> np.ndarray:
        """A control-rate signal (T, ...) through the encoders' low-pass, at the control rate (T, ...)."""
        ...

    def to_slow(self, v: np.ndarray) -> np.ndarray:
        """A control-rate signal (T, ...) through the observations' filter chain -> (S, ...)."""
        ...

    def cached(self, key: Hashable, compute: Callable[[], _T]) -> _T:
        """``compute()`` once per ``key`` for this log (columns that do not depend on the fit)."""
        ...


class FitContext(NamedTuple):
    """What an effect's ``design`` may use besides the data, for one pass of a fit: elongations
    ``x`` (S, C) m with the model's rest elongations, tension estimates ``tension_fast`` (T, C) and
    ``tension`` (S, C) N from the previous pass."""

    x: np.ndarray
    tension_fast: np.ndarray
    tension: np.ndarray


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

    def names(self, n_joints: int, n_cables: int, joint: int | None = None,
              cable: int | None = None) -> tuple[str, ...]:
        """Column names for a neck of N = ``n_joints`` joints and m = ``n_cables`` cables; with
        ``joint`` (or ``cable``, 1-based) those of that joint (cable) only (:meth:`select`)."""
        if self.per == "one":
            return (self.symbol,)
        if self.per == "spring":
            out = tuple(f"{self.symbol}({i + 1}{side})" for i in range(n_joints) for side in "LR")
        else:
            count = {"cable": n_cables, "joint": n_joints}[self.per]
            out = tuple(f"{self.symbol}({i + 1})" for i in range(count))
        return out[self.select(joint, cable)]

    def select(self, joint: int | None, cable: int | None = None) -> slice:
        """The columns of 1-based ``joint`` among this group's (one per joint, two per joint's
        side springs), or of 1-based ``cable`` in a group per cable; every column when neither
        applies to the group."""
        if cable is not None and self.per == "cable":
            return slice(cable - 1, cable)
        if joint is None or self.per not in ("joint", "spring"):
            return slice(None)
        width = 2 if self.per == "spring" else 1
        return slice(width * (joint - 1), width * joint)

    def expand(self, values, n_joints: int, joint: int | None, n_cables: int = 0,
               cable: int | None = None) -> np.ndarray:
        """The group's values on every joint or cable (zeros off ``joint`` or ``cable``) from
        those of :meth:`select`."""
        v = np.asarray(values, dtype=float)
        located = (cable is not None and self.per == "cable") or (joint is not None and self.per in ("joint", "spring"))
        if not located:
            return v
        out = np.zeros(len(self.names(n_joints, n_cables)))
        out[self.select(joint, cable)] = v
        return out


@dataclass(frozen=True)
class Shape:
    """A nonlinear shape parameter of an effect, fixed inside each linear fit and searched around it.

    ``default`` -- the value when a model names the effect without a shape; ``grid`` -- the values
    a candidate is tried at; ``refine`` -- ``"log"`` or ``"linear"`` to refine the best grid point
    by a bounded 1-D search (None: grid only); ``span`` -- the later re-tuning range (factor for
    ``log``, +- units for ``linear``); ``profile_step`` -- step of the profile-likelihood sigma in
    reports (None: reported without sigma).  ``per_cable``: one value per cable, keys
    ``<name>_<i>`` (1-based), searched on ``bounds`` cable by cable: ``search`` = ``"cable_law"``
    on that cable's law alone (an elongation offset), ``"fit"`` by whole fits with the shape on
    one cable at a time, on ``grid`` then refined between neighbours (a delay on one motor).
    ``every_cable`` (with ``search="cable_law"``): once the kept cables' term passes its training
    F-test, the term with every cable at its searched value is tried as well (a gear play on every
    motor), the form with the smaller training F-test p kept.
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
    search: str = "cable_law"
    every_cable: bool = False

    def __post_init__(self):
        if self.refine not in (None, "log", "linear"):
            raise ValueError(f"Shape.refine: None, 'log' or 'linear', got {self.refine!r}")
        if self.search not in ("cable_law", "fit"):
            raise ValueError(f"Shape.search: 'cable_law' or 'fit', got {self.search!r}")

    def per_cable_values(self, shape: dict, n_cables: int) -> np.ndarray:
        """This per-cable shape's values (n_cables,) from a shape dict's keys ``<name>_<i>``
        (1-based); 0 for a cable the dict does not name."""
        prefix, out = f"{self.name}_", np.zeros(n_cables)
        for key, v in shape.items():
            if key.startswith(prefix):
                out[int(key[len(prefix):]) - 1] = v
        return out


class Design(NamedTuple):
    """Regressor columns of one effect for one fit (S samples, N joints, C cables, p columns):
    ``torque`` (S, N, p) N m per unit parameter, ``cable`` (S, C, p) N per unit parameter, and for
    motor-side forces ``motor`` = (fast (T, C), slow (S, C)) force per unit magnitude (the fit
    subtracts them to estimate the tension)."""

    torque: np.ndarray
    cable: np.ndarray
    motor: tuple | None = None

    @staticmethod
    def concat(designs: "list[Design]", n_joints: int, n_cables: int, n_samples: int) -> tuple[np.ndarray, np.ndarray]:
        """(torque (S, N, p), cable (S, C, p)): the designs side by side, p their columns in all."""
        if not designs:
            return np.zeros((n_samples, n_joints, 0)), np.zeros((n_samples, n_cables, 0))
        return np.concatenate([d.torque for d in designs], axis=2), np.concatenate([d.cable for d in designs], axis=2)


class EffectColumns:
    """Base of every effect's identification side; see the module docstring for the protocol.

    ``effect`` is the registered name of the effect in :mod:`neck_sim.effects`.
    """

    effect: ClassVar[str] = ""
    columns: ClassVar[tuple] = ()
    shapes: ClassVar[tuple] = ()
    elastic_cables: ClassVar[bool] = False      # in a model, makes its cables elastic (eq 54)
    uses_tension: ClassVar[bool] = False        # columns need the tension estimate (iterated fit)
    columns_exact: ClassVar[bool] = True        # columns x values = the plant's law exactly (False: the
    #                                             plant's law is a MuJoCo constraint the columns smooth)
    # its magnitudes read the camera's noisy joint accelerations on both sides of the equation (an
    # inertial term): corrected by simulation-extrapolation when C < N (diagnosis/errors_in_variables.py)
    camera_noise_bias: ClassVar[bool] = False
    # a term may carry the shape key ``joint`` (1-based): its per-joint and per-spring columns on
    # that joint only (one joint's spring error, one hinge's friction), searched joint by joint
    locates_joint: ClassVar[bool] = False
    # a motor-side term may carry the shape key ``cable`` (1-based): its per-cable columns on that
    # cable only (a friction on one motor), tried when the every-cable form fails its tests
    locates_cable: ClassVar[bool] = False

    @classmethod
    def effect_class(cls) -> type[Effect]:
        """The physics of the effect (:mod:`neck_sim.effects`)."""
        return effect_registry.get(cls.effect)

    @classmethod
    def default_shape(cls) -> tuple:
        """((key, value), ...) sorted by key: the shape of a term named without one."""
        return tuple(sorted((s.name, float(s.default)) for s in cls.shapes if s.default is not None))

    @classmethod
    def joint_of(cls, shape: dict) -> int | None:
        """The 1-based joint a located term acts on (shape key ``joint`` of an effect with
        :attr:`locates_joint`); None: every joint."""
        v = shape.get("joint") if cls.locates_joint else None
        return None if v is None else int(v)

    @classmethod
    def cable_of(cls, shape: dict) -> int | None:
        """The 1-based cable a located motor-side term acts on (shape key ``cable`` of an effect
        with :attr:`locates_cable`); None: every cable."""
        v = shape.get("cable") if cls.locates_cable else None
        return None if v is None else int(v)

    @classmethod
    def without_location(cls, shape: dict) -> dict:
        """``shape`` less its location key (``cable``): the effect's own shape parameters."""
        return {k: v for k, v in shape.items() if not (k == "cable" and cls.locates_cable)}

    @classmethod
    def column_names(cls, n_joints: int, n_cables: int, shape: dict) -> tuple[tuple[str, str], ...]:
        """(name, unit) of each regressor column of a term with ``shape`` (a located term: its
        joint's or cable's only), in :meth:`design`'s order."""
        joint, cable = cls.joint_of(shape), cls.cable_of(shape)
        return tuple((nm, col.unit) for col in cls.columns for nm in col.names(n_joints, n_cables, joint, cable))

    @classmethod
    def places(cls, shape: dict, n_joints: int, n_cables: int | None = None) -> int:
        """The number of tests a term with ``shape`` stands for (its p values are multiplied by it:
        Bonferroni).  An effect with :attr:`locates_joint` is tried in two forms, each at half the
        candidate's level: every joint at once (2), then, when that form's training F-test does not
        pass, each of the N joints alone (2 N); one with :attr:`locates_cable` the same over its
        cables (2, then 2 C for a term on one cable, which needs ``n_cables``); 1 for every other
        effect (a per-cable shape tried on every cable too, ``Shape.every_cable``, only once the
        kept cables pass their training F-test: that test bounds its level)."""
        if cls.locates_joint:
            return 2 * n_joints if cls.joint_of(shape) is not None else 2
        if cls.locates_cable:
            if cls.cable_of(shape) is None:
                return 2
            if n_cables is None:
                raise ValueError(f"{cls.effect}: the places of a term on one cable need the number of cables")
            return 2 * n_cables
        return 1

    @classmethod
    def design(cls, data: ColumnData, shape: dict, context: FitContext) -> Design:
        """Regressor columns for one fit on ``data``; ``context`` carries the fit's current
        elongations ``x`` (S, C) m and tension estimates (``tension_fast`` (T, C), ``tension`` (S, C) N)."""
        S, n, C = data.S, data.n, data.C
        return Design(np.zeros((S, n, 0)), np.zeros((S, C, 0)))

    @classmethod
    def fit_delay(cls, shape: dict) -> float:
        """Delay (s) of the commanded force this term imposes on the observations."""
        return 0.0

    @classmethod
    def fit_motor_delays(cls, shape: dict, n_cables: int) -> np.ndarray:
        """(n_cables,) s by which this term delays each motor's commanded force on top of
        :meth:`fit_delay` (a delay on some motors only)."""
        return np.zeros(n_cables)

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
    def fit_elongation_series(cls, data: ColumnData, shape: dict) -> np.ndarray | None:
        """(S, C) m this term adds to the measured elongations sample by sample (None: nothing);
        for offsets that follow the motion (a dead band)."""
        return None

    @classmethod
    def fit_force_offset(cls, data: ColumnData, shape: dict) -> tuple[np.ndarray, np.ndarray] | None:
        """(fast (T, C), slow (S, C)) N this term adds to the cable-side observations
        y_C = f - (R/r_d) I_a theta_ddot (None: nothing); e.g. the inertia term read from the
        drum's acceleration where the encoders show the motor's."""
        return None

    @classmethod
    def fit_cable_offset(cls, data: ColumnData, cable: int, value: float) -> np.ndarray | float:
        """(S,) or scalar m added to cable ``cable``'s measured elongation when the per-cable shape
        (``Shape.per_cable``) of this effect is ``value``: the per-cable search's trial offset
        (default: ``value`` itself, a rest elongation)."""
        return value

    @classmethod
    def to_plant(cls, params: NeckParams, values: dict, shape: dict) -> tuple[NeckParams, Effect | None]:
        """The fitted term as plant data: ``values`` symbol -> fitted array (per :attr:`columns`),
        ``shape`` its shape; returns (constants, extra effect or None)."""
        return params, None

    @classmethod
    def when_absent(cls, params: NeckParams, elastic: bool) -> NeckParams:
        """Plant constants for a fitted model that lacks this (baseline) effect."""
        return params

    @classmethod
    def derived_parameters(cls, theta_dot: np.ndarray, fitted: dict, shape: dict) -> dict:
        """Parameters reported beside the fitted ones, {name: (value, sigma, unit, note)}, from
        ``fitted`` {name: (value, sigma)}, the searched ``shape`` and the encoders' speeds
        ``theta_dot`` (T, C) rad/s (default: none)."""
        return {}

    @classmethod
    def shape_violation(cls, shape: dict) -> str:
        """'' when the searched ``shape`` is one this effect can take, else why not (default: any)."""
        return ""

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
                return f"fitted {col.symbol} < 0 on {where} {idx}: not a {cls.effect}"
        return ""


class MotorColumns(EffectColumns):
    """Columns of a :class:`~neck_sim.effects.MotorEffect`: force = magnitude x regressor per
    cable, in the torque block (eq 51) through Z and in the cable block (eq 42/54) as itself."""

    @classmethod
    def basis(cls, data: ColumnData, shape: dict, tension_fast: np.ndarray | None = None
              ) -> tuple[np.ndarray, np.ndarray]:
        """(fast (T, C), slow (S, C)) force per unit magnitude with ``shape``: the effect's
        regressor on the encoders' speed (and the tension estimate, clipped at 0, when it needs
        one), through the observations' filter chain (parallel filtering: both sides of every
        equation see the same filter)."""
        effect = cls.effect_class()
        shape = cls.without_location(shape)

        def compute():
            t = None
            if cls.uses_tension:
                if tension_fast is None:
                    raise ValueError(f"{effect.name}: needs a tension estimate")
                t = np.maximum(tension_fast, 0.0)
            fast = effect.unit(shape).regressor(data.theta_dot_fast, t)
            return fast, data.to_slow(fast)

        if cls.uses_tension:                # changes with every pass of the fit
            return compute()
        return data.cached((effect.name, tuple(sorted(shape.items()))), compute)

    @classmethod
    def design(cls, data: ColumnData, shape: dict, context: FitContext) -> Design:
        fast, slow = cls.basis(data, shape, context.tension_fast if cls.uses_tension else None)
        C = data.C
        cable = cls.cable_of(shape)
        if cable is None:
            return Design(data.Z * slow[:, None, :], slow[:, :, None] * np.eye(C), (fast, slow))
        # one cable's column; the motor forces zero on the others (the fit scales them by its value)
        on = np.eye(C)[cable - 1]
        return Design(data.Z[:, :, cable - 1:cable] * slow[:, None, cable - 1:cable],
                      (slow * on)[:, :, None], (fast * on, slow * on))

    @classmethod
    def to_plant(cls, params: NeckParams, values: dict, shape: dict) -> tuple[NeckParams, Effect | None]:
        eff = cls.effect_class()
        sym = cls.columns[0].symbol
        mag = np.asarray(values[sym], dtype=float)
        if cls.columns[0].signed:
            mag = np.clip(mag, 0.0, None)
        return params, eff(**{eff.magnitude_field: tuple(mag)}, **shape)
