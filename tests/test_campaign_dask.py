"""Campaigns on a Dask distributed cluster (scheduler and workers on the loopback address only)."""

import numpy as np
import pytest

from controllers.campaign import ClusterError, ExecutorSpec, open_executor
from controllers.parallel import RunSpec, run_all
from neck_sim.effects import Effects, ViscousFriction
from neck_sim.logs import read_log
from neck_sim.params import default_params

distributed = pytest.importorskip("distributed")


@pytest.fixture(scope="module")
def cluster():
    # everything on the loopback address, the scheduler's HTTP server included (on a free port)
    with distributed.LocalCluster(host="127.0.0.1", n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address="127.0.0.1:0", silence_logs=40) as c:
        yield c


def test_a_campaign_on_a_dask_cluster_equals_the_serial_runs(cluster, tmp_path):
    p = default_params()
    specs = [RunSpec("law 2", p, law=2, duration_scale=0.1, seed=3, log_path=str(tmp_path / "law2.mcap")),
             RunSpec("viscous", p, law=3, duration_scale=0.1, seed=4, effects=Effects.of(ViscousFriction(0.1)))]
    on_dask = run_all(specs, ExecutorSpec(cluster=cluster.scheduler_address), progress=False)
    log = read_log(tmp_path / "law2.mcap", topics=("motors", "truth"))    # written by a worker, sent back
    serial = run_all(specs, None, progress=False)
    for a, b in zip(on_dask, serial):
        for name in ("theta", "force", "alpha", "tension", "alpha_hat"):
            np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
        assert a.metrics.as_dict() == b.metrics.as_dict()
    assert not np.array_equal(on_dask[0].alpha, on_dask[1].alpha)
    np.testing.assert_array_equal(log.motors.force, serial[0].force)
    np.testing.assert_array_equal(log.truth.alpha, serial[0].alpha)


def test_an_unreachable_cluster_is_named():
    with pytest.raises(ClusterError, match=r"tcp://127.0.0.1:9.*no Dask scheduler"):
        with open_executor(ExecutorSpec(cluster="tcp://127.0.0.1:9", connect_timeout=1.0)):
            pass


def test_blind_logs_generated_on_the_cluster_equal_local_ones(cluster, tmp_path):
    from identification.blind import make_case, make_cases

    [(case, path)] = make_cases([("viscous_friction", 5, 0.5)], tmp_path / "dask",
                                ExecutorSpec(cluster=cluster.scheduler_address), progress=False)
    here, _ = make_case("viscous_friction", 5, tmp_path / "here.mcap", level=0.5)
    assert case == here and path == str(tmp_path / "dask" / "viscous_friction_5_0.5.mcap")
    a, b = read_log(path, topics=("motors", "camera")), read_log(tmp_path / "here.mcap", topics=("motors", "camera"))
    np.testing.assert_array_equal(a.motors.theta, b.motors.theta)
    np.testing.assert_array_equal(a.camera.alpha, b.camera.alpha)
