"""Settings of the output-error fit (light: the command line reads its defaults)."""

from __future__ import annotations

from dataclasses import dataclass

from identification.output_error.misfit import MISFIT_RATIO

__all__ = ["OutputErrorSettings"]

_JACOBIAN_INTEGRATOR = "discrete"


@dataclass(frozen=True)
class OutputErrorSettings:
    """``integrator``: MuJoCo integrator for every rollout of the fit (None: ``integrator_for`` of
    the nominal constants, :func:`identification.output_error.fit.choose_integrator`); ``max_evaluations``: trial steps of the solver (each one rollout per
    experiment, besides the finite-difference Jacobians' p); ``rel_step``: finite-difference step
    relative to the parameter scale; ``xtol``: the solver's relative tolerance on the step;
    ``ftol``: its absolute tolerance on the cost, half the chi-square of the noise-weighted
    residuals (:mod:`identification.output_error.solver`); ``misfit_ratio``: see
    :mod:`identification.output_error.misfit`.

    The Jacobian's columns of the parameter groups ``jacobian_groups`` are forward differences of
    rollouts on a cheaper model: physics step ``jacobian_timestep`` s (it must divide the control
    period; None: every column on the fit's own model) on ``jacobian_integrator`` (None: the
    fit's).  Only the
    Jacobian is approximate: the start, every trial step and the accepted point are simulated on
    the fit's model, so the solver still converges to the minimiser of the true cost (at J_a^T r = 0
    instead of J^T r = 0, which differ by (J_a - J)^T r: noise times the columns' error).  The
    defaults are measured on the 85 s identification run (docs/identification.md, "Output-error
    identification"): at 2 ms on ``discrete`` a rollout costs 0.42 of the plant's (0.5 ms,
    ``implicitfast``), stays bounded over the whole run at the least-squares start and at the
    truth (``implicitfast`` at 1 ms diverges there: c_a dt is too large for the bars), and the
    f_s, k and lambda columns are within 1.3 % of the plant's on a 10 s window; the c_a columns
    are 60-70 % off (the integrator's own damping), so c_a and every effect magnitude stay on the
    fit's model.  A coarse column whose rollout diverges is taken on the fit's model instead."""

    integrator: str | None = None
    max_evaluations: int = 30
    rel_step: float = 1e-5
    xtol: float = 1e-7
    ftol: float = 0.01
    misfit_ratio: float = MISFIT_RATIO
    jacobian_timestep: float | None = 2e-3
    jacobian_integrator: str = _JACOBIAN_INTEGRATOR
    jacobian_groups: tuple = ("f_s", "k", "lambda")

    def __post_init__(self):
        for name, default in (("integrator", None), ("jacobian_integrator", _JACOBIAN_INTEGRATOR)):
            value = getattr(self, name)
            if value is not None and value != default:      # the defaults need no check, and the check imports MuJoCo
                from neck_sim.plant import INTEGRATORS

                if value not in INTEGRATORS:
                    raise ValueError(f"{name}: unknown {value!r} (known: {', '.join(INTEGRATORS)})")
        if not (isinstance(self.max_evaluations, int) and self.max_evaluations >= 1):
            raise ValueError(f"max_evaluations: must be a positive integer, got {self.max_evaluations!r}")
        for name in ("rel_step", "xtol", "ftol", "misfit_ratio"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name}: must be positive, got {getattr(self, name)!r}")
        if self.jacobian_timestep is not None and not self.jacobian_timestep > 0:
            raise ValueError(f"jacobian_timestep: must be positive seconds or None, got {self.jacobian_timestep!r}")
        if isinstance(self.jacobian_groups, str) or not all(isinstance(g, str) for g in self.jacobian_groups):
            raise ValueError(f"jacobian_groups: expected a tuple of parameter-group symbols, got "
                             f"{self.jacobian_groups!r}")
        object.__setattr__(self, "jacobian_groups", tuple(self.jacobian_groups))
