"""The compiled control step against the batched numpy model, and lockstep runs.

The numpy side composes the public batched functions (eq 35 increment, linkage dynamics, Z,
tension distribution, eq 58) with the PID of eq (59) written here; the compiled side is one
``control_rows`` call over a batch of random controller states.
"""

from __future__ import annotations

import os

import numpy as np
import pytest

from controllers.closed_loop import run_closed_loop, run_lockstep
from controllers.computed_torque import (ComputedTorqueController, ControllerState, MotorReference, advance,
                                         output_slices, reference_table, step_error)
from controllers.tension import distribute_tensions
from controllers.trajectories import cycloidal_path
from neck_sim.analytic.cables import transmission_kernel, transmission_matrix
from neck_sim.analytic.dynamics import arctan_friction, elongation_step, linkage_dynamics
from neck_sim.analytic.estimation import pinv_increment
from neck_sim.params import CableRoute, Routing, default_params
from neck_sim.plant import Plant


def mirrored(n: int):
    """Left cables strut-routed to C_j and a long right cable up the right sides (mirror kinds)."""
    p = default_params(n)
    left = [CableRoute("left", ("strut",) * j, j + 1) for j in range(n)]
    return p.replace(routing=Routing(tuple(left + [CableRoute("right", ("side",) * (n - 1), n)])))


def random_batch(ctrl: ComputedTorqueController, rng, B: int):
    """B random controller states and one reference row each, as (state, theta, table)."""
    p = ctrl.params
    n = p.n_joints
    st = ControllerState.stack([ctrl.state] * B)
    deg = np.radians
    ah = rng.uniform(-deg(40), deg(40), (B, n))
    st.values[:, 0, :n] = ah                                       # alpha_hat
    st.values[:, 1, :n] = ah + rng.normal(0, deg(0.2), (B, n))     # alpha_hat of the previous period
    st.values[:, 2, :n] = rng.normal(0, 1e-3, (B, n))              # integral of e
    st.values[:, 3] = rng.normal(0, 3.0, (B, n + 1))               # theta of the previous period
    st.values[:, 4] = rng.uniform(0, 2e-4, (B, n + 1))             # elongation estimate
    st.values[:, 5] = rng.uniform(10, 60, (B, n + 1))              # force commanded
    st.values[:, 6] = rng.normal(0, 5, (B, n + 1))                 # desired motor speed
    st.flags[:] = 1
    st.Z[:] = transmission_matrix(ah, p)
    theta = st.values[:, 3] + rng.normal(0, 0.05, (B, n + 1))
    alpha_d = ah + rng.normal(0, deg(1), (B, n))
    ad, add = rng.normal(0, 0.3, (B, n)), rng.normal(0, 2, (B, n))
    td = rng.normal(0, 5, (B, n + 1))
    ref = MotorReference(alpha_d, ad, add, td, np.zeros((B, n + 1)), arctan_friction(td, p.friction.c_s, ctrl.f_s),
                         rng.uniform(5, 20, (B, n + 1)))
    return st, theta, reference_table(ref)[:, None, :]


def numpy_step(ctrl: ComputedTorqueController, st: ControllerState, theta, table):
    """The same period from the batched numpy functions (inputs are not modified)."""
    p = ctrl.params
    n = p.n_joints
    ratio = p.actuation.r_d / p.actuation.R
    v = st.values
    ah, ah_prev, integral = v[:, 0, :n], v[:, 1, :n], v[:, 2, :n]
    th_prev, x, f_prev, td_prev = v[:, 3], v[:, 4], v[:, 5], v[:, 6]
    r = table[:, 0]
    alpha_d, ad, add = r[:, :n], r[:, n:2 * n], r[:, 2 * n:3 * n]
    td, friction, lower = r[:, 3 * n:4 * n + 1], r[:, 4 * n + 1:5 * n + 2], r[:, 5 * n + 2:]
    dx = None
    x_new = x
    el = ctrl.elongation
    if el is not None:
        t_hat = np.maximum(f_prev - arctan_friction(td_prev, el.c_s, el.f_s), 0.0)
        x_new = elongation_step(x, t_hat, el.dt, el.k, el.lam, el.c_a)
        dx = x_new - x
    a = ah + pinv_increment(ah, theta - th_prev, p, dx)
    dt = 1 / p.control.rate_hz
    k_p, k_v, k_i = ctrl.gains
    e = alpha_d - a
    integral = integral + e * dt
    w = add + k_v * (ad - (a - ah_prev) / dt) + k_p * e + k_i * integral                  # eq (59)
    lk = linkage_dynamics(a, np.zeros_like(a), p)
    Z = transmission_matrix(a, p)
    M = lk.M + p.actuation.reflected_inertia * Z @ np.swapaxes(Z, -1, -2)
    gamma = np.einsum("bij,bj->bi", M, w) + lk.g + np.einsum("bij,bj->bi", Z, friction)   # eq (66)
    dist = distribute_tensions(Z, gamma, lower, ctrl.f_max)
    assert ratio > 0 and td.shape == friction.shape
    return {"alpha_hat": a, "elongation": x_new, "w": w, "gamma": gamma, "forces": dist.forces,
            "requested": dist.requested, "saturated": dist.saturated.astype(float), "Z": Z, "integral": integral}


