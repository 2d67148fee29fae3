"""Trajectories for necks the paper's laws cannot move: paths through reachable, stable poses.

A neck with m cables holds only the poses where g(alpha) = Z(alpha) t for some tensions t in the
force box (eq 30 at rest; :mod:`neck_sim.analytic.statics`); with m < N + 1 they form an
m-dimensional set, and a position-controlled neck holds only those that are stable with the motors
held (``K_theta`` positive definite).  The paths here are therefore planned in tension space
(:class:`controllers.underactuated.ReachablePath`: cycloidal moves between tension waypoints, the
equilibrium of every grid point, refused if one leaves the reachable set or is unstable):

* :func:`straight_pretension` -- where every path starts: the straight pose held by the least
  tensions above a pretension level (``least_tensions``), the level in the middle of the range
  whose straight pose is stable with held motors (co-contraction stiffens a neck with antagonist
  cables; below the range it buckles, above it the feedback has no force left);
* :func:`bending_directions` -- tension directions that make the typical shapes of
  ``neck-sim design`` (:func:`neck_sim.design.typical_shapes`): a C curve (every joint bent alike),
  an S curve (lower half one way, upper half the other) and a head reach (the head bar's centre
  moved sideways, its angle kept), from the linearised equilibrium
  ``K_f d alpha = Z d t`` at the start pose (least squares: the routing makes what it can);
* :func:`largest_move` -- how far along a direction the path stays feasible: bisection on the
  step, every candidate checked by solving its equilibria (in the joint range, stable with held
  motors, tensions in [t_min, margin f_max], no joint bent beyond ``bend_deg`` from the start);
* :func:`shapes_tour` -- the default trajectory of such a neck (C both ways, S both ways, head
  reach, back to straight after each);
* :func:`excitation_path` -- the identification experiment of such a neck (README of
  ``docs/your-own-neck.md``, "the identification experiment"): §5.2.2's pattern of six moves
  (+d, -d, 0, -d, +d, 0) along the C and S directions at a low and at a high pretension, joined by
  co-contraction moves, so that every cable's motor reverses many times and its tension sweeps the
  stable range (friction from the reversals, k and lambda from the tension sweep);
* :func:`check_holdable` -- refuse, before a run, a joint-space trajectory whose poses this neck
  cannot hold, naming the pose and the cable;
* :func:`check_plant_holds` -- refuse, before a run, a path planned on the nominal model that the
  simulated plant (with its ``--effect`` effects: a payload, weaker springs, a pretension) cannot
  hold with the motors at the path's angles, naming the pose, the joint or the cable.

Units: tensions N, angles rad (degrees only in messages and ``bend_deg``), times s.
"""

from __future__ import annotations

from typing import NamedTuple, Sequence

import numpy as np
import numpy.typing as npt

from controllers.trajectories import FORCE_MARGIN, HOLD_TIME, MOVE_TIME
from controllers.underactuated import ReachablePath
from neck_sim.analytic.cables import transmission_matrix
from neck_sim.analytic.dynamics import gravity_spring_torque
from neck_sim.analytic.statics import (equilibrium_for_forces, equilibrium_for_motor_angles, force_stiffness,
                                       head_jacobian, least_tensions, motor_angles_for, motor_stiffness)
from neck_sim.cache import memo
from neck_sim.params import NeckParams
from neck_sim.trajectory import Trajectory

__all__ = ["Pretension", "straight_pretension", "bending_directions", "largest_move", "shapes_tour",
           "excitation_path", "check_holdable", "check_plant_holds", "BEND_DEG", "LEVEL_STEP"]

BEND_DEG = 20.0
"""Largest joint angle (deg) a waypoint of :func:`shapes_tour` / :func:`excitation_path` may bend."""

LEVEL_STEP = 2.5
"""N between the pretension levels :func:`straight_pretension` tries."""


class Pretension(NamedTuple):
    """The start of every path: ``tensions`` (m,) N holding ``alpha`` (N,) rad (straight when the
    neck can hold it), at ``level`` N; ``stable`` (lo, hi) N the pretension levels whose straight
    pose is stable with the motors held."""

    level: float
    tensions: np.ndarray
    alpha: np.ndarray
    stable: tuple


def _held_stable(alpha, tensions, params: NeckParams) -> bool:
    K = motor_stiffness(alpha, motor_angles_for(alpha, tensions, params), params)
    return bool(np.linalg.eigvalsh(K)[0] > 0)


def _hold_at(level: float, params: NeckParams, hi: float):
    """(tensions, pose) of the straight pose held with tensions >= level, or, where no tensions in
    the box hold it, the equilibrium of equal tensions ``level`` reached from straight; None if none."""
    n = params.n_joints
    try:
        t = least_tensions(np.zeros(n), params, f_min=level, f_max=hi)
        return t, np.zeros(n)
    except ValueError:
        t = np.full(params.n_cables, float(level))
        eq = equilibrium_for_forces(t, params, np.zeros(n))
        return (t, eq.alpha) if eq.converged else None


