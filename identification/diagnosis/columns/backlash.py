"""Columns of ``backlash``: none; the band of each cable is a bounded shape that offsets the elongation."""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from neck_sim.analytic.dynamics import arctan_friction
from neck_sim.effects import Backlash
from neck_sim.jit import kernel

from identification.diagnosis.columns.base import ColumnData, EffectColumns, Shape

__all__ = ["BacklashColumns", "BACKLASH_RANGE", "motor_lead"]

#: Search range of the band of each cable (m of cable): up to 2 mm (the blind tests hide 0.15-0.6 mm).
BACKLASH_RANGE = (0.0, 2e-3)


def motor_lead(motor: np.ndarray, band: np.ndarray) -> np.ndarray:
    """The lead (T, C) m of the motor over the drum from the motor's own positions ``motor``
    (T, C) m of cable (encoder angle x r_d / R): the play operator, the drum standing still while
    the motor crosses the band, ``lead_k = clip(lead_{k-1} + motor_k - motor_{k-1}, -band/2,
    band/2)``; starting at 0 (the encoders are zeroed in the middle of the band).  The plant's
    :func:`neck_sim.effects.backlash.lead_step` is the same band crossed with the drum moving
    1/SWING of it."""
    motor = np.asarray(motor, dtype=float)
    half = 0.5 * np.broadcast_to(np.asarray(band, dtype=float), motor.shape[1:])
    step = np.ascontiguousarray(np.diff(motor, axis=0, prepend=motor[:1]).reshape(motor.shape[0], -1))
    out = np.empty(step.shape)
    _play(step, np.ascontiguousarray(half.reshape(-1)), out)
    return out.reshape(motor.shape)


@kernel
def _play(step, half, out) -> None:
    """The play operator of :func:`motor_lead` on columns ``step`` (T, K) with half bands ``half``
    (K,), written into ``out`` (T, K): a sequential recursion, so compiled.  Bit for bit
    ``np.minimum(np.maximum(lead + s, lo), hi)``: the same IEEE sums, and numpy's clip rules (the
    first argument when it is larger or NaN, else the second, which decides the signed zeros)."""
    for c in range(step.shape[1]):
        lo, hi, lead = -half[c], half[c], 0.0
        for k in range(step.shape[0]):
            v = lead + step[k, c]
            if not (v > lo or v != v):
                v = lo
            if not (v < hi or v != v):
                v = hi
            out[k, c] = v
            lead = v


class BacklashColumns(EffectColumns):
    """The band (m of cable) per cable, searched on :data:`BACKLASH_RANGE` cable by cable: the
    cable law then uses x_c - lead(theta) (:func:`motor_lead` from the encoders, through the
    observations' filter chain), and eq (37)'s motor inertia and dry friction from the
    drum's acceleration and speed (:meth:`fit_force_offset`)."""

    effect: ClassVar[str] = Backlash.name
    # a play in one gear model may sit on every motor: every cable's band is tried too
    shapes: ClassVar[tuple] = (Shape("band", "m", per_cable=True, bounds=BACKLASH_RANGE, profile_step=2e-5,
                                     every_cable=True),)

    @classmethod
    def bands(cls, shape: dict, n_cables: int) -> np.ndarray:
        """The band (n_cables,) m from the shape keys ``band_<i>`` (1-based)."""
        return cls.shapes[0].per_cable_values(shape, n_cables)

    @classmethod
    def fit_cable_offset(cls, data: ColumnData, cable: int, value: float) -> np.ndarray:
        """(S,) m added to cable ``cable``'s measured elongation when its band is ``value``: minus
        the motor's lead, from the encoders at the control rate through the filter chain."""
        def compute():
            motor = data.theta_fast[:, cable:cable + 1] / data.ratio                 # m of cable
            return -data.to_slow(motor_lead(motor, value))[:, 0]
        return data.cached(("backlash", cable, round(float(value), 9)), compute)

    @classmethod
    def fit_elongation_series(cls, data: ColumnData, shape: dict) -> np.ndarray | None:
        out = np.zeros((data.S, data.C))
        for j, v in enumerate(cls.bands(shape, data.C)):
            if v > 0:
                out[:, j] = cls.fit_cable_offset(data, j, v)
        return out

    @classmethod
    def fit_force_offset(cls, data: ColumnData, shape: dict):
        """What the encoders misread of the cable-side force y_C of eq (37), N: the motor
        inertia's term from the drum's acceleration, + (R/r_d)^2 I_a d^2(lead)/dt^2, and the dry
        friction of eq (37) at the drum's speed, + f_s [g(theta_dot) - g(theta_dot - (R/r_d)
        d(lead)/dt)] with g(w) = (2/pi) arctan(c_s w) and the nominal f_s, c_s (the friction acts
        where the drum turns; across a reversal the encoder crosses the band and its speed leads
        the drum's by a burst of band x R/r_d rad, the play's strongest trace: up to f_s of
        force while the two speeds differ, against the +-band/2 of elongation)."""
        bands = cls.bands(shape, data.C)
        if not np.any(bands > 0):
            return None

        def compute():
            motor = data.theta_fast / data.ratio                                     # m of cable
            lead = motor_lead(motor, bands)
            acc = np.gradient(np.gradient(lead, data.dt, axis=0), data.dt, axis=0)
            fast = data.ratio ** 2 * data.params.actuation.I_a * acc
            fs = np.asarray(data.params.friction.f_s, dtype=float)
            if np.any(fs > 0):
                # the drum's speed through the same low-pass as the encoders' (parallel filtering)
                drum = data.theta_dot_fast - data.ratio * np.gradient(data.motor_lowpass(lead), data.dt, axis=0)
                cs = data.params.friction.c_s
                fast = fast + arctan_friction(data.theta_dot_fast, cs, fs) - arctan_friction(drum, cs, fs)
            return fast, data.to_slow(fast)
        return data.cached(("backlash force", tuple(np.round(bands, 9))), compute)

    @classmethod
    def to_plant(cls, params, values, shape):
        return params, Backlash(band=tuple(cls.bands(shape, params.n_cables)))
