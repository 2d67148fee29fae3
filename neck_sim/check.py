"""Check a simulated log's truth against the analytic model (``neck-sim check``).

From ``/neck/truth`` (and the encoders of ``/neck/motors`` at the same instants) three relations
of the paper's model are recomputed with :mod:`neck_sim.analytic`:

1. ``cable lengths``: the logged elongation against x_c = l_c(alpha) - l_c0 + (r_d/R) theta
   (corrected eq 27; plus the ``pretension`` offset when the plant had that effect).
   Tolerance 0.2 mm + half an encoder count along the cable ((r_d/R) pi/counts, 1.2 um): theta
   is the quantised encoder reading, and MuJoCo's loop closures and helper constraints are soft
   (the design notes keep their gaps under 0.1 mm; measured: up to 0.06 mm in a closed-loop run,
   0.1 mm in a violent open-loop run, growing about 1 um per N of tension).
2. ``joint torques``: Z(alpha) t against M_m(alpha) alpha_ddot + c_m(alpha, alpha_dot) + g(alpha)
   (eq 30 with tau = Z t), alpha_ddot from central differences of the logged alpha_dot.  Both
   sides are compared as 20 ms moving averages: a moving average of a central difference is a
   change of momentum over the window, exact up to the variation of M_m, so the comparison
   needs no filter.  Tolerance per joint 0.005 N m + 3 % of the largest |Z t| of that joint
   (measured: 0.2 % in a closed-loop run, 2 % in a violent open-loop run with slack cables)
   + 0.6 % of the joint's largest gross cable torque sum_i |Z_ji| t_i.  The last term is for fast
   moves: the plant's implicit integration and soft loop closures differ from the continuous
   eq (30) by a fraction of each cable's torque, not of their net, and fast moves are made with
   high co-contraction (all four cables near f_max, a net |Z t| 50-100 times smaller than the
   gross).  Measured, largest disagreement over the largest gross torque of the same joint, in
   closed-loop control tests: 0.30 % at ``--duration-scale 0.1``, 0.22 % at 0.2, 0.01 % at 1
   (the first two exceeded the net-only tolerance, up to 1.8x, and failed honest logs).
   Where the disagreement comes from: it is the integrator's first-order error, not a missing
   term of eq (30).  On the control test at ``--duration-scale 0.1`` the 20 ms-averaged
   disagreement follows alpha_ddot (R^2 0.46-0.89 per joint) like an extra inertia of
   0.95-1.67e-4 kg m^2 at the plant's 0.5 ms step, 0.52-0.92e-4 at 0.25 ms and 0.28-0.48e-4 at
   0.125 ms: it halves with the step, and so does its largest value (0.0145, 0.0085, 0.0044 N m).
   The implicit treatment of the cables' damping, h Z diag(c_a) Z^T, accounts for about 4e-5 of
   it at 0.5 ms.  A smaller timestep, not a wider tolerance, is the way to a tighter check.
3. ``elongation sign``: tension-only cables (eq 54) pull only when stretched: no sample may have
   tension > 0 with elongation <= 0 (tolerance 0).  With rigid cables the elongation must stay
   within the tolerance of relation 1 instead.

The model's constants are the plant's (the ``run`` record's ``plant_params`` with its effects
applied) when the log has them, else the nominal ``neck`` record.

A log whose true joint angles leave |alpha| <= alpha_max is refused (ValueError naming the first
such sample and the command that wrote the log): the relations are the paper's model, which does
not hold there.  ``neck-sim simulate`` no longer writes such logs.
"""

from __future__ import annotations

import math
import os
from dataclasses import asdict, dataclass

import numpy as np

from neck_sim.analytic import cable_lengths, linkage_dynamics, transmission_matrix
from neck_sim.effects import Effects
from neck_sim.joint_range import first_excursion
from neck_sim.logs import Log, read_log
from neck_sim.params import NeckParams
from neck_sim.plant_spec import PlantSpec

__all__ = ["Relation", "CheckResult", "check_log", "LENGTH_TOLERANCE", "TORQUE_TOLERANCE_ABS",
           "TORQUE_TOLERANCE_REL", "TORQUE_TOLERANCE_GROSS", "TORQUE_WINDOW"]

