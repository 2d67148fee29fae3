"""Geometry, cable lengths and Z against independent computations."""

import numpy as np
import pytest

import neck_sim.analytic as an
from neck_sim.params import EXAMPLES, default_params, example_params


def central_jacobian(fun, x, h=1e-4):
    """4th-order central differences of fun (..., n) -> (..., m) w.r.t. x; returns (..., n, m)."""
    n = x.shape[-1]
    cols = []
    for i in range(n):
        e = np.zeros(n)
        e[i] = h
        cols.append((-fun(x + 2 * e) + 8 * fun(x + e) - 8 * fun(x - e) + fun(x - 2 * e)) / (12 * h))
    return np.stack(cols, -2)


NECKS = [("paper N=1", lambda: default_params(1)), ("paper N=3", lambda: default_params(3)),
         ("paper N=10", lambda: default_params(10))] + [(name, lambda name=name: example_params(name))
                                                        for name in EXAMPLES if name != "paper"]


@pytest.mark.parametrize("make", [m for _, m in NECKS], ids=[k for k, _ in NECKS])
def test_z_matches_differentiated_lengths(make, rng):
    p = make()
    n = p.n_joints
    alpha = rng.uniform(-np.pi / 3, np.pi / 3, (200, n))
    Z = an.transmission_matrix(alpha, p)
    fd = -central_jacobian(lambda a: an.cable_lengths(a, p), alpha)
    assert Z.shape == (200, n, p.n_cables)
    np.testing.assert_allclose(Z, fd, atol=1e-11, rtol=0)


@pytest.mark.parametrize("make", [m for _, m in NECKS[1:]], ids=[k for k, _ in NECKS[1:]])
def test_zdot_matches_differentiated_z(make, rng):
    p = make()
    alpha = rng.uniform(-1, 1, (100, p.n_joints))
    alpha_dot = rng.normal(size=(100, p.n_joints))
    h = 1e-5
    fd = (an.transmission_matrix(alpha + h * alpha_dot, p) - an.transmission_matrix(alpha - h * alpha_dot, p)) / (2 * h)
    np.testing.assert_allclose(an.transmission_matrix_dot(alpha, alpha_dot, p), fd, atol=1e-10)
    k = an.cable_kinematics(alpha, alpha_dot, p)      # one pass gives the same three
    np.testing.assert_array_equal(k.Zdot, an.transmission_matrix_dot(alpha, alpha_dot, p))
    np.testing.assert_array_equal(k.Z, an.transmission_matrix(alpha, p))
    np.testing.assert_array_equal(k.lengths, an.cable_lengths(alpha, p))


def test_design_note_invariants(params, rng):
    alpha = rng.uniform(-np.pi / 3, np.pi / 3, (2000, 3))
    Z = an.transmission_matrix(alpha, params)
    Z1, Z2 = Z[..., :3], Z[..., 3]
    lower = Z1[:, [1, 2, 2], [0, 0, 1]]
    assert np.all(lower == 0.0), "Z1 must be upper triangular"
    diag = np.diagonal(Z1, axis1=1, axis2=2)
    assert diag.max() < -0.0178 and diag.min() > -0.0305
    assert Z2.min() > 0.0178 and Z2.max() < 0.0328
    assert np.abs(Z1[:, [0, 0, 1], [1, 2, 2]]).max() <= 1.3e-3
    K = -np.linalg.solve(Z1, Z2[..., None])[..., 0]
    assert K.min() > 0.59


def test_psi_and_rest_lengths(params):
    assert np.degrees(an.psi(0.0, params)) == pytest.approx(120.0, abs=1e-12)
    lo, hi = np.degrees(an.psi(np.radians([-60.0, 60.0]), params))
    assert lo == pytest.approx(85.66, abs=0.01) and hi == pytest.approx(145.66, abs=0.01)
    np.testing.assert_array_equal(an.cable_lengths(np.zeros(3), params), 0.0)


def test_forward_kinematics_is_a_rigid_linkage(params, rng):
    alpha = rng.uniform(-1.2, 1.2, (300, 3))
    kin = an.forward_kinematics(alpha, params)
    A, B, C, D = (kin.corners[..., k, :] for k in range(4))
    g = params.geometry
    for u, v, length in [(A, D, g.L), (B, C, g.L), (A, B, g.b), (C, D, g.b)]:
        np.testing.assert_allclose(np.linalg.norm(v - u, axis=-1), length, atol=1e-14)
    sides = an.side_lengths(alpha, params)
    np.testing.assert_allclose(np.linalg.norm(C - A, axis=-1), sides.l_l, atol=1e-14)
    np.testing.assert_allclose(np.linalg.norm(D - B, axis=-1), sides.l_r, atol=1e-14)
    # top bar of joint i is the base bar of joint i+1
    np.testing.assert_allclose(C[:, :-1], A[:, 1:], atol=1e-14)
    np.testing.assert_allclose(D[:, :-1], B[:, 1:], atol=1e-14)
    # bar angles accumulate alpha; alpha > 0 is counter-clockwise (bends left)
    np.testing.assert_allclose(kin.head_angle, alpha.sum(-1), atol=1e-14)
    left = an.forward_kinematics(np.array([0.3, 0.0, 0.0]), params)
    assert left.head_position[0] < 0


def test_side_length_derivatives(params, rng):
    alpha = rng.uniform(-1.5, 1.5, 100)
    sd = an.side_lengths(alpha, params)
    h = 1e-5
    for l, dl, ddl in [(0, 1, 2), (3, 4, 5)]:
        f = lambda a: an.side_lengths(a, params)[l]
        np.testing.assert_allclose(sd[dl], (f(alpha + h) - f(alpha - h)) / (2 * h), atol=1e-10)
        np.testing.assert_allclose(sd[ddl], (f(alpha + h) - 2 * f(alpha) + f(alpha - h)) / h ** 2, atol=1e-5)


def test_bad_alpha_is_rejected(params):
    with pytest.raises(ValueError, match=r"alpha: expected shape \(\.\.\., 3\)"):
        an.transmission_matrix(np.zeros(4), params)
    with pytest.raises(ValueError, match="NaN"):
        an.cable_lengths(np.array([0.0, np.nan, 0.0]), params)
