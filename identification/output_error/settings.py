"""Settings of the output-error fit (light: the command line reads its defaults)."""

from __future__ import annotations

from dataclasses import dataclass

from identification.output_error.misfit import MISFIT_RATIO

__all__ = ["OutputErrorSettings"]


@dataclass(frozen=True)
class OutputErrorSettings:
    """``integrator``: MuJoCo integrator for every rollout of the fit (None: ``integrator_for`` of
    the nominal constants, :func:`identification.output_error.fit.choose_integrator`); ``max_evaluations``: trial steps of the solver (each one rollout per
    experiment, besides the finite-difference Jacobians' p); ``rel_step``: finite-difference step
    relative to the parameter scale; ``xtol``: the solver's relative tolerance on the step;
    ``ftol``: its absolute tolerance on the cost, half the chi-square of the noise-weighted
    residuals (:mod:`identification.output_error.solver`); ``misfit_ratio``: see
    :mod:`identification.output_error.misfit`."""

    integrator: str | None = None
    max_evaluations: int = 30
    rel_step: float = 1e-5
    xtol: float = 1e-7
    ftol: float = 0.01
    misfit_ratio: float = MISFIT_RATIO

    def __post_init__(self):
        if self.integrator is not None:
            from neck_sim.plant import INTEGRATORS

            if self.integrator not in INTEGRATORS:
                raise ValueError(f"integrator: unknown {self.integrator!r} (known: {', '.join(INTEGRATORS)})")
        if not (isinstance(self.max_evaluations, int) and self.max_evaluations >= 1):
            raise ValueError(f"max_evaluations: must be a positive integer, got {self.max_evaluations!r}")
        for name in ("rel_step", "xtol", "ftol", "misfit_ratio"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name}: must be positive, got {getattr(self, name)!r}")
