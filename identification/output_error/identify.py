"""Output-error identification of one or more logs, started from the paper's least squares.

The start point is the least-squares estimate of each log (:func:`identification.paper.identify`,
eqs 44-57), the median over the logs: f_s from the friction-only model (eqs 46-47; the most
accurate of the least-squares frictions), k and lambda from the variable-stiffness model (eqs
54-57), c_a from it too but at least :data:`C_A_START_FLOOR` (the least squares are blind to
damping: its c_a can come out at or below zero, a corner of the box to start from), and an
extended model's effect magnitudes from its file.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from identification.output_error.fit import OutputErrorResult, OutputErrorSettings, fit
from identification.output_error.problem import Layout, Measured, same_neck
from neck_sim.params import NeckParams

__all__ = ["ExtendedPlant", "load_extended_model", "start_point", "identify_output_error", "C_A_START_FLOOR"]

#: N s/m: the least-squares c_a is not trusted below this as a start (the box's corner is 0)
C_A_START_FLOOR = 1.0


@dataclass(frozen=True)
class ExtendedPlant:
    """An extended model written by ``neck-sim diagnose --extended``: plant constants and effects."""

    params: NeckParams
    effects: object
    path: str


def load_extended_model(path) -> ExtendedPlant:
    """Read a ``diagnose --extended`` JSON file; ValueError in one line naming what is wrong."""
    from identification.diagnosis.settings import read_model_file
    from neck_sim.effects import Effects
    from neck_sim.params import from_dict

    data = read_model_file(path, ("params", "effects"), "'params' and 'effects'")
    if data.get("rigid_cables"):
        raise ValueError(f"--model {path}: a rigid-cable model; output-error fits the elastic cables of eq (54)")
    try:
        return ExtendedPlant(from_dict(data["params"]), Effects.from_dict(data["effects"] or {}), str(path))
    except (ValueError, TypeError, KeyError) as exc:
        raise ValueError(f"--model {path}: {str(exc).splitlines()[0]}") from None


def start_point(layout: Layout, least_squares) -> tuple[np.ndarray, list]:
    """x0 from the least-squares results (one :class:`~identification.paper.IdentificationResult`
    per log; median over logs) for the base groups, the layout's nominal values elsewhere."""
    x0 = layout.vector()
    notes = []
    pick = {"f_s": ("friction", "f_s"), "k": ("variable", "k"), "lambda": ("variable", "lambda"),
            "c_a": ("variable", "c_a")}
    for sym, (model, group) in pick.items():
        vals = [getattr(r, model).group(group) for r in least_squares if getattr(r, model) is not None]
        if not vals:
            raise ValueError(f"output-error: the least-squares {model} model did not run; it gives the start of {sym}")
        v = np.median(np.stack(vals), axis=0)
        idx = [i for i, n in enumerate(layout.names) if n.split("(")[0] == sym]
        if sym == "c_a" and np.any(v < C_A_START_FLOOR):
            low = ", ".join(f"cable {j + 1}: {v[j]:.3g}" for j in np.flatnonzero(v < C_A_START_FLOOR))
            notes.append(f"start: least-squares c_a below {C_A_START_FLOOR:g} N s/m ({low}) started at "
                         f"{C_A_START_FLOOR:g} (the least squares cannot see damping)")
            v = np.maximum(v, C_A_START_FLOOR)
        x0[idx] = v
    return x0, notes


def identify_output_error(logs, params: NeckParams | None = None, *, model: ExtendedPlant | None = None,
                          settings: OutputErrorSettings | None = None, least_squares=None, ls_settings=None,
                          progress: bool = False) -> tuple[OutputErrorResult, list]:
    """Fit one parameter set to every log in ``logs`` (:class:`neck_sim.logs.Log` read with
    motors, camera and, when present, reference).  Returns (result, least-squares results).

    ``params``: nominal constants (default the first log's neck record; every log must be of that
    neck); ``model``: an extended model (its constants replace ``params``, its effect magnitudes
    are fitted too); ``least_squares``: the least-squares results per log if already computed."""
    from identification.paper import IdentificationSettings, identify_log

    logs = list(logs)
    if not logs:
        raise ValueError("output-error: no log given")
    first = str(logs[0].path)
    for log in logs[1:]:
        same_neck(logs[0].params, log.params, str(log.path), first)
    nominal = model.params if model is not None else (params or logs[0].params)
    if model is not None:
        lp = logs[0].params
        if (nominal.n_joints, nominal.n_cables) != (lp.n_joints, lp.n_cables):
            raise ValueError(f"--model {model.path}: {nominal.n_joints} joints and {nominal.n_cables} cables, the log "
                             f"{first} has {lp.n_joints} and {lp.n_cables}")
        if nominal.routing.segment_cases(nominal.n_joints).tolist() != lp.routing.segment_cases(lp.n_joints).tolist():
            raise ValueError(f"--model {model.path}: routes the cables differently from the neck record of {first}")
        model.effects.check(nominal)
    measured = [Measured.from_log(log, nominal, name=str(log.path)) for log in logs]
    if least_squares is None:
        s_ls = ls_settings or IdentificationSettings(bootstrap=0, reconstruct_alpha=False)
        least_squares = [identify_log(log, s_ls, params=params, models=("friction", "variable")) for log in logs]
    layout = Layout.of(nominal, model.effects if model is not None else None)
    x0, notes = start_point(layout, least_squares)
    notes += [f"{m.name}: start pose from {m.start_pose}" for m in measured]
    result = fit(measured, layout, x0, settings, progress=progress, notes=notes)
    return result, least_squares
