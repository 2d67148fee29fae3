"""Where a recorded run leaves the joint range |alpha| <= ``geometry.alpha_max`` (paper §2.1).

Outside that range the X-joint's geometry (eqs 1, 2) and every relation built on it no longer
describe the neck, and the log contract refuses such angles; a simulated run that goes there is
stopped (``neck-sim simulate``) and a log that holds one is refused by ``neck-sim check``, both
with :meth:`Excursion.describe`.

Usage::

    import numpy as np
    from neck_sim.joint_range import first_excursion

    t = np.arange(4) * 0.002
    alpha = np.radians([[0.0, 10.0], [0.0, 80.0], [0.0, 91.0], [95.0, 0.0]])
    print(first_excursion(t, alpha, np.radians(90.0)).describe())
    # joint 2 at 91.00 deg at t = 0.004 s, outside the joint range |alpha| <= 90.00 deg (geometry.alpha_max)
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

__all__ = ["Excursion", "JointRangeError", "first_excursion"]


@dataclass(frozen=True)
class Excursion:
    """The first sample out of the joint range: its index ``sample``, time ``t`` (s), ``joint``
    (0-based), its ``angle`` (rad) and the range's ``alpha_max`` (rad)."""

    sample: int
    t: float
    joint: int
    angle: float
    alpha_max: float

    def describe(self, with_time: bool = True) -> str:
        """One line naming the joint (1-based), its angle, the time (unless not ``with_time``) and
        the range, in degrees."""
        at = f" at t = {self.t:.3f} s" if with_time else ""
        return (f"joint {self.joint + 1} at {math.degrees(self.angle):.2f} deg{at}, outside the joint range "
                f"|alpha| <= {math.degrees(self.alpha_max):.2f} deg (geometry.alpha_max)")


class JointRangeError(RuntimeError):
    """A simulated run left the joint range; ``excursion`` says where."""

    def __init__(self, excursion: Excursion) -> None:
        # the runner's message names the time already (closed loop stopped at t = ...)
        super().__init__(f"the neck left its joint range: {excursion.describe(with_time=False)}")
        self.excursion = excursion

    def __reduce__(self):          # rebuilt from the excursion (other processes, pickling)
        return type(self), (self.excursion,)


def first_excursion(t: npt.ArrayLike, alpha: npt.ArrayLike, alpha_max: float) -> Excursion | None:
    """The first sample of ``alpha`` (T, N) rad at times ``t`` (T,) s with some |alpha_j| >
    ``alpha_max`` (rad; the lowest such joint of that sample), or None if every sample is in range.
    A NaN angle counts as out of range (a diverged plant)."""
    a, times = np.asarray(alpha, dtype=float), np.asarray(t, dtype=float)
    if a.ndim != 2 or times.shape != a.shape[:1]:
        raise ValueError(f"alpha: expected (T, N) angles at T times, got shapes {a.shape} and {times.shape}")
    outside = ~(np.abs(a) <= alpha_max)
    if not outside.any():
        return None
    k, j = (int(v) for v in np.unravel_index(int(np.argmax(outside)), outside.shape))
    return Excursion(k, float(times[k]), j, float(a[k, j]), float(alpha_max))
