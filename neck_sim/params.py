"""Every physical constant of the neck, with its unit and its source, in one place.

Parameters are frozen dataclasses grouped by concept (geometry, actuation, springs, inertia,
friction, cables, control, sensors) under one :class:`NeckParams`.  Per-joint arrays have length
N (``n_joints``) and per-cable arrays length N + 1 (cables c1..cN pull on the right, the last one
is the long left cable).  Arrays are stored as tuples of floats so that parameter sets are
immutable and hashable; use ``np.asarray`` to compute with them.

Each field carries ``metadata={"unit": ..., "source": ...}``; :func:`describe` prints them.

Sources: "paper" is ``shared/paper`` (Table/section numbers are the paper's own); "design" is
``shared/design/geometry-and-errata.md``; "assumption" is a value the paper does not give.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import tomllib
from dataclasses import dataclass, field, fields
from typing import Any, Mapping

import numpy as np

from neck_sim.atomic import atomic_write_bytes

__all__ = [
    "Geometry", "Actuation", "Springs", "Inertia", "Friction", "Cables", "Control", "Sensors",
    "NeckParams", "ParameterError", "MAX_JOINTS", "default_params", "describe", "load", "save",
    "to_dict", "from_dict",
]


class ParameterError(ValueError):
    """An invalid parameter value; the message names the offending field."""


MAX_JOINTS = 31
"""Most X-joints a neck may have: the plant's compiled callback holds at most 32 cables."""


def _f(default, unit: str, source: str, **kw):
    return field(default=default, metadata={"unit": unit, "source": source}, **kw)


def _per_joint(n: int, first: float, rest: float) -> tuple[float, ...]:
    return tuple([first] + [rest] * (n - 1))


def _per_cable(n: int, right: tuple[float, ...], left: float) -> tuple[float, ...]:
    """Right cables c1..cN then the left cable; right cables beyond the table repeat its last."""
    vals = [right[min(j, len(right) - 1)] for j in range(n)]
    return tuple(vals + [left])


def _check_number(obj, name: str) -> float:
    """The field as a float, or ParameterError when it is not a number (a string, a bool, a list)."""
    v = getattr(obj, name)
    if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)):
        raise ParameterError(f"{type(obj).__name__.lower()}.{name}: must be a number, got {v!r} "
                             f"({type(v).__name__})")
    object.__setattr__(obj, name, float(v))
    return float(v)


def _check_integer(obj, name: str, minimum: int, maximum: int | None = None) -> None:
    v = getattr(obj, name)
    ok = (not isinstance(v, bool) and isinstance(v, (int, float, np.integer, np.floating))
          and math.isfinite(v) and int(v) == v and v >= minimum and (maximum is None or v <= maximum))
    if not ok:
        limit = f"between {minimum} and {maximum}" if maximum is not None else f">= {minimum}"
        raise ParameterError(f"{type(obj).__name__.lower()}.{name}: must be an integer {limit}, got {v!r}")
    object.__setattr__(obj, name, int(v))


def _check_positive(obj, *names: str, strict: bool = True) -> None:
    for name in names:
        v = _check_number(obj, name)
        bad = (not math.isfinite(v)) or (v <= 0 if strict else v < 0)
        if bad:
            kind = "positive" if strict else "non-negative"
            raise ParameterError(f"{type(obj).__name__.lower()}.{name}: must be finite and {kind}, got {v!r}")