def straight_pretension(params: NeckParams, *, margin: float = FORCE_MARGIN, step: float = LEVEL_STEP,
                        position: float = 0.5) -> Pretension:
    """The start pose and its tensions at the level ``position`` (0 lowest, 1 highest) of the
    stable range of pretension levels in [t_min, margin f_max] (steps of ``step`` N).

    ValueError when no level holds a stable start pose (this routing cannot be position-controlled
    within the force limits).
    """
    act = params.actuation
    hi = margin * act.f_max
    levels = np.arange(act.t_min, hi + 1e-9, step)
    good = []
    for level in levels:
        held = _hold_at(level, params, hi)
        if held is not None and _held_stable(held[1], held[0], params):
            good.append(level)
    if not good:
        raise ValueError(f"no pretension in [{act.t_min:g}, {hi:g}] N holds this neck's start pose stably with "
                         f"the motors held ({params.n_cables} cables on {params.n_joints} joints): it cannot be "
                         "position-controlled within its force limits")
    lo_s, hi_s = float(good[0]), float(good[-1])
    level = float(good[int(round(position * (len(good) - 1)))])
    t, alpha = _hold_at(level, params, hi)
    return Pretension(level, t, alpha, (lo_s, hi_s))


def bending_directions(params: NeckParams, start: Pretension) -> dict[str, np.ndarray]:
    """Tension directions (m,) N per linearised degree of the largest joint bend for the shapes
    ``"C"``, ``"S"`` (N >= 2) and ``"reach"`` (see the module docstring).  Shapes the routing
    cannot make at all (their least-squares direction bends nothing) are left out."""
    n = params.n_joints
    a0, t0 = start.alpha, start.tensions
    Z = transmission_matrix(a0, params)
    A = np.linalg.lstsq(force_stiffness(a0, t0, params), Z, rcond=None)[0]       # d alpha / d t, (N, m)
    targets = {"C": (A, np.ones(n))}
    if n >= 2:
        targets["S"] = (A, np.where(np.arange(n) < n // 2, 1.0, -1.0))
    J = head_jacobian(a0, params)[[0, 2]]                    # head x and head angle
    targets["reach"] = (J @ A, np.array([1.0, 0.0]))
    out = {}
    for name, (M, goal) in targets.items():
        d = np.linalg.lstsq(M, goal, rcond=None)[0]
        bend = np.degrees(np.abs(A @ d).max())
        if bend > 1e-9 and np.isfinite(bend):
            out[name] = d / bend
    return out


def _feasible(params: NeckParams, start: Pretension, w: np.ndarray, lo: float, hi: float, bend: float) -> bool:
    if np.any(w < lo) or np.any(w > hi):
        return False
    try:
        path = ReachablePath(params, [start.tensions, w], move_time=1.0, hold_time=0.0, grid_dt=0.125,
                             alpha0=start.alpha)
    except ValueError:
        return False
    return bool(np.abs(path.grid_alpha - start.alpha).max() <= bend)     # bent from the start pose


def largest_move(params: NeckParams, start: Pretension, direction: npt.ArrayLike, *, bend_deg: float = BEND_DEG,
                 margin: float = FORCE_MARGIN, iterations: int = 6) -> np.ndarray | None:
    """The waypoint start + s direction (m,) N with the largest s in (0, bend_deg] whose path from
    the start stays feasible (module docstring); None when not even a small step is."""
    lo, hi = params.actuation.t_min, margin * params.actuation.f_max
    bend = np.radians(bend_deg)
    d = np.asarray(direction, dtype=float)
    s_max = float(bend_deg)
    if _feasible(params, start, start.tensions + s_max * d, lo, hi, bend):
        return start.tensions + s_max * d
    good, bad = 0.0, s_max
    for _ in range(iterations):
        mid = 0.5 * (good + bad)
        good, bad = (mid, bad) if _feasible(params, start, start.tensions + mid * d, lo, hi, bend) else (good, mid)
    return start.tensions + good * d if good > 0 else None


def _moves(params: NeckParams, start: Pretension, bend_deg: float, margin: float) -> dict[str, np.ndarray]:
    """Waypoints '<shape>+' and '<shape>-' of every shape the neck can make."""
    out = {}
    for name, d in bending_directions(params, start).items():
        for sign in (1.0, -1.0):
            w = largest_move(params, start, sign * d, bend_deg=bend_deg, margin=margin)
            if w is not None:
                out[f"{name}{'+' if sign > 0 else '-'}"] = w
    return out


def shapes_tour(params: NeckParams, duration_scale: float = 1.0, *, bend_deg: float = BEND_DEG,
                margin: float = FORCE_MARGIN, position: float = 0.5) -> ReachablePath:
    """C curve both ways, S curve both ways and the head reach, each from and back to the start
    pose (:func:`straight_pretension` at ``position``): 2.5 s moves and 1 s holds times
    ``duration_scale`` (the paper's control-test timing).  Planned once per neck and request
    (:func:`neck_sim.cache.memo`: seconds of static solves on a ten-joint neck)."""
    key = (params, float(duration_scale), float(bend_deg), float(margin), float(position))
    return memo("shapes_tour", key, lambda: _shapes_tour(*key))


def _shapes_tour(params: NeckParams, duration_scale: float, bend_deg: float, margin: float,
                 position: float) -> ReachablePath:
    start = straight_pretension(params, margin=margin, position=position)
    moves = _moves(params, start, bend_deg, margin)
    order = [k for k in ("C+", "C-", "S+", "S-", "reach+") if k in moves]
    if not order:
        raise ValueError("shapes: no bending direction of this neck stays reachable and stable")
    waypoints = [start.tensions]
    for k in order:
        waypoints += [moves[k], start.tensions]
    path = ReachablePath(params, waypoints, move_time=MOVE_TIME * duration_scale,
                         hold_time=HOLD_TIME * duration_scale, name="shapes", alpha0=start.alpha)
    path.labels = ["start"] + [x for k in order for x in (k, "start")]
    return path


def excitation_path(params: NeckParams, duration_scale: float = 1.0, *, bend_deg: float = BEND_DEG,
                    margin: float = FORCE_MARGIN, levels: Sequence[float] = (0.2, 0.6)) -> ReachablePath:
    """The identification experiment of a neck the paper's laws cannot move (module docstring).

    At each pretension level (``levels``: positions in the stable range, see
    :func:`straight_pretension`), for the C and S directions (whichever the routing makes), the six
    moves +d, -d, start, -d, +d, start of §5.2.2; a co-contraction move joins the levels, and the path
    returns to the first level at the end.  Planned once per neck and request
    (:func:`neck_sim.cache.memo`).
    """
    key = (params, float(duration_scale), float(bend_deg), float(margin), tuple(float(x) for x in levels))
    return memo("excitation_path", key, lambda: _excitation_path(*key))


def _excitation_path(params: NeckParams, duration_scale: float, bend_deg: float, margin: float,
                     levels: tuple) -> ReachablePath:
    waypoints, labels = [], []
    first = None
    for pos in levels:
        start = straight_pretension(params, margin=margin, position=pos)
        first = first or start
        moves = _moves(params, start, bend_deg, margin)
        waypoints.append(start.tensions)
        labels.append(f"start {start.level:g} N")
        # two shapes per level (C and S, else whichever the routing makes): about the paper's run length
        shapes = [s for s in ("C", "S", "reach") if f"{s}+" in moves and f"{s}-" in moves][:2]
        for shape in shapes:
            plus, minus = moves[f"{shape}+"], moves[f"{shape}-"]
            waypoints += [plus, minus, start.tensions, minus, plus, start.tensions]
            labels += [f"{shape}+", f"{shape}-", "start", f"{shape}-", f"{shape}+", "start"]
    if first is None:
        raise ValueError("levels: at least one pretension level is needed")
    waypoints.append(first.tensions)
    labels.append(f"start {first.level:g} N")
    path = ReachablePath(params, waypoints, move_time=MOVE_TIME * duration_scale,
                         hold_time=HOLD_TIME * duration_scale, name="identification", alpha0=first.alpha)
    path.labels = labels
    return path


def check_holdable(trajectory: Trajectory, params: NeckParams, *, margin: float = FORCE_MARGIN,
                   sample_dt: float = 0.05) -> None:
    """Refuse (ValueError) a joint-space trajectory this neck cannot hold under position control:
    at some pose no tensions in [0, margin f_max] balance gravity and springs (eq 30 at rest), or the
    pose is unstable with the motors held.  The message names the time, the pose and the cables."""
    hi = margin * params.actuation.f_max
    t = np.arange(0.0, trajectory.duration + 0.5 * sample_dt, sample_dt)
    alpha = trajectory.sample(t).alpha
    Z = transmission_matrix(alpha, params)
    g = gravity_spring_torque(alpha, params)
    from scipy.optimize import lsq_linear

    scale = max(float(np.abs(g).max()), 1e-3)
    held, residuals, solved = [], [], {}
    for k in range(t.size):                        # reach first: it says more than stability
        # a hold repeats its pose sample after sample: each distinct (Z, g) is solved once
        key = (Z[k].tobytes(), g[k].tobytes())
        if key not in solved:
            solved[key] = lsq_linear(Z[k], g[k], bounds=(0.0, hi)).x
        held.append(solved[key].copy())
        residuals.append(Z[k] @ held[-1] - g[k])
    residuals = np.abs(np.array(residuals))
    if residuals.max() > 1e-3 * scale:
        k, j = map(int, np.unravel_index(np.argmax(residuals), residuals.shape))   # the pose furthest out of reach
        x = held[k]
        at = [f"c{c + 1} at {'0' if x[c] < 1e-6 else f'{hi:g}'} N" for c in range(params.n_cables)
              if x[c] < 1e-6 or x[c] > hi - 1e-6]
        limit = f"; {', '.join(at)}" if at else ""
        first = t[np.argmax(residuals.max(-1) > 1e-3 * scale)]
        raise ValueError(f"{trajectory.name}: the pose at t = {t[k]:.2f} s, {_pose(alpha[k])}, is out of this neck's "
                         f"reach (the first out of reach is at t = {first:.2f} s): no tensions of its "
                         f"{params.n_cables} cables in [0, {hi:g}] N hold it (the closest leave "
                         f"{residuals[k, j]:.3g} N m unbalanced at joint {j + 1}{limit})")
    for k, tk in enumerate(held):
        if not _held_stable(alpha[k], tk, params):
            c = int(np.argmin(tk))
            raise ValueError(f"{trajectory.name}: the pose at t = {t[k]:.2f} s, {_pose(alpha[k])}, is unstable with "
                             f"the motors held by the tensions that hold it ({np.round(tk, 1).tolist()} N; cable "
                             f"c{c + 1} carries the least): choose poses from the reachable set (--trajectory shapes)")


def check_plant_holds(path: ReachablePath, plant_params: NeckParams, elongation_offset: npt.ArrayLike | None = None,
                      *, margin: float = FORCE_MARGIN) -> None:
    """Refuse (ValueError) a path planned on the controller's model (``path.params``) that the plant
    ``plant_params`` (the model with the run's effects applied) cannot hold statically.

    At every grid point of the path the motors are held at the angles the controller commands
    there (the model's inverse statics, ``theta_d``) and the plant's static pose is solved from the
    planned pose (eq 30 at rest, elastic cables of eq 54, ``elongation_offset`` (m) per cable added
    to every elongation, a pretension).  Refused: no equilibrium in the joint range, one that is
    unstable with the motors held, or one whose tension exceeds ``margin`` f_max (the motor
    saturates).  Static only: a fast path can still swing the plant out of its range.
    """
    model, t = path.params, path.grid_t
    theta = motor_angles_for(path.grid_alpha, path.forces_at(t), model)
    if elongation_offset is not None:
        theta = theta + np.asarray(elongation_offset, dtype=float) * model.actuation.R / model.actuation.r_d
    eq = equilibrium_for_motor_angles(theta, plant_params, path.grid_alpha)
    hi = margin * plant_params.actuation.f_max
    over = eq.tension > hi
    bad = ~eq.converged | ~eq.stable | over.any(-1)
    if not bad.any():
        return
    k = int(np.argmax(bad))
    labels = getattr(path, "labels", None)
    w = min(len(path.waypoints) - 1, int(np.searchsorted(path.knots, t[k], side="right")) // 2)
    where = (f"{path.name}: the pose planned at t = {t[k]:.2f} s ({_pose(path.grid_alpha[k])}, "
             + (f"towards waypoint {labels[w]!r}" if labels else f"towards waypoint {w}") + ")")
    if not eq.converged[k]:
        j = int(np.argmax(np.abs(eq.alpha[k])))
        why = (f"has no equilibrium in the joint range on the simulated plant with the motors held there (joint "
               f"{j + 1} heads to {np.degrees(eq.alpha[k, j]):.1f} deg)")
    elif not eq.stable[k]:
        j = int(np.argmax(np.abs(np.linalg.eigh(eq.stiffness[k])[1][:, 0])))     # the softest mode's largest joint
        why = (f"is unstable on the simulated plant with the motors held there (its unstable mode moves joint "
               f"{j + 1} most; tensions {np.round(eq.tension[k], 1).tolist()} N)")
    else:
        c = int(np.argmax(eq.tension[k]))
        why = (f"needs {eq.tension[k, c]:.1f} N in cable c{c + 1} on the simulated plant, more than "
               f"{hi:g} N ({margin:g} f_max)")
    raise ValueError(f"{where} {why}: simulate a smaller effect (or, for a payload or springs, plan with the "
                     "plant's values: they belong in the parameter file)")


def _pose(alpha) -> str:
    return "[" + ", ".join(f"{x:.1f}" for x in np.degrees(alpha)) + "] deg"
