"""A motor-side term located on one cable (shape key ``cable``) against the effect's own force law."""

from types import SimpleNamespace

import numpy as np
import pytest

from identification.diagnosis import columns as effect_columns
from identification.diagnosis.columns.base import FitContext
from neck_sim.effects import StribeckFriction, ViscousFriction


def _data(seed: int, S: int = 40, n: int = 3, C: int = 4):
    """What a motor-side term's design reads (``ColumnData``): encoder speeds at twice the slow
    rate, a random transmission matrix, the slow grid every other control sample."""
    rng = np.random.default_rng(seed)
    return SimpleNamespace(S=S, n=n, C=C, Z=rng.normal(size=(S, n, C)), theta_dot_fast=rng.normal(0, 3, (2 * S, C)),
                           to_slow=lambda v: v[::2], cached=lambda key, compute: compute())


@pytest.mark.parametrize("effect, shape, cable", [(StribeckFriction, {"smoothing": 0.5, "speed": 3.0}, 2),
                                                  (ViscousFriction, {}, 4)])
def test_a_one_cable_term_is_the_effect_on_that_cable_alone(effect, shape, cable):
    """The term's one column times a magnitude m is the effect's force law with m on that cable and
    0 on the others: through Z in the torque block (eq 51), as itself in the cable block; the
    force the fit subtracts for the tension is that cable's only; the plant gets m there."""
    data, m = _data(cable), 2.5
    cols = effect_columns.get(effect.name)
    located = {**shape, "cable": cable}
    ctx = FitContext(None, None, None)
    d = cols.design(data, located, ctx)
    mags = np.zeros(data.C)
    mags[cable - 1] = m
    force = effect(**{effect.magnitude_field: tuple(mags)}, **shape).motor_force(data.theta_dot_fast)[::2]   # (S, C)
    np.testing.assert_allclose(d.torque[:, :, 0] * m, np.einsum("snc,sc->sn", data.Z, force), rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(d.cable[:, :, 0] * m, force, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(d.motor[0] * m, effect(**{effect.magnitude_field: tuple(mags)}, **shape)
                               .motor_force(data.theta_dot_fast), rtol=1e-12, atol=1e-12)
    assert cols.column_names(data.n, data.C, located) == ((f"{cols.columns[0].symbol}({cable})", cols.columns[0].unit),)
    # Bonferroni: every cable at once and each cable alone, each at half the candidate's level
    assert (cols.places(shape, data.n), cols.places(located, data.n, data.C)) == (2, 2 * data.C)
    values = {cols.columns[0].symbol: cols.columns[0].expand([m], data.n, None, data.C, cable)}
    _, plant = cols.to_plant(None, values, cols.without_location(located))
    np.testing.assert_array_equal(plant.per_cable(data.C), mags)