def _check_array(obj, name: str, length: int | None, *, positive: bool = False,
                 non_negative: bool = False) -> None:
    v = getattr(obj, name)
    try:
        arr = np.asarray(v, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ParameterError(f"{type(obj).__name__.lower()}.{name}: not a list of numbers ({exc})") from None
    if arr.ndim != 1:
        raise ParameterError(f"{type(obj).__name__.lower()}.{name}: expected a flat list, got shape {arr.shape}")
    if length is not None and arr.shape[0] != length:
        raise ParameterError(
            f"{type(obj).__name__.lower()}.{name}: expected {length} values, got {arr.shape[0]}")
    if not np.all(np.isfinite(arr)):
        raise ParameterError(f"{type(obj).__name__.lower()}.{name}: contains NaN or infinity")
    if positive and np.any(arr <= 0):
        raise ParameterError(f"{type(obj).__name__.lower()}.{name}: all values must be > 0, got {tuple(arr)}")
    if non_negative and np.any(arr < 0):
        raise ParameterError(f"{type(obj).__name__.lower()}.{name}: all values must be >= 0, got {tuple(arr)}")
    object.__setattr__(obj, name, tuple(float(x) for x in arr))


@dataclass(frozen=True)
class Geometry:
    """X-joint and pulley geometry (metres, radians)."""

    n_joints: int = _f(3, "-", "paper §2.1: three X-joints in series")
    b: float = _f(0.050, "m", "paper §2.1: base and top bar length b = 50 mm")
    L: float = _f(0.100, "m", "paper §2.1: diagonal bar length L = 100 mm")
    r: float = _f(0.0046, "m", "paper §2.2: pulley radius r = 4.6 mm")
    alpha_max: float = _f(math.pi / 2, "rad",
                          "assumption: joint range |alpha| < pi/2, the range of the paper's §5.6 study")

    def __post_init__(self):
        _check_integer(self, "n_joints", 1, MAX_JOINTS)
        _check_positive(self, "b", "L", "alpha_max")
        _check_positive(self, "r", strict=False)
        if self.L <= self.b:
            raise ParameterError(f"geometry.L: the diagonal L = {self.L} m must be longer than the bar b = {self.b} m")
        if not self.alpha_max < math.pi:
            raise ParameterError(f"geometry.alpha_max: must be below pi, got {self.alpha_max}")
        # The shortest side over the range must still wrap its pulley (tangent length > 0).
        if self.r >= self.L - self.b:
            raise ParameterError(f"geometry.r: pulley radius {self.r} m must be below L - b = {self.L - self.b} m")


@dataclass(frozen=True)
class Actuation:
    """Winches, geared motors and force limits (SI)."""

    r_d: float = _f(0.020, "m", "paper §2.2: drum radius r_d = 20 mm")
    R: float = _f(25.0, "-", "paper §2.2: gear ratio R = 25 (MAXON ECMAX40L/PM42)")
    I_a: float = _f(1.0e-5, "kg m^2", "design: motor + gearhead inertia at the motor shaft (assumption)")
    f_min: float = _f(2.0, "N", "paper §6.2: minimal actuation force f_min = 2 N")
    f_max: float = _f(100.0, "N", "design: maximal actuation force (assumption)")
    t_min: float = _f(8.5, "N", "paper §6.2: minimal cable tension t_min = 8.5 N")

    def __post_init__(self):
        _check_positive(self, "r_d", "R", "I_a", "f_max")
        _check_positive(self, "f_min", "t_min", strict=False)
        for name in ("f_min", "t_min"):
            if getattr(self, name) > self.f_max:
                raise ParameterError(f"actuation.{name}: {getattr(self, name)} N exceeds f_max = {self.f_max} N")

    @property
    def reflected_inertia(self) -> float:
        """I_a (R/r_d)^2: motor inertia seen along a cable (kg)."""
        return self.I_a * (self.R / self.r_d) ** 2


@dataclass(frozen=True)
class Springs:
    """Side springs, one on each side of every X-joint (eq 1, 2 sides)."""

    stiffness: tuple = _f(None, "N/m",
                          "paper §2.1: 2x300 N/m in parallel on joint 1 (600), 200 N/m on joints 2, 3; "
                          "joints beyond 3: 200 N/m (assumption)")
    rest_length: float = _f(0.046, "m", "paper §2.1: rest length l0 = 0.046 m")

    def __post_init__(self):
        if self.stiffness is None:
            raise ParameterError("springs.stiffness: required (use NeckParams.default)")
        _check_array(self, "stiffness", None, non_negative=True)
        _check_positive(self, "rest_length")


@dataclass(frozen=True)
class Inertia:
    """Masses of the bar linkage and gravity."""

    bar_mass: float = _f(0.020, "kg", "design: each base/top bar (both planes), assumption")
    diagonal_mass: float = _f(0.025, "kg", "design: each diagonal bar (both planes), assumption")
    gravity: float = _f(9.81, "m/s^2", "standard gravity, acting along -y of the neck's plane")
    payload_mass: float = _f(0.0, "kg", "effect `payload`: point mass at the head's bar centre; nominal 0")

    def __post_init__(self):
        # Moving bars need mass: a massless body has no inertia for MuJoCo (nor for M of eq 24).
        _check_positive(self, "bar_mass", "diagonal_mass")
        _check_positive(self, "gravity", "payload_mass", strict=False)


@dataclass(frozen=True)
class Friction:
    """Arctan dry friction at the geared motors, eq (37)."""

    f_s: tuple = _f(None, "N", "paper Table 1 (ident. with eqs 44-45): 14.42, 17.65, 18.77, 16.18 N; "
                               "right cables beyond c3 repeat c3 (assumption)")
    c_s: float = _f(0.5, "s/rad", "paper §5.1.1: c_s = 0.5")

    def __post_init__(self):
        if self.f_s is None:
            raise ParameterError("friction.f_s: required (use NeckParams.default)")
        _check_array(self, "f_s", None, non_negative=True)
        _check_positive(self, "c_s")


@dataclass(frozen=True)
class Cables:
    """Tension-only elastic cables, eq (54): t = (k + lambda t) x + c_a x_dot."""

    k: tuple = _f(None, "N/m", "paper Table 2: 5378, 5364, 6231, 1908 N/m")
    lam: tuple = _f(None, "1/m", "paper Table 2: 103.3, 88.7, 53.2, 120.9 1/m")
    c_a: tuple = _f(None, "N s/m", "design: 50 N s/m (paper could not identify damping)")
    k_linear: tuple | None = _f(None, "N/m", "paper Table 1: constant-stiffness cable model (model 1, lambda = 0) "
                                             "10454, 9256, 8319, 5336 N/m; what a model-1 estimator believes")
    t_cap: float = _f(1000.0, "N",
                      "assumption: above this tension eq (54) continues linearly (no 1/(1 - lambda x) pole)")

    def __post_init__(self):
        for name in ("k", "lam", "c_a"):
            if getattr(self, name) is None:
                raise ParameterError(f"cables.{name}: required (use NeckParams.default)")
        _check_array(self, "k", None, positive=True)
        _check_array(self, "lam", None, non_negative=True)
        _check_array(self, "c_a", None, non_negative=True)
        if self.k_linear is not None:
            _check_array(self, "k_linear", None, positive=True)
        _check_positive(self, "t_cap")
        # Lengths are checked against n_joints by NeckParams, which names the array that is wrong.


@dataclass(frozen=True)
class Control:
    """Control-law constants of §6."""

    rate_hz: float = _f(500.0, "Hz", "paper §2.2: control frequency 500 Hz")
    omega: float = _f(11.0, "rad/s", "paper §6.1: k_p = 3 w^2, k_v = 3 w, k_i = w^3 with w = 11")
    c_a_estimator: float = _f(3000.0, "N s/m",
                              "paper §5.3: damping used in the elongation estimator of eq (58)")

    def __post_init__(self):
        _check_positive(self, "rate_hz", "omega", "c_a_estimator")

    @property
    def gains(self) -> tuple[float, float, float]:
        """(k_p, k_v, k_i) of eq (59)."""
        w = self.omega
        return 3 * w * w, 3 * w, w ** 3


@dataclass(frozen=True)
class Sensors:
    """What the prototype measures."""

    encoder_counts_per_turn: int = _f(2048, "counts/turn", "design: encoder resolution at the motor shaft")
    camera_rate_hz: float = _f(30.0, "Hz", "paper §4.2: 30 frames per second")
    camera_noise: float = _f(math.radians(1.0), "rad", "paper §4.2: image-processing precision about 1 deg")

    def __post_init__(self):
        _check_integer(self, "encoder_counts_per_turn", 1)
        _check_positive(self, "camera_rate_hz")
        _check_positive(self, "camera_noise", strict=False)

    @property
    def encoder_resolution(self) -> float:
        """One encoder count in radians at the motor shaft."""
        return 2 * math.pi / self.encoder_counts_per_turn


_GROUPS = {"geometry": Geometry, "actuation": Actuation, "springs": Springs, "inertia": Inertia,
           "friction": Friction, "cables": Cables, "control": Control, "sensors": Sensors}


@dataclass(frozen=True)
class NeckParams:
    """All constants of one neck: N X-joints, N + 1 cables."""

    geometry: Geometry
    actuation: Actuation
    springs: Springs
    inertia: Inertia
    friction: Friction
    cables: Cables
    control: Control
    sensors: Sensors

    def __post_init__(self):
        n = self.geometry.n_joints
        checks = [("springs.stiffness", self.springs.stiffness, n, "joint"),
                  ("friction.f_s", self.friction.f_s, n + 1, "cable"),
                  ("cables.k", self.cables.k, n + 1, "cable"),
                  ("cables.lam", self.cables.lam, n + 1, "cable"),
                  ("cables.c_a", self.cables.c_a, n + 1, "cable"),
                  ("cables.k_linear", self.cables.k_linear, n + 1, "cable")]
        for name, vals, want, per in checks:
            if vals is not None and len(vals) != want:
                raise ParameterError(f"{name}: expected {want} values (one per {per}, n_joints = {n}), got {len(vals)}")
        g, l0 = self.geometry, self.springs.rest_length
        if l0 >= g.L + g.b:
            raise ParameterError(
                f"springs.rest_length: {l0} m is longer than a side can ever be (L + b = {g.L + g.b} m)")

    @property
    def n_joints(self) -> int:
        return self.geometry.n_joints

    @property
    def n_cables(self) -> int:
        return self.geometry.n_joints + 1

    @classmethod
    def default(cls, n_joints: int = 3) -> "NeckParams":
        """The paper's prototype (N = 3) or its natural extension to N joints."""
        return default_params(n_joints)

    def replace(self, **groups_or_fields) -> "NeckParams":
        """Copy with whole groups replaced (``geometry=...``) or dotted fields (``**{"geometry.r": 0}``)."""
        groups = {name: getattr(self, name) for name in _GROUPS}
        for key, value in groups_or_fields.items():
            if "." in key:
                grp, fld = key.split(".", 1)
                if grp not in groups:
                    raise ParameterError(f"{key}: unknown group {grp!r}")
                try:
                    groups[grp] = dataclasses.replace(groups[grp], **{fld: value})
                except TypeError:
                    raise ParameterError(f"{key}: unknown field") from None
            elif key in groups:
                groups[key] = value
            else:
                raise ParameterError(f"{key}: unknown parameter group")
        return NeckParams(**groups)


def default_params(n_joints: int = 3) -> NeckParams:
    """Defaults of the paper and the design notes for an N-joint neck."""
    geometry = Geometry(n_joints=n_joints)
    n = geometry.n_joints
    return NeckParams(
        geometry=geometry,
        actuation=Actuation(),
        springs=Springs(stiffness=_per_joint(n, 600.0, 200.0)),
        inertia=Inertia(),
        friction=Friction(f_s=_per_cable(n, (14.42, 17.65, 18.77), 16.18)),
        cables=Cables(k=_per_cable(n, (5378.0, 5364.0, 6231.0), 1908.0),
                      lam=_per_cable(n, (103.3, 88.7, 53.2), 120.9),
                      c_a=_per_cable(n, (50.0,), 50.0),
                      k_linear=_per_cable(n, (10454.0, 9256.0, 8319.0), 5336.0)),
        control=Control(),
        sensors=Sensors(),
    )


def to_dict(params: NeckParams) -> dict[str, dict[str, Any]]:
    """Nested plain dict (lists for arrays), the layout of the JSON/TOML files."""
    out = {}
    for grp in _GROUPS:
        obj = getattr(params, grp)
        out[grp] = {f.name: (list(v) if isinstance(v := getattr(obj, f.name), tuple) else v) for f in fields(obj)}
    return out


def from_dict(data: Mapping[str, Any], base: NeckParams | None = None) -> NeckParams:
    """Build parameters from a nested dict; missing fields come from ``base`` (defaults for its N).

    Unknown groups or fields raise :class:`ParameterError` naming them (a typo must not be ignored).
    """
    if not isinstance(data, Mapping):
        raise ParameterError(f"parameter file: expected a table of groups, got {type(data).__name__}")
    for grp, vals in data.items():
        if grp not in _GROUPS:
            raise ParameterError(f"{grp}: unknown parameter group (known: {', '.join(_GROUPS)})")
        if not isinstance(vals, Mapping):
            raise ParameterError(f"{grp}: expected a table of fields")
        known = {f.name for f in fields(_GROUPS[grp])}
        for key in vals:
            if key not in known:
                raise ParameterError(f"{grp}.{key}: unknown field (known: {', '.join(sorted(known))})")
    n = data.get("geometry", {}).get("n_joints", base.n_joints if base else 3)
    if base is None or base.n_joints != n:
        base = default_params(n)
    groups = {}
    for grp, cls in _GROUPS.items():
        current = dataclasses.asdict(getattr(base, grp))
        current.update(data.get(grp, {}))
        groups[grp] = cls(**current)
    return NeckParams(**groups)


def save(params: NeckParams, path: str | os.PathLike) -> None:
    """Save as ``.json`` or ``.toml`` (by extension), atomically."""
    path = os.fspath(path)
    data = to_dict(params)
    if path.endswith(".toml"):
        import tomli_w
        payload = tomli_w.dumps(data).encode()
    elif path.endswith(".json"):
        payload = (json.dumps(data, indent=2) + "\n").encode()
    else:
        raise ParameterError(f"{path}: parameter files end in .json or .toml")
    atomic_write_bytes(path, payload)


def load(path: str | os.PathLike) -> NeckParams:
    """Load a ``.json`` or ``.toml`` parameter file; fields it omits take the defaults."""
    path = os.fspath(path)
    try:
        with open(path, "rb") as fh:
            raw = fh.read()
    except OSError as exc:
        raise ParameterError(f"{path}: cannot read parameter file ({exc.strerror})") from None
    try:
        if path.endswith(".toml"):
            data = tomllib.loads(raw.decode())
        elif path.endswith(".json"):
            data = json.loads(raw)
        else:
            raise ParameterError(f"{path}: parameter files end in .json or .toml")
    except (tomllib.TOMLDecodeError, json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise ParameterError(f"{path}: malformed parameter file ({exc})") from None
    if not data:
        raise ParameterError(f"{path}: the parameter file is empty (it would silently mean the defaults; "
                             "write `neck-sim params -o FILE` to start from them, or leave --params out)")
    return from_dict(data)


def describe(params: NeckParams) -> str:
    """A table of every constant with its unit and source."""
    rows = []
    for grp in _GROUPS:
        obj = getattr(params, grp)
        for f in fields(obj):
            v = getattr(obj, f.name)
            vs = ", ".join(f"{x:g}" for x in v) if isinstance(v, tuple) else f"{v:g}"
            rows.append((f"{grp}.{f.name}", vs, f.metadata.get("unit", ""), f.metadata.get("source", "")))
    w0 = max(len(r[0]) for r in rows)
    w1 = max(len(r[1]) for r in rows)
    w2 = max(len(r[2]) for r in rows)
    return "\n".join(f"{a:<{w0}}  {b:<{w1}}  {c:<{w2}}  {d}" for a, b, c, d in rows)
