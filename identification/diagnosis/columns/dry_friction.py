"""Columns of ``dry_friction`` (eq 37, in the paper's model): f_s per cable, the sign sharpness c_s searched.

Besides f_s (the law's asymptote) a named dry friction reports ``f_travel(i)``: the fitted law's
mean force per unit of the cable's travel over the log (:func:`travel_mean_friction`), the
friction the log's own speeds hold.  Why: f_s is the force as the speed goes to infinity, and where
the friction the encoders see does not follow eq 37's shape it reads what the shape extrapolates
(docs/your-own-neck.md section 7: on the 10-joint, 4-cable neck a motor dither at 100-250 Hz, which
the encoders do not resolve, makes the seen friction rise over 0.3-1 rad/s and stay flat above; an
arctan fitted to it overshoots the flat part, f_s +24 to +30 % on one seed).

    f_bar = travel_mean_friction(data.theta_dot_fast[:, 0], f_s=9.4, c_s=2.2)   # N
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from neck_sim.analytic.dynamics import arctan_friction
from neck_sim.effects import DryFriction
from neck_sim.params import NeckParams

from identification.diagnosis.columns.base import Column, MotorColumns, Shape

__all__ = ["DryFrictionColumns", "TRAVEL_NOTE", "travel_mean_friction"]

#: The note of ``f_travel``: what it is and why it is reported.
TRAVEL_NOTE = ("the fitted law's mean force per unit of the cable's travel over this log, sum f(theta_dot) "
               "|theta_dot| / sum |theta_dot| (the friction work over the distance): the friction the log's "
               "speeds hold; f_s is its value at infinite speed")


def travel_mean_friction(theta_dot: np.ndarray, f_s: float, c_s: float) -> float:
    """Mean force (N) of eq (37)'s law f_s (2/pi) arctan(c_s theta_dot) per unit of travel over the
    speeds ``theta_dot`` (rad/s, one cable, equally spaced in time): the friction's work over the
    distance the cable moved, sum f |theta_dot| / sum |theta_dot|; f_s (N), c_s (s/rad).  NaN
    when the cable never moves."""
    v = np.abs(np.asarray(theta_dot, dtype=float))
    travel = float(v.sum())
    if not travel > 0:
        return float("nan")
    return float(np.sum(arctan_friction(v, c_s, f_s) * v) / travel)


class DryFrictionColumns(MotorColumns):
    """f_s (N) per cable: the torque and cable blocks of (2/pi) arctan(c_s theta_dot), c_s (s/rad)
    a log-refined shape.  A model without it has no friction at all (``when_absent``)."""

    effect: ClassVar[str] = DryFriction.name
    locates_cable: ClassVar[bool] = True
    columns: ClassVar[tuple] = (Column("f_s", "N"),)
    shapes: ClassVar[tuple] = (Shape("c_s", "s/rad", default=0.5, grid=(0.5, 1.0, 2.0, 5.0, 10.0, 20.0),
                                     refine="log", span=2.0),)

    # the plant applies eq (37) from params.friction (apply); no extra native force
    @classmethod
    def to_plant(cls, params, values, shape):
        return DryFriction(f_s=tuple(np.clip(values["f_s"], 0.0, None)), c_s=shape["c_s"]).apply(params), None

    @classmethod
    def when_absent(cls, params: NeckParams, elastic: bool) -> NeckParams:
        return params.replace(**{"friction.f_s": (0.0,) * params.n_cables})

    @classmethod
    def derived_parameters(cls, theta_dot: np.ndarray, fitted: dict, shape: dict) -> dict:
        """{``f_travel(i)``: (value, sigma, unit, note)} for every fitted ``f_s(i)`` = (value,
        sigma): :func:`travel_mean_friction` over cable i's encoder speeds ``theta_dot`` (T, C)
        rad/s at the searched c_s; its sigma f_s's scaled alike (c_s held, as a grid search's)."""
        out = {}
        for i, name in enumerate(cls.columns[0].names(0, theta_dot.shape[1])):
            if name not in fitted:
                continue
            value, sigma = fitted[name]
            share = travel_mean_friction(theta_dot[:, i], 1.0, shape["c_s"])
            out[f"f_travel({i + 1})"] = (value * share, None if sigma is None else abs(sigma) * share, "N", TRAVEL_NOTE)
        return out