@pytest.mark.parametrize("n, law", [(1, 2), (3, 2), (3, 3), (10, 2)])
def test_compiled_step_equals_the_numpy_model(n, law):
    p = default_params(n)
    ctrl = ComputedTorqueController(p, law)
    rng = np.random.default_rng(n * 10 + law)
    st, theta, table = random_batch(ctrl, rng, 40)
    want = numpy_step(ctrl, st, theta, table)
    out = np.zeros((40, 1, 7 * n + 4))
    advance(st, theta, 0, table, out)
    assert not st.status.any()
    got = {name: out[:, 0, sl] for name, sl in output_slices(n).items()}
    got.update(Z=st.Z, integral=st.values[:, 2, :n])
    for name, value in want.items():
        np.testing.assert_allclose(got[name], value, rtol=1e-12, atol=1e-12 * np.abs(value).max(), err_msg=name)
    assert want["forces"].min() > 0 and np.abs(want["w"]).max() > 1


def test_compiled_z_follows_any_routing():
    rng = np.random.default_rng(5)
    for p in (default_params(4), mirrored(4), default_params(4).replace(**{"geometry.r": 0.0})):
        cases = p.routing.segment_cases(4).astype(np.int64)
        geom = np.array([p.geometry.b, p.geometry.L, p.geometry.r])
        for a in rng.uniform(-1.2, 1.2, (5, 4)):
            Z = np.empty((4, p.n_cables))
            transmission_kernel(a, geom, cases, Z)
            np.testing.assert_allclose(Z, transmission_matrix(a, p), rtol=1e-13, atol=1e-15)


def test_failing_states_are_reported_not_computed():
    ctrl = ComputedTorqueController(default_params(3), 2)
    st, theta, table = random_batch(ctrl, np.random.default_rng(1), 3)
    theta[1, 2] = np.nan
    st.values[2, 0, 1] = np.radians(95.0)          # joint 2 outside the workspace, encoders unchanged
    theta[2] = st.values[2, 3]
    out = np.zeros((3, 1, 25))
    advance(st, theta, 0, table, out)
    assert st.status[0] == 0 and np.all(out[0, 0, output_slices(3)["forces"]] > 0)
    assert str(step_error(int(st.status[1]), out[1, 0, :3], np.pi / 2)) == "theta: contains NaN or infinity"
    assert "joint 2 estimated at 95.0 deg" in str(step_error(int(st.status[2]), st.values[2, 0, :3], np.pi / 2))
    assert np.all(out[1:] == 0)


# -- lockstep ---------------------------------------------------------------------------------------

def short_path(n=3):
    return cycloidal_path(np.radians([[0.0] * n, [25.0, -15.0, 20.0][:n]]), 0.3, 0.1)


@pytest.mark.parametrize("group", [16, 2])          # 2: the three runs go as a group of 2, then 1
def test_lockstep_runs_equal_single_runs(group, monkeypatch):
    import controllers.closed_loop as closed_loop

    monkeypatch.setattr(closed_loop, "LOCKSTEP_GROUP", group)
    p = default_params(3)
    heavy = p.replace(**{"inertia.bar_mass": 1.3 * p.inertia.bar_mass})
    cases = [(p, 0, 2), (heavy, 1, 3), (p, 2, 1)]
    traj = short_path()
    single = [run_closed_loop(Plant(pp, seed=s), ComputedTorqueController(pp, law), traj, progress=False)
              for pp, s, law in cases]
    batch = run_lockstep([Plant(pp, seed=s) for pp, s, _ in cases],
                         [ComputedTorqueController(pp, law) for pp, _, law in cases], [traj] * 3, progress=False)
    assert len(batch) == 3
    for a, b in zip(single, batch):
        assert a.saturated.shape == a.requested.shape == a.force.shape == (len(a.t), 4)
        for name in ("alpha", "alpha_hat", "force", "requested", "saturated", "theta", "gamma", "camera_alpha"):
            np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
    assert not np.array_equal(single[0].force, single[1].force)


class DivergingPlant:
    """A real plant that raises like PlantDivergedError in its 20th period."""

    def __init__(self, plant):
        self.plant, self.periods = plant, 0

    def __getattr__(self, name):
        return getattr(self.plant, name)

    def step(self, forces):
        self.periods += 1
        if self.periods == 20:
            raise RuntimeError("plant: the simulation diverged (test)")
        self.plant.step(forces)


def test_lockstep_keeps_going_past_a_failed_run(tmp_path):
    p = default_params(3)
    traj = short_path()
    logs = [str(tmp_path / "a.mcap"), str(tmp_path / "b.mcap")]
    res = run_lockstep([Plant(p, seed=0), DivergingPlant(Plant(p, seed=1))],
                       [ComputedTorqueController(p, 2), ComputedTorqueController(p, 2)], [traj, traj],
                       log_paths=logs, progress=False)
    alone = run_closed_loop(Plant(p, seed=0), ComputedTorqueController(p, 2), traj, progress=False)
    np.testing.assert_array_equal(res[0].force, alone.force)
    assert res[0].log_path == logs[0] and os.path.exists(logs[0]) and not os.path.exists(logs[1])
    assert isinstance(res[1], RuntimeError) and "t = 0.038 s" in str(res[1]) and "diverged" in str(res[1])
    with pytest.raises(RuntimeError, match="diverged"):
        run_lockstep([Plant(p), DivergingPlant(Plant(p))], [ComputedTorqueController(p, 2)] * 2, [traj] * 2,
                     progress=False, stop_on_error=True)
    with pytest.raises(ValueError, match="control periods"):
        run_lockstep([Plant(p)] * 2, [ComputedTorqueController(p, 2)] * 2,
                     [traj, cycloidal_path(np.zeros((2, 3)), 0.2)], progress=False)
