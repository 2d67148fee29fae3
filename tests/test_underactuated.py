"""Moving a neck with fewer cables than N + 1: the 10-X neck on the MuJoCo plant, logged to MCAP."""

import json

import numpy as np
import pytest

from controllers.closed_loop import run_closed_loop
from controllers.underactuated import ReachablePath, UnderactuatedController, holding_tensions
from neck_sim.analytic import gravity_spring_torque, transmission_matrix
from neck_sim.params import default_params
from neck_sim.plant import Plant


def _neck10():
    """The 10-X, 4-cable neck (the segmented routing of ``neck-sim design``)."""
    from neck_sim.design import routing_strategies
    return routing_strategies(default_params(10), 4)[0].params


def _waypoints(p):
    """Straight at 70 N pretension (stable with held motors), then an S curve one way and the other:
    the lower pair pulls left and the upper pair right by 3 N, then the reverse."""
    straight = np.full(p.n_cables, 70.0)
    side = np.array([1.0 if c.side == "left" else -1.0 for c in p.routing.cables])
    lower = np.array([1.0 if c.ends_at < p.n_joints else -1.0 for c in p.routing.cables])
    bend = straight + 3.0 * side * lower
    return [straight, bend, 2 * straight - bend]


def _plant(p):
    try:
        return Plant(p)
    except (IndexError, ValueError) as exc:       # before the MJCF builder took any routing
        pytest.skip(f"the plant cannot be built for {p.n_cables} cables on {p.n_joints} joints yet: {exc!r}")


def test_reference_poses_are_held_by_their_tensions():
    """Between the solved grid points the spline of poses stays on the reachable set: each
    reference pose is an equilibrium of the path's tensions at that instant."""
    p = _neck10()
    path = ReachablePath(p, _waypoints(p)[:2], move_time=1.0, hold_time=0.2)
    ref = path.sample(np.linspace(0, path.duration, 53))
    g = gravity_spring_torque(ref.alpha, p)
    residual = g - np.einsum("...ij,...j->...i", transmission_matrix(ref.alpha, p), ref.tension)
    assert np.max(np.abs(residual)) < 2e-3 * np.max(np.abs(g))
    assert np.degrees(np.ptp(ref.alpha, 0)).max() > 5                 # it moves
    # holding_tensions recovers a well-conditioned neck's tensions (the 3-X paper neck, 4 cables)
    p3 = default_params(3)
    path3 = ReachablePath(p3, [[10.0, 10.0, 10.0, 20.0], [20.0, 12.0, 15.0, 25.0]], move_time=1.0, hold_time=0.0)
    ref3 = path3.sample(np.linspace(0, path3.duration, 7))
    t3 = holding_tensions(ref3.alpha, p3, 0.0)
    z3 = transmission_matrix(ref3.alpha, p3)
    assert np.max(np.abs(np.einsum("...ij,...j->...i", z3, t3 - ref3.tension))) < 1e-3


def test_closed_loop_on_the_ten_joint_neck(tmp_path):
    from mcap.reader import make_reader

    from neck_sim.logs.reader import read_log

    p = _neck10()
    path = ReachablePath(p, _waypoints(p), move_time=2.0, hold_time=0.5)
    log = tmp_path / "neck10.mcap"
    res = run_closed_loop(_plant(p), UnderactuatedController(p), path, progress=False, log_path=log)
    err = np.degrees(np.abs(res.alpha - res.alpha_d))
    bend = np.degrees(np.abs(res.alpha_d)).max()
    assert bend > 5                                          # the neck really moves
    # 0.44 deg mean, 2.4 deg max achieved: the joint-space modes the four cables cannot reach
    # (N - m of them) ring, undamped, after each move
    assert err.mean() < 0.55 and err.max() < 3.0, (err.mean(), err.max())
    assert res.metrics.slack_samples == 0 and not res.saturated[res.t > 0.3].any()   # take-up aside
    # the static estimate from the encoders cannot see those modes either (1.23 deg achieved)
    assert np.degrees(np.abs(res.alpha_hat - res.alpha)).mean() < 1.5
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
    # the 10-X, 4-cable neck straight at 8.5 N pretension: an equilibrium, unstable with held motors
    p10 = _neck10()
    with pytest.raises(ValueError, match="unstable even with the motors held"):
        ReachablePath(p10, [np.full(4, 8.5), np.full(4, 8.5)], move_time=0.2, hold_time=0.0)
