"""The dm_control environment: dm_env's and gymnasium's own API checks, seeding, observations,
reward, termination, MCAP recording, and two environments with different parameters in one process."""

import math
import unittest
import warnings

import numpy as np
import pytest
from dm_env import test_utils

from neck_sim import env as neck_env
from neck_sim.logs import MJCF_ATTACHMENT, read_log
from neck_sim.params import default_params
from neck_sim.plant import Plant
from neck_sim.trajectory import control_test_trajectory, cycloidal_path

RATE = 500.0


def run(env, actions, reset=True):
    """Observations (list of dicts) and time steps after reset + each action."""
    steps = [env.reset()] if reset else []
    for a in actions:
        steps.append(env.step(a))
    return steps


def stack(steps, key):
    return np.array([ts.observation[key] for ts in steps])


# ------------------------------------------------------------------------------- API conformance

class DmEnvConformance(test_utils.EnvironmentTestMixin, unittest.TestCase):
    """dm_env's own test-suite, on episodes of 12 control periods."""

    def make_object_under_test(self):
        return neck_env.load(seed=0, time_limit=12 / RATE)

    def make_action_sequence(self):
        rng = np.random.default_rng(0)
        for _ in range(30):                          # crosses two episode ends
            yield rng.uniform(10.0, 30.0, 4)


def test_gymnasium_check_env_through_shimmy():
    from gymnasium.utils.env_checker import check_env
    from shimmy import DmControlCompatibilityV0
    gym_env = DmControlCompatibilityV0(neck_env.load(seed=0, time_limit=0.05))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(gym_env, skip_render_check=True)
    # only the advice that measurements are unbounded and forces are in newtons, not [-1, 1]
    allowed = ("observation space maximum value is infinity", "observation space minimum value is -infinity",
               "symmetric and normalized space")
    unexpected = [str(w.message) for w in caught
                  if not any(a in str(w.message) for a in allowed) and "DISPLAY" not in str(w.message)]
    assert not unexpected, unexpected
    obs, _ = gym_env.reset(seed=5)
    assert set(obs) >= {"encoder_angles", "camera_angles", "reference"}
    assert gym_env.action_space.shape == (4,) and np.all(gym_env.action_space.high == 100.0)
    # the gymnasium seed reaches the task: same seed, same random targets; another seed, others
    ref5 = gym_env.step(np.full(4, 20.0))[0]["reference"]
    gym_env.reset(seed=5)
    np.testing.assert_array_equal(gym_env.step(np.full(4, 20.0))[0]["reference"], ref5)
    gym_env.reset(seed=6)
    assert not np.array_equal(gym_env.step(np.full(4, 20.0))[0]["reference"], ref5)
    gym_env.close()


def test_specs_and_control_rate(params):
    env = neck_env.load(seed=0, observe_truth=True)
    spec = env.action_spec()
    assert spec.shape == (4,) and np.all(spec.minimum == 0) and np.all(spec.maximum == params.actuation.f_max)
    assert env.control_timestep() == pytest.approx(1 / params.control.rate_hz)
    obs_spec = env.observation_spec()
    assert obs_spec["encoder_angles"].shape == (4,) and obs_spec["camera_angles"].shape == (3,)
    assert obs_spec["true_tension"].shape == (4,)
    assert "true_alpha" not in neck_env.load(seed=0).observation_spec()
    five = neck_env.load(n_joints=5, seed=0)
    assert five.action_spec().shape == (6,) and five.observation_spec()["reference"].shape == (5,)


# ------------------------------------------------------------------------------------ behaviour

def test_physics_is_the_plant(params):
    """Stepping the environment is stepping the plant: a bare Plant given the same forces agrees."""
    env = neck_env.load(seed=3, observe_truth=True)
    assert env.physics.data.ptr is env.physics.plant.data
    rng = np.random.default_rng(1)
    actions = rng.uniform(5.0, 40.0, (60, 4))
    steps = run(env, actions)
    plant = Plant(params)
    enc = []
    for a in actions:
        plant.step(a)
        enc.append(plant.encoders())
    np.testing.assert_array_equal(stack(steps[1:], "encoder_angles"), np.array(enc))
    np.testing.assert_array_equal(steps[-1].observation["true_tension"], plant.truth().tension)
    assert np.all(steps[-1].observation["true_tension"] > 0)          # the plant's cable callback acts
    assert env.physics.time() == pytest.approx(60 / RATE)
    hinge = env.physics.named.data.qpos["j1_A"] + env.physics.named.data.qpos["j1_D"]
    assert hinge == pytest.approx(plant.truth().alpha[0], abs=1e-12)


