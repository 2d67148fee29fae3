"""``spring_error``: side springs whose stiffness or rest length differs from nominal, one by one."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from neck_sim.effects.base import Effect
from neck_sim.params import NeckParams
from neck_sim.validation import finite, indices

__all__ = ["SpringError", "SIDES"]

SIDES = ("left", "right")
"""Order of the two side springs of a joint in per-spring arrays (index 2 (j - 1) + side)."""


def _per_spring(name: str, v, n_springs: int | None = None) -> tuple[float, ...] | None:
    if v is None:
        return None
    out = tuple(finite(f"{name}[{k}]", x) for k, x in enumerate(np.atleast_1d(v)))
    if n_springs is not None and len(out) != n_springs:
        raise ValueError(f"{name}: {len(out)} values for {n_springs} side springs (joint 1 left, joint 1 right, ...)")
    return out


@dataclass(frozen=True)
class SpringError(Effect):
    """Side springs differ from nominal.

    Symmetric form (``params.springs``): stiffness times ``stiffness_scale`` on ``joints`` (both
    sides), rest length plus ``rest_length_offset`` (m) on every spring.  Spring by spring:
    ``dk`` (2N,) N/m added to each spring's stiffness and ``dl0`` (2N,) m to its rest length, in
    the order joint 1 left, joint 1 right, joint 2 left, ...; the plant edits MuJoCo's
    ``tendon_stiffness`` / ``tendon_lengthspring`` of ``j{i}_spring_left/right``.
    """

    name: ClassVar[str] = "spring_error"
    description: ClassVar[str] = "a side spring stiffer, softer or longer than nominal (each spring on its own)"
    abbreviation: ClassVar[str] = "spring"            # column heads of tables
    kind: ClassVar[str] = "params"
    stiffness_scale: float = 1.0
    rest_length_offset: float = 0.0
    joints: tuple | None = None
    dk: tuple | None = None
    dl0: tuple | None = None

    def __post_init__(self):
        object.__setattr__(self, "stiffness_scale", finite("spring_error.stiffness_scale", self.stiffness_scale,
                                                           non_negative=True))
        object.__setattr__(self, "rest_length_offset", finite("spring_error.rest_length_offset",
                                                              self.rest_length_offset))
        object.__setattr__(self, "joints", indices("spring_error.joints", self.joints))
        object.__setattr__(self, "dk", _per_spring("spring_error.dk", self.dk))
        object.__setattr__(self, "dl0", _per_spring("spring_error.dl0", self.dl0))

    def check(self, params: NeckParams) -> None:
        super().check(params)
        _per_spring("spring_error.dk", self.dk, 2 * params.n_joints)
        _per_spring("spring_error.dl0", self.dl0, 2 * params.n_joints)

    def apply(self, params: NeckParams) -> NeckParams:
        k = np.asarray(params.springs.stiffness, dtype=float).copy()
        idx = np.arange(params.n_joints) if self.joints is None else np.asarray(self.joints)
        k[idx] *= self.stiffness_scale
        return params.replace(**{"springs.stiffness": tuple(k),
                                 "springs.rest_length": params.springs.rest_length + self.rest_length_offset})

    def setup_mujoco(self, model, data, index) -> None:
        ids = index.spring_tendon.reshape(-1)
        dk = np.zeros(ids.size) if self.dk is None else np.asarray(self.dk)
        dl0 = np.zeros(ids.size) if self.dl0 is None else np.asarray(self.dl0)
        k = index.spring_stiffness.reshape(-1) + dk
        if np.any(k < 0):
            raise ValueError(f"spring_error.dk: a spring stiffness would be negative ({k.round(1).tolist()} N/m)")
        model.tendon_stiffness[ids] = k
        model.tendon_lengthspring[ids] = (index.spring_length.reshape(-1) + dl0)[:, None]
