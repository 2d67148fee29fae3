"""Joint angles from motor angles (paper §4.1): the triangular method (eq 33) and pseudo-inverse
increments (eq 35, corrected).

Both accept cable elongations x_c (zero for inextensible cables) with the sign convention of
:mod:`neck_sim.analytic.cables`: x_c = l_c - l_c0 + (r_d/R) theta, so the cable length the
motors allow is l_c - l_c0 = x_c - (r_d/R) theta.
"""

from __future__ import annotations


import numpy as np
import numpy.typing as npt

from neck_sim.analytic.cables import _evaluate, _segments, _z, cable_lengths
from neck_sim.analytic.dynamics import static_elongation
from neck_sim.analytic.geometry import check_cables, check_pose
from neck_sim.jit import kernel, solve_in_place
from neck_sim.params import NeckParams
from neck_sim.routing import SEG_RIGHT_END, SEG_RIGHT_STRUT

__all__ = ["UnreachableError", "estimate_alpha_triangular", "pinv_increment", "pinv_increment_kernel",
           "cable_stretch_at_f_max",
           "estimate_alpha_pinv"]


class UnreachableError(ValueError):
    """Motor angles that no pose within the joint range explains."""


def _right_segments(alpha: np.ndarray, params: NeckParams):
    """Case (b) value and derivative and case (d) value for joint angles of any shape."""
    g = params.geometry
    seg = _segments(alpha[..., None], g.b, g.L, g.r, orders=(0, 1), left_strut=False)
    return (seg[0][..., SEG_RIGHT_END, 0], seg[1][..., SEG_RIGHT_END, 0], seg[0][..., SEG_RIGHT_STRUT, 0])


def estimate_alpha_triangular(theta: npt.ArrayLike, params: NeckParams, elongation: npt.ArrayLike | None = None, *,
                              tol: float = 1e-13, max_iter: int = 60) -> np.ndarray:
    """alpha_hat from the N right cables, joint after joint (eq 33), shape (..., N), rad.

    Joint j's right cable length is sum_{i<j} case (d)(alpha_i) + case (b)(alpha_j); case (b) is
    strictly increasing in alpha_j, so each joint is one monotone root, found by safeguarded Newton
    iterations inside [-alpha_max, alpha_max] (to ``tol`` rad, far below one encoder count).
    The left cable's reading is not used.  Raises :class:`UnreachableError` naming the cable and
    the first offending sample when no angle in the joint range fits.
    """
    n = params.n_joints
    act = params.actuation
    if not params.routing.is_paper_kind(n):
        raise ValueError("estimate_alpha_triangular: eq (33) needs the paper's routing (right cable j strut-routed "
                         "below joint j and attached at D_j, plus one long left cable); this neck's routing differs")
    th = check_cables(theta, n + 1, "theta")
    x = np.zeros_like(th) if elongation is None else check_cables(elongation, n + 1, "elongation")
    th, x = np.broadcast_arrays(th, x)
    target = x - (act.r_d / act.R) * th                   # l_c - l_c0 per cable
    amax = params.geometry.alpha_max
    b0, _, d0 = _right_segments(np.zeros(1), params)
    b_lo, _, _ = _right_segments(np.array([-amax]), params)
    b_hi, _, _ = _right_segments(np.array([amax]), params)
    alpha = np.zeros(th.shape[:-1] + (n,))
    passed = np.zeros(th.shape[:-1])                      # sum of case (d) terms (minus their rest value)
    for j in range(n):
        want = target[..., j] - passed + b0[0]            # required case (b) value on joint j
        bad = (want < b_lo[0] - 1e-15) | (want > b_hi[0] + 1e-15)
        if np.any(bad):
            idx = np.argwhere(bad)[0]
            raise UnreachableError(
                f"theta: cable c{j + 1} length at sample {tuple(int(i) for i in idx)} needs joint {j + 1} "
                f"outside |alpha| <= {amax:.4g} rad (unreachable pose or wrong encoder offset)")
        lo = np.full(want.shape, -amax)
        hi = np.full(want.shape, amax)
        a = np.zeros(want.shape)
        for _ in range(max_iter):
            val, der, _ = _right_segments(a, params)
            err = val - want
            lo = np.where(err < 0, a, lo)
            hi = np.where(err > 0, a, hi)
            step = a - err / der
            outside = (step <= lo) | (step >= hi)
            new = np.where(outside, 0.5 * (lo + hi), step)
            done = np.max(np.abs(new - a), initial=0.0) < tol
            a = new
            if done:
                break
        alpha[..., j] = a
        passed = passed + _right_segments(a, params)[2] - d0[0]
    return alpha


