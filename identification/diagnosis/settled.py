"""A named finding's fit settled: its tension and stiffness iteration run to its fixed point.

A candidate's fit (``candidates.fit_model``) runs ``settings.iterations`` passes (3) of its
tension/stiffness iteration from the step baseline's tensions: each pass subtracts the fitted
motor-side forces from the motor force, so the tension, and with it the stiffness k + lambda T
the elongation row divides by (eq 42), moves, and the next pass refits.  On the 10-joint, 4-cable
neck's 59.3 s logs a cable moving at tens of rad/s leaves the motor-force candidates far from their
fixed point after 3 passes: on the dry logs of two fresh seeds dry f_s 31 sigma (-21 % -> +0.6 %
of the hidden force), pulley mu 27 sigma, viscous c_v 16 sigma; every other effect moves by less
than 1 sigma, and on the 3-joint neck and on clean logs every effect does.  Viscous friction hidden
on a fast cable (``bench_any_neck.py --detection --moves 31 --sigma --cases viscous_friction``,
seeds 3, 7, 6, 8) read -17.6, +0.3, -1.9, -1.0 % as made and +0.3, +2.2, -1.7, -0.5 % settled
(eq 50's sigma 1-2 % of the value).

The diagnosis names effects on the fits as made (their scores, p values and margins; settling
every candidate of every step would change what it compares).  Once an effect is named, its
magnitudes are read on its own fit settled (:func:`settled_candidate`: one-pass steps until every
parameter of the candidate's own columns moves by less than :data:`SETTLED` of its sigma), which
the magnitudes' later readings then use (``pipeline._finding_parameters``: SIMEX, the hinge's
interval, the dry level).  The next step's baseline keeps the fit as made; the extended model
(what ``diagnose --extended`` writes) is the last model settled on every named term's parameters
(:func:`settled_fit`), so that it holds the values the report gives (exactly so for the last step's
finding when that step named one).

    >>> from identification.diagnosis.settled import settled_candidate
    >>> cand = settled_candidate(ctx, cand)        # doctest: +SKIP
    >>> cand.fit.value                             # the candidate's parameters at the fixed point
"""

from __future__ import annotations

import dataclasses
from typing import Callable

import numpy as np

__all__ = ["SETTLED", "MAX_PASSES", "settle", "own_indices", "settled_fit", "settled_candidate"]

#: The fit's tension and stiffness estimates have settled when one more pass moves every settled
#: value by less than this share of its sigma (eq 50).
SETTLED = 0.25
#: Passes at most (a fresh seed's cable 4 settles in 7-10, the other blind logs in 1-5).
MAX_PASSES = 30


def settle(step: Callable, fit, indices, max_passes: int = MAX_PASSES):
    """``fit`` after passes ``fit = step(fit)`` until one moves every ``fit.value[indices]`` by less
    than :data:`SETTLED` of its ``sigma`` (or ``max_passes``).  ``step``: one pass of the fit's
    tension/stiffness iteration (``candidates.fit_model`` with ``iterations=1`` from the fit's state):
    the candidate's fit stops after ``settings.iterations`` passes from the baseline's tensions, which
    on a cable moving at tens of rad/s leaves f_s far from the fixed point (-21 % -> -0.6 % over 7 more
    passes on a fresh seed's cable 4, where the friction subtracted from the motor force changes the
    tension and so the stiffness k + lambda T its elongation row divides by, eq 42)."""
    idx = np.asarray(indices, int)
    for _ in range(max_passes):
        new = step(fit)
        moved = np.abs(np.asarray(new.value)[idx] - np.asarray(fit.value)[idx])
        fit = new
        if np.all(moved < SETTLED * np.asarray(new.sigma)[idx]):
            break
    return fit


def own_indices(fit, term, n_joints: int, n_cables: int) -> list[int]:
    """Indices into ``fit.value`` of the parameters of ``term``'s own columns (``f_s(1)``, ...,
    ``c_v(4)``: their ``Column.names`` on a neck of ``n_joints`` joints and ``n_cables`` cables)."""
    own = {name for col in term.identification.columns for name in col.names(n_joints, n_cables)}
    return [k for k, n in enumerate(fit.names) if n in own]


def settled_fit(ctx, fit, terms):
    """``fit`` settled (:func:`settle` of one-pass ``candidates.fit_model`` steps from its state,
    ``ctx`` a ``fitting.StepContext``) on the parameters of the own columns of ``terms``
    (:func:`own_indices`); ``fit`` itself when they have none."""
    from identification.diagnosis.candidates import fit_model

    indices = sorted({k for term in terms for k in own_indices(fit, term, ctx.data.n, ctx.data.C)})
    if not indices:
        return fit
    return settle(lambda f: fit_model(ctx.data, f.model, ctx.split.train, ctx.scales, f.state, iterations=1),
                  fit, indices)


def settled_candidate(ctx, cand):
    """``cand`` (a named ``candidate.CandidateScore``) with its fit settled (:func:`settled_fit` on
    its own term); its scores and evidence as they were.  ``cand`` itself when it has no fit or no
    column of its own (a shape-only effect: its values come from the grid search, not the iteration)."""
    if cand.fit is None:
        return cand
    fit = settled_fit(ctx, cand.fit, [cand.term])
    if fit is cand.fit:
        return cand
    return dataclasses.replace(cand, model=dataclasses.replace(cand.model, fit=fit))
