"""Which controller can move a neck, and which trajectory it runs (``neck-sim simulate``).

* ``computed-torque`` -- the paper's control laws (§6.3, eqs 59-66): their tension distribution
  (eqs 63-65) needs the paper's kind of routing, N right cables and one long left cable;
* ``elastic-lqr`` -- law 2's feed-forward with LQR feedback on a neck observer
  (:mod:`controllers.elastic_lqr`): the paper's routing, long necks (N >= :data:`LQR_FROM_JOINTS`)
  on elastic cables, which the paper's laws lose (README, Known limitations);
* ``inverse-statics`` -- inverse statics on the reachable set plus a motor-angle PID
  (:mod:`controllers.underactuated`): any routing, in particular necks with fewer cables than N + 1,
  which hold only an m-dimensional set of poses and are moved along paths planned in tension space
  (:mod:`controllers.reachable_paths`).

:func:`choose_controller` picks one (or checks the user's) and says why in one line;
:func:`make_run_trajectory` builds a trajectory the chosen controller can follow on that neck,
refusing one it cannot before any simulation.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, NamedTuple, Sequence

from neck_sim.params import NeckParams

if TYPE_CHECKING:
    from controllers.underactuated import ReachablePath
    from neck_sim.effects import Effects
    from neck_sim.trajectory import Trajectory

__all__ = ["CONTROLLERS", "TRAJECTORY_NAMES", "LQR_FROM_JOINTS", "PLANT_TIMESTEP", "Choice", "choose_controller",
           "make_run_trajectory", "plant_timestep"]

#: The controllers by the name ``neck-sim simulate --controller`` takes, each with what it runs and on which necks.
CONTROLLERS = {
    "computed-torque": "the paper's computed-torque laws (§6.3; --law 1, 2, 3), paper routing",
    "elastic-lqr": "the elastic LQR (law 2's feed-forward, LQR feedback on a neck observer), paper routing",
    "inverse-statics": "inverse statics + motor-angle PID on paths of reachable poses, any routing",
}
"""Controller name -> one line saying what it is and which necks it moves."""

TRAJECTORY_NAMES = ("control-test", "identification", "shapes")
"""``control-test`` and ``identification``: the paper's §7 and §5.2.2 trajectories (for a neck the
paper's laws cannot move, ``identification`` is :func:`controllers.reachable_paths.excitation_path`);
``shapes``: C and S curves and a head reach through reachable poses
(:func:`controllers.reachable_paths.shapes_tour`)."""

LQR_FROM_JOINTS = 9      # law 2 saturates from N = 9 and diverges at 10 on elastic cables (README, Known limitations)

PLANT_TIMESTEP = {"inverse-statics": 2.5e-4}
"""Physics timestep (s) of the plant a controller runs on, where it differs from the default
(:data:`neck_sim.mjcf.DEFAULT_TIMESTEP`, 0.5 ms).  Measured on the 10-X, 4-cable neck's 36 s shapes
tour: at 0.5 ms MuJoCo (``implicitfast``) diverged in all 7 runs tried (bandwidths 10-90 rad/s,
pretension 61-84 N), 10-23 s in; at 0.25 ms the same tour ran to the end (0.87 deg mean joint error).
The paper's laws keep the default (their tests are held to its numbers)."""


class Choice(NamedTuple):
    """The controller's name (a key of :data:`CONTROLLERS`) and one line saying which and why."""

    name: str
    line: str


def plant_timestep(controller: str) -> float | None:
    """The plant's physics timestep (s) for ``controller``; None: the default."""
    return PLANT_TIMESTEP.get(controller)


def _paper_routing(params: NeckParams) -> bool:
    return params.routing.is_paper_kind(params.n_joints)


