"""Least squares with the paper's quality measures (eqs 48-50).

v = W^+ Y (eq 49); C_X = sigma_rho^2 (W^T W)^-1 with sigma_rho^2 = |Y - W v|^2 / (r - p) (eq 50);
sigma_i = sqrt(C_X(i, i)); relative sigma 100 sigma_i / |v_i| (%).  Weights (the paper's W = 100
on the torque rows) are applied to the rows before solving, as the paper does, so the one
sigma_rho of eq (50) is that of the weighted residual.

Two condition numbers are reported: ``cond`` of W as it stands (units mixed: the paper's) and
``cond_scaled`` of W with unit-norm columns, the scale-free number used to compare excitations
(a change of units does not change it).
"""

from __future__ import annotations

from dataclasses import dataclass

from typing import Sequence

import numpy as np
import numpy.typing as npt

__all__ = ["LSResult", "solve_weighted"]


@dataclass(frozen=True, eq=False)
class LSResult:
    """Identified values with eq (50)'s statistics; arrays are (p,) in the order of ``names``."""

    names: tuple
    units: tuple
    value: np.ndarray
    sigma: np.ndarray
    rel_sigma: np.ndarray      # %, 100 sigma / |value|
    cov: np.ndarray            # (p, p)
    cond: float
    cond_scaled: float
    sigma_rho: float
    n_rows: int
    residual: np.ndarray       # (r,) Y - W v (weighted rows)

    def __getitem__(self, name: str) -> float:
        try:
            return float(self.value[self.names.index(name)])
        except ValueError:
            raise KeyError(f"{name!r}: not a parameter of this model (parameters: {', '.join(self.names)})") from None

    def group(self, symbol: str) -> np.ndarray:
        """Values of the parameters named ``symbol(i)``, in cable order."""
        idx = [i for i, n in enumerate(self.names) if n.split("(")[0] == symbol]
        if not idx:
            raise KeyError(f"{symbol!r}: no such parameter group (parameters: {', '.join(self.names)})")
        return self.value[idx]

    def group_rel_sigma(self, symbol: str) -> np.ndarray:
        idx = [i for i, n in enumerate(self.names) if n.split("(")[0] == symbol]
        return self.rel_sigma[idx]

    def to_dict(self) -> dict:
        return {"parameters": {n: {"value": float(v), "unit": u, "sigma": float(s), "rel_sigma_percent": float(r)}
                               for n, u, v, s, r in zip(self.names, self.units, self.value, self.sigma,
                                                        self.rel_sigma)},
                "cond": self.cond, "cond_scaled": self.cond_scaled, "sigma_rho": self.sigma_rho,
                "n_rows": self.n_rows}


def solve_weighted(W: npt.ArrayLike, Y: npt.ArrayLike, names: Sequence[str] | None = None,
                   units: Sequence[str] | None = None, row_weights: npt.ArrayLike | None = None, *,
                   condition: bool = True) -> LSResult:
    """Least-squares solution of W v + rho = Y (eq 48) with eq (50)'s covariance.

    W (r, p), Y (r,), ``row_weights`` (r,) multiply rows of both before solving.  Raises ValueError
    for mismatched shapes, NaN, too few rows (r <= p) or an unidentifiable parameter (a column of
    zeros, or W rank-deficient: the message names the parameters involved).
    ``condition=False`` skips the two condition numbers (``cond`` of W, one more SVD, and
    ``cond_scaled``, whose SVD lstsq's singular values stand in for: both NaN in the result) for
    callers that never read them, such as the diagnosis' repeated fits; the values and errors
    are the same.
    """
    Wm = np.asarray(W, dtype=float)
    Ym = np.asarray(Y, dtype=float)
    if Wm.ndim != 2 or Ym.ndim != 1 or Wm.shape[0] != Ym.shape[0]:
        raise ValueError(f"least squares: expected W (r, p) and Y (r,), got {Wm.shape} and {Ym.shape}")
    r, p = Wm.shape
    names = tuple(names) if names is not None else tuple(f"v{i + 1}" for i in range(p))
    units = tuple(units) if units is not None else ("",) * p
    if len(names) != p or len(units) != p:
        raise ValueError(f"least squares: {p} columns but {len(names)} names and {len(units)} units")
    if row_weights is not None:
        w = np.asarray(row_weights, dtype=float)
        if w.shape != (r,):
            raise ValueError(f"row_weights: expected shape ({r},), got {w.shape}")
        Wm, Ym = Wm * w[:, None], Ym * w
    if not (np.all(np.isfinite(Wm)) and np.all(np.isfinite(Ym))):
        raise ValueError("least squares: the observation matrix or the observations contain NaN or infinity")
    if r <= p:
        raise ValueError(f"least squares: {r} equations for {p} parameters; need more samples than parameters (r > p)")
    norms = np.linalg.norm(Wm, axis=0)
    zero = [names[i] for i in np.nonzero(norms == 0)[0]]
    if zero:
        raise ValueError(f"least squares: parameters {', '.join(zero)} are not excited by the data "
                         f"(their columns of W are zero)")
    Ws = Wm / norms
    if condition:
        cond_scaled = _checked_scaled_condition(Ws, names)
        v_s, *_ = np.linalg.lstsq(Ws, Ym, rcond=None)
    else:
        # lstsq's own singular values of Ws decide the rank; within a factor 2 of the bound the
        # exact SVD's do (the two agree to ~1e-15 relative on the diagnosis' W, and to eps x cond
        # at worst): the same decision and message as with the condition numbers, one SVD fewer
        v_s, _, _, sv = np.linalg.lstsq(Ws, Ym, rcond=None)
        if not (sv[-1] > 0 and sv[0] / sv[-1] < 0.5 * _COND_BOUND):
            _checked_scaled_condition(Ws, names)
        cond_scaled = float("nan")
    value = v_s / norms
    residual = Ym - Wm @ value
    sigma_rho2 = float(residual @ residual) / (r - p)
    inv_s = np.linalg.inv(Ws.T @ Ws)
    cov = sigma_rho2 * inv_s / np.outer(norms, norms)
    sigma = np.sqrt(np.diag(cov))
    with np.errstate(divide="ignore"):
        rel = 100.0 * sigma / np.abs(value)
    cond = float(np.linalg.cond(Wm)) if condition else float("nan")
    return LSResult(names, units, value, sigma, rel, cov, cond, cond_scaled,
                    float(np.sqrt(sigma_rho2)), r, residual)


#: Scaled condition number from which W counts as rank-deficient.
_COND_BOUND = 1e10


def _checked_scaled_condition(Ws: np.ndarray, names: tuple) -> float:
    """The condition number of the column-scaled W, or ValueError naming the three parameters
    of its weakest direction when it is not below :data:`_COND_BOUND`."""
    sv = np.linalg.svd(Ws, compute_uv=False)
    cond_scaled = float(sv[0] / sv[-1]) if sv[-1] > 0 else np.inf
    if not cond_scaled < _COND_BOUND:
        _, _, vt = np.linalg.svd(Ws)
        worst = np.argsort(-np.abs(vt[-1]))[:3]
        raise ValueError(f"least squares: the observation matrix is rank-deficient (scaled condition number "
                         f"{cond_scaled:.3g}); not separable: {', '.join(names[i] for i in worst)}")
    return cond_scaled
