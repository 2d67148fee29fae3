"""Online joint-angle estimation from the motor encoders (paper §4.1.2 and §5.5).

alpha_hat is integrated by eq (35) corrected (:func:`neck_sim.analytic.pinv_increment`): with the
sign convention of :mod:`neck_sim.analytic.cables`,

    alpha_hat(t + dt) = alpha_hat(t) + (Z(alpha_hat)^T)^+ [(r_d/R)(theta(t + dt) - theta(t)) - (x_c(t + dt) - x_c(t))].

The cable elongation x_c is what the controller's cable model predicts (§5.5):

* ``inextensible``: x_c = 0;
* ``constant`` (model 1): lambda = 0 and k of the paper's Table 1 (``cables.k_linear``);
* ``variable`` (model 2): k and lambda of Table 2 (``cables.k``, ``cables.lam``).

For models 1 and 2, x_c follows eq (58), an explicit Euler step of eq (54) with the tension
estimated from the commanded force minus the friction the controller believes in:

    t_hat = max(f - (2/pi) arctan(c_s theta_dot) f_s, 0)
    x_c(t + dt) = x_c(t) + dt / c_a (t_hat - (k + lambda t_hat) x_c(t)).

Two choices differ from the printed eq (58): the stiffening term uses t_hat, the tension eq (54)
was identified with, rather than the raw force f; and t_hat is clipped at 0 because a cable
cannot push.  c_a is the estimator's damping ``control.c_a_estimator`` (3000 N s/m as in §5.3),
not the plant's: eq (58) ignores the reflected motor inertia, and with a small c_a the estimate
and the commanded force form a fast positive loop (design notes, "Closed-loop facts").
"""

from __future__ import annotations

from enum import Enum

import numpy as np
import numpy.typing as npt

from neck_sim.analytic.dynamics import arctan_friction, elongation_step
from neck_sim.analytic.estimation import pinv_increment
from neck_sim.analytic.geometry import check_cables
from neck_sim.jit import dual
from neck_sim.params import NeckParams, default_params

__all__ = ["CableModel", "estimated_tension", "ElongationEstimator", "JointAngleEstimator"]


class CableModel(str, Enum):
    """The cable model an estimator believes in (§5.5)."""

    INEXTENSIBLE = "inextensible"
    CONSTANT = "constant"       # model 1, Table 1
    VARIABLE = "variable"       # model 2, Table 2

    @classmethod
    def _missing_(cls, value):
        raise ValueError(f"cable model: unknown {value!r} (known: {', '.join(m.value for m in cls)})")


def _per_cable(value, n_cables: int, name: str) -> np.ndarray:
    """A per-cable vector (N+1,); a scalar stands for the same value on every cable."""
    arr = np.asarray(value, dtype=float)
    if arr.ndim == 0:
        arr = np.full(n_cables, float(arr))
    if arr.ndim != 1:
        raise ValueError(f"{name}: expected {n_cables} values (one per cable), got shape {arr.shape}")
    return check_cables(arr, n_cables, name)


@dual
def estimated_tension(force: np.ndarray | float, friction: np.ndarray | float) -> np.ndarray:
    """t_hat = max(f - friction, 0) (N): the commanded force less the believed friction; a cable cannot push."""
    return np.maximum(force - friction, 0.0)


