"""The cables' law, eq (54): tension from elongation and back, and its time steps (eqs 54, 58).

t = (k x + c_a x_dot) / (1 - lambda x) for a taut cable (x > 0 stretched, the sign convention of
:mod:`neck_sim.analytic.cables`), 0 when slack.  Re-exported by :mod:`neck_sim.analytic.dynamics`,
whose elastic model (eqs 29, 30) it closes.  SI units throughout.

    x = static_elongation(t, k, lam)         # (..., m) m for tensions (..., m) N
    t = cable_tension(x, np.zeros_like(x), params)
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from neck_sim.jit import dual
from neck_sim.params import NeckParams

__all__ = ["cable_tension", "secant_stiffness", "cable_stiffness", "static_elongation", "euler_elongation",
           "elongation_step", "elongation_series"]


def cap_elongation(k, lam, t_cap: float) -> np.ndarray:
    """Elongation (m) at which eq (54)'s resting tension reaches ``t_cap`` (N), where the cable law
    continues with its tangent stiffness: t_cap / (k + lambda t_cap); ``k`` N/m, ``lam`` 1/m."""
    return t_cap / (k + lam * t_cap)


def cable_tension(x: npt.ArrayLike, x_dot: npt.ArrayLike, params: NeckParams, k: npt.ArrayLike | None = None,
                  lam: npt.ArrayLike | None = None, c_a: npt.ArrayLike | None = None) -> np.ndarray:
    """Tension-only cable tension of eq (54) solved for t, (..., m), N.

    t = (k x + c_a x_dot) / (1 - lambda x) for x > 0, 0 when slack (x <= 0) and never negative.
    Above ``cables.t_cap`` the elastic part continues with its tangent stiffness, so there is no
    pole at x = 1/lambda.  Defaults are the plant's ``params.cables``.
    """
    cab = params.cables
    k = np.asarray(cab.k if k is None else k, dtype=float)
    lam = np.asarray(cab.lam if lam is None else lam, dtype=float)
    c_a = np.asarray(cab.c_a if c_a is None else c_a, dtype=float)
    x = np.asarray(x, dtype=float)
    x_dot = np.asarray(x_dot, dtype=float)
    x_star = cap_elongation(k, lam, cab.t_cap)
    xe = np.minimum(x, x_star)
    denom = 1.0 - lam * xe
    elastic = k * xe / denom + np.maximum(x - x_star, 0.0) * k / (1.0 - lam * x_star) ** 2
    t = elastic + c_a * x_dot / denom
    return np.where(x > 0, np.maximum(t, 0.0), 0.0)


@dual
def secant_stiffness(tension: np.ndarray | float, k: np.ndarray | float,
                     lam: np.ndarray | float) -> np.ndarray | float:
    """Secant stiffness k + lambda max(t, 0) of eq (54), N/m: the formula :func:`cable_stiffness`
    runs on arrays, with a compiled scalar twin ``.jit`` for the control step.

    ``tension`` N, ``k`` N/m, ``lam`` 1/m; arrays broadcast (numpy) or scalars (``.jit``).
    """
    return k + lam * np.maximum(tension, 0.0)


def cable_stiffness(tension: npt.ArrayLike, k: npt.ArrayLike, lam: npt.ArrayLike) -> np.ndarray:
    """Secant stiffness k + lambda t of eq (54), (..., m) N/m, for tensions t (..., m) N
    (negative tensions count as 0: a cable cannot push); ``k`` N/m, ``lam`` 1/m."""
    return secant_stiffness(np.asarray(tension, dtype=float), np.asarray(k, dtype=float),
                            np.asarray(lam, dtype=float))


def static_elongation(tension: npt.ArrayLike, k: npt.ArrayLike, lam: npt.ArrayLike) -> np.ndarray:
    """Eq (54) inverted at rest (x_dot = 0): x = t / (k + lambda t), (..., m) m, 0 for t <= 0.

    The one definition of elongation from tension; :func:`elongation_step` and
    :func:`elongation_series` add the damping c_a x_dot."""
    return np.maximum(np.asarray(tension, dtype=float), 0.0) / cable_stiffness(tension, k, lam)


@dual
def euler_elongation(x: np.ndarray | float, tension: np.ndarray | float, dt: float, c_a: np.ndarray | float,
                     stiffness: np.ndarray | float) -> np.ndarray | float:
    """Eq (58): x + dt / c_a (t - K x), one explicit Euler step of eq (54) for a given secant
    stiffness K = :func:`secant_stiffness` (N/m), with a compiled scalar twin ``.jit``.

    ``x`` m, ``tension`` N, ``dt`` s, ``c_a`` N s/m > 0; arrays broadcast (numpy) or scalars.
    """
    return x + dt / c_a * (tension - stiffness * x)


def elongation_step(x: npt.ArrayLike, tension: npt.ArrayLike, dt: float, k: npt.ArrayLike, lam: npt.ArrayLike,
                    c_a: npt.ArrayLike) -> np.ndarray:
    """Eq (58): one explicit Euler step of eq (54), c_a x_dot = t - (k + lambda t) x, (m,) m.

    ``x`` (..., m) m the elongation at the start of the step, ``tension`` (..., m) N (>= 0)
    applied during it, ``dt`` s, ``c_a`` N s/m > 0.  The compiled control step calls the same
    formulas' twins (``secant_stiffness.jit``, ``euler_elongation.jit``)."""
    return euler_elongation(x, tension, dt, c_a, cable_stiffness(tension, k, lam))


def elongation_series(tension: npt.ArrayLike, dt: float, k: npt.ArrayLike, lam: npt.ArrayLike, c_a: npt.ArrayLike,
                      x0: npt.ArrayLike | None = None) -> np.ndarray:
    """Elongations x (T, m) m of eq (54) for tensions (T, m) N held per sample of ``dt`` s.

    Each step is the exact solution x_inf + (x - x_inf) exp(-(k + lambda t) dt / c_a) with
    x_inf = :func:`static_elongation` (stable for any dt; c_a = 0 gives the static elongation);
    ``x0`` (m,) m defaults to the static elongation of the first sample."""
    tension = np.asarray(tension, dtype=float)
    c_a = np.asarray(c_a, dtype=float)
    stiff = cable_stiffness(tension, k, lam)
    x_inf = static_elongation(tension, k, lam)
    if np.all(c_a == 0):
        return x_inf
    decay = np.exp(-stiff * dt / np.where(c_a > 0, c_a, 1.0))
    decay = np.where(c_a > 0, decay, 0.0)
    x = np.empty_like(tension)
    x[0] = x_inf[0] if x0 is None else x0
    for i in range(1, tension.shape[0]):
        x[i] = x_inf[i] + (x[i - 1] - x_inf[i]) * decay[i]
    return x
