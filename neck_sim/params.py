"""Every physical constant of the neck, with its unit and its source, in one place.

Parameters are frozen dataclasses grouped by concept (geometry, actuation, springs, inertia,
friction, cables, control, sensors) under one :class:`NeckParams`, with the neck's cable routing
(:class:`neck_sim.routing.Routing`).  Per-joint arrays have
length N (``n_joints``) and per-cable arrays length m (``n_cables``), in the order of
``routing.cables``; the default routing is the paper's (m = N + 1: cables c1..cN pull on the right,
the last one is the long left cable).  Arrays are stored as tuples of floats so that parameter sets
are immutable and hashable; use ``np.asarray`` to compute with them.

Each field carries ``metadata={"unit": ..., "source": ...}``; :func:`describe` prints them.

Sources: "paper" is the paper cited in ``README.md`` (Table/section numbers are the paper's own); "design" is
``docs/geometry-and-errata.md``; "assumption" is a value the paper does not give.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import tomllib
from dataclasses import dataclass, fields
from typing import Any, Mapping, cast

from neck_sim.atomic import atomic_write_bytes
from neck_sim.native.source import MAX_CABLES   # most joints and cables: the arrays of the compiled callback
from neck_sim.routing import Routing, mirrored_paper_routing, mixed4_routing, neck10x4_routing, paper_routing
from neck_sim.validation import ParameterError, check_array, check_integer, check_positive, param_field as _f

__all__ = [
    "Geometry", "Actuation", "Springs", "Inertia", "Friction", "Cables", "Control", "Sensors",
    "NeckParams", "ParameterError", "default_params", "describe", "load", "save", "to_dict", "from_dict",
    "implausible_values", "EXAMPLES", "example_params",
]


def _per_joint(n: int, first: float, rest: float) -> tuple[float, ...]:
    return tuple([first] + [rest] * (n - 1))


def _per_cable(sides: tuple[str, ...], right: tuple[float, ...], left: float) -> tuple[float, ...]:
    """Per-cable defaults by side: the k-th right cable takes ``right[k]`` (the table's last
    beyond it), every left cable ``left``."""
    out, k = [], 0
    for side in sides:
        if side == "right":
            out.append(right[min(k, len(right) - 1)])
            k += 1
        else:
            out.append(left)
    return tuple(out)


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
        check_integer(self, "n_joints", 1, MAX_CABLES)
        check_positive(self, "b", "L", "alpha_max")
        check_positive(self, "r", strict=False)
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
        check_positive(self, "r_d", "R", "I_a", "f_max")
        check_positive(self, "f_min", "t_min", strict=False)
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
        check_array(self, "stiffness", None, non_negative=True)
        check_positive(self, "rest_length")


@dataclass(frozen=True)
class Inertia:
    """Masses of the bar linkage and gravity."""

    bar_mass: float = _f(0.020, "kg", "design: each base/top bar (both planes), assumption")
    diagonal_mass: float = _f(0.025, "kg", "design: each diagonal bar (both planes), assumption")
    gravity: float = _f(9.81, "m/s^2", "standard gravity, acting along -y of the neck's plane")
    payload_mass: float = _f(0.0, "kg", "effect `payload`: point mass at the head's bar centre; nominal 0")

    def __post_init__(self):
        # Moving bars need mass: a massless body has no inertia for MuJoCo (nor for M of eq 24).
        check_positive(self, "bar_mass", "diagonal_mass")
        check_positive(self, "gravity", "payload_mass", strict=False)


@dataclass(frozen=True)
class Friction:
    """Arctan dry friction at the geared motors, eq (37)."""

    f_s: tuple = _f(None, "N", "paper Table 1 (ident. with eqs 44-45): 14.42, 17.65, 18.77, 16.18 N; "
                               "right cables beyond c3 repeat c3 (assumption)")
    c_s: float = _f(0.5, "s/rad", "paper §5.1.1: c_s = 0.5")

    def __post_init__(self):
        if self.f_s is None:
            raise ParameterError("friction.f_s: required (use NeckParams.default)")
        check_array(self, "f_s", None, non_negative=True)
        check_positive(self, "c_s")


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
        check_array(self, "k", None, positive=True)
        check_array(self, "lam", None, non_negative=True)
        check_array(self, "c_a", None, non_negative=True)
        if self.k_linear is not None:
            check_array(self, "k_linear", None, positive=True)
        check_positive(self, "t_cap")
        # Lengths are checked against n_joints by NeckParams, which names the array that is wrong.


@dataclass(frozen=True)
class Control:
    """Control-law constants of §6."""

    rate_hz: float = _f(500.0, "Hz", "paper §2.2: control frequency 500 Hz")
    omega: float = _f(11.0, "rad/s", "paper §6.1: k_p = 3 w^2, k_v = 3 w, k_i = w^3 with w = 11")
    c_a_estimator: float = _f(3000.0, "N s/m",
                              "paper §5.3: damping used in the elongation estimator of eq (58)")

    def __post_init__(self):
        check_positive(self, "rate_hz", "omega", "c_a_estimator")

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
        check_integer(self, "encoder_counts_per_turn", 1)
        check_positive(self, "camera_rate_hz")
        check_positive(self, "camera_noise", strict=False)

    @property
    def encoder_resolution(self) -> float:
        """One encoder count in radians at the motor shaft."""
        return 2 * math.pi / self.encoder_counts_per_turn


EXAMPLES = {
    "paper": (3, lambda: paper_routing(3), "the paper's prototype: 3 X-joints, 3 right cables + 1 long left cable"),
    "neck10x4": (10, neck10x4_routing, "10 X-joints, 4 cables: lower and upper antagonistic pairs"),
    "mirrored3": (3, lambda: mirrored_paper_routing(3),
                  "the paper's neck with its routing mirrored (3 left cables + 1 long right cable)"),
    "mixed4": (4, mixed4_routing, "4 X-joints, 4 cables using every segment kind (a test case)"),
}
"""Example necks: name -> (n_joints, routing factory, description)."""


def example_params(name: str) -> "NeckParams":
    """Default parameters of an example neck (:data:`EXAMPLES`)."""
    if name not in EXAMPLES:
        raise ParameterError(f"example {name!r}: unknown (known: {', '.join(EXAMPLES)})")
    n, routing, _ = EXAMPLES[name]
    return default_params(n, routing())

_GROUPS = {"geometry": Geometry, "actuation": Actuation, "springs": Springs, "inertia": Inertia,
           "friction": Friction, "cables": Cables, "control": Control, "sensors": Sensors,
           "routing": Routing}


@dataclass(frozen=True)
class NeckParams:
    """All constants of one neck: N X-joints, m cables (``routing``; default the paper's N + 1)."""

    geometry: Geometry
    actuation: Actuation
    springs: Springs
    inertia: Inertia
    friction: Friction
    cables: Cables
    control: Control
    sensors: Sensors
    # None asks for the paper's routing of N joints, which __post_init__ sets: never None after it
    routing: Routing = cast(Routing, None)

    def __post_init__(self):
        n = self.geometry.n_joints
        if self.routing is None:
            object.__setattr__(self, "routing", paper_routing(n))
        elif not isinstance(self.routing, Routing):
            raise ParameterError(f"routing: expected a Routing, got {type(self.routing).__name__}")
        self.routing.check_joints(n)
        m = self.routing.n_cables
        if m > MAX_CABLES:
            raise ParameterError(f"routing: {m} cables (n_joints = {n}), at most {MAX_CABLES} are supported "
                                 f"(so at most {MAX_CABLES - 1} joints with the paper's routing)")
        checks = [("springs.stiffness", self.springs.stiffness, n, f"joint, n_joints = {n}"),
                  ("friction.f_s", self.friction.f_s, m, f"cable, {m} in routing.cables"),
                  ("cables.k", self.cables.k, m, f"cable, {m} in routing.cables"),
                  ("cables.lam", self.cables.lam, m, f"cable, {m} in routing.cables"),
                  ("cables.c_a", self.cables.c_a, m, f"cable, {m} in routing.cables"),
                  ("cables.k_linear", self.cables.k_linear, m, f"cable, {m} in routing.cables")]
        for name, vals, want, per in checks:
            if vals is not None and len(vals) != want:
                raise ParameterError(f"{name}: expected {want} values (one per {per}), got {len(vals)}")
        g, l0 = self.geometry, self.springs.rest_length
        if l0 >= g.L + g.b:
            raise ParameterError(
                f"springs.rest_length: {l0} m is longer than a side can ever be (L + b = {g.L + g.b} m)")

    @property
    def n_joints(self) -> int:
        return self.geometry.n_joints

    @property
    def n_cables(self) -> int:
        """Number of cables m (and motors), the length of every per-cable array."""
        return self.routing.n_cables

    @classmethod
    def default(cls, n_joints: int = 3) -> "NeckParams":
        """The paper's prototype (N = 3) or its natural extension to N joints."""
        return default_params(n_joints)

    def replace(self, **groups_or_fields: Any) -> "NeckParams":
        """Copy with whole groups replaced (``geometry=...``) or dotted fields (``**{"geometry.r": 0}``).

        Each group is validated once, with all its changed fields set: the order of the changes
        does not matter (b = 0.12 m then L = 0.2 m is as valid as L then b)."""
        groups = {name: getattr(self, name) for name in _GROUPS}
        fields_by_group: dict[str, dict[str, Any]] = {}
        for key, value in groups_or_fields.items():
            if "." in key:
                grp, fld = key.split(".", 1)
                if grp not in groups:
                    raise ParameterError(f"{key}: unknown group {grp!r}")
                if fld not in {f.name for f in fields(groups[grp])}:
                    raise ParameterError(f"{key}: unknown field")
                fields_by_group.setdefault(grp, {})[fld] = value
            elif key in groups:
                groups[key] = value
            else:
                raise ParameterError(f"{key}: unknown parameter group")
        for grp, changes in fields_by_group.items():
            groups[grp] = dataclasses.replace(groups[grp], **changes)
        return NeckParams(**groups)


def default_params(n_joints: int = 3, routing: Routing | None = None) -> NeckParams:
    """Defaults of the paper and the design notes for an N-joint neck with ``routing`` (default
    the paper's); per-cable defaults go by side (right cables take Table 1/2's c1, c2, c3 in order,
    left cables c4's)."""
    geometry = Geometry(n_joints=n_joints)
    n = geometry.n_joints
    routing = paper_routing(n) if routing is None else routing
    sides = routing.sides
    return NeckParams(
        geometry=geometry,
        actuation=Actuation(),
        springs=Springs(stiffness=_per_joint(n, 600.0, 200.0)),
        inertia=Inertia(),
        friction=Friction(f_s=_per_cable(sides, (14.42, 17.65, 18.77), 16.18)),
        cables=Cables(k=_per_cable(sides, (5378.0, 5364.0, 6231.0), 1908.0),
                      lam=_per_cable(sides, (103.3, 88.7, 53.2), 120.9),
                      c_a=_per_cable(sides, (50.0,), 50.0),
                      k_linear=_per_cable(sides, (10454.0, 9256.0, 8319.0), 5336.0)),
        control=Control(),
        sensors=Sensors(),
        routing=routing,
    )


def to_dict(params: NeckParams) -> dict[str, dict[str, Any]]:
    """Nested plain dict (lists for arrays), the layout of the JSON/TOML files."""
    out = {}
    for grp in _GROUPS:
        obj = getattr(params, grp)
        if grp == "routing":
            out[grp] = {"cables": [_plain(c) for c in obj.cables]}
        else:
            out[grp] = _plain(obj)
    return out


def _plain(obj) -> dict[str, Any]:
    return {f.name: (list(v) if isinstance(v := getattr(obj, f.name), tuple) else v) for f in fields(obj)}


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
    n = Geometry(n_joints=data.get("geometry", {}).get("n_joints", base.n_joints if base else 3)).n_joints
    if "routing" in data:
        routing = Routing(**data["routing"])
    else:
        routing = base.routing if base is not None and base.n_joints == n else paper_routing(n)
    routing.check_joints(n)
    # Per-cable values of ``base`` stay only while the cables are the same (count and sides).
    if base is None or base.n_joints != n or base.routing.sides != routing.sides:
        base = default_params(n, routing)
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


# -- plausibility of a parameter file: unit mistakes that pass every range check ----------------
# Thresholds sit far above any neck this testbed models (bars of 0.05-0.1 m, masses of 20-25 g)
# and far below what the same values in the wrong unit give (50 mm -> 50 "m", 20 g -> 20 "kg").
EARTH_GRAVITY = 9.81          # m/s^2, standard gravity (the default of Inertia.gravity)
_MAX_LENGTH_M = 5.0           # a length above this in a parameter file reads as millimetres
_MAX_MASS_KG = 10.0           # a mass above this reads as grams
_MAX_GRAVITY = 25.0           # m/s^2; Jupiter's surface is 24.8


def implausible_values(data: "NeckParams | Mapping[str, Any]") -> list[str]:
    """One sentence per value whose magnitude points to a unit mistake (mm for m, g for kg) or an
    unphysical gravity; empty when all are plausible.  ``data``: parameters or the nested dict of a
    parameter file (checked before the values are built, so a unit mistake is named before the
    range checks it would trip)."""
    if isinstance(data, NeckParams):
        data = to_dict(data)

    def value(name):
        grp, fld = name.split(".")
        group = data.get(grp)
        v = group.get(fld) if isinstance(group, Mapping) else None
        return float(v) if isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) else None

    found = []
    for name in ("geometry.b", "geometry.L", "geometry.r", "springs.rest_length", "actuation.r_d"):
        v = value(name)
        if v is not None and v > _MAX_LENGTH_M:
            found.append(f"{name} = {v:g} m looks like millimetres (expected metres: {v / 1000:g} m?)")
    for name in ("inertia.bar_mass", "inertia.diagonal_mass", "inertia.payload_mass"):
        v = value(name)
        if v is not None and v > _MAX_MASS_KG:
            found.append(f"{name} = {v:g} kg looks like grams (expected kilograms: {v / 1000:g} kg?)")
    g = value("inertia.gravity")
    if g is not None and g > _MAX_GRAVITY:
        found.append(f"inertia.gravity = {g:g} m/s^2 is {g / EARTH_GRAVITY:.3g}x Earth's ({EARTH_GRAVITY} m/s^2)")
    return found


