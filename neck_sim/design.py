"""Comparing cable routings for one neck (``neck-sim design``).

For each candidate routing of the same neck (geometry, springs, masses):

* reachable workspace (:mod:`neck_sim.analytic.workspace`): sampled tensions in [f_min, f_max],
  equilibria kept when in range and stable with held motors; head position/angle cloud, its area,
  per-joint angle ranges;
* stiffness: at the straight pose held with the least tensions above t_min, 25 N and 50 N
  (co-contraction stiffens; smallest eigenvalue of K_f and K_theta, head lateral stiffness with
  held motors) and across the workspace;
* forces that hold typical shapes (:func:`typical_shapes`: a C curve, an S curve, a head reach),
  by inverse statics on the reachable set (the nearest reachable pose when the shape itself is
  not reachable, with its error);
* the pose spread of motor friction: the band of equilibria with every motor's friction at +f_s
  or -f_s (:func:`~neck_sim.analytic.statics.friction_band`), those stable with held motors.

The routings compared for a neck of N joints and m cables are :func:`routing_strategies` (three
strategies, explained there) plus the routing of the parameter file.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from neck_sim.analytic.geometry import forward_kinematics
from neck_sim.analytic.statics import (equilibrium_for_forces, friction_band, inverse_statics, least_tensions,
                                       motor_angles_for, motor_stiffness)
from neck_sim.analytic.workspace import head_stiffness, sample_workspace
from neck_sim.params import NeckParams

__all__ = ["Strategy", "routing_strategies", "typical_shapes", "evaluate", "StrategyResult"]


@dataclass(frozen=True)
class Strategy:
    """A candidate routing: its name, why one would build it, and the neck's parameters with it."""

    name: str
    description: str
    params: NeckParams


def routing_strategies(base: NeckParams, n_cables: int = 4) -> list[Strategy]:
    """Three routings of ``base``'s neck with ``n_cables`` (even, >= 4) cables; see ``docs/designing-a-neck.md``.

    * ``segmented``: the neck is cut in two halves.  A proximal antagonist pair is side-routed to
      the middle joint; the distal pair is strut-routed through the proximal half (a strut pass has
      an almost zero moment arm r(2 psi' - 1)) and side-routed to the head.  Two nearly independent
      bending segments: C and S curves.
    * ``nested``: as segmented, but the distal pair is side-routed all the way: it bends the whole
      neck, the proximal pair adds to the lower half.  Stiffer and stronger at the base (where
      gravity loads most), coupled.
    * ``doubled``: both pairs side-routed to the head (in two pulley rows): one bending mode with
      twice the force; the baseline that shows what a second attachment height buys.

    With more than four cables the extra pairs split the neck into more segments (segmented,
    nested) or join the head pairs (doubled).
    """
    from neck_sim.routing import CableRoute, Routing

    n = base.n_joints
    if n_cables < 4 or n_cables % 2:
        raise ValueError(f"n_cables: the strategies use antagonist pairs, need an even count >= 4, got {n_cables}")
    pairs = n_cables // 2
    if n < pairs:
        raise ValueError(f"n_cables: {pairs} pairs need at least {pairs} joints, the neck has {n}")
    ends = [round(n * (k + 1) / pairs) for k in range(pairs)]            # segment ends, last = N

    def pair(end, start_side):
        """Left and right cable ending at ``end``, strut-routed below joint ``start_side``."""
        passes = tuple("strut" if i < start_side else "side" for i in range(1, end))
        return [CableRoute(side=s, passes=passes, ends_at=end) for s in ("left", "right")]

    segmented, nested, doubled = [], [], []
    for k, end in enumerate(ends):
        segmented += pair(end, ends[k - 1] + 1 if k else 1)
        nested += pair(end, 1)
        doubled += pair(n, 1)
    out = []
    for name, cables, text in (
            ("segmented", segmented, "pairs side-routed on their own segment, strut-routed below it: "
                                     "independent segments"),
            ("nested", nested, "every pair side-routed from the base to its end: the distal pairs bend the "
                               "whole neck"),
            ("doubled", doubled, "every pair side-routed to the head: one bending mode, more force")):
        out.append(Strategy(name, text, with_routing(base, Routing(cables=tuple(cables)))))
    return out


