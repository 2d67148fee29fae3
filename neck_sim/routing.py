"""How the cables run: the routing topology of the neck (paper §2.2, §3.1) as frozen data.

A :class:`Routing` is m :class:`CableRoute` s, one per cable in motor order (m independent of the
number of joints N).  Each cable wraps the first pulley of its side, passes the joints below its
attachment either strut-routed or side-routed, and is attached at the top corner of its side of
one joint; :meth:`Routing.segment_cases` compiles this into the ``SEG_*`` code of every (cable,
joint), the analytic model's input (segment lengths, eqs (3)-(6), in
:mod:`neck_sim.analytic.cables`).  Bad routings raise :class:`~neck_sim.validation.ParameterError`
naming the field (``routing.cables[k].passes``, ...).  The parameter set :class:`neck_sim.params.NeckParams`
holds one routing beside its constants.

Example::

    from neck_sim.routing import CableRoute, Routing, paper_routing

    paper_routing(3).segment_cases(3)          # (4, 3) SEG_* codes of the paper's prototype
    Routing((CableRoute("right", (), 1), CableRoute("left", ("side",), 2)))   # two cables, two joints
"""

from __future__ import annotations

import dataclasses
import functools
from dataclasses import dataclass, fields
from typing import Mapping

import numpy as np

from neck_sim.validation import ParameterError, is_integer, param_field as _f

__all__ = ["SIDES", "PASS_ROUTINGS", "SEG_NONE", "SEG_LEFT_END", "SEG_RIGHT_END", "SEG_LEFT_SIDE",
           "SEG_RIGHT_STRUT", "SEG_RIGHT_SIDE", "SEG_LEFT_STRUT", "N_SEGMENT_KINDS", "CableRoute", "Routing",
           "paper_routing", "neck10x4_routing", "mirrored_paper_routing", "mixed4_routing"]



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