def test_same_seed_same_episode_other_seed_other_episode():
    rng = np.random.default_rng(2)
    actions = rng.uniform(10.0, 30.0, (40, 4))          # 80 ms: two camera frames
    a = run(neck_env.load(seed=11), actions)
    b = run(neck_env.load(seed=11), actions)
    c = run(neck_env.load(seed=12), actions)
    for key in a[0].observation:
        np.testing.assert_array_equal(stack(a, key), stack(b, key), err_msg=key)
    assert stack(a, "camera_new").sum() >= 2
    assert not np.array_equal(stack(a, "reference"), stack(c, "reference"))      # random targets
    assert not np.array_equal(stack(a, "camera_angles"), stack(c, "camera_angles"))  # camera noise
    assert [ts.reward for ts in a[1:]] == [ts.reward for ts in b[1:]]


def test_episodes_of_one_env_differ_but_replay_with_the_seed():
    env = neck_env.load(seed=4, time_limit=0.02)
    act = [np.full(4, 20.0)] * 10
    ep1, ep2 = run(env, act), run(env, act)
    assert ep1[-1].last() and ep2[-1].last() and len(ep1) == 11
    assert not np.array_equal(stack(ep1, "reference"), stack(ep2, "reference"))
    env2 = neck_env.load(seed=4, time_limit=0.02)
    np.testing.assert_array_equal(stack(run(env2, act), "reference"), stack(ep1, "reference"))


def test_observations_are_what_the_prototype_measures(params):
    env = neck_env.load(seed=5, trajectory="control-test", duration_scale=0.2, observe_truth=True)
    steps = run(env, [np.full(4, 25.0)] * 500)                       # 1 s
    t = np.arange(len(steps)) / RATE
    theta = stack(steps, "encoder_angles")
    res = params.sensors.encoder_resolution
    np.testing.assert_allclose(theta / res, np.rint(theta / res), atol=1e-9)  # whole encoder counts
    np.testing.assert_allclose(stack(steps, "encoder_speeds")[1:], np.diff(theta, axis=0) * RATE, atol=1e-9)
    assert np.all(stack(steps, "encoder_speeds")[0] == 0)
    # reference: the paper's control-test trajectory, computed independently
    ref = control_test_trajectory(params, move_time=0.5, hold_time=0.2).sample(t)
    np.testing.assert_allclose(stack(steps, "reference"), ref.alpha, atol=1e-12)
    np.testing.assert_allclose(stack(steps, "reference_velocity"), ref.alpha_dot, atol=1e-12)
    np.testing.assert_allclose(stack(steps, "reference_acceleration"), ref.alpha_ddot, atol=1e-12)
    # camera: ~30 frames/s, held between frames, within 5 sigma of the truth when they arrive
    new = stack(steps, "camera_new")[:, 0]
    cam = stack(steps, "camera_angles")
    assert set(np.unique(new)) <= {0.0, 1.0} and abs(new.sum() - 30) <= 1
    held = np.flatnonzero(new[1:] == 0) + 1
    np.testing.assert_array_equal(cam[held], cam[held - 1])
    fresh = new == 1
    err = cam[fresh] - stack(steps, "true_alpha")[fresh]
    assert np.all(np.abs(err) < 5 * params.sensors.camera_noise)
    assert 0.5 < np.degrees(np.std(err)) < 1.6                      # 1 deg camera noise
    np.testing.assert_array_equal(cam[0], ref.alpha[0])             # the known start pose


def test_reward_is_the_gaussian_tolerance_of_the_tracking_error():
    tol, margin = math.radians(0.2), math.radians(3.0)
    env = neck_env.load(seed=6, observe_truth=True, reward_tolerance=tol, reward_margin=margin)
    steps = run(env, [np.array([30.0, 10.0, 10.0, 20.0])] * 200)
    scale = math.sqrt(-2 * math.log(0.1))          # dm_control's gaussian: 0.1 at the margin
    for ts in steps[1:]:
        err = np.abs(ts.observation["true_alpha"] - ts.observation["reference"])
        d = np.maximum(err - tol, 0.0) / margin
        expected = np.mean(np.exp(-0.5 * (d * scale) ** 2))
        assert ts.reward == pytest.approx(expected, rel=1e-12)
        assert 0.0 <= ts.reward <= 1.0
    rewards_ = np.array([ts.reward for ts in steps[1:]])
    assert rewards_.min() < 0.9 and rewards_.max() > 0.99        # the test spans the reward's range


def test_leaving_the_workspace_ends_the_episode_with_discount_zero(params):
    env = neck_env.load(seed=0, observe_truth=True)
    ts = env.reset()
    n = 0
    while not ts.last():
        ts = env.step(np.array([100.0, 0.0, 0.0, 0.0]))           # cable 1 alone: joint 1 bends right
        n += 1
    assert ts.discount == 0.0 and n < RATE * 2
    assert np.abs(ts.observation["true_alpha"]).max() >= params.geometry.alpha_max
    assert env.step(np.zeros(4)).first()                            # the next step starts anew


