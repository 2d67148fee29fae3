"""What a log can separate, checked before anything is named (``insufficient_excitation``).

Pure functions of the measured data on the slow grid (a
:class:`~identification.diagnosis.measured.MeasuredData`):

* the usable length (the slow grid after trimming) -- the split needs two blocks per fold;
* per cable: the motor speed reached (95th percentile of |theta_dot|, rad/s), the reversals
  (sign changes of theta_dot between excursions beyond a fifth of that speed), the span of the
  tension between its 5th and 95th percentiles over the taut samples (N: eq 41's tension
  y_C - f_motor with a first dry-friction estimate, ``MeasuredData.tension0``; not the span of
  y_C itself, which the friction's sign flips widen by twice f_s on every reversal: a multisine
  whose cables stay within 9-12 N of tension spans 38-42 N of y_C), the time spent in holds;
* per joint: the angle range between the camera angle's 5th and 95th percentiles (deg).

Each shortfall is a :class:`Gap`: what is missing, which parameters it leaves inseparable, and
what to record instead, in one line.  A *fatal* gap (the log too short, or no cable reversing, or
no joint moving) makes the verdict ``insufficient_excitation``: no candidate is tried.  The
other gaps travel with the diagnosis (JSON ``gaps``, the report); the candidates that need what
is missing on every cable (or joint) are not tried (:func:`blocked_candidates`), and a candidate
that rests only on cables (or joints) with such a gap is not named (:func:`unsupported_items`).
After the fits, a candidate whose parameters the baseline's columns explain beyond
``max_explained`` is not named either (:func:`separability_gap` says why in one line).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from identification.gaps import tension_to_record

__all__ = ["SupportSettings", "Gap", "ExcitationSummary", "excitation_summary", "log_gaps", "reversals",
           "blocked_candidates", "short_log_gap", "separability_gap", "log_support"]


@dataclass(frozen=True)
class SupportSettings:
    """Least excitation for a verdict.  ``min_duration_s``: usable slow-grid length (s; with 3
    folds of two blocks each, a block is then >= 1.3 s, a few moves); ``min_reversals``: per
    cable, the direction changes that separate a friction (odd in speed) from a force offset in
    every fold; ``min_speed``: motor speed (rad/s at the shaft, 95th percentile) that separates a
    viscous from a dry friction (the paper's arctan saturates by 5 c_s = 2.5 rad/s);
    ``min_tension_span``: N between the 5th and 95th percentile of a cable's tension, below which
    the stiffening lambda and a rest elongation cannot be told from the stiffness k;
    ``min_joint_range_deg``: a joint's range for its springs, the head mass and the joint friction;
    ``min_hold_s``: total time in holds (rest elongations and static offsets are read there);
    ``max_explained``: the share (R^2) of a parameter's weighted regressor column that the
    baseline's columns may explain for the parameter to count as separable from them (see
    :func:`~identification.diagnosis.statistics.explained_share`).
    The defaults sit below what the shortest excitations that name effects reliably have (the
    open-world tests' 12 s logs: >= 6 reversals, tension spans >= 25 N, >= 48 deg per joint);
    ``max_explained`` above what their hidden effects reach at the tests' level (over the
    open-world effects at seeds 1-3 and the native cable effects: a rest elongation up to
    R^2 = 0.990 (VIF 100) on the §5.2.2 sequences and 0.9962 (VIF 260) on the generator's random
    multisine, a joint friction 0.95, the tension stiffening 0.89, the rest below 0.81; a rest
    elongation of the soft left cable that k(4) absorbs, on its bound, 0.998).  A clean 24 s
    multisine's spurious rest elongation reaches only 0.975: R^2 alone does not tell it from a
    true one; what does is the tension range of its cable (9-12 N), a gap."""

    min_duration_s: float = 8.0
    min_reversals: int = 2
    min_speed: float = 2.5
    min_tension_span: float = 15.0
    min_joint_range_deg: float = 5.0
    min_hold_s: float = 0.5
    max_explained: float = 0.997

    def __post_init__(self):
        if min(self.min_duration_s, self.min_speed, self.min_tension_span, self.min_joint_range_deg) <= 0 \
                or self.min_reversals < 1 or self.min_hold_s < 0:
            raise ValueError("support: every minimum must be > 0 (min_reversals >= 1, min_hold_s >= 0)")
        if not 0 < self.max_explained <= 1:
            raise ValueError(f"support: max_explained must lie in (0, 1], got {self.max_explained}")

    def to_dict(self) -> dict:
        return {"min_duration_s": self.min_duration_s, "min_reversals": self.min_reversals,
                "min_speed_rad_s": self.min_speed, "min_tension_span_N": self.min_tension_span,
                "min_joint_range_deg": self.min_joint_range_deg, "min_hold_s": self.min_hold_s,
                "max_explained_by_baseline": self.max_explained}


@dataclass(frozen=True)
class ExcitationSummary:
    """The excitation of one log: usable ``duration_s``; per cable ``speed`` (rad/s, 95th
    percentile of |theta_dot|), ``reversals``, ``force_lo``/``force_hi`` (N, 5th/95th percentile
    of the tension over the taut samples); per joint ``joint_range_deg``; ``hold_s`` total time
    in holds; ``force_max`` (N) the motors' largest force, which bounds what to record."""

    duration_s: float
    speed: tuple
    reversals: tuple
    force_lo: tuple
    force_hi: tuple
    joint_range_deg: tuple
    hold_s: float
    force_max: float = float("inf")

    def to_dict(self) -> dict:
        return {"duration_s": self.duration_s, "motor_speed_p95_rad_s": list(self.speed),
                "reversals": list(self.reversals), "tension_p5_N": list(self.force_lo),
                "tension_p95_N": list(self.force_hi),
                "joint_range_deg": list(self.joint_range_deg), "hold_s": self.hold_s}


