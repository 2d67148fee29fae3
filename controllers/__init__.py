"""Controllers of the neck and the loop that runs them on a plant.

The paper's computed-torque laws 1-3 (§6.3, eqs 59-66: :class:`ComputedTorqueController`), the
elastic LQR for long necks on elastic cables (:class:`ElasticLQRController`) and inverse statics
for any routing (:class:`UnderactuatedController`); :func:`choose_controller` picks one for a neck
and :func:`make_run_trajectory` a trajectory it can follow.  :func:`run_closed_loop` runs one
controller on one plant at the control rate (an MCAP log if asked), :func:`run_lockstep` many at
once, :func:`run_all` a campaign of :class:`RunSpec`.  :func:`make_trajectory` scales the paper's
trajectories (§7, §5.2.2) to a neck's force limits.

Usage::

    import neck_sim
    from controllers import ComputedTorqueController, make_trajectory, run_closed_loop

    params = neck_sim.default_params(3)
    trajectory = make_trajectory("control-test", params, duration_scale=0.05)   # 0.75 s
    result = run_closed_loop(neck_sim.Plant(params), ComputedTorqueController(params, law=2),
                             trajectory, progress=False)
    print(result.metrics.tracking_error)                   # e of §7, deg

Names are imported when first used (PEP 562): ``import controllers`` loads neither numba nor
MuJoCo.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from neck_sim.lazy import lazy_attributes

if TYPE_CHECKING:
    from controllers.closed_loop import run_closed_loop, run_lockstep
    from controllers.computed_torque import ComputedTorqueController, ControlLaw, OutsideWorkspaceError
    from controllers.elastic_lqr import ElasticLQRController, LQRWeights
    from controllers.parallel import RunSpec, run_all
    from controllers.run_result import Metrics, RunResult
    from controllers.selection import CONTROLLERS, Choice, choose_controller, make_run_trajectory
    from controllers.tension import TensionInfeasibleError
    from controllers.trajectories import make_trajectory
    from controllers.underactuated import UnderactuatedController

__all__ = ["ComputedTorqueController", "ControlLaw", "OutsideWorkspaceError", "ElasticLQRController", "LQRWeights",
           "UnderactuatedController", "TensionInfeasibleError",
           "run_closed_loop", "run_lockstep", "RunResult", "Metrics", "RunSpec", "run_all",
           "CONTROLLERS", "Choice", "choose_controller", "make_run_trajectory", "make_trajectory"]

# exported name -> the module that defines it
_SOURCES: dict[str, str] = {
    "run_closed_loop": "controllers.closed_loop", "run_lockstep": "controllers.closed_loop",
    **dict.fromkeys(("ComputedTorqueController", "ControlLaw", "OutsideWorkspaceError"), "controllers.computed_torque"),
    "ElasticLQRController": "controllers.elastic_lqr", "LQRWeights": "controllers.elastic_lqr",
    "RunSpec": "controllers.parallel", "run_all": "controllers.parallel",
    "Metrics": "controllers.run_result", "RunResult": "controllers.run_result",
    **dict.fromkeys(("CONTROLLERS", "Choice", "choose_controller", "make_run_trajectory"), "controllers.selection"),
    "TensionInfeasibleError": "controllers.tension",
    "make_trajectory": "controllers.trajectories",
    "UnderactuatedController": "controllers.underactuated",
}

__getattr__, __dir__ = lazy_attributes(__name__, _SOURCES, __all__)
