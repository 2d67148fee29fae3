"""A named finding's magnitudes are read on its fit settled (``identification/diagnosis/settled.py``).

The fit's one-pass step is replaced here by a contraction built in the test, x -> a x + b on the
candidate's own parameter (fixed point b / (1 - a)), so that the fixed point is known without the
code under test; the candidate's fit "as made" stops three passes short of it.
"""

from __future__ import annotations

import dataclasses
from types import SimpleNamespace

import numpy as np
import pytest

A, B, SIGMA = 0.7, 0.03, 1e-4
FIXED = B / (1 - A)


def _fit(k: float, c_v: float):
    """A fit of the baseline's k(1) and the candidate's c_v(1); its state (what the next pass starts
    from) is itself."""
    f = SimpleNamespace(names=("k(1)", "c_v(1)"), units=("N/m", "N s/rad"), value=np.array([k, c_v]),
                        sigma=np.full(2, SIGMA), model=None)
    f.state = f
    return f


@pytest.fixture
def named(monkeypatch):
    """(ctx, cand, calls): a viscous friction candidate on cable 1 of a 4-cable, 10-joint neck whose
    fit is 3 passes of the contraction from 0, and ``candidates.fit_model`` replaced by one pass of it
    (the baseline's k(1) halves each pass: not the candidate's own column, not what settles)."""
    from identification.diagnosis import candidates
    from identification.diagnosis.candidate import CandidateScore
    from identification.diagnosis.candidates import Term
    from identification.diagnosis.fitting import Evaluated

    calls = []

    def one_pass(data, model, train, scales, state=None, *, iterations=3, keep_rows=False):
        assert iterations == 1
        calls.append(1)
        return _fit(0.5 * state.value[0], A * state.value[1] + B)

    def made_fit():
        x = 0.0
        for _ in range(3):
            x = A * x + B
        return _fit(1000.0, x)

    monkeypatch.setattr(candidates, "fit_model", lambda d, m, t, s, state=None, **kw: one_pass(d, m, t, s, state, **kw))
    cand = CandidateScore(Term("viscous_friction"), Evaluated(made_fit(), np.zeros((1, 1))), 1, 1.0, 1.0, 0.1, 0.1,
                          {}, 1e-9, 1e-9, True, True)
    data = SimpleNamespace(theta_dot_fast=np.zeros((5, 4)), C=4, n=10)
    ctx = SimpleNamespace(data=data, split=SimpleNamespace(train=np.ones(5, bool)), scales=np.ones(14))
    return ctx, cand, calls


def test_a_named_findings_parameters_are_its_settled_fits(named):
    """``pipeline._finding_parameters`` reports c_v(1) within SETTLED sigma a / (1 - a) of the
    contraction's fixed point, after more than one further pass, where the fit as made is more than
    10 sigma short of it; the candidate itself keeps the fit as made (its evidence, the verdict's)."""
    from identification.diagnosis.pipeline import _finding_parameters
    from identification.diagnosis.settled import SETTLED

    ctx, cand, calls = named
    made = float(cand.fit.value[1])
    assert FIXED - made > 10 * SIGMA
    p = _finding_parameters(ctx, cand, None)["c_v(1)"]
    assert len(calls) > 1
    assert abs(p.value - FIXED) <= SETTLED * SIGMA * A / (1 - A)
    assert p.sigma == SIGMA and p.unit == "N s/rad"
    assert cand.fit.value[1] == made


def test_simex_on_the_settled_fit_adds_its_correction_to_the_settled_value(named, monkeypatch):
    """Where SIMEX corrects a magnitude, it extrapolates for the fit as made (its replicates repeat
    that estimator): the reported value is the settled one plus that correction."""
    from identification.diagnosis import pipeline
    from identification.diagnosis.settled import settled_candidate

    ctx, cand, _ = named
    seen = {}

    def correct(ctx_, cand_, parameters, state):
        seen.update({n: p.value for n, p in parameters.items()})
        return {**parameters, "c_v(1)": dataclasses.replace(parameters["c_v(1)"], value=parameters["c_v(1)"].value - 0.002)}

    monkeypatch.setattr(pipeline, "corrected_parameters", correct)
    settled = settled_candidate(ctx, cand)
    parameters = pipeline.term_parameters(ctx, settled)
    out = pipeline._simex_on_settled(ctx, cand, settled.fit, parameters, None)
    assert seen["c_v(1)"] == cand.fit.value[1]                 # SIMEX saw the fit as made
    assert out["c_v(1)"].value == pytest.approx(settled.fit.value[1] - 0.002, abs=1e-12)
    assert settled.fit.value[1] - cand.fit.value[1] > 10 * SIGMA          # the shift is the settling's