def choose_controller(params: NeckParams, requested: str | None = None, *, laws: Sequence[int] | None = None,
                      rigid_cables: bool = False, cable_model: str | None = None, table3: bool = False) -> Choice:
    """The controller for ``params``' neck: ``requested`` checked (None or ``"auto"``: chosen).

    The automatic choice: ``inverse-statics`` for a routing other than the paper's; on the paper's
    routing ``elastic-lqr`` from N = :data:`LQR_FROM_JOINTS` on elastic cables unless the paper's
    laws are asked for (``laws``, ``table3``, ``cable_model``, ``rigid_cables``), else
    ``computed-torque``.  ValueError (one line) for an unknown name or a controller that cannot
    move this neck.
    """
    n, m = params.n_joints, params.n_cables
    paper = _paper_routing(params)
    if requested not in (None, "auto"):
        if requested not in CONTROLLERS:
            raise ValueError(f"--controller {requested}: unknown (known: auto, {', '.join(CONTROLLERS)})")
        if requested != "inverse-statics" and not paper:
            raise ValueError(f"--controller {requested}: the paper's laws need the paper's routing (N right cables "
                             f"strut-routed to D_j and one long left cable, {n + 1} cables for N = {n}); this neck has "
                             f"{m} cables on another routing: use --controller inverse-statics")
        return Choice(requested, f"controller: {CONTROLLERS[requested]} (--controller {requested})")
    if not paper:
        why = (f"{m} cables on {n} joints, fewer than N + 1 = {n + 1}" if m < n + 1
               else f"{m} cables on {n} joints, not the paper's routing")
        return Choice("inverse-statics", f"controller: inverse statics + motor-angle PID ({why}: the paper's laws "
                                         "cannot distribute its tensions; --controller names the choices)")
    if n >= LQR_FROM_JOINTS and not (laws or table3 or rigid_cables or cable_model):
        return Choice("elastic-lqr", f"N = {n} on elastic cables: the elastic LQR (the paper's laws lose necks this "
                                     "long; --law 2 to run law 2 anyway)")
    which = ", ".join(str(int(x)) for x in (laws or [2]))
    return Choice("computed-torque", f"controller: the paper's computed torque, law {which} (the paper's routing, "
                                     f"N = {n}, {m} cables)")


def make_run_trajectory(name: str | None, params: NeckParams, controller: str, duration_scale: float = 1.0,
                        effects: Effects | None = None) -> Trajectory | ReachablePath:
    """The trajectory ``name`` (None: the controller's default) for ``controller`` on ``params``.

    The paper's laws run the §7 and §5.2.2 trajectories scaled to the force limits
    (:func:`controllers.trajectories.make_trajectory`); ``inverse-statics`` runs ``shapes`` by
    default, its own identification experiment, or a joint-space trajectory it has checked
    (:func:`controllers.reachable_paths.check_holdable`).  ValueError before any simulation when
    the neck cannot follow it.

    ``effects``: the plant's (``simulate --effect``).  ``inverse-statics`` plans on ``params`` (its
    model) and then checks the path on the plant those effects make, statically
    (:func:`controllers.reachable_paths.check_plant_holds`, :func:`~controllers.reachable_paths.check_holdable`
    with the plant's constants); the paper's laws, whose feedback supplies the torque the plant
    needs, are not checked here.
    """
    if name is not None and name not in TRAJECTORY_NAMES:
        raise ValueError(f"--trajectory {name}: unknown (known: {', '.join(TRAJECTORY_NAMES)})")
    if controller != "inverse-statics":
        if name == "shapes":
            raise ValueError("--trajectory shapes: a path planned in tension space for --controller inverse-statics; "
                             "the paper's laws run control-test or identification")
        from controllers.trajectories import make_trajectory
        return make_trajectory(name or "control-test", params, duration_scale)
    from controllers import reachable_paths as rp
    plant = params if effects is None else effects.true_params(params)
    offset = None if effects is None else effects.elongation_offset(params.n_cables)
    if name in (None, "shapes", "identification"):
        path = (rp.excitation_path if name == "identification" else rp.shapes_tour)(params, duration_scale)
        if plant != params or (offset is not None and offset.any()):
            rp.check_plant_holds(path, plant, offset)
        return path
    from neck_sim.trajectory import scaled_trajectory as joint_trajectory
    traj = joint_trajectory(name, params, duration_scale)
    traj.check_workspace(params)
    rp.check_holdable(traj, params)
    if plant != params:
        rp.check_holdable(traj, plant)
    return traj