def with_routing(base: NeckParams, routing) -> NeckParams:
    """``base`` with another routing; per-cable constants follow the new cables' sides."""
    from neck_sim.params import default_params
    ref = default_params(base.n_joints, routing=routing)
    return base.replace(routing=routing, friction=ref.friction, cables=ref.cables)


def typical_shapes(params: NeckParams) -> dict[str, dict[str, Any]]:
    """Targets for the holding-force comparison, scaled to the neck's N and height.

    C: every joint bent alike, 60 deg at the head; S: the lower half +a, the upper half -a, the
    head upright (a = 120 deg / N); reach: the head bar's centre at x = 25 % of the straight
    height, at 90 % of that height.
    """
    n = params.n_joints
    height = float(forward_kinematics(np.zeros(n), params).head_position[1])
    c_curve = np.full(n, math.radians(60.0) / n)
    a = math.radians(120.0) / n
    s_curve = np.where(np.arange(n) < n // 2, a, -a) if n > 1 else np.array([a])
    return {"C": {"alpha_target": c_curve}, "S": {"alpha_target": s_curve},
            "reach": {"head_target": np.array([0.25 * height, 0.9 * height])}}


@dataclass(frozen=True)
class StrategyResult:
    """Numbers (``summary``, JSON-able) and arrays for the figures of one strategy."""

    strategy: Strategy
    summary: dict
    workspace: Any
    shapes: dict        # name -> (target dict, HoldingSolution or None, band alphas (K, N))


def _deg(x):
    return np.degrees(np.asarray(x, dtype=float))


def _uncontrolled_stiffness(K, alpha, p: NeckParams) -> float | None:
    """Smallest stiffness (N m/rad) of the joint motions no cable reaches (the null space of Z^T,
    N - rank Z of them): only springs, gravity and the cables' curvature hold them, and no motor
    can damp or correct them.  None when the cables reach every motion."""
    from neck_sim.analytic.cables import transmission_matrix
    U, sv, _ = np.linalg.svd(transmission_matrix(alpha, p))
    rank = int(np.sum(sv > 1e-9 * sv.max()))
    if rank == p.n_joints:
        return None
    Un = U[:, rank:]
    return float(np.linalg.eigvalsh(Un.T @ K @ Un)[0])


PRETENSIONS = (None, 25.0, 50.0)   # N: the straight pose held with tensions >= t_min (None), 25 N, 50 N


def _straight(p: NeckParams) -> dict:
    """The straight pose held with the least tensions above each pretension of ``PRETENSIONS``."""
    out = {}
    for level in PRETENSIONS:
        lo = p.actuation.t_min if level is None else level
        forces = least_tensions(np.zeros(p.n_joints), p, f_min=lo)
        eq = equilibrium_for_forces(forces, p)
        K_m = motor_stiffness(eq.alpha, motor_angles_for(eq.alpha, forces, p), p)
        lam_m = np.linalg.eigvalsh(K_m)
        out[f"{lo:g}"] = {
            "min_eig_uncontrolled": _uncontrolled_stiffness(K_m, eq.alpha, p),
            "forces": forces, "pose_error_deg": float(np.max(np.abs(_deg(eq.alpha)))),
            "min_eig_force": float(eq.eigenvalues[0]), "min_eig_motor": float(lam_m[0]),
            "max_eig_motor": float(lam_m[-1]), "force_control_stable": bool(eq.eigenvalues[0] > 0),
            "head_lateral_stiffness_motor": float(head_stiffness(eq.alpha, K_m, p)[0])}
    return out


def _shape(p: NeckParams, target: dict):
    try:
        sol = inverse_statics(p, f_min=p.actuation.t_min, **target)
    except ValueError as exc:
        return {"reachable": False, "reason": str(exc)}, None, np.empty((0, p.n_joints))
    eq = sol.equilibrium
    K_m = motor_stiffness(eq.alpha, motor_angles_for(eq.alpha, sol.forces, p), p)
    band = friction_band(sol.forces, eq.alpha, p)
    # a stopped motor is held by its friction: only corners stable with held motors are rest poses
    safe = np.where(band.converged[:, None], band.alpha, 0.0)
    held = np.linalg.eigvalsh(motor_stiffness(safe, motor_angles_for(safe, band.tension, p), p))[:, 0] > 0
    ok = band.converged & held
    kin = forward_kinematics(eq.alpha, p)
    out = {"reachable": True, "forces": sol.forces, "max_force": float(sol.forces.max()),
           "alpha_deg": _deg(eq.alpha), "head": np.r_[kin.head_position, _deg(kin.head_angle)],
           "min_eig_motor": float(np.linalg.eigvalsh(K_m)[0]),
           "friction_corners": int(ok.size), "friction_corners_in_range": int(ok.sum())}
    if "alpha_target" in target:
        err = _deg(sol.task_error)
        out.update(pose_error_rms_deg=float(np.sqrt(np.mean(err ** 2))), pose_error_max_deg=float(np.abs(err).max()))
    else:
        out.update(head_error_mm=float(1e3 * np.linalg.norm(sol.task_error)))
    if ok.any():
        poses = np.concatenate([eq.alpha[None], band.alpha[ok]])        # the band includes the nominal pose
        bk = forward_kinematics(poses, p)
        out.update(friction_joint_spread_deg=float(_deg(np.ptp(poses, 0)).max()),
                   friction_head_spread_mm=float(1e3 * np.linalg.norm(bk.head_position - kin.head_position, axis=-1).max()),
                   friction_head_angle_spread_deg=float(_deg(np.ptp(bk.head_angle))))
    return out, sol, band.alpha[ok]


def evaluate(strategy: Strategy, samples: int = 600, *, seed: int = 0, progress: bool = False) -> StrategyResult:
    """Workspace, stiffness, holding forces and friction spread of one routing."""
    from scipy.spatial import ConvexHull, QhullError

    p = strategy.params
    ws = sample_workspace(p, samples, seed=seed, progress=progress)
    feas = ws.feasible
    head = ws.head[feas]
    area = 0.0
    if feas.sum() >= 3:
        try:
            area = float(ConvexHull(head[:, :2]).volume)
        except QhullError:
            area = 0.0
    alpha = ws.alpha[feas]
    summary = {
        "name": strategy.name, "description": strategy.description, "n_joints": p.n_joints,
        "n_cables": p.n_cables, "routing": _routing_dict(p),
        "workspace": {
            "samples": int(len(feas)), "feasible_fraction": float(feas.mean()),
            "force_control_stable_fraction": float(ws.force_stable.mean()),
            "head_area_cm2": 1e4 * area,
            "head_x_range_mm": (1e3 * head[:, 0].min(), 1e3 * head[:, 0].max()) if len(head) else None,
            "head_angle_range_deg": (float(_deg(head[:, 2].min())), float(_deg(head[:, 2].max()))) if len(head) else None,
            "joint_range_deg": (_deg(alpha.min(0)), _deg(alpha.max(0))) if len(alpha) else None,
            "min_eig_motor_median": float(np.median(ws.min_eig_motor[feas])) if feas.any() else None,
            "lateral_stiffness_median": float(np.median(ws.lateral_stiffness[feas])) if feas.any() else None,
            "lateral_stiffness_p5": float(np.percentile(ws.lateral_stiffness[feas], 5)) if feas.any() else None,
        },
        "straight": _straight(p),
    }
    shapes, shape_summary = {}, {}
    for name, target in typical_shapes(p).items():
        info, sol, band = _shape(p, target)
        shape_summary[name] = info
        shapes[name] = (target, sol, band)
    summary["shapes"] = shape_summary
    return StrategyResult(strategy, summary, ws, shapes)


def _routing_dict(p: NeckParams) -> list | None:
    routing = getattr(p, "routing", None)
    if routing is None:
        return None
    return [{"side": c.side, "passes": list(c.passes), "ends_at": c.ends_at} for c in routing.cables]