@kernel
def pinv_increment_kernel(Z: np.ndarray, rhs: np.ndarray, out: np.ndarray) -> bool:
    """out = (Z Z^T)^{-1} Z rhs for one sample: Z (N, N+1) m, rhs (N+1,) m; False if Z Z^T is singular."""
    n = Z.shape[0]
    zz = np.empty((n, n))
    y = np.empty((n, 1))
    for i in range(n):
        acc = 0.0
        for j in range(Z.shape[1]):
            acc += Z[i, j] * rhs[j]
        y[i, 0] = acc
        for k in range(n):
            acc = 0.0
            for j in range(Z.shape[1]):
                acc += Z[i, j] * Z[k, j]
            zz[i, k] = acc
    ok = solve_in_place(zz, y)
    for i in range(n):
        out[i] = y[i, 0]
    return ok


@kernel
def _pinv_rows(Z, rhs, out) -> int:
    for r in range(Z.shape[0]):
        if not pinv_increment_kernel(Z[r], rhs[r], out[r]):
            return r
    return -1


def pinv_increment(alpha_hat: npt.ArrayLike, d_theta: npt.ArrayLike, params: NeckParams,
                   d_elongation: npt.ArrayLike | None = None, *, allow_outside_range: bool = False) -> np.ndarray:
    """One step of eq (35) corrected: (Z(alpha_hat)^T)^+ [(r_d/R) d_theta - d_x_c], (..., N), rad.

    Needs at least as many cables as joints (m >= N), so that Z has full row rank and
    (Z^T)^+ = (Z Z^T)^{-1} Z (:func:`pinv_increment_kernel`): with fewer cables the motor angles do
    not determine the pose.
    """
    n, m = params.n_joints, params.n_cables
    _check_determined(n, m)
    act = params.actuation
    a = check_pose(alpha_hat, params, "alpha_hat", allow_outside_range)
    dth = check_cables(d_theta, m, "d_theta")
    rhs = (act.r_d / act.R) * dth
    if d_elongation is not None:
        rhs = rhs - check_cables(d_elongation, m, "d_elongation")
    return _increment(a, rhs, params)


def _check_determined(n: int, m: int) -> None:
    if m < n:
        raise ValueError(f"pinv_increment: {m} cables cannot determine {n} joint angles (eq 35 needs m >= N)")


def _increment(a: np.ndarray, rhs: np.ndarray, params: NeckParams) -> np.ndarray:
    """(Z(a)^T)^+ rhs of :func:`pinv_increment` for a checked pose ``a`` (..., N) rad and
    right-hand side ``rhs`` (..., m) m."""
    n, m = params.n_joints, params.n_cables
    Z = _z(_evaluate(a, params, (1,))[1], params)     # transmission_matrix of the checked pose
    batch = np.broadcast_shapes(Z.shape[:-2], rhs.shape[:-1])
    rows = int(np.prod(batch))
    if Z.shape[:-2] != batch:         # the estimator's batch: already one Z per right-hand side
        Z = np.broadcast_to(Z, batch + (n, m))
    if rhs.shape[:-1] != batch:
        rhs = np.broadcast_to(rhs, batch + (m,))
    Z = np.ascontiguousarray(Z).reshape(rows, n, m)
    rhs = np.ascontiguousarray(rhs).reshape(rows, m)
    out = np.empty((rows, n))
    bad = _pinv_rows(Z, rhs, out)
    if bad >= 0:
        where = np.unravel_index(bad, batch) if batch else ()
        raise UnreachableError(f"alpha_hat: Z Z^T is singular at sample {where} (pose outside the workspace)")
    return out.reshape(batch + (n,))


def _finite_steps(values: np.ndarray) -> np.ndarray:
    """(T - 1,) bool: whether every sample-to-sample difference of ``values`` (..., T, m) at each
    step is finite, the check :func:`pinv_increment` makes of one step's differences."""
    fin = np.isfinite(values).all(axis=-1)
    return fin.reshape(-1, fin.shape[-1]).all(axis=0)


def cable_stretch_at_f_max(params: NeckParams) -> np.ndarray:
    """Static elongation of each cable at the force limit f_max by eq (54), (m,) m."""
    cab = params.cables
    return static_elongation(np.full(params.n_cables, params.actuation.f_max), cab.k, cab.lam)