@dataclass(frozen=True)
class Gap:
    """One thing the log lacks: ``where`` ("log", "cable 4", "joint 2"), ``what`` is missing,
    ``cannot`` (what it leaves inseparable), ``record`` (what to record instead), ``fatal``
    (no verdict at all) and ``kind`` (duration, reversals, speed, tension, range, hold: which
    candidates it leaves without support when it holds on every cable or joint, see
    :func:`blocked_candidates`)."""

    where: str
    what: str
    cannot: str
    record: str
    fatal: bool = False
    kind: str = ""

    def describe(self) -> str:
        return f"{self.where} {self.what}: {self.cannot}; {self.record}"

    def to_dict(self) -> dict:
        return {"where": self.where, "what": self.what, "cannot": self.cannot, "record": self.record,
                "fatal": self.fatal, "kind": self.kind, "text": self.describe()}


def reversals(speed: np.ndarray, threshold: float) -> int:
    """Direction changes of a speed series (S,): sign changes between excursions beyond
    ``threshold`` (a hysteresis: noise around zero does not count)."""
    s = np.where(speed > threshold, 1, np.where(speed < -threshold, -1, 0))
    s = s[s != 0]
    return int(np.count_nonzero(np.diff(s))) if s.size else 0


def excitation_summary(data) -> ExcitationSummary:
    """The quantities of the module docstring for ``data`` (a MeasuredData)."""
    td = data.theta_dot
    speed = np.percentile(np.abs(td), 95, axis=0)
    rev = tuple(reversals(td[:, i], 0.2 * speed[i]) for i in range(data.C))
    lo, hi = np.zeros(data.C), np.zeros(data.C)
    for i in range(data.C):
        t = data.tension0[data.taut[:, i], i]
        if t.size:
            lo[i], hi[i] = np.percentile(t, [5, 95])
    rng = np.degrees(np.percentile(data.alpha, 95, axis=0) - np.percentile(data.alpha, 5, axis=0))
    dt = float(np.median(np.diff(data.t)))
    act = data.activity
    hold = float(np.count_nonzero(act < 0.1 * max(np.percentile(act, 95), 1e-12)) * dt)
    return ExcitationSummary(float(data.t[-1] - data.t[0]), tuple(speed.tolist()), rev, tuple(lo.tolist()),
                             tuple(hi.tolist()), tuple(rng.tolist()), hold, float(data.params.actuation.f_max))


