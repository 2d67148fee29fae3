"""``backlash``: a dead band between the motor shaft (with the encoder) and the cable drum."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from neck_sim.effects.base import Effect
from neck_sim.validation import indices, per_item

__all__ = ["Backlash", "SWING", "lead_step"]


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


@dataclass(frozen=True)
class Backlash(Effect):
    """A dead band of ``band`` (m of cable) between each motor shaft and its drum (gear play).

    The encoder sits on the motor shaft; the drum, which winds the cable, lags the motor: while
    the motor moves on in one direction it leads the drum by half the band; after a reversal the
    motor crosses the band before it drives the drum the other way.  The plant keeps the lead of
    each motor over its drum (:func:`lead_step`: the motor swings across the band while the drum
    moves a twentieth of it) and reports encoder angles of drum + lead, so the elongation of
    eq (27) computed from the encoders is off by the lead (the diagnosis fits the band per cable:
    :mod:`identification.diagnosis.columns.backlash`).  Force transmission is unchanged (the
    tensions keep every gear loaded on one flank).
    """

    name: ClassVar[str] = "backlash"
    description: ClassVar[str] = "a dead band between motor shaft and drum (gear play)"
    abbreviation: ClassVar[str] = "play"
    kind: ClassVar[str] = "encoder"
    magnitude_field: ClassVar[str] = "band"
    acts_on_cable_law: ClassVar[bool] = True
    requires: ClassVar[tuple] = ("cable_elasticity",)
    band: tuple | float = 0.3e-3
    cables: tuple | None = None

    def __post_init__(self):
        object.__setattr__(self, "band", per_item("backlash.band", self.band, non_negative=True))
        object.__setattr__(self, "cables", indices("backlash.cables", self.cables))

    def encoder_band(self, n_cables: int) -> np.ndarray:
        """(n_cables,) m of cable: the band of each motor (0: none)."""
        return self.per_cable(n_cables)
