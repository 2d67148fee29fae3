import pytest

from neck_sim.params import default_params
from neck_sim.pulley_study import pulley_effect


def test_no_pulleys_no_difference():
    eff = pulley_effect(default_params().replace(**{"geometry.r": 0.0}), samples=2000)
    assert eff.torque_rel_diff == 0.0 and eff.increment_rel_diff == 0.0


def test_indicators_scale_with_pulley_radius():
    """The pulley terms of Z are first order in r: halving r about halves both indicators."""
    full = pulley_effect(default_params(), samples=20_000, seed=3)
    half = pulley_effect(default_params().replace(**{"geometry.r": 0.0023}), samples=20_000, seed=3)
    assert 0.05 < full.torque_rel_diff < 0.5
    assert half.torque_rel_diff / full.torque_rel_diff == pytest.approx(0.5, abs=0.08)
    assert half.increment_rel_diff / full.increment_rel_diff == pytest.approx(0.5, abs=0.08)


def test_bad_sample_count():
    with pytest.raises(ValueError, match="samples"):
        pulley_effect(default_params(), samples=0)
