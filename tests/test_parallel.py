import numpy as np
import pytest

from neck_sim.campaign import ExecutorSpec, run_campaign
from controllers.parallel import RunSpec, run_all
from neck_sim.effects import Effects, ViscousFriction
from neck_sim.logs import read_log
from neck_sim.params import default_params


def test_parallel_runs_equal_serial_runs(tmp_path):
    p = default_params()
    specs = [RunSpec("law 2", p, law=2, duration_scale=0.15, seed=1, log_path=str(tmp_path / "a.mcap")),
             RunSpec("viscous", p, law=1, duration_scale=0.15, seed=2,
                     effects=Effects(viscous_friction=ViscousFriction(c_v=0.1)))]
    par = run_all(specs, ExecutorSpec(workers=2), progress=False)
    log = read_log(tmp_path / "a.mcap", topics=("motors",))        # shipped back by the worker
    ser = run_all(specs, None, progress=False)
    for a, b in zip(par, ser):
        np.testing.assert_array_equal(a.theta, b.theta)
        np.testing.assert_array_equal(a.force, b.force)
    assert not np.array_equal(par[0].force, par[1].force)
    assert par[0].log_path == str(tmp_path / "a.mcap")
    np.testing.assert_array_equal(log.motors.force, ser[0].force)


def test_failures_name_the_run():
    p = default_params()
    bad = RunSpec("bad trajectory", p, trajectory="no-such-trajectory")
    with pytest.raises(RuntimeError, match="bad trajectory"):
        run_all([bad, RunSpec("ok", p, duration_scale=0.1)], ExecutorSpec(workers=2), progress=False)
    with pytest.raises(ValueError, match="unique"):
        run_all([RunSpec("x", p), RunSpec("x", p)], progress=False)


def test_executor_choice_is_checked():
    with pytest.raises(ValueError, match="workers"):
        ExecutorSpec(workers=0)
    with pytest.raises(ValueError, match="cluster.*tcp://"):
        ExecutorSpec(cluster="localhost")
    assert ExecutorSpec(workers=1).serial and not ExecutorSpec(cluster="tcp://127.0.0.1:8786").serial
    with pytest.raises(RuntimeError, match="job 'b' failed.*ZeroDivisionError"):
        run_campaign(_inverse, [1, 0], ExecutorSpec(workers=1), labels=["a", "b"], progress=False)
    assert run_campaign(_inverse, [1, 2, 4], ExecutorSpec(workers=2), progress=False) == [1.0, 0.5, 0.25]


def _inverse(x):
    return 1 / x


def test_the_reference_is_fitted_to_the_plant_not_to_the_controllers_model():
    # Table 3: a controller whose model ignores the pulleys (r = 0) would fit the identification
    # trajectory to x0.96 of the paper's angles; the runs with and without pulleys must follow the
    # same reference, the one the plant (the paper's neck) can carry.
    from controllers.trajectories import make_trajectory, workspace_amplitude

    p = default_params()
    no_pulleys = p.replace(**{"geometry.r": 0.0})
    assert workspace_amplitude("identification", no_pulleys, 0.05) < 1.0     # the case that matters
    spec = RunSpec("no pulleys", p, law=2, trajectory="identification", duration_scale=0.05,
                   controller_params=no_pulleys)
    [res] = run_all([spec], None, progress=False)
    ref = make_trajectory("identification", p, 0.05).sample(res.t).alpha
    np.testing.assert_allclose(res.alpha_d, ref, atol=1e-12)
