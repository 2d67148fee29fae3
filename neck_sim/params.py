"""Every physical constant of the neck, with its unit and its source, in one place.

Parameters are frozen dataclasses grouped by concept (geometry, actuation, springs, inertia,
friction, cables, control, sensors, routing) under one :class:`NeckParams`.  Per-joint arrays have
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
import functools
import json
import math
import os
import tomllib
from dataclasses import dataclass, field, fields
from typing import Any, Mapping

import numpy as np

from neck_sim.atomic import atomic_write_bytes
from neck_sim.native import MAX_CABLES   # most joints and cables: the arrays of the compiled callback
from neck_sim.validation import ParameterError, check_array, check_integer, check_positive, is_integer

__all__ = [
    "Geometry", "Actuation", "Springs", "Inertia", "Friction", "Cables", "Control", "Sensors",
    "NeckParams", "ParameterError", "MAX_CABLES", "default_params", "describe", "load", "save",
    "to_dict", "from_dict", "CableRoute", "Routing", "paper_routing", "neck10x4_routing",
    "mirrored_paper_routing", "EXAMPLES", "example_params",
]


def _f(default, unit: str, source: str, **kw):
    return field(default=default, metadata={"unit": unit, "source": source}, **kw)


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


# ------------------------------------------------------------------------------------- routing

SIDES = ("left", "right")
PASS_ROUTINGS = ("strut", "side")

# Segment kinds: what one cable does on one X-joint (the paper's cases a-d and their mirror
# images), compiled into ``Routing.segment_cases`` (m, N).  Their lengths, eqs (3)-(6), and the
# mirror relations live in :mod:`neck_sim.analytic.cables`.
SEG_NONE = 0          # the cable does not reach this joint (it ended below)
SEG_LEFT_END = 1      # case (a): left cable, wraps A_i clockwise, attached at C_i
SEG_RIGHT_END = 2     # case (b) = mirror of (a): right cable, wraps B_i ccw, attached at D_i
SEG_LEFT_SIDE = 3     # case (c): left cable up the left side outside the pulleys (extra turn on C_i)
SEG_RIGHT_STRUT = 4   # case (d): right cable crossing along the diagonal B->C, then the top bar C->D
SEG_RIGHT_SIDE = 5    # mirror of (c): right cable up the right side (extra turn on D_i)
SEG_LEFT_STRUT = 6    # mirror of (d): left cable crossing along the diagonal A->D, then the top bar D->C
N_SEGMENT_KINDS = 7
_PASS_KIND = {("left", "side"): SEG_LEFT_SIDE, ("left", "strut"): SEG_LEFT_STRUT,
              ("right", "side"): SEG_RIGHT_SIDE, ("right", "strut"): SEG_RIGHT_STRUT}
_END_KIND = {"left": SEG_LEFT_END, "right": SEG_RIGHT_END}


@dataclass(frozen=True)
class CableRoute:
    """The path of one cable from its motor at the base to its attachment point.

    Every cable leaves its motor under the base bar and wraps the first pulley of its side
    (A_1 clockwise on the left, B_1 counter-clockwise on the right); it then passes joints
    1..ends_at-1, each either ``"strut"``-routed (crossing along the diagonal from its side's base
    corner to the opposite top corner, then back along the top bar: case d and its mirror) or
    ``"side"``-routed (up its side outside the pulleys: case c and its mirror), and is attached at
    the top corner of its side of joint ``ends_at`` (C for left, D for right: cases a, b).
    """

    side: str = _f("right", "-", "which side's pulleys the cable wraps at every base bar: 'left' or 'right'")
    passes: tuple = _f((), "-", "routing at joints 1..ends_at-1, each 'strut' or 'side'")
    ends_at: int = _f(1, "-", "joint (1-based) at whose top corner of the cable's side it is attached")
    extra_turns: tuple | None = _f(None, "turns",
                                   "extra full turns on the top pulley of each passed joint; a side-routed "
                                   "pass needs one (paper §2.2: the long cable turns once more on C_1, C_2), a "
                                   "strut-routed pass none; default from the routing")
    row: int | None = _f(None, "-", "plane of the cable's pulleys along the hinge axes, in 4 mm steps from the "
                                    "bars (non-zero); default: right cables 1, 2, ..., left cables -1, -2, ...")

    def _where(self, index: int | None) -> str:
        return "routing.cables" if index is None else f"routing.cables[{index}]"

    def validated(self, index: int | None = None) -> "CableRoute":
        """A normalised copy (tuples, ints, default turns) or :class:`ParameterError` naming the field."""
        where = self._where(index)
        if self.side not in SIDES:
            raise ParameterError(f"{where}.side: must be 'left' or 'right', got {self.side!r}")
        passes = (self.passes,) if isinstance(self.passes, str) else self.passes
        try:
            passes = tuple(passes)
        except TypeError:
            raise ParameterError(f"{where}.passes: expected a list of 'strut'/'side', got {self.passes!r}") from None
        for i, p in enumerate(passes):
            if p not in PASS_ROUTINGS:
                raise ParameterError(f"{where}.passes[{i}]: joint {i + 1} must be 'strut' or 'side', got {p!r}")
        e = self.ends_at
        if not is_integer(e) or e < 1:
            raise ParameterError(f"{where}.ends_at: must be a joint number >= 1, got {e!r}")
        e = int(e)
        if len(passes) >= e:
            raise ParameterError(
                f"{where}.ends_at: the cable ends at joint {e} but passes joints 1..{len(passes)} ({len(passes)} "
                f"entries in passes): it must end above the last joint it passes (ends_at = {len(passes) + 1})")
        if len(passes) < e - 1:
            raise ParameterError(
                f"{where}.passes: {len(passes)} entries, but a cable that ends at joint {e} runs up from the base "
                f"and passes every joint below it: give one routing for each of joints 1..{e - 1}")
        default_turns = tuple(1 if p == "side" else 0 for p in passes)
        turns = default_turns if self.extra_turns is None else self.extra_turns
        try:
            turns = tuple(turns)
        except TypeError:
            raise ParameterError(f"{where}.extra_turns: expected a list of integers, got {self.extra_turns!r}") from None
        if len(turns) != len(passes):
            raise ParameterError(f"{where}.extra_turns: expected {len(passes)} values (one per passed joint), "
                                 f"got {len(turns)}")
        for i, (t, p) in enumerate(zip(turns, passes)):
            if not is_integer(t):
                raise ParameterError(f"{where}.extra_turns[{i}]: must be an integer, got {t!r}")
            if p == "side" and t != 1:
                raise ParameterError(
                    f"{where}.extra_turns[{i}]: a side-routed pass needs exactly one extra turn on the top pulley of "
                    f"joint {i + 1} (without it the cable leaves the pulley when the neck bends toward its side; "
                    f"more turns only add a constant length), got {t!r}")
            if p == "strut" and t != 0:
                raise ParameterError(
                    f"{where}.extra_turns[{i}]: a strut-routed pass wraps its pulleys less than half a turn; extra "
                    f"turns there are not modelled (they only add a constant length), got {t!r}")
        row = self.row
        if row is not None:
            if not is_integer(row):
                raise ParameterError(f"{where}.row: must be an integer, got {row!r}")
            if row == 0:
                raise ParameterError(f"{where}.row: row 0 is the plane of the bars, which has no pulleys; "
                                     f"use a non-zero row (1, 2, ... or -1, -2, ...)")
            row = int(row)
        return CableRoute(self.side, passes, e, tuple(int(t) for t in turns), row)

    @property
    def kinds(self) -> tuple[int, ...]:
        """Segment kind on joints 1..ends_at (``SEG_*`` codes)."""
        return tuple(_PASS_KIND[self.side, p] for p in self.passes) + (_END_KIND[self.side],)

    def pulleys(self) -> tuple[tuple[str, int], ...]:
        """Pulleys the cable wraps, in order, as (corner, joint): ``("A", 1)`` is A_1.

        The top corners C_i, D_i of joint i are the base corners A_{i+1}, B_{i+1}; they are
        named as top corners here.  The attachment point is not a wrap and is not listed.
        """
        own_top, other_top = ("C", "D") if self.side == "left" else ("D", "C")
        out = [("A" if self.side == "left" else "B", 1)]
        for i, p in enumerate(self.passes, start=1):
            out += [(other_top, i), (own_top, i)] if p == "strut" else [(own_top, i)]
        return tuple(out)


def _corner_key(corner: str, joint: int) -> tuple[str, int]:
    """One hinge axis, whichever joint names it: C_i = A_{i+1}, D_i = B_{i+1}."""
    if corner in ("A", "B"):
        return ("C" if corner == "A" else "D", joint - 1)
    return corner, joint


@dataclass(frozen=True)
class Routing:
    """The cables of the neck (m of them, m independent of N); per-cable arrays follow this order."""

    cables: tuple = _f(None, "-", "one CableRoute per cable; default: the paper's routing (design notes): right "
                                  "cable j strut-routed on joints 1..j-1 and attached at D_j, one long left cable "
                                  "side-routed to C_N")

    def __post_init__(self):
        if self.cables is None:
            raise ParameterError("routing.cables: required (use paper_routing(n_joints))")
        if isinstance(self.cables, (str, Mapping)) or not hasattr(self.cables, "__iter__"):
            raise ParameterError(f"routing.cables: expected a list of cable tables, got {type(self.cables).__name__}")
        cables = []
        for k, c in enumerate(self.cables):
            if isinstance(c, Mapping):
                known = {f.name for f in fields(CableRoute)}
                unknown = sorted(set(c) - known)
                if unknown:
                    raise ParameterError(f"routing.cables[{k}].{unknown[0]}: unknown field "
                                         f"(known: {', '.join(sorted(known))})")
                c = CableRoute(**c)
            elif not isinstance(c, CableRoute):
                raise ParameterError(f"routing.cables[{k}]: expected a table, got {type(c).__name__}")
            cables.append(c.validated(k))
        if not cables:
            raise ParameterError("routing.cables: a neck needs at least one cable")
        # Default rows: right cables 1, 2, ..., left cables -1, -2, ... (the paper's planes).
        counters = {"right": 0, "left": 0}
        rows = []
        for c in cables:
            counters[c.side] += 1
            rows.append(c.row if c.row is not None else (counters[c.side] if c.side == "right" else -counters[c.side]))
        cables = [dataclasses.replace(c, row=r) for c, r in zip(cables, rows)]
        self._check_rows(cables)
        object.__setattr__(self, "cables", tuple(cables))

    @staticmethod
    def _check_rows(cables) -> None:
        """Two cables may share a row of pulleys only if they touch no common hinge axis."""
        used: dict[tuple[int, tuple[str, int]], int] = {}
        for k, c in enumerate(cables):
            end = ("C" if c.side == "left" else "D", c.ends_at)
            for corner in [_corner_key(*p) for p in c.pulleys()] + [end]:
                other = used.get((c.row, corner))
                if other is not None and other != k:
                    name = (corner[0] + str(corner[1])) if corner[1] > 0 else ("A1" if corner[0] == "C" else "B1")
                    raise ParameterError(
                        f"routing.cables[{k}].row: cables {other} and {k} are both in row {c.row} and both use the "
                        f"hinge axis {name} (a pulley groove holds one cable); give them different rows")
                used[(c.row, corner)] = k

    @property
    def n_cables(self) -> int:
        return len(self.cables)

    def check_joints(self, n_joints: int) -> None:
        """Every cable ends on an existing joint."""
        for k, c in enumerate(self.cables):
            if c.ends_at > n_joints:
                raise ParameterError(f"routing.cables[{k}].ends_at: joint {c.ends_at} does not exist "
                                     f"(n_joints = {n_joints})")

    def segment_cases(self, n_joints: int) -> np.ndarray:
        """``SEG_*`` code of every (cable j, joint i), shape (m, N), int; the analytic model's input."""
        return _segment_cases(self, n_joints)

    @property
    def sides(self) -> tuple[str, ...]:
        return tuple(c.side for c in self.cables)

    def is_paper_kind(self, n_joints: int) -> bool:
        """True for the paper's kind of routing: cables 1..N on the right, cable j strut-routed on
        joints below j and attached at D_j, cable N+1 the long left cable (any turns and rows)."""
        return self.segment_cases(n_joints).tolist() == paper_routing(n_joints).segment_cases(n_joints).tolist()

    def describe(self) -> str:
        """One line per cable: side, row, segment case per joint, pulleys wrapped, attachment."""
        letters = {SEG_LEFT_END: "a", SEG_RIGHT_END: "b", SEG_LEFT_SIDE: "c", SEG_RIGHT_STRUT: "d",
                   SEG_RIGHT_SIDE: "c'", SEG_LEFT_STRUT: "d'"}
        lines = []
        for k, c in enumerate(self.cables):
            own_top = "C" if c.side == "left" else "D"
            turned = {(own_top, i + 1) for i, t in enumerate(c.extra_turns) if t}
            wraps = " ".join(f"{p}{i}" + ("+turn" if (p, i) in turned else "") for p, i in c.pulleys())
            lines.append(f"c{k + 1}: {c.side:<5} row {c.row:+d}  cases {' '.join(letters[x] for x in c.kinds)}  "
                         f"wraps {wraps}  attached at {own_top}{c.ends_at}")
        return "\n".join(lines)