def test_time_limit_ends_the_episode_with_discount_one():
    env = neck_env.load(seed=0, time_limit=0.1)
    steps = run(env, [np.full(4, 20.0)] * 50)
    assert steps[-1].last() and steps[-1].discount == 1.0
    assert not any(ts.last() for ts in steps[:-1])


def test_custom_trajectory_object(params):
    traj = cycloidal_path([[0, 0, 0], [0.2, -0.1, 0.3]], 0.1, 0.0, name="mine")
    env = neck_env.load(trajectory=traj, seed=0)
    steps = run(env, [np.full(4, 20.0)] * 50)
    assert steps[-1].last() and not any(ts.last() for ts in steps[:-1])  # time limit: its duration
    np.testing.assert_allclose(stack(steps, "reference"), traj.sample(np.arange(51) / RATE).alpha)


def test_records_mcap_per_episode(tmp_path, params):
    path = tmp_path / "ep{episode}.mcap"
    env = neck_env.load(seed=7, time_limit=0.1, log_path=str(path), observe_truth=True)
    rng = np.random.default_rng(3)
    actions = rng.uniform(-5.0, 120.0, (50, 4))                       # out of range: clipped
    steps = run(env, actions)
    assert steps[-1].last()
    log = read_log(tmp_path / "ep0.mcap", require=("motors", "reference", "camera", "truth"))
    np.testing.assert_allclose(log.motors.t, np.arange(50) / RATE, atol=1e-9)
    np.testing.assert_allclose(log.motors.force, np.clip(actions, 0, 100))
    np.testing.assert_allclose(log.motors.theta, stack(steps[:-1], "encoder_angles"))
    np.testing.assert_allclose(log.reference.alpha_d, stack(steps[:-1], "reference"))
    np.testing.assert_allclose(log.truth.alpha, stack(steps[:-1], "true_alpha"))
    fresh = stack(steps, "camera_new")[:, 0] == 1
    np.testing.assert_allclose(log.camera.alpha, stack(steps, "camera_angles")[fresh])
    assert log.attachments[MJCF_ATTACHMENT].decode() == env.physics.plant.xml
    assert log.params.n_joints == 3
    run(env, actions[:10])                                          # second episode, cut short
    env.close()
    assert read_log(tmp_path / "ep1.mcap").motors.t.shape == (10,)


def test_two_environments_with_different_params_in_one_process(params):
    """Process-global MuJoCo callbacks: interleaved stepping gives each env its own physics."""
    stiff = params.replace(**{"cables.k": (2 * 5378.0, 2 * 5364.0, 2 * 6231.0, 2 * 1908.0),
                              "friction.f_s": (1.0, 1.0, 1.0, 1.0)})
    actions = np.random.default_rng(4).uniform(10.0, 40.0, (80, 4))

    def solo(p):
        return stack(run(neck_env.load(seed=1, params=p, observe_truth=True), actions), "true_tension")

    ref_a, ref_b = solo(params), solo(stiff)
    assert np.abs(ref_a - ref_b).max() > 1.0                       # the two plants differ
    ea = neck_env.load(seed=1, params=params, observe_truth=True)
    eb = neck_env.load(seed=1, params=stiff, observe_truth=True)
    sa, sb = [ea.reset()], [eb.reset()]
    for a in actions:
        sa.append(ea.step(a))
        sb.append(eb.step(a))
    np.testing.assert_array_equal(stack(sa, "true_tension"), ref_a)
    np.testing.assert_array_equal(stack(sb, "true_tension"), ref_b)


@pytest.mark.parametrize("kwargs, match", [
    (dict(colour="red"), "unknown option.*'colour'"),
    (dict(trajectory="spiral"), "unknown name 'spiral'"),
    (dict(trajectory=42), "trajectory: expected"),
    (dict(time_limit=-1.0), "time_limit"),
    (dict(target_range=math.radians(95)), "target_range"),
    (dict(n_joints=4, params=default_params(3)), "n_joints"),
    (dict(trajectory=cycloidal_path([[0, 0], [0.1, 0.1]], 1.0)), "2 joints|shape"),
])
def test_bad_options_are_named(kwargs, match):
    with pytest.raises(ValueError, match=match):
        neck_env.load(**kwargs)


def test_bad_actions_are_named():
    env = neck_env.load(seed=0)
    env.reset()
    with pytest.raises(ValueError, match="NaN"):
        env.step(np.array([1.0, np.nan, 1.0, 1.0]))
    with pytest.raises(ValueError, match="shape"):
        env.step(np.ones(3))