def log_support(data, s: SupportSettings) -> tuple[ExcitationSummary, tuple[Gap, ...]]:
    """(:func:`excitation_summary`, :func:`log_gaps`) of ``data`` (a MeasuredData), computed once
    per log and settings: the diagnosis reads them before its steps and every candidate's
    separability reads the gaps again."""
    def compute():
        summary = excitation_summary(data)
        return summary, log_gaps(summary, data.n, s)

    return data.cached(("log support", s), compute)


def log_gaps(summary: ExcitationSummary, n_joints: int, s: SupportSettings | None = None) -> tuple[Gap, ...]:
    """Every gap of a log (:class:`Gap`), fatal ones first."""
    s = s or SupportSettings()
    C = len(summary.speed)
    gaps: list[Gap] = []
    if summary.duration_s < s.min_duration_s:
        gaps.append(Gap("log", f"is {summary.duration_s:.1f} s long after filtering (needs {s.min_duration_s:g} s)",
                        "too few moves for held-out blocks in every fold: no effect can be tested",
                        f"record at least {s.min_duration_s:g} s of moves (12 s or more to name small effects)",
                        True, "duration"))
    rev_short = [i for i in range(C) if summary.reversals[i] < s.min_reversals]
    for i in rev_short:
        gaps.append(Gap(f"cable {i + 1}", f"reverses {summary.reversals[i]} time(s) (needs {s.min_reversals})",
                        f"friction on cable {i + 1} (f_s({i + 1}), c_v({i + 1}), a delay) cannot be separated from "
                        "a force offset",
                        "record moves back and forth that wind and unwind it", False, "reversals"))
    if len(rev_short) == C:
        gaps.append(Gap("log", "has no cable that reverses", "no friction, delay or offset can be separated",
                        "record moves back and forth over every joint", True, "reversals"))
    for i in range(C):
        if summary.speed[i] < s.min_speed:
            gaps.append(Gap(f"cable {i + 1}", f"never turns its motor faster than {summary.speed[i]:.2g} rad/s "
                            f"(needs {s.min_speed:g})",
                            f"viscous c_v({i + 1}) and dry f_s({i + 1}) friction cannot be told apart",
                            "record faster moves", False, "speed"))
        span = summary.force_hi[i] - summary.force_lo[i]
        if span < s.min_tension_span:
            gaps.append(Gap(f"cable {i + 1}", f"stays between {summary.force_lo[i]:.0f} and {summary.force_hi[i]:.0f} N "
                            f"(needs a span of {s.min_tension_span:g} N)",
                            f"lambda({i + 1}) and a rest elongation cannot be separated from k({i + 1})",
                            "record moves that " + tension_to_record(summary.force_lo[i], summary.force_hi[i],
                                                                     summary.force_lo[i] + 2 * s.min_tension_span,
                                                                     summary.force_max),
                            False, "tension"))
    still = [j for j in range(n_joints) if summary.joint_range_deg[j] < s.min_joint_range_deg]
    for j in still:
        gaps.append(Gap(f"joint {j + 1}", f"moves over {summary.joint_range_deg[j]:.1f} deg "
                        f"(needs {s.min_joint_range_deg:g})",
                        f"its springs dk({j + 1}L), dk({j + 1}R), its friction and the head mass cannot be separated "
                        "from the cable forces' offsets",
                        f"record moves of joint {j + 1} over at least {4 * s.min_joint_range_deg:g} deg", False, "range"))
    if len(still) == n_joints:
        gaps.append(Gap("log", "is too still: no joint moves", "nothing can be separated",
                        "record moves of every joint", True, "range"))
    if summary.hold_s < s.min_hold_s:
        gaps.append(Gap("log", f"holds still for {summary.hold_s:.1f} s (needs {s.min_hold_s:g} s)",
                        "static offsets (a rest elongation) are read only in moves, where the friction shapes mix "
                        "with them", "record short holds between moves", False, "hold"))
    return tuple(sorted(gaps, key=lambda g: not g.fatal))


