"""Diagnosis settings and the baseline model named on the command line (``--model``)."""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field

from identification.diagnosis.candidates import ModelSpec, effect_names, paper_model
from identification.diagnosis.support import SupportSettings
from identification.preprocessing import PreprocessSettings
from neck_sim.effects import CableElasticity, DryFriction


#: ``--model`` shortcuts (any comma-separated list of effect names is also accepted).
MODEL_SHORTCUTS = {
    "paper": paper_model(),
    "rigid": (),                                   # rigid cables, no friction: eq (25)
    "rigid-frictionless": (),
    "rigid-friction": (DryFriction.name,),
    "linear": (DryFriction.name, CableElasticity.name),  # Table 1's constant stiffness
}


#: What names a baseline model: a :class:`ModelSpec`, a shortcut or effect list, a model JSON path,
#: or None (the paper's).
ModelLike = ModelSpec | str | os.PathLike | None



def read_model_file(path: str | os.PathLike, keys: tuple[str, ...], what: str) -> dict:
    """The JSON object of a model file written by ``neck-sim diagnose --extended`` that holds
    ``keys`` (``what`` says them in the error); ValueError in one line naming what is wrong."""
    try:
        with open(path, "rb") as fh:
            data = json.loads(fh.read())
    except OSError as exc:
        raise ValueError(f"--model {path}: cannot read ({exc.strerror})") from None
    except json.JSONDecodeError as exc:
        raise ValueError(f"--model {path}: not JSON ({exc})") from None
    if not isinstance(data, dict) or not set(keys) <= set(data):
        raise ValueError(f"--model {path}: expected a model file written by 'neck-sim diagnose --extended' "
                         f"(with {what})")
    return data


def parse_model(spec: ModelLike) -> ModelSpec:
    """A model from a shortcut (:data:`MODEL_SHORTCUTS`), a comma-separated list of effect names,
    a :class:`ModelSpec`, or a model JSON file written by a previous diagnosis (``model`` list)."""
    if isinstance(spec, ModelSpec):
        return spec
    if spec is None:
        return ModelSpec.of(*paper_model())
    s = str(spec).strip()
    if s.endswith(".json") or os.path.sep in s:
        return ModelSpec.from_list(read_model_file(s, ("model",), "a 'model' list of terms")["model"])
    if s in MODEL_SHORTCUTS:
        return ModelSpec.of(*MODEL_SHORTCUTS[s])
    names = [x.strip() for x in s.split(",") if x.strip() and x.strip() != "none"]
    unknown = [x for x in names if x not in effect_names()]
    if unknown:
        raise ValueError(f"model: unknown {', '.join(unknown)} (shortcuts: {', '.join(MODEL_SHORTCUTS)}; "
                         f"effects: {', '.join(effect_names())})")
    return ModelSpec.of(*names)


@dataclass(frozen=True)
class StructureSettings:
    """``alpha``: family-wise false-alarm level (Bonferroni over every test); ``min_rho``: the
    smallest |correlation| with a state feature that counts as structure; ``min_rho_white``: the
    same for the lag-one autocorrelation at the filter's bandwidth.  The defaults sit above what
    noise-only logs of the simulated prototype give (README, "Detection power"); the tests are in
    :mod:`identification.diagnosis.structure`.  ``min_rho_named``: the same beside a name the
    diagnosis found: a fitted effect whose form differs from the true one leaves structure of its
    own (over the open-world generator's forms at their test magnitudes, 3 seeds: up to |rho| =
    0.79, a hidden spring error's leftover; out-of-vocabulary creep and a camera scale error leave
    0.81-0.89 beside the name they borrow), so beside a name only a stronger leftover says
    ``unexplained``."""

    alpha: float = 0.01
    min_rho: float = 0.35
    min_rho_white: float = 0.6
    min_rho_named: float = 0.8
    alpha_hat: bool = True

    def __post_init__(self):
        if not (0 < self.alpha < 1 and 0 < self.min_rho < 1 and 0 < self.min_rho_white < 1
                and 0 < self.min_rho_named < 1):
            raise ValueError("structure: alpha, min_rho, min_rho_named and min_rho_white must lie in (0, 1)")


@dataclass(frozen=True)
class DiagnosisSettings:
    """Method settings of the diagnosis (see the module docstring)."""

    moves_per_block: int = 3
    holdout_every: int = 3
    chunk_s: float = 0.25
    min_improvement: float = 0.02
    alpha: float = 0.01
    max_steps: int = 3
    candidates: tuple = field(default_factory=effect_names)     # every registered effect
    resimulate: bool = True
    alpha_hat: bool = True
    iterations: int = 3
    preprocess: PreprocessSettings = field(default_factory=PreprocessSettings)
    structure: StructureSettings = field(default_factory=StructureSettings)     # the tests behind an UNEXPLAINED verdict
    support: SupportSettings = field(default_factory=SupportSettings)    # what a log needs for a verdict
    # a decision within this margin of a threshold is ``borderline``: relative for the improvement
    # and the structure z and rho, decades for p values
    borderline: float = 0.1
    borderline_decades: float = 0.3
    # the held-out test may also be read on the candidate's best channel (times the N + C channels
    # it may pick): an effect on one cable or joint is diluted by the other channels' noise when pooled
    channel_holdout: bool = True

    def __post_init__(self):
        if self.moves_per_block < 1 or self.holdout_every < 2:
            raise ValueError("moves_per_block must be >= 1 and holdout_every >= 2")
        if not (self.borderline > 0 and self.borderline_decades > 0):
            raise ValueError("borderline and borderline_decades must be > 0")
        if not (0 < self.alpha < 1 and 0 <= self.min_improvement < 1 and self.chunk_s > 0):
            raise ValueError("alpha in (0, 1), min_improvement in [0, 1), chunk_s > 0")
        unknown = [c for c in self.candidates if c not in effect_names()]
        if unknown:
            raise ValueError(f"candidates: unknown {unknown}")

    def to_dict(self) -> dict:
        """The method settings (the pre-processing's are recorded with the data)."""
        return {"moves_per_block": self.moves_per_block, "holdout_every": self.holdout_every, "chunk_s": self.chunk_s,
                "min_improvement": self.min_improvement, "alpha": self.alpha, "max_steps": self.max_steps,
                "candidates": list(self.candidates), "resimulate": self.resimulate, "alpha_hat": self.alpha_hat,
                "iterations": self.iterations, "borderline": self.borderline,
                "borderline_decades": self.borderline_decades, "channel_holdout": self.channel_holdout,
                "support": self.support.to_dict(), "structure": {"alpha": self.structure.alpha,
                                                             "min_rho": self.structure.min_rho,
                                                             "min_rho_white": self.structure.min_rho_white,
                                                             "min_rho_named": self.structure.min_rho_named}}
