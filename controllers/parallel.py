"""Run independent closed-loop experiments on a campaign executor (:mod:`controllers.campaign`).

Each run is described by a picklable :class:`RunSpec` (plant, controller, trajectory by name) and
built inside its worker: MuJoCo models, callbacks and controllers never cross process boundaries.
Results come back as :class:`~controllers.closed_loop.RunResult` in the order of the specs; a run's
MCAP log is written by the worker into a scratch directory and sent back, so a Dask worker on
another machine needs no shared file system.
"""

from __future__ import annotations

import concurrent.futures as cf
import dataclasses
from dataclasses import dataclass, field
from typing import Any, Mapping, Sequence

from controllers.campaign import ExecutorSpec, map_jobs, run_campaign, run_in_scratch, write_shipped
from controllers.closed_loop import RunResult, run_closed_loop
from controllers.computed_torque import ComputedTorqueController
from controllers.trajectories import make_trajectory
from neck_sim.params import NeckParams
from neck_sim.plant_spec import PlantSpec

__all__ = ["RunSpec", "run_one", "run_all"]


@dataclass(frozen=True)
class RunSpec:
    """One closed-loop run.

    ``params``: the plant's constants; ``controller_params``: the controller's model (default the
    same); ``trajectory``: a name understood by :func:`controllers.trajectories.make_trajectory`
    with ``duration_scale``; ``effects``: a :class:`neck_sim.effects.Effects` hidden in the plant;
    ``log_path``: MCAP of the run, or None.  The plant the run drives is :attr:`plant`.
    """

    label: str
    params: NeckParams
    law: int = 2
    trajectory: str = "control-test"
    duration_scale: float = 1.0
    controller_params: NeckParams | None = None
    controller_kwargs: Mapping[str, Any] = field(default_factory=dict)
    rigid_cables: bool = False
    effects: Any = None
    seed: int = 0
    log_path: str | None = None
    run_info: Mapping[str, Any] = field(default_factory=dict)

    @property
    def plant(self) -> PlantSpec:
        """The plant of this run (params, effects, seed, cable model; default timestep)."""
        return PlantSpec(self.params, self.effects, seed=self.seed, rigid_cables=self.rigid_cables)


def run_one(spec: RunSpec, progress: bool = False) -> RunResult:
    """Build the plant, controller and trajectory of ``spec`` and run them."""
    plant = spec.plant.build()
    model = spec.params if spec.controller_params is None else spec.controller_params
    controller = ComputedTorqueController(model, spec.law, **dict(spec.controller_kwargs))
    # the trajectory is fitted to the neck that moves (the plant), not to the controller's model:
    # Table 3's controller without pulleys must follow the same reference as the one with them
    trajectory = make_trajectory(spec.trajectory, spec.params, spec.duration_scale)
    info = {"experiment": spec.label, **dict(spec.run_info)}
    return run_closed_loop(plant, controller, trajectory, log_path=spec.log_path, progress=progress, run_info=info)


def run_all(specs: Sequence[RunSpec], executor: ExecutorSpec | cf.Executor | None = ExecutorSpec(), *,
            progress: bool = True, desc: str = "closed-loop runs") -> list[RunResult]:
    """Run every spec; results in spec order.

    ``executor``: where (an :class:`~controllers.campaign.ExecutorSpec`, default one local process
    per core; an executor already open; or None: serially here, with per-step progress).  A
    failing run raises ``RuntimeError`` naming the run's label.
    """
    labels = [s.label for s in specs]
    if len(set(labels)) != len(labels):
        raise ValueError(f"run labels must be unique, got {labels}")
    if executor is None or (isinstance(executor, ExecutorSpec) and executor.cluster is None
                            and (executor.serial or len(specs) <= 1)):
        return map_jobs(_run_here, [(s, progress) for s in specs], None, labels=labels, progress=False)
    shipped = run_campaign(_run_shipped, specs, executor, labels=labels, progress=progress, desc=desc)
    out = []
    for spec, (result, log) in zip(specs, shipped):
        if spec.log_path is not None:
            write_shipped(spec.log_path, log)
            result = dataclasses.replace(result, log_path=spec.log_path)
        out.append(result)
    return out


def _run_here(job) -> RunResult:
    spec, progress = job
    return run_one(spec, progress)


def _run_shipped(spec: RunSpec) -> tuple[RunResult, bytes | None]:
    """On a worker: the run, and its log's bytes (None without a log)."""
    if spec.log_path is None:
        return run_one(spec), None
    return run_in_scratch(_run_logged, "run.mcap", spec)


def _run_logged(path: str, spec: RunSpec) -> RunResult:
    return run_one(dataclasses.replace(spec, log_path=path))
