"""``backlash``: a dead band between the motor shaft (with the encoder) and the cable drum."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from neck_sim.effects.base import Effect, Hidden, Shape, indices, per_item
from neck_sim.effects.cable_elasticity import CableElasticity

__all__ = ["Backlash", "BACKLASH_RANGE", "SWING", "lead_step", "motor_lead"]

#: Search range of the band of each cable (m of cable): up to 2 mm (the blind tests hide 0.15-0.6 mm).
BACKLASH_RANGE = (0.0, 2e-3)


#: How much faster than the drum the motor crosses the band in the plant: the drum, which the
#: plant simulates, moves a twentieth of the band while the motor swings across it (a dead band
#: seen from the drum: the motor spins almost freely through the gap).
SWING = 20.0


def lead_step(lead: np.ndarray, drum_step: np.ndarray, band: np.ndarray) -> np.ndarray:
    """One period of the motor's lead over the drum (m of cable or rad, (C,)): the drum moved
    ``drum_step``; inside the band the lead takes :data:`SWING` times it,
    ``clip(lead + SWING drum_step, -band/2, band/2)``."""
    half = 0.5 * np.asarray(band, dtype=float)
    return np.clip(lead + SWING * drum_step, -half, half)


def motor_lead(motor: np.ndarray, band: np.ndarray) -> np.ndarray:
    """The lead (T, C) m of the motor over the drum from the motor's own positions ``motor``
    (T, C) m of cable (encoder angle x r_d / R): the play operator, the drum standing still while
    the motor crosses the band, ``lead_k = clip(lead_{k-1} + motor_k - motor_{k-1}, -band/2,
    band/2)``; starting at 0 (the encoders are zeroed in the middle of the band).  The plant's
    :func:`lead_step` is the same band crossed with the drum moving 1/SWING of it."""
    motor = np.asarray(motor, dtype=float)
    half = 0.5 * np.broadcast_to(np.asarray(band, dtype=float), motor.shape[1:])
    step = np.diff(motor, axis=0, prepend=motor[:1])
    out = np.empty_like(motor)
    lead = np.zeros(motor.shape[1:])
    for k in range(motor.shape[0]):          # a play operator: sequential by nature, T x C cheap steps
        lead = np.minimum(np.maximum(lead + step[k], -half), half)
        out[k] = lead
    return out


@dataclass(frozen=True)
class Backlash(Effect):
    """A dead band of ``band`` (m of cable) between each motor shaft and its drum (gear play).

    The encoder sits on the motor shaft; the drum, which winds the cable, lags the motor: while
    the motor moves on in one direction it leads the drum by half the band; after a reversal the
    motor crosses the band before it drives the drum the other way.  The plant keeps the lead of
    each motor over its drum (:func:`lead_step`: the motor swings across the band while the drum
    moves a twentieth of it) and reports encoder angles of drum + lead, so the elongation of
    eq (27) computed from the encoders is off by the lead.  The diagnosis fits it as a shape: the
    band per cable, searched on :data:`BACKLASH_RANGE` cable by cable; the cable law then uses
    x_c - lead(theta) (:func:`motor_lead` from the encoders, through the observations' filter
    chain), and the motor inertia's force of eq (37) from the drum's acceleration
(:meth:`fit_force_offset`).  Force transmission is unchanged (the tensions keep every gear
loaded on one flank).
    """

    name: ClassVar[str] = "backlash"
    description: ClassVar[str] = "a dead band between motor shaft and drum (gear play)"
    abbreviation: ClassVar[str] = "play"
    kind: ClassVar[str] = "encoder"
    magnitude_field: ClassVar[str] = "band"
    acts_on_cable_law: ClassVar[bool] = True
    requires: ClassVar[tuple] = (CableElasticity.name,)
    shapes: ClassVar[tuple] = (Shape("band", "m", per_cable=True, bounds=BACKLASH_RANGE, profile_step=2e-5),)
    blind_magnitude: ClassVar[float] = 0.3e-3   # m of cable on one right cable
    blind_unit: ClassVar[str] = "m"
    band: tuple | float = 0.3e-3
    cables: tuple | None = None

    def __post_init__(self):
        object.__setattr__(self, "band", per_item("backlash.band", self.band, non_negative=True))
        object.__setattr__(self, "cables", indices("backlash.cables", self.cables))

    def encoder_band(self, n_cables: int) -> np.ndarray:
        """(n_cables,) m of cable: the band of each motor (0: none)."""
        return self.per_cable(n_cables)

    @classmethod
    def bands(cls, shape: dict, n_cables: int) -> np.ndarray:
        """The band (n_cables,) m from the shape keys ``band_<i>`` (1-based)."""
        out = np.zeros(n_cables)
        for key, v in shape.items():
            if key.startswith("band_"):
                out[int(key[5:]) - 1] = v
        return out

    @classmethod
    def fit_cable_offset(cls, data, cable: int, value: float) -> np.ndarray:
        """(S,) m added to cable ``cable``'s measured elongation when its band is ``value``: minus
        the motor's lead, from the encoders at the control rate through the filter chain."""
        def compute():
            motor = data.prep.fast.theta[:, cable:cable + 1] / data.ratio        # m of cable
            return -data.to_slow(motor_lead(motor, value))[:, 0]
        return data.cached(("backlash", cable, round(float(value), 9)), compute)

    @classmethod
    def fit_elongation_series(cls, data, shape: dict) -> np.ndarray | None:
        out = np.zeros((data.S, data.C))
        for j, v in enumerate(cls.bands(shape, data.C)):
            if v > 0:
                out[:, j] = cls.fit_cable_offset(data, j, v)
        return out

    @classmethod
    def fit_force_offset(cls, data, shape: dict):
        """The inertia term from the drum's acceleration (the plant's motor inertia moves with the
        drum; the encoders show the motor): y_C + (R/r_d)^2 I_a d^2(lead)/dt^2, N."""
        bands = cls.bands(shape, data.C)
        if not np.any(bands > 0):
            return None

        def compute():
            motor = data.prep.fast.theta / data.ratio                                # m of cable
            lead = motor_lead(motor, bands)
            acc = np.gradient(np.gradient(lead, data.dt, axis=0), data.dt, axis=0)
            fast = data.ratio ** 2 * data.params.actuation.I_a * acc
            return fast, data.to_slow(fast)
        return data.cached(("backlash force", tuple(np.round(bands, 9))), compute)

    @classmethod
    def to_plant(cls, params, values, shape):
        return params, cls(band=tuple(cls.bands(shape, params.n_cables)))

    @classmethod
    def hide(cls, params, rng, magnitude, cable, joint):
        cable = int(rng.integers(params.n_cables - 1))        # a right cable (see ``pretension``)
        desc = f"backlash {1e3 * magnitude:.2f} mm of cable on motor {cable + 1}"
        return Hidden(params, (cls(band=magnitude, cables=(cable,)),), (cable,), (), desc, cls.name)
