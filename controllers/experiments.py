"""The paper's closed-loop experiments on the simulated plant, with the paper's numbers beside them.

* :func:`control_tests`: the three control laws of §6.3 on one trajectory (the §7 tests);
* :func:`table3`: the law with and without pulleys in its model (r = 0 in the controller only)
  on a rigid-cable plant and on the identified-cable plant (§5.6, Table 3);
* :func:`format_control_table`, :func:`format_table3`: plain-text tables of measured vs paper.
"""

from __future__ import annotations

import datetime
import os
from typing import TYPE_CHECKING, Callable, Mapping, Sequence

from controllers.closed_loop import LoopController, RunResult, run_closed_loop
from controllers.computed_torque import ComputedTorqueController
from controllers.trajectories import Trajectory
from neck_sim.params import NeckParams

if TYPE_CHECKING:
    from controllers.underactuated import ReachablePath
    from neck_sim.plant import Plant

__all__ = ["PAPER_CONTROL_TESTS", "PAPER_TABLE3", "TABLE3_CASES", "default_log_path", "control_log_labels",
           "table3_log_label", "control_tests", "table3", "format_control_table", "format_table3"]

# §7: mean |alpha_hat - alpha_d| and mean |alpha_hat - alpha_IP| (deg) of tests 1-3 on the prototype.
PAPER_CONTROL_TESTS = {1: {"tracking": 0.52, "estimation": 2.19},
                       2: {"tracking": 0.37, "estimation": 1.51},
                       3: {"tracking": 0.66, "estimation": 1.09}}

# Table 3 (simulation, identification trajectory, law with friction and inextensible estimator):
# e_alpha = mean |alpha - alpha_hat| and e = mean tracking error (deg).
PAPER_TABLE3 = {("rigid", True): {"estimation": 0.35, "tracking": 0.08},
                ("identified", True): {"estimation": 1.68, "tracking": 0.11},
                ("rigid", False): {"estimation": 2.00, "tracking": 0.21},
                ("identified", False): {"estimation": 2.88, "tracking": 0.26}}
TABLE3_CASES = tuple(PAPER_TABLE3)           # (plant cable model, pulleys in the controller)


def default_log_path(trajectory: str, label: str, directory: str = "logs") -> str:
    """``logs/simulate-<trajectory>-<label>-<UTC time>.mcap``."""
    stamp = datetime.datetime.now(datetime.timezone.utc).strftime("%Y%m%dT%H%M%S")
    return os.path.join(directory, f"simulate-{trajectory}-{label}-{stamp}.mcap")


def control_log_labels(controller: str, laws: Sequence[int]) -> list[str]:
    """The labels :func:`control_tests` gives its runs' logs (``log_path(label)``), in run order:
    ``law<k>`` per law of the computed-torque controller, else the controller's name."""
    if controller != "computed-torque":
        return [controller]
    return [f"law{int(law)}" for law in laws]


def table3_log_label(plant_kind: str, pulleys: bool) -> str:
    """The label :func:`table3` gives the log of its run with ``plant_kind`` cables and a
    controller with (or without) pulleys."""
    return f"{plant_kind}-{'pulleys' if pulleys else 'no-pulleys'}"


def _make_plant(params: NeckParams, rigid_cables: bool, seed: int) -> Plant:
    from neck_sim.plant import Plant
    return Plant(params, seed=seed, rigid_cables=rigid_cables)


def control_tests(params: NeckParams, trajectory: Trajectory | ReachablePath, laws: Sequence[int] = (1, 2, 3), *,
                  log_path: Callable[[str], str | None] | None = None, progress: bool = True, seed: int = 0,
                  rigid_cables: bool = False, controller_params: NeckParams | None = None,
                  controller_kwargs: Mapping | None = None,
                  plant_factory: Callable[[NeckParams, bool, int], Plant] | None = None,
                  controller: str = "computed-torque", stop_outside_range: bool = False) -> dict[str, RunResult]:
    """Run each law on a fresh plant; returns ``{"law 1": RunResult, ...}``.

    ``controller="elastic-lqr"`` runs :class:`controllers.elastic_lqr.ElasticLQRController` (law 2's
    feed-forward, LQR feedback on a neck observer: long necks on elastic cables) once instead of
    the laws, labelled ``"elastic lqr"``; ``controller="inverse-statics"`` runs
    :class:`controllers.underactuated.UnderactuatedController` (any routing; ``trajectory`` then
    usually a :class:`controllers.underactuated.ReachablePath`), labelled ``"inverse statics"``.

    ``params`` are the plant's; ``controller_params`` the controller's model (default the same,
    e.g. ``params.replace(**{"geometry.r": 0.0})`` for a controller that ignores the pulleys).
    ``log_path(label)`` gives each run's MCAP path (None: no log).  ``controller_kwargs`` go to
    every :class:`ComputedTorqueController` (e.g. ``t_min``, ``cable_model``, ``f_s``).
    ``plant_factory(params, rigid_cables, seed)`` replaces :class:`neck_sim.plant.Plant`.
    ``stop_outside_range``: a run whose neck leaves its joint range stops with an error and writes
    no log (:func:`controllers.closed_loop.run_lockstep`).
    """
    make = plant_factory or _make_plant
    guard = {"stop_outside_range": stop_outside_range}
    model = params if controller_params is None else controller_params
    info = {"experiment": "control test", "seed": seed, "rigid_cables": rigid_cables}
    if controller == "elastic-lqr":
        from controllers.elastic_lqr import ElasticLQRController
        ctrl: LoopController = ElasticLQRController(model, **dict(controller_kwargs or {}))
        return {"elastic lqr": run_closed_loop(make(params, rigid_cables, seed), ctrl, trajectory, progress=progress,
                                               log_path=log_path(controller) if log_path else None,
                                               run_info={**info, "controller": "elastic-lqr"}, **guard)}
    if controller == "inverse-statics":
        from controllers.underactuated import UnderactuatedController
        ctrl = UnderactuatedController(model, **dict(controller_kwargs or {}))
        return {"inverse statics": run_closed_loop(make(params, rigid_cables, seed), ctrl, trajectory,
                                                   progress=progress,
                                                   log_path=log_path(controller) if log_path else None,
                                                   run_info={**info, "controller": "inverse-statics"}, **guard)}
    if controller != "computed-torque":
        raise ValueError(f"controller: unknown {controller!r} (computed-torque, elastic-lqr, inverse-statics)")
    out = {}
    for law, label in zip(laws, control_log_labels(controller, laws)):
        ctrl = ComputedTorqueController(model, law, **dict(controller_kwargs or {}))
        out[f"law {int(law)}"] = run_closed_loop(make(params, rigid_cables, seed), ctrl, trajectory,
                                                 progress=progress, log_path=log_path(label) if log_path else None,
                                                 run_info=info, **guard)
    return out