def load(path: str | os.PathLike, *, accept_implausible: bool = False) -> NeckParams:
    """Load a ``.json`` or ``.toml`` parameter file; fields it omits take the defaults.

    Values :func:`implausible_values` names (a length in mm, a mass in g, gravity 10x Earth's)
    raise ParameterError unless ``accept_implausible``."""
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
        if _looks_like_the_printed_table(raw):
            raise ParameterError(f"{path}: this is the table `neck-sim params` prints, not a parameter file; "
                                 "write one with `neck-sim params [--example NAME] -o FILE.toml`") from None
        raise ParameterError(f"{path}: malformed parameter file ({exc})") from None
    if not data:
        raise ParameterError(f"{path}: the parameter file is empty (it would silently mean the defaults; "
                             "write `neck-sim params -o FILE` to start from them, or leave --params out)")
    found = implausible_values(data) if isinstance(data, Mapping) else []
    if found and not accept_implausible:
        raise ParameterError(f"{path}: {'; '.join(found)}; use --accept-implausible-params if intended")
    return from_dict(data)


def _looks_like_the_printed_table(raw: bytes) -> bool:
    """True when ``raw`` starts like :func:`describe`'s output (``group.name  value  unit  source``),
    which a user may have redirected into a file meant to be a parameter file."""
    first = raw.decode(errors="replace").lstrip().split("\n", 1)[0].split()
    return len(first) >= 3 and first[0].split(".", 1)[0] in _GROUPS and "=" not in first


def describe(params: NeckParams) -> str:
    """A table of every constant with its unit and source."""
    rows = []
    for grp in _GROUPS:
        obj = getattr(params, grp)
        if grp == "routing":
            continue
        for f in fields(obj):
            v = getattr(obj, f.name)
            vs = ", ".join(f"{x:g}" for x in v) if isinstance(v, tuple) else f"{v:g}"
            rows.append((f"{grp}.{f.name}", vs, f.metadata.get("unit", ""), f.metadata.get("source", "")))
    w0 = max(len(r[0]) for r in rows)
    w1 = max(len(r[1]) for r in rows)
    w2 = max(len(r[2]) for r in rows)
    table = "\n".join(f"{a:<{w0}}  {b:<{w1}}  {c:<{w2}}  {d}" for a, b, c, d in rows)
    return f"{table}\nrouting ({params.n_cables} cables; cases of paper §3.1, ' = mirror image):\n{params.routing.describe()}"