class ElongationEstimator:
    """Cable elongations x_c (N+1,) m predicted from commanded forces by eq (58).

    ``k`` N/m, ``lam`` 1/m, ``c_a`` N s/m (scalar or per cable), ``f_s`` N, ``c_s`` s/rad, ``dt`` s.
    """

    def __init__(self, k: npt.ArrayLike, lam: npt.ArrayLike, c_a: npt.ArrayLike, f_s: npt.ArrayLike, c_s: float,
                 dt: float) -> None:
        self.k = _per_cable(k, np.size(k), "k")
        n1 = self.k.size
        self.lam = _per_cable(lam, n1, "lam")
        self.c_a = _per_cable(c_a, n1, "c_a")
        self.f_s = _per_cable(f_s, n1, "f_s")
        if np.any(self.k <= 0) or np.any(self.c_a <= 0) or np.any(self.lam < 0):
            raise ValueError("k and c_a must be > 0 and lam >= 0 for the elongation estimator")
        if not (dt > 0 and c_s > 0):
            raise ValueError(f"dt and c_s must be positive, got dt = {dt}, c_s = {c_s}")
        self.c_s = float(c_s)
        self.dt = float(dt)
        self.x = np.zeros(n1)

    @classmethod
    def for_model(cls, model: CableModel | str, params: NeckParams, *, k: npt.ArrayLike | None = None,
                  lam: npt.ArrayLike | None = None, c_a: npt.ArrayLike | None = None,
                  f_s: npt.ArrayLike | None = None) -> "ElongationEstimator | None":
        """Estimator of cable model ``model`` (None for inextensible cables).

        Unset coefficients take the paper's values (``default_params(N)``: Table 1 for model 1,
        Table 2 for model 2, friction of Table 1, c_a = ``params.control.c_a_estimator``),
        never the plant's hidden ones.
        """
        model = CableModel(model)
        if model is CableModel.INEXTENSIBLE:
            return None
        paper = default_params(params.n_joints)
        if model is CableModel.CONSTANT:
            k = paper.cables.k_linear if k is None else k
            if k is None:
                raise ValueError("cable model constant: no k given and the paper's k_linear is not set")
            lam = 0.0 if lam is None else lam
        else:
            k = paper.cables.k if k is None else k
            lam = paper.cables.lam if lam is None else lam
        return cls(k, lam, params.control.c_a_estimator if c_a is None else c_a,
                   paper.friction.f_s if f_s is None else f_s, params.friction.c_s,
                   1.0 / params.control.rate_hz)

    def reset(self, x0: npt.ArrayLike | None = None) -> None:
        self.x = np.zeros_like(self.k) if x0 is None else _per_cable(x0, self.k.size, "x0")

    def tension(self, force: npt.ArrayLike, theta_dot: npt.ArrayLike) -> np.ndarray:
        """t_hat = max(f - (2/pi) arctan(c_s theta_dot) f_s, 0), (N+1,) N."""
        fr = arctan_friction(np.asarray(theta_dot, dtype=float), self.c_s, self.f_s)
        return estimated_tension(np.asarray(force, dtype=float), fr)

    def step(self, force: npt.ArrayLike, theta_dot: npt.ArrayLike) -> np.ndarray:
        """Advance one period with the force (N+1,) N applied during it and the motor speed (rad/s)."""
        self.x = elongation_step(self.x, self.tension(force, theta_dot), self.dt, self.k, self.lam, self.c_a)
        return self.x

    def constants(self) -> np.ndarray:
        """(5, N+1) rows k, lam, c_a, f_s, and [c_s, dt, 0...] for the compiled control step."""
        n1 = self.k.size
        extra = np.zeros(n1)
        extra[:2] = self.c_s, self.dt
        return np.stack([self.k, self.lam, self.c_a, self.f_s, extra])


class JointAngleEstimator:
    """alpha_hat (N,) from successive encoder readings by eq (35) corrected."""

    def __init__(self, params: NeckParams, elongation: ElongationEstimator | None = None) -> None:
        self.params = params
        self.elongation = elongation
        n = params.n_joints
        self.alpha_hat = np.zeros(n)
        self.theta: np.ndarray | None = None
        self.x = np.zeros(params.n_cables)

    def reset(self, alpha0: npt.ArrayLike | None = None, theta0: npt.ArrayLike | None = None) -> None:
        """Start at pose ``alpha0`` (default straight) with the cables unstretched.

        ``theta0`` is the encoder reading at that pose; None takes the first reading given to
        :meth:`update`.
        """
        n = self.params.n_joints
        self.alpha_hat = np.zeros(n) if alpha0 is None else _per_cable(alpha0, n, "alpha0")
        m = self.params.n_cables
        self.theta = None if theta0 is None else _per_cable(theta0, m, "theta0")
        self.x = np.zeros(m)
        if self.elongation is not None:
            self.elongation.reset()

    def update(self, theta: npt.ArrayLike, force_prev: npt.ArrayLike | None = None,
               theta_dot_prev: npt.ArrayLike | None = None) -> np.ndarray:
        """New estimate from encoder reading ``theta`` (N+1,) rad.

        ``force_prev`` (N+1,) N and ``theta_dot_prev`` (N+1,) rad/s are the force commanded and the
        motor speed over the period that just ended (used by the elongation model only).
        """
        theta = _per_cable(theta, self.params.n_cables, "theta")
        if self.theta is None:
            self.theta = theta
            return self.alpha_hat
        dx = None
        if self.elongation is not None and force_prev is not None:
            if theta_dot_prev is None:
                raise ValueError("theta_dot_prev: needed with force_prev (the elongation model's friction)")
            x_new = self.elongation.step(force_prev, theta_dot_prev)
            dx = x_new - self.x
            self.x = x_new.copy()
        self.alpha_hat = self.alpha_hat + pinv_increment(self.alpha_hat, theta - self.theta, self.params, dx)
        self.theta = theta
        return self.alpha_hat