def table3(params: NeckParams, trajectory: Trajectory | ReachablePath, law: int = 2, *,
           log_path: Callable[[str], str | None] | None = None, progress: bool = True, seed: int = 0,
           controller_kwargs: Mapping | None = None,
           plant_factory: Callable[[NeckParams, bool, int], Plant] | None = None,
           stop_outside_range: bool = False) -> dict[tuple[str, bool], RunResult]:
    """The four runs of Table 3: plant ``rigid``/``identified`` cables x controller with/without
    pulleys (``geometry.r = 0`` in the controller's model only; the plant always has them);
    ``stop_outside_range`` as in :func:`control_tests`."""
    make = plant_factory or _make_plant
    bare = params.replace(**{"geometry.r": 0.0})
    out = {}
    for plant_kind, pulleys in TABLE3_CASES:
        label = table3_log_label(plant_kind, pulleys)
        ctrl = ComputedTorqueController(params if pulleys else bare, law, **dict(controller_kwargs or {}))
        plant = make(params, plant_kind == "rigid", seed)
        out[(plant_kind, pulleys)] = run_closed_loop(
            plant, ctrl, trajectory, progress=progress, log_path=log_path(label) if log_path else None,
            run_info={"experiment": "table 3", "plant_cables": plant_kind, "controller_pulleys": pulleys,
                      "seed": seed}, stop_outside_range=stop_outside_range)
    return out


def _f(x: float, width: int = 6) -> str:
    return f"{x:{width}.2f}"


def format_control_table(results: Mapping[str, RunResult], compare_with_paper: bool = True) -> str:
    """Measured metrics per run; with ``compare_with_paper`` the paper's §7 values for laws 1-3."""
    run_w = max([8] + [len(label) for label in results])
    cols = [("run", run_w, None), ("e", 6, None), ("(paper)", 7, "tracking"), ("e_a cam", 7, None),
            ("(paper)", 7, "estimation"), ("e_a true", 8, None), ("e true", 6, None), ("f min", 6, None),
            ("f max", 6, None), ("f mean", 6, None), ("slack", 6, None), ("sat", 5, None)]
    if not compare_with_paper:
        cols = [c for c in cols if c[2] is None]
    head = " ".join(f"{name:<{w}}" if name == "run" else f"{name:>{w}}" for name, w, _ in cols)
    lines = ["angles in deg: e = mean|alpha_hat - alpha_d|, e_a cam = mean|alpha_hat - alpha_camera|, "
             "e_a true = mean|alpha_hat - alpha|, e true = mean|alpha - alpha_d|; forces in N; "
             "slack/sat = samples with a slack cable / a force clipped at f_max", head, "-" * len(head)]
    for label, res in results.items():
        m = res.metrics
        law = res.info.get("law")
        paper = {} if law is None else PAPER_CONTROL_TESTS.get(law, {})
        values = {"run": f"{label:<{run_w}}", "e": _f(m.tracking_error), "e_a cam": _f(m.estimation_error_camera, 7),
                  "e_a true": _f(m.estimation_error_true, 8), "e true": _f(m.tracking_error_true),
                  "f min": _f(m.force_min), "f max": _f(m.force_max), "f mean": _f(m.force_mean),
                  "slack": f"{m.slack_samples:>6d}", "sat": f"{m.saturated_samples:>5d}"}
        cells = []
        for name, w, key in cols:
            if key is None:
                cells.append(values[name])
            else:
                cells.append(_f(paper[key], w) if key in paper else f"{'':>{w}}")
        lines.append(" ".join(cells))
    return "\n".join(lines)


def format_table3(results: Mapping[tuple[str, bool], RunResult]) -> str:
    """Table 3 layout: rows with/without pulleys, columns rigid/identified cables, measured (paper)."""
    lines = ["Table 3 (deg): e_alpha = mean|alpha - alpha_hat|, e = mean|alpha_hat - alpha_d|; measured (paper)",
             f"{'control law':<16} | {'rigid-cable plant':<31} | {'identified-cable plant':<31}"]
    for pulleys in (True, False):
        cells = []
        for plant_kind in ("rigid", "identified"):
            res = results.get((plant_kind, pulleys))
            paper = PAPER_TABLE3[(plant_kind, pulleys)]
            if res is None:
                cells.append(f"{'-':<31}")
                continue
            m = res.metrics
            cells.append(f"e_a {m.estimation_error_true:4.2f} ({paper['estimation']:4.2f}), "
                         f"e {m.tracking_error:4.2f} ({paper['tracking']:4.2f})")
        lines.append(f"{'with pulleys' if pulleys else 'without pulleys':<16} | {cells[0]:<31} | {cells[1]:<31}")
    return "\n".join(lines)
