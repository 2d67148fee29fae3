import numpy as np

def test_the_plateau_rule_tells_a_flat_friction_from_an_arctan_that_never_flattens():
    """A channel built from its own formula: speeds log-uniform over 0.05-20 rad/s with random
    signs, force = friction(speed) + white noise of 1 N, binned (``speed_edges``, ``bin_columns``)
    and fitted (``level_fit``).  F tanh(|v| / 0.3) is flat above ~1 rad/s: ``plateau`` finds it and
    its level is F within 2 sigma; eq (37) with c_s = 0.5 (the paper's plant) still rises at
    20 rad/s: no plateau."""
    from identification.diagnosis.dry_level import bin_columns, level_fit, plateau, speed_edges

    rng = np.random.default_rng(3)
    v = np.exp(rng.uniform(np.log(0.05), np.log(20.0), 200000)) * rng.choice([-1.0, 1.0], 200000)
    F = 10.0
    for law, flat in ((lambda s: F * np.tanh(s / 0.3), True),
                      (lambda s: F * (2 / np.pi) * np.arctan(0.5 * s), False)):
        y = np.sign(v) * law(np.abs(v)) + rng.normal(0.0, 1.0, v.size)
        edges = speed_edges(v)
        level, sigma = level_fit(bin_columns(v, edges), y)
        found = plateau(level, sigma)
        assert (found is not None) == flat, (level, sigma)
        if flat:
            first, lvl, sig, p = found
            assert edges[first] >= 0.5 and abs(lvl - F) <= 2 * sig, found