@functools.lru_cache(maxsize=256)
def _segment_cases(routing: Routing, n_joints: int) -> np.ndarray:
    out = np.zeros((routing.n_cables, n_joints), dtype=np.intp)
    for j, c in enumerate(routing.cables):
        out[j, : c.ends_at] = c.kinds
    out.flags.writeable = False
    return out


@functools.lru_cache(maxsize=64)
def paper_routing(n_joints: int = 3) -> Routing:
    """The paper's routing for N joints (design notes): right cable j (j = 1..N) strut-routed on
    joints 1..j-1 and attached at D_j; the long left cable N+1 side-routed on joints 1..N-1 with one
    extra turn on each C_i, attached at C_N."""
    right = [CableRoute("right", ("strut",) * j, j + 1) for j in range(n_joints)]
    return Routing(tuple(right + [CableRoute("left", ("side",) * (n_joints - 1), n_joints)]))



def _route(side: str, strut: int, side_routed: int) -> CableRoute:
    """A cable strut-routed on the first ``strut`` joints, side-routed on the next
    ``side_routed`` and attached at the joint after them."""
    return CableRoute(side, ("strut",) * strut + ("side",) * side_routed, strut + side_routed + 1)


def neck10x4_routing() -> Routing:
    """Ten X-joints, four cables: two antagonistic pairs, like a bird neck's lower and upper
    muscle groups (README "Designing a neck").

    c1 (right) and c2 (left) run up their sides over joints 1-4 and are attached at joint 5:
    they bend the lower neck.  c3 (right) and c4 (left) cross joints 1-5 strut-routed (along the
    diagonals, where their moment arm is small: |Z| <= 1.3 mm against about 25 mm on a side),
    then run up their sides over joints 6-9 and are attached at the head (joint 10): they bend
    the upper neck.  Same-side pulls make C curves, crossed pulls S curves.
    """
    return Routing((_route("right", 0, 4), _route("left", 0, 4), _route("right", 5, 4), _route("left", 5, 4)))