LENGTH_TOLERANCE = 2e-4          # m, plus half an encoder count along the cable
TORQUE_TOLERANCE_ABS = 0.005     # N m
TORQUE_TOLERANCE_REL = 0.03      # of the joint's largest |Z t|
TORQUE_TOLERANCE_GROSS = 0.006   # of the joint's largest gross torque sum_i |Z_ji| t_i (fast moves)
TORQUE_WINDOW = 0.02             # s, moving-average window of relation 2


@dataclass(frozen=True)
class Relation:
    """One checked relation: the largest disagreement, where it is, and its tolerance."""

    name: str
    description: str
    unit: str
    max_error: float           # largest |disagreement| (for relation 2: largest error / tolerance x tol)
    tolerance: float
    t: float                   # time of the largest disagreement (s)
    index: int                 # cable or joint index (0-based) of it
    violations: int            # samples over tolerance
    samples: int

    @property
    def passed(self) -> bool:
        return self.violations == 0


@dataclass(frozen=True)
class CheckResult:
    relations: tuple[Relation, ...]
    params_source: str

    @property
    def passed(self) -> bool:
        return all(r.passed for r in self.relations)

    def table(self) -> str:
        rows = [("relation", "max disagreement", "tolerance", "at t (s)", "where", "samples over", "verdict")]
        for r in self.relations:
            where = ("cable " if r.name != "joint torques" else "joint ") + str(r.index + 1)
            at = f"{r.t:.3f}"
            if r.max_error == 0 and r.passed:
                where = at = "-"
            rows.append((r.name, f"{r.max_error:.3g} {r.unit}", f"{r.tolerance:.3g} {r.unit}", at, where,
                         f"{r.violations}/{r.samples}", "ok" if r.passed else "FAIL"))
        widths = [max(len(row[c]) for row in rows) for c in range(len(rows[0]))]
        lines = ["  ".join(cell.ljust(w) for cell, w in zip(row, widths)).rstrip() for row in rows]
        return "\n".join([lines[0], "-" * len(lines[0])] + lines[1:])

    def as_dict(self) -> dict:
        return {"passed": self.passed, "params_source": self.params_source,
                "relations": [dict(asdict(r), passed=r.passed) for r in self.relations]}


def _model(log: Log) -> tuple[NeckParams, Effects, bool, str]:
    """(true constants, effects, rigid cables, where the constants came from) of the log's plant,
    read from its run record by :class:`neck_sim.plant_spec.PlantSpec`."""
    try:
        spec, assumed = PlantSpec.read_record(log.run_info or {}, nominal=log.params)
    except ValueError as exc:
        raise ValueError(f"{log.path}: {exc}") from None
    source = ("nominal constants of the neck record (the run record has no plant_params)" if "params" in assumed
              else "plant parameters of the run record")
    return spec.effects.true_params(spec.params), spec.effects, spec.rigid_cables, source


def _written_by(log: Log) -> str:
    """" (written by `neck-sim simulate ...`)" from the run record's command line, "" without one."""
    cmd = log.run_value("command_line")
    if not isinstance(cmd, list) or not cmd or str(cmd[0]) in ("", "-c"):
        return ""
    first = str(cmd[0])
    prog = "neck-sim" if os.path.basename(first) in ("neck-sim", "__main__.py") else first
    return f" (written by `{' '.join([prog, *map(str, cmd[1:])])}`)"


def _worst(err: np.ndarray, tol, t: np.ndarray, name, description, unit, tol_value) -> Relation:
    """Relation from per-sample errors (T, K) and tolerance broadcastable to it."""
    ratio = np.abs(err) / tol
    flat = int(np.argmax(ratio)) if err.size else 0
    i, j = divmod(flat, err.shape[1]) if err.size else (0, 0)
    return Relation(name, description, unit, float(np.abs(err).flat[flat]) if err.size else 0.0, float(tol_value),
                    float(t[i]) if err.size else math.nan, j, int((ratio > 1).sum()), int(err.shape[0]))


