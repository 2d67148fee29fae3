"""Run independent closed-loop experiments in parallel worker processes.

Each run is described by a picklable :class:`RunSpec` (plant, controller, trajectory by name) and
built inside its worker: MuJoCo models, callbacks and controllers never cross process boundaries.
Results come back as :class:`~controllers.closed_loop.RunResult` in the order of the specs.
"""

from __future__ import annotations

import concurrent.futures as cf
import multiprocessing
import os
from dataclasses import dataclass, field
from typing import Any, Mapping, Sequence

from controllers.closed_loop import RunResult, run_closed_loop
from controllers.computed_torque import ComputedTorqueController
from controllers.trajectories import make_trajectory
from neck_sim.params import NeckParams

__all__ = ["RunSpec", "run_one", "run_all", "default_workers"]


@dataclass(frozen=True)
class RunSpec:
    """One closed-loop run.

    ``params``: the plant's constants; ``controller_params``: the controller's model (default the
    same); ``trajectory``: a name understood by :func:`controllers.trajectories.make_trajectory`
    with ``duration_scale``; ``effects``: a :class:`neck_sim.effects.Effects` hidden in the plant;
    ``log_path``: MCAP of the run, or None.
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


def run_one(spec: RunSpec, progress: bool = False) -> RunResult:
    """Build the plant, controller and trajectory of ``spec`` and run them."""
    from neck_sim.plant import Plant

    plant = Plant(spec.params, effects=spec.effects, seed=spec.seed, rigid_cables=spec.rigid_cables)
    model = spec.params if spec.controller_params is None else spec.controller_params
    controller = ComputedTorqueController(model, spec.law, **dict(spec.controller_kwargs))
    trajectory = make_trajectory(spec.trajectory, model, spec.duration_scale)
    info = {"experiment": spec.label, **dict(spec.run_info)}
    return run_closed_loop(plant, controller, trajectory, log_path=spec.log_path, progress=progress, run_info=info)


def default_workers() -> int:
    """One worker per available core (at least 1)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on Linux
        return max(1, os.cpu_count() or 1)


def run_all(specs: Sequence[RunSpec], *, workers: int | None = None, progress: bool = True,
            desc: str = "closed-loop runs") -> list[RunResult]:
    """Run every spec, ``workers`` at a time (default: one per core); results in spec order.

    With one worker (or one spec) everything runs in this process, with per-step progress.
    A failing run raises its error, naming the run's label.
    """
    labels = [s.label for s in specs]
    if len(set(labels)) != len(labels):
        raise ValueError(f"run labels must be unique, got {labels}")
    workers = default_workers() if workers is None else int(workers)
    if workers < 1:
        raise ValueError(f"workers: must be >= 1, got {workers}")
    if workers == 1 or len(specs) <= 1:
        return [_run_labelled(s, progress) for s in specs]

    from tqdm.auto import tqdm

    # fork keeps start-up cheap; the workers start before any MuJoCo model exists in them.
    ctx = multiprocessing.get_context("fork")
    results: list[RunResult | None] = [None] * len(specs)
    with cf.ProcessPoolExecutor(max_workers=min(workers, len(specs)), mp_context=ctx) as pool:
        futures = {pool.submit(run_one, s): i for i, s in enumerate(specs)}
        with tqdm(total=len(specs), desc=desc, unit="run", disable=not progress) as bar:
            for fut in cf.as_completed(futures):
                i = futures[fut]
                try:
                    results[i] = fut.result()
                except Exception as exc:
                    for other in futures:
                        other.cancel()
                    raise RuntimeError(f"run {specs[i].label!r} failed: {exc}") from exc
                bar.set_postfix_str(specs[i].label)
                bar.update()
    return results


def _run_labelled(spec: RunSpec, progress: bool) -> RunResult:
    try:
        return run_one(spec, progress)
    except Exception as exc:
        raise RuntimeError(f"run {spec.label!r} failed: {exc}") from exc