def short_log_gap(log, s: SupportSettings | None = None) -> Gap | None:
    """The fatal gap of a log (a :class:`neck_sim.logs.Log`) whose motors and camera overlap for
    less than ``min_duration_s`` (then it is too short even to filter), else None."""
    s = s or SupportSettings()
    tm, tc = log.motors.t, log.camera.t
    span = (min(tm[-1], tc[-1]) - max(tm[0], tc[0])) if tm.size and tc.size else 0.0
    if span >= s.min_duration_s:
        return None
    return Gap("log", f"has {max(span, 0.0):.1f} s of motors and camera together (needs {s.min_duration_s:g} s)",
               "too few moves for held-out blocks in every fold: no effect can be tested",
               f"record at least {s.min_duration_s:g} s of moves (12 s or more to name small effects)", True, "duration")


#: which gap kinds, holding on every cable (or joint), leave which candidate effects without support
_BLOCKS = {"speed": ("viscous_friction", "stribeck_friction"),
           "tension": ("tension_stiffening", "pretension"),
           "reversals": ("dry_friction", "viscous_friction", "stribeck_friction", "pulley_friction",
                         "actuation_delay", "backlash"),
           "range": ("spring_error", "payload", "joint_friction")}


def unsupported_items(gaps, effect: str) -> set[str]:
    """The cables and joints ("cable 3", "joint 2") whose gaps leave ``effect`` without support
    there (the kinds of :data:`_BLOCKS` that name it)."""
    return {g.where for g in gaps if not g.fatal and g.where != "log" and effect in _BLOCKS.get(g.kind, ())}


def blocked_candidates(gaps, n_cables: int, n_joints: int) -> dict[str, str]:
    """Candidate name -> why it is not named: the gaps of one kind hold on every cable (or joint)."""
    out = {}
    for kind, names in _BLOCKS.items():
        hit = [g for g in gaps if g.kind == kind and not g.fatal and g.where != "log"]
        if len(hit) >= (n_joints if kind == "range" else n_cables):
            for n in names:
                out.setdefault(n, f"{hit[0].cannot} ({kind} too small on every {'joint' if kind == 'range' else 'cable'})")
    return out



def separability_gap(effect: str, parameter: str, where: str, explained: float, partners,
                     summary: ExcitationSummary | None, s: SupportSettings | None = None) -> Gap:
    """The one line for a candidate ``effect`` that the data cannot separate from the baseline:
    its ``parameter`` (a report name such as "x0(3)") acting ``where`` ("cable 3", "joint 2" or
    "log") has ``explained`` (R^2) of its weighted column explained by the baseline's
    ``partners``; what is missing and what to record follow from the partners (a tension range
    for k and lambda, speeds and reversals for the frictions, a joint's range)."""
    s = s or SupportSettings()
    kinds = {p.split("(")[0] for p in partners}
    with_ = " and ".join(partners) if partners else "the baseline's parameters"
    share = f"they explain {100 * explained:.1f} % of its column, {100 * s.max_explained:g} % at most"
    cable = int(where.split()[1]) - 1 if where.startswith("cable") and summary is not None else None
    if kinds & {"k", "lambda"} and cable is not None:
        lo, hi = summary.force_lo[cable], summary.force_hi[cable]
        what = f"stays between {lo:.0f} and {hi:.0f} N"
        record = "record moves that " + tension_to_record(lo, hi, max(2 * hi, lo + 2 * s.min_tension_span, 60.0),
                                                          summary.force_max)
    elif kinds & {"f_s", "c_v", "df", "mu", "c_a"}:
        what = "moves at too few distinct speeds"
        record = "record moves at several speeds, slow and fast, with reversals"
    elif where.startswith("joint"):
        what = "moves over too narrow a range"
        record = f"record moves of {where} over its whole range, slow and fast"
    else:
        what = "has too little variety of moves"
        record = "record a longer log with moves of every joint at several speeds and amplitudes"
    return Gap(where, what, f"{parameter} ({effect}) cannot be separated from {with_} ({share})", record,
               False, "conditioning")
