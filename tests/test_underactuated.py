"""Moving a neck with fewer cables than N + 1: the 10-X neck on the MuJoCo plant, logged to MCAP."""

import json

import numpy as np
import pytest

import neck_sim.params
from controllers.closed_loop import run_closed_loop
from controllers.underactuated import ReachablePath, UnderactuatedController, holding_tensions
from neck_sim.analytic import gravity_spring_torque, transmission_matrix
from neck_sim.params import default_params
from neck_sim.plant import Plant


def _neck10():
    """The 10-X, 4-cable neck (segmented routing); the paper's 11-cable routing before routing-as-data."""
    if hasattr(neck_sim.params, "Routing"):
        from neck_sim.design import routing_strategies
        return routing_strategies(default_params(10), 4)[0].params
    return default_params(10)


def _waypoints(p):
    """Straight with equal tensions, then bent one way and the other (tensions swapped by side)."""
    m = p.n_cables
    straight = np.full(m, 17.0)
    if m == 4:
        bend = np.array([23.0, 11.0, 15.0, 19.0])          # proximal pair left, distal pair right
        return [straight, bend, bend[[1, 0, 3, 2]], straight]
    bend = straight.copy()
    bend[-1] += 6.0
    return [straight, bend, straight]


def test_holding_tensions_hold_the_path():
    """Every pose of the reachable path is held by the tensions the controller computes for it."""
    p = _neck10()
    path = ReachablePath(p, _waypoints(p)[:2], move_time=1.0, hold_time=0.2)
    alpha = path.sample(np.linspace(0, path.duration, 40)).alpha
    t = holding_tensions(alpha, p, p.actuation.t_min)
    residual = gravity_spring_torque(alpha, p) - np.einsum("...ij,...j->...i", transmission_matrix(alpha, p), t)
    assert np.max(np.abs(residual)) < 1e-3 * np.max(np.abs(gravity_spring_torque(alpha, p)))
    # the path's own tensions are the holding ones (one pose, one tension vector when m <= N)
    if p.n_cables <= p.n_joints:
        assert np.max(np.abs(t - path.forces_at(np.linspace(0, path.duration, 40)))) < 0.05


def test_closed_loop_on_the_ten_joint_neck(tmp_path):
    from mcap.reader import make_reader

    from neck_sim.logs.reader import read_log

    p = _neck10()
    path = ReachablePath(p, _waypoints(p), move_time=1.5, hold_time=0.5)
    log = tmp_path / "neck10.mcap"
    res = run_closed_loop(Plant(p), UnderactuatedController(p), path, progress=False, log_path=log)
    err = np.degrees(np.abs(res.alpha - res.alpha_d))
    bend = np.degrees(np.abs(res.alpha_d)).max()
    assert bend > 5                                          # the neck really moves
    assert err.mean() < 0.6 and err.max() < 2.5, (err.mean(), err.max())
    assert res.metrics.slack_samples == 0 and res.metrics.saturated_samples == 0
    assert np.degrees(np.abs(res.alpha_hat - res.alpha)).mean() < 0.6
    # the log: vectors sized by the routing, Foxglove frames for all ten joints
    lg = read_log(log, topics=["motors", "truth"])
    assert lg.n_joints == 10 and lg.truth.alpha.shape[1] == 10 and lg.motors.theta.shape[1] == p.n_cables
    with open(log, "rb") as fh:
        for _, channel, message in make_reader(fh).iter_messages(topics=["/tf"]):
            frames = {t["child_frame_id"] for t in json.loads(message.data)["transforms"]}
            break
    assert {f"bar{i}" for i in range(11)} <= frames


def test_bad_input_names_the_problem():
    p = default_params(3)
    with pytest.raises(ValueError, match="waypoints"):
        ReachablePath(p, np.ones((2, 3)))
    with pytest.raises(ValueError, match="leaves the reachable set"):
        ReachablePath(p, [[10, 10, 10, 10], [100, 2, 2, 2]], move_time=0.5)
    with pytest.raises(ValueError, match="f_s"):
        UnderactuatedController(p, f_s=[1.0, 2.0])
