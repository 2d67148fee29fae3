"""Text report of an output-error fit beside the least-squares start it came from."""

from __future__ import annotations

import numpy as np

from identification.output_error.fit import OutputErrorResult

__all__ = ["format_output_error"]


def _reference(names, params, effects=None) -> list:
    """The reference value per parameter name (the plant's or the nominal constants'), or NaN."""
    table = {"f_s": params.friction.f_s, "k": params.cables.k, "lambda": params.cables.lam, "c_a": params.cables.c_a}
    out = []
    for n in names:
        sym, _, rest = n.partition("(")
        j = int(rest.rstrip(")")) - 1 if rest else None
        out.append(float(table[sym][j]) if sym in table and j is not None else float("nan"))
    return out


def format_output_error(result: OutputErrorResult, reference=None, *, reference_name: str = "nominal") -> str:
    """The fitted parameters (value +- 95 % half-width) beside the least-squares start and, when
    ``reference`` (NeckParams) is given, its values with our relative difference; then the cost
    per signal against the noise floor, the misfit lines, rejected steps and the cost of the fit."""
    ref = _reference(result.names, reference) if reference is not None else [float("nan")] * len(result.names)
    lines = [f"Output-error identification ({len(result.logs)} log{'s' if len(result.logs) > 1 else ''}, "
             f"one parameter set; integrator {result.integrator})",
             f"{'parameter':24} {'least squares (start)':>22} {'output error +- 95 %':>28} {reference_name + ' (diff)':>26}"]
    for n, u, s0, v, c, r in zip(result.names, result.units, result.start, result.value, result.ci95, ref):
        diff = f"{r:.6g} ({100 * (v - r) / abs(r):+.3f} %)" if np.isfinite(r) and r != 0 else "-"
        lines.append(f"{n + ' (' + u + ')':24} {s0:22.6g} {f'{v:.6g} +- {c:.3g}':>28} {diff:>26}")
    lines.append("cost / noise floor per signal: " + ", ".join(f"{k} {v:.3f}" for k, v in result.cost_ratio.items())
                 + " (about 1: the residuals are the sensors' noise)")
    coarse = f", {result.coarse_rollouts} of them on the Jacobian's coarse model" if result.coarse_rollouts else ""
    lines.append(f"{result.rollouts} rollouts ({result.simulated_s:.0f} s of plant time{coarse}): {result.iterations} "
                 f"finite-difference Jacobian{'s' if result.iterations != 1 else ''}, {result.trial_steps} trial "
                 f"steps, {result.cpu_s:.1f} s CPU; stopped: {result.status}")
    if result.rejected:
        lines.append(f"{len(result.rejected)} rejected step(s): " + "; ".join(result.rejected[:3])
                     + (" ..." if len(result.rejected) > 3 else ""))
    lines += list(result.misfit) + list(result.notes)
    return "\n".join(lines)
