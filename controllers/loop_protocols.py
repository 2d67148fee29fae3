"""The interfaces a closed-loop run (:mod:`controllers.closed_loop`) asks of a controller and of a
trajectory."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Protocol

import numpy.typing as npt

if TYPE_CHECKING:
    from controllers.computed_torque import ControlStep
    from neck_sim.params import NeckParams

__all__ = ["LoopController", "LoopTrajectory"]


class LoopController(Protocol):
    """What a closed-loop run asks of a controller: :class:`ComputedTorqueController` (the
    compiled path), :class:`controllers.elastic_lqr.ElasticLQRController`,
    :class:`controllers.underactuated.UnderactuatedController` or anything with their interface."""

    @property
    def params(self) -> NeckParams: ...

    @property
    def law(self) -> int: ...

    def describe(self) -> str: ...

    def motor_reference(self, sample: Any) -> Any: ...

    def reset(self, alpha0: npt.ArrayLike | None = None, theta0: npt.ArrayLike | None = None) -> None: ...

    def step(self, theta: npt.ArrayLike, ref: Any) -> ControlStep: ...


class LoopTrajectory(Protocol):
    """What a closed-loop run asks of a trajectory: :class:`controllers.trajectories.Trajectory`,
    :class:`controllers.underactuated.ReachablePath` or anything with their interface."""

    @property
    def name(self) -> str: ...

    @property
    def duration(self) -> float: ...

    def sample(self, t: npt.ArrayLike) -> Any: ...

    def check_workspace(self, params: NeckParams) -> None: ...