def check_log(log: Log | str) -> CheckResult:
    """Recompute the three relations from the truth topics; see the module docstring."""
    if not isinstance(log, Log):
        log = read_log(log, topics=("motors", "truth"), require=("motors", "truth"))
    if log.truth is None or len(log.truth.t) == 0:
        raise ValueError(f"{log.path}: no /neck/truth samples: check needs a simulated log")
    params, effects, rigid, source = _model(log)
    tr, mo = log.truth, log.motors
    out = first_excursion(tr.t, tr.alpha, params.geometry.alpha_max)
    if out is not None:
        raise ValueError(f"{log.path}: /neck/truth: {out.describe()}: the simulated neck left its joint range, where "
                         f"the paper's model (and so this check) does not hold{_written_by(log)}; simulate it again "
                         "with slower moves or a lighter plant (`neck-sim simulate` refuses such runs)")
    if mo is None:
        raise ValueError(f"{log.path}: no /neck/motors samples: check needs the motor angles")
    common, it, im = np.intersect1d(np.round(tr.t * 1e9).astype(np.int64), np.round(mo.t * 1e9).astype(np.int64),
                                    return_indices=True)
    if len(common) < 3:
        raise ValueError(f"{log.path}: /neck/truth and /neck/motors share {len(common)} sample times; need >= 3")
    t = tr.t[it]
    alpha, alpha_dot = tr.alpha[it], tr.alpha_dot[it]
    tension, x_log = tr.tension[it], tr.elongation[it]
    theta = mo.theta[im]
    act = params.actuation

    # 1. cable lengths
    ratio = act.r_d / act.R
    x_model = cable_lengths(alpha, params) + ratio * theta + effects.elongation_offset(params.n_cables)
    tol1 = LENGTH_TOLERANCE + ratio * params.sensors.encoder_resolution / 2
    rel1 = _worst(x_log - x_model, tol1, t, "cable lengths",
                  "elongation vs l_c(alpha) - l_c0 + (r_d/R) theta", "m", tol1)

    # 2. joint torques, as moving averages of both sides (changes of momentum over the window)
    alpha_ddot = np.gradient(alpha_dot, t, axis=0)
    lk = linkage_dynamics(alpha, alpha_dot, params)
    z = transmission_matrix(alpha, params)
    z_t = np.einsum("tij,tj->ti", z, tension)
    gross = np.einsum("tij,tj->ti", np.abs(z), np.abs(tension))
    residual = (z_t - (np.einsum("tij,tj->ti", lk.M, alpha_ddot) + lk.c + lk.g))[1:-1]
    dt = float(np.median(np.diff(t)))
    w = max(1, min(len(residual), int(round(TORQUE_WINDOW / dt)) + 1))
    kernel = np.ones(w) / w
    smooth = np.stack([np.convolve(residual[:, j], kernel, mode="valid") for j in range(residual.shape[1])], 1)
    t_mid = t[1:-1][w // 2: w // 2 + len(smooth)]
    tol2 = (TORQUE_TOLERANCE_ABS + TORQUE_TOLERANCE_REL * np.abs(z_t).max(axis=0)
            + TORQUE_TOLERANCE_GROSS * gross.max(axis=0))
    rel2 = _worst(smooth, tol2, t_mid, "joint torques",
                  f"Z t vs M_m alpha_ddot + c_m + g ({w}-sample means)", "N m", 0.0)
    rel2 = Relation(**{**asdict(rel2), "tolerance": float(tol2[rel2.index])})

    # 3. elongation sign
    if rigid:
        rel3 = _worst(x_log, tol1, t, "elongation sign", "rigid cables: elongation stays zero", "m", tol1)
    else:
        bad = (tension > 0) & (x_log <= 0)
        deficit = np.where(bad, -x_log, 0.0)
        flat = int(np.argmax(np.where(bad, 1.0 + deficit, 0.0)))
        i, j = divmod(flat, deficit.shape[1])
        rel3 = Relation("elongation sign", "tension > 0 only when elongation > 0", "m", float(deficit.flat[flat]),
                        0.0, float(t[i]), j, int(bad.sum()), len(t))
    return CheckResult((rel1, rel2, rel3), source)