def mirrored_paper_routing(n_joints: int = 3) -> Routing:
    """The paper's routing mirrored: N left cables (cable j strut-routed along the diagonals A->D
    below joint j, attached at C_j) and one long right cable side-routed to D_N."""
    left = [CableRoute("left", ("strut",) * j, j + 1) for j in range(n_joints)]
    return Routing(tuple(left + [CableRoute("right", ("side",) * (n_joints - 1), n_joints)]))


def mixed4_routing() -> Routing:
    """Four joints, four cables using every segment kind (a test case, not a design): a left cable
    alternating strut and side, a right cable alternating side and strut, a short right cable
    and a left cable attached at joint 1."""
    return Routing((CableRoute("left", ("strut", "side", "strut"), 4),
                    CableRoute("right", ("side", "strut", "side"), 4),
                    CableRoute("right", ("side",), 2), CableRoute("left", (), 1)))


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
    routing: Routing | None = None

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

    def replace(self, **groups_or_fields) -> "NeckParams":
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
        raise ParameterError(f"{path}: malformed parameter file ({exc})") from None
    if not data:
        raise ParameterError(f"{path}: the parameter file is empty (it would silently mean the defaults; "
                             "write `neck-sim params -o FILE` to start from them, or leave --params out)")
    found = implausible_values(data) if isinstance(data, Mapping) else []
    if found and not accept_implausible:
        raise ParameterError(f"{path}: {'; '.join(found)}; use --accept-implausible-params if intended")
    return from_dict(data)


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