def estimate_alpha_pinv(theta: npt.ArrayLike, params: NeckParams, elongation: npt.ArrayLike | None = None,
                        alpha0: npt.ArrayLike | None = None, *, tol: float | None = None) -> np.ndarray:
    """alpha_hat over a time series by eq (35) corrected, all m cables, shape (..., T, N), rad.

    ``theta`` (..., T, m); ``elongation`` (..., T, m) or None; ``alpha0`` (..., N) the pose at
    the first sample (default straight).  Vectorised over the leading batch axes, sequential in T.

    More cables than joints over-determine the pose: after the fit, the cable lengths of
    alpha_hat must match the ones the motors allow, l_c - l_c0 = x_c - (r_d/R) theta (both taken
    from the first sample).  Motor angles whose mismatch exceeds ``tol`` (m; default the norm of
    :func:`cable_stretch_at_f_max`, the most that taut cables within f_max can explain) are
    reached by no pose, nor are estimates leaving |alpha| <= alpha_max: both raise
    :class:`UnreachableError` naming the first offending sample.
    """
    n, m = params.n_joints, params.n_cables
    th = check_cables(theta, m, "theta")
    if th.ndim < 2:
        raise ValueError(f"theta: expected a time series of shape (..., T, {m}), got {th.shape}")
    x = None if elongation is None else check_cables(elongation, m, "elongation")
    if x is not None and x.shape[-2] != th.shape[-2]:
        raise ValueError(f"elongation: {x.shape[-2]} samples but theta has {th.shape[-2]}")
    a = np.zeros(th.shape[:-2] + (n,)) if alpha0 is None else check_pose(alpha0, params, "alpha0")
    out = np.empty(th.shape[:-1] + (n,))
    out[..., 0, :] = a
    # pinv_increment at every step, its differences, right-hand sides and their checks taken
    # over the whole series at once (the same values; each error raised at the step it names)
    if th.shape[-2] > 1:
        _check_determined(n, m)
    dth = np.diff(th, axis=-2)
    rhs = (params.actuation.r_d / params.actuation.R) * dth
    ok_th, ok_x = _finite_steps(dth), None
    if x is not None:
        dx = np.diff(x, axis=-2)
        rhs, ok_x = rhs - dx, _finite_steps(dx)
    for t in range(1, th.shape[-2]):
        a = check_pose(a, params, "alpha_hat", allow_outside_range=True)
        if not ok_th[t - 1]:
            raise ValueError("d_theta: contains NaN or infinity")
        if ok_x is not None and not ok_x[t - 1]:
            raise ValueError("d_elongation: contains NaN or infinity")
        a = a + _increment(a, rhs[..., t - 1, :], params)
        out[..., t, :] = a
    _check_reachable(out, th, x, params, float(np.linalg.norm(cable_stretch_at_f_max(params))) if tol is None else tol)
    return out


def _check_reachable(alpha_hat, theta, elongation, params: NeckParams, tol: float, iterations: int = 20) -> None:
    """Raise UnreachableError at the first sample where alpha_hat leaves the joint range or where no
    pose's m cable lengths come within ``tol`` (m) of the ones the motors allow.

    The distance is the least-squares one: samples over ``tol`` at alpha_hat are refined by
    Gauss-Newton (eq 35's own step, with the length mismatch as right-hand side) before judging,
    so that the linearisation error of eq (35) over a fast motion is never taken for a mismatch.
    """
    act = params.actuation
    amax = params.geometry.alpha_max
    outside = ~np.all(np.abs(alpha_hat) <= amax, axis=-1)                 # (..., T), NaN counts as outside
    allowed = -(act.r_d / act.R) * theta if elongation is None else elongation - (act.r_d / act.R) * theta
    target = cable_lengths(alpha_hat[..., :1, :], params) + allowed - allowed[..., :1, :]
    with np.errstate(invalid="ignore"):
        lengths = cable_lengths(np.where(outside[..., None], 0.0, alpha_hat), params)
    mismatch = np.linalg.norm(lengths - target, axis=-1)
    refine = ~outside & ~(mismatch <= tol)
    if np.any(refine):
        a, goal = alpha_hat[refine], target[refine]
        with np.errstate(invalid="ignore"):
            for _ in range(iterations):
                gap = goal - cable_lengths(a, params, allow_outside_range=True)
                a = a + pinv_increment(a, np.zeros_like(goal), params, gap, allow_outside_range=True)
            mismatch[refine] = np.linalg.norm(cable_lengths(a, params, allow_outside_range=True) - goal, axis=-1)
    bad = outside | ~(mismatch <= tol)
    if not np.any(bad):
        return
    first = int(np.argmax(np.any(bad.reshape(-1, bad.shape[-1]), axis=0)))   # earliest sample over the batch
    batch = tuple(int(i) for i in np.argwhere(bad[..., first])[0])
    idx = batch + (first,)
    where = f"sample {first}" + (f" of series {batch}" if batch else "")
    if outside[idx]:
        j = int(np.argmax(~(np.abs(alpha_hat[idx]) <= amax)))
        raise UnreachableError(
            f"theta: at {where} the motor angles need joint {j + 1} at {np.degrees(alpha_hat[idx][j]):.1f} deg, "
            f"outside |alpha| <= {np.degrees(amax):.4g} deg (unreachable pose, encoder jump or wrong cable order)")
    raise UnreachableError(
        f"theta: at {where} the {params.n_cables} cable lengths the motors allow are "
        f"{mismatch[idx] * 1e3:.1f} mm from those of any pose (taut cables within f_max explain at most "
        f"{tol * 1e3:.1f} mm): no pose reaches these motor angles (encoder jump, slipped cable or wrong cable order)")
