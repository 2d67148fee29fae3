"""The shape search's one-dimensional refinement (``identification.diagnosis.search``)."""

from __future__ import annotations

import math

import pytest

from identification.diagnosis.candidates import Term
from identification.diagnosis.columns import Shape
from identification.diagnosis.search import _refine_between


def _trial(best_c: float):
    """A trial whose training score is (log c - log best_c)^2, counted."""
    calls = []

    def trial(term: Term):
        calls.append(term.get("c"))
        return ((math.log(term.get("c")) - math.log(best_c)) ** 2, term, None)

    return trial, calls


@pytest.mark.parametrize("start", [2.0, 2.1849])
def test_refinement_between_the_neighbours_of_the_start_on_or_off_the_grid(start):
    """From a grid point or from a value between grid points (the every-cable form's refined
    sharpness handed to the one-cable search), the search stays between the grid points on either
    side and finds the minimum there."""
    shape = Shape("c", "s/rad", default=0.5, grid=(0.5, 2.0, 8.0), refine="log", span=2.0)
    trial, calls = _trial(3.0)
    start_entry = trial(Term("pulley_friction", (("c", start), ("cable", 1.0))))
    best = _refine_between(trial, "pulley_friction", shape, "c", start_entry)
    assert best[1].get("c") == pytest.approx(3.0, rel=0.05) and best[1].get("cable") == 1.0
    lo, hi = (0.5, 8.0) if start == 2.0 else (2.0, 8.0)
    assert all(lo <= c <= hi for c in calls[1:]), calls
