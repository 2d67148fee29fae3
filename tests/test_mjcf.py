"""The MJCF builder: committed file, structure, routing validity, closed-form placement."""

import itertools
import math

import mujoco
import numpy as np
import pytest

import neck_sim.analytic as an
from neck_sim import mjcf
from neck_sim.params import default_params


def _compile(params, **kw):
    return mujoco.MjModel.from_xml_string(mjcf.build_xml(params, **kw))


def test_committed_xml_is_the_builder_output(params):
    with open(mjcf.committed_xml_path()) as fh:
        committed = fh.read()
    assert committed == mjcf.build_xml(params), "mjcf/neck3x.xml is stale: run python -m neck_sim.mjcf"


def test_committed_xml_runs_on_its_own():
    """Without neck_sim's callbacks the file is a linear-cable neck that stays put and finite."""
    model = mujoco.MjModel.from_xml_path(mjcf.committed_xml_path())
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    ix = mjcf.model_index(model)
    np.testing.assert_allclose(data.actuator_force[ix.tension_actuator], 0.0, atol=1e-9)
    data.ctrl[ix.drive_actuator] = 20.0
    mujoco.mj_step(model, data, 2000)
    assert np.all(np.isfinite(data.qpos))
    gaps = data.site_xpos[ix.loop_sites[:, 0]] - data.site_xpos[ix.loop_sites[:, 1]]
    assert np.linalg.norm(gaps, axis=1).max() < 1e-4


@pytest.mark.parametrize("n", [1, 3, 5])
def test_structure_for_n_joints(n):
    p = default_params(n)
    m = _compile(p)
    assert m.nq == m.nv == 3 * n + (n - 1) + (n + 1)        # bars, helpers, motors
    assert m.neq == n + (n - 1)                              # loops, helper locks
    assert m.ntendon == (n + 1) + 2 * n + (n - 1)            # cables, springs, helper locks
    assert m.nu == 2 * (n + 1)
    ix = mjcf.model_index(m)
    assert ix.n_joints == n and len(ix.cable_tendon) == n + 1
    np.testing.assert_array_equal(ix.drive_actuator, np.arange(n + 1))
    rigid = _compile(p, rigid_cables=True)
    assert rigid.neq == m.neq + n + 1
    assert len(mjcf.model_index(rigid).rigid_equality) == n + 1


def test_physical_constants_reach_the_model(params):
    p = params.replace(**{"inertia.payload_mass": 0.05, "springs.rest_length": 0.05})
    m = _compile(p)
    bar = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "j3_top")
    assert m.body_mass[bar] == pytest.approx(p.inertia.bar_mass + 0.05)
    k = [m.tendon_stiffness[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_TENDON, f"j{i}_spring_{s}")]
         for i in (1, 2, 3) for s in ("left", "right")]
    np.testing.assert_allclose(k, np.repeat(p.springs.stiffness, 2))
    t = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_TENDON, "j2_spring_left")
    assert m.tendon_lengthspring[t, 0] == pytest.approx(0.05)
    ix = mjcf.model_index(m)
    motor_inertia = m.dof_armature[ix.dof_motor] + m.body_mass[ix.other_bodies[2:]]
    np.testing.assert_allclose(motor_inertia, p.actuation.reflected_inertia)
    assert m.opt.gravity[1] == pytest.approx(-p.inertia.gravity)


def test_every_wrap_arc_stays_valid_over_the_range(params):
    """Each pulley wrap keeps an arc in (0, 180) deg, so the sidesites keep picking the right side."""
    grid = np.radians(np.linspace(-60, 60, 5))
    arcs = np.array([list(mjcf.wrap_arcs(params, np.array(a)).values())
                     for a in itertools.product(grid, repeat=3)])
    assert arcs.shape[1] == 14
    assert np.degrees(arcs.min()) > 40 and np.degrees(arcs.max()) < 170


def test_pose_qpos_derivatives_match_finite_differences(params, rng):
    a = rng.uniform(-1, 1, 3)
    h = 1e-6
    for i in range(3):
        da = np.zeros(3)
        da[i] = h
        up, dn = mjcf.pose_qpos(a + da, params), mjcf.pose_qpos(a - da, params)
        here = mjcf.pose_qpos(a, params)
        for name in ("A", "B", "D"):
            fd = (getattr(up, f"q_{name}")[i] - getattr(dn, f"q_{name}")[i]) / (2 * h)
            assert getattr(here, f"dq_{name}")[i] == pytest.approx(fd, rel=1e-6, abs=1e-9)
        # a joint's hinges do not move with another joint's angle
        for j in set(range(3)) - {i}:
            assert up.q_A[j] == here.q_A[j]


def test_straight_pose_is_qpos_zero(params):
    pq = mjcf.pose_qpos(np.zeros(3), params)
    for v in (pq.q_A, pq.q_B, pq.q_D, pq.q_helper):
        np.testing.assert_allclose(v, 0.0, atol=1e-15)


def test_placed_pose_closes_loops_and_matches_forward_kinematics(params, rng):
    m = _compile(params)
    d = mujoco.MjData(m)
    ix = mjcf.model_index(m)
    a = rng.uniform(-1, 1, 3)
    pq = mjcf.pose_qpos(a, params)
    d.qpos[ix.qpos_A], d.qpos[ix.qpos_B], d.qpos[ix.qpos_D] = pq.q_A, pq.q_B, pq.q_D
    mujoco.mj_kinematics(m, d)
    gaps = d.site_xpos[ix.loop_sites[:, 0]] - d.site_xpos[ix.loop_sites[:, 1]]
    assert np.linalg.norm(gaps, axis=1).max() < 1e-14
    kin = an.forward_kinematics(a, params)
    head = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "j3_top")
    np.testing.assert_allclose(d.xpos[head, :2], kin.head_position, atol=1e-14)
    assert math.atan2(d.xmat[head, 3], d.xmat[head, 0]) == pytest.approx(kin.head_angle, abs=1e-13)


def test_bad_input_is_refused(params):
    with pytest.raises(ValueError, match="timestep"):
        mjcf.build_xml(params, timestep=0.0)
    plain = mujoco.MjModel.from_xml_string("<mujoco><worldbody><body><joint/><geom size='1'/></body></worldbody></mujoco>")
    with pytest.raises(ValueError, match="not a neck_sim model"):
        mjcf.model_index(plain)
    with pytest.raises(ValueError, match="alpha"):
        mjcf.pose_qpos(np.zeros(2), params)
