import numpy as np
import pytest

from controllers.parallel import RunSpec, run_all
from neck_sim.effects import Effects, ViscousFriction
from neck_sim.params import default_params


def test_parallel_runs_equal_serial_runs(tmp_path):
    p = default_params()
    specs = [RunSpec("law 2", p, law=2, duration_scale=0.15, seed=1, log_path=str(tmp_path / "a.mcap")),
             RunSpec("viscous", p, law=1, duration_scale=0.15, seed=2,
                     effects=Effects(viscous_friction=ViscousFriction(c_v=0.1)))]
    par = run_all(specs, workers=2, progress=False)
    ser = run_all(specs, workers=1, progress=False)
    for a, b in zip(par, ser):
        np.testing.assert_array_equal(a.theta, b.theta)
        np.testing.assert_array_equal(a.force, b.force)
    assert not np.array_equal(par[0].force, par[1].force)
    assert (tmp_path / "a.mcap").exists()


def test_failures_name_the_run():
    p = default_params()
    bad = RunSpec("bad trajectory", p, trajectory="no-such-trajectory")
    with pytest.raises(RuntimeError, match="bad trajectory"):
        run_all([bad, RunSpec("ok", p, duration_scale=0.1)], workers=2, progress=False)
    with pytest.raises(ValueError, match="unique"):
        run_all([RunSpec("x", p), RunSpec("x", p)], progress=False)
