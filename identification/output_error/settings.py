"""Settings of the output-error fit (light: the command line reads its defaults)."""

from __future__ import annotations

from dataclasses import dataclass

from identification.output_error.misfit import MISFIT_RATIO

__all__ = ["OutputErrorSettings"]


@dataclass(frozen=True)
class OutputErrorSettings:
    """``integrator``: MuJoCo integrator for every rollout of the fit (None: ``integrator_for`` at
    the start point); ``max_evaluations``: cost evaluations of the trust region (each one rollout
    per experiment, besides the Jacobians' p); ``rel_step``: finite-difference step relative to
    the parameter scale; ``xtol``/``ftol``: scipy's relative tolerances; ``misfit_ratio``: see
    :mod:`identification.output_error.misfit`; ``first_horizon_s`` s and ``horizon_growth``: the
    spans the fit grows through (:func:`identification.output_error.fit.horizons`)."""

    integrator: str | None = None
    first_horizon_s: float = 2.0
    horizon_growth: float = 4.0
    max_evaluations: int = 12
    rel_step: float = 1e-5
    xtol: float = 1e-7
    ftol: float = 1e-9
    misfit_ratio: float = MISFIT_RATIO

    def __post_init__(self):
        if self.integrator is not None:
            from neck_sim.plant import INTEGRATORS

            if self.integrator not in INTEGRATORS:
                raise ValueError(f"integrator: unknown {self.integrator!r} (known: {', '.join(INTEGRATORS)})")
        if not (isinstance(self.max_evaluations, int) and self.max_evaluations >= 1):
            raise ValueError(f"max_evaluations: must be a positive integer, got {self.max_evaluations!r}")
        if not self.horizon_growth > 1:
            raise ValueError(f"horizon_growth: must exceed 1, got {self.horizon_growth!r}")
        for name in ("rel_step", "xtol", "ftol", "misfit_ratio", "first_horizon_s"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name}: must be positive, got {getattr(self, name)!r}")
