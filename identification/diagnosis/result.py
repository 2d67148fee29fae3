"""The result of a diagnosis: summaries of the models compared, findings with their gains, the
extended model and the method text, each a frozen dataclass whose ``to_dict()`` is its JSON."""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from identification.diagnosis.candidates import Fit, MeasuredData, ModelSpec, plant_model
from identification.diagnosis.candidate import CandidateScore
from identification.diagnosis.gains import AlphaHatErrors, ResidualRMS
from identification.diagnosis.parameters import Parameter, all_parameters
from identification.diagnosis.resimulation import Resimulation
from identification.diagnosis.settings import DiagnosisSettings
from identification.diagnosis.split import Split
from identification.diagnosis.structure import Leftover
from identification.diagnosis.support import ExcitationSummary
from neck_sim.effects import INSUFFICIENT_EXCITATION, NONE, UNEXPLAINED, Effects
from neck_sim.atomic import atomic_write_json, jsonable
from neck_sim.params import NeckParams, to_dict


def _params_dict(parameters: dict[str, Parameter]) -> dict:
    return {name: p.to_dict() for name, p in parameters.items()}


@dataclass(frozen=True, eq=False)
class ModelSummary:
    """One model the diagnosis compared (a step's baseline or the final extension): its
    parameters, residual RMS (cross-validated, primary held-out and training), alpha_hat against
    the camera and the re-simulation (None when not run), and its cross-validated residuals
    ``cv_residuals`` (S, N + C) for plots."""

    model: ModelSpec
    parameters: dict
    residual_rms_crossvalidated: ResidualRMS
    residual_rms_holdout: ResidualRMS
    residual_rms_train: ResidualRMS
    alpha_hat_vs_camera: AlphaHatErrors | None
    resimulation: Resimulation | None
    cv_residuals: np.ndarray

    @property
    def description(self) -> str:
        return self.model.describe()

    def to_dict(self) -> dict:
        out = {"model": self.model.to_list(), "description": self.description,
               "parameters": _params_dict(self.parameters),
               "residual_rms_crossvalidated": self.residual_rms_crossvalidated.to_dict(),
               "residual_rms_holdout": self.residual_rms_holdout.to_dict(),
               "residual_rms_train": self.residual_rms_train.to_dict()}
        if self.alpha_hat_vs_camera is not None:
            out["alpha_hat_vs_camera"] = self.alpha_hat_vs_camera.to_dict()
        if self.resimulation is not None:
            out["resimulation"] = self.resimulation.to_dict()
        return out


@dataclass(frozen=True, eq=False)
class Gain:
    """What a finding changed: the model before and after it (held-out residual RMS, alpha_hat
    and re-simulation on the primary held-out fold where both models have them)."""

    before: ModelSummary
    after: ModelSummary

    def to_dict(self) -> dict:
        b, a = self.before, self.after
        out = {"residual_rms_crossvalidated": {"before": b.residual_rms_crossvalidated.to_dict(),
                                               "after": a.residual_rms_crossvalidated.to_dict()},
               "residual_rms_holdout": {"before": b.residual_rms_holdout.to_dict(),
                                        "after": a.residual_rms_holdout.to_dict()}}
        if b.alpha_hat_vs_camera is not None and a.alpha_hat_vs_camera is not None:
            out["alpha_hat_vs_camera_holdout"] = {"before": b.alpha_hat_vs_camera.holdout.to_dict(),
                                                  "after": a.alpha_hat_vs_camera.holdout.to_dict()}
        if b.resimulation is not None and a.resimulation is not None:
            out["resimulation_holdout"] = {"before": b.resimulation.holdout.to_dict(),
                                           "after": a.resimulation.holdout.to_dict()}
        return out


@dataclass(frozen=True, eq=False)
class Finding:
    """An effect forward selection accepted at ``step`` (1-based): its name (a list of names when
    the data cannot tell look-alikes apart), where it acts (1-based cables or joints, None when
    not per cable or joint), its fitted parameters, the evidence, the gain, and the structure the
    final model still leaves in the residuals (``leftover``: empty when the findings explain the
    data to within noise; else the finding is no clean explanation)."""

    step: int
    effect: object
    cables: list | None
    joints: list | None
    parameters: dict
    evidence: CandidateScore
    gain: Gain
    leftover: tuple = ()

    def to_dict(self) -> dict:
        return {"effect": self.effect, "cables": self.cables, "joints": self.joints,
                "parameters": _params_dict(self.parameters), "evidence": self.evidence.evidence(),
                "gain": self.gain.to_dict(), "step": self.step, "model_after": self.gain.after.description,
                "leftover": [x.to_dict() for x in self.leftover[:5]]}


@dataclass(frozen=True, eq=False)
class ExtendedModel:
    """The final model as terms, plant parameters and effects (``--model`` reads its JSON back)."""

    model: ModelSpec
    params: NeckParams
    effects: Effects
    rigid_cables: bool
    parameters: dict

    @classmethod
    def of(cls, fit: Fit, nominal: NeckParams) -> "ExtendedModel":
        params, effects, rigid = plant_model(fit, nominal)
        return cls(fit.model, params, effects, rigid, all_parameters(fit))

    def to_dict(self) -> dict:
        return {"model": self.model.to_list(), "description": self.model.describe(), "rigid_cables": self.rigid_cables,
                "params": to_dict(self.params), "effects": self.effects.to_dict(),
                "parameters": _params_dict(self.parameters)}


def method_text(s: DiagnosisSettings) -> dict:
    """The method, in words, with the settings actually used."""
    train = ", ".join(str(f) for f in range(s.holdout_every) if f != 1)
    return {
        "split": f"contiguous blocks of about {s.moves_per_block} moves cut in holds, assigned to {s.holdout_every} "
                 "folds in turn; residuals cross-validated (each block predicted by the model fitted on the other "
                 f"folds); the primary split trains on folds {train} and holds fold 1 out (alpha_hat, "
                 "re-simulation, written model)",
        "score": "S = per channel (N torque, m elongation) mean square residual / (primary baseline training "
                 "RMS)^2, averaged within each residual type, then over the two types",
        "significance": f"cross-validated improvement 1 - S_cand/S_base >= min_improvement ({s.min_improvement:g}), "
                        f"one-sided Wilcoxon signed-rank test over {s.chunk_s:g} s chunks and "
                        "training F-test counting the added linear and searched shape parameters (one effective "
                        f"sample per 1/(2 f_c) s per channel) both p < alpha ({s.alpha:g}) / the candidates of the "
                        "step (Bonferroni: the step's false-alarm level is alpha), fitted magnitudes of "
                        f"physical sign; a decision within {s.borderline:g} (relative) or {s.borderline_decades:g} "
                        "decades of p of a threshold is borderline",
        "held_out_p": "a candidate's held-out p (JSON p_holdout_wilcoxon, the report's p (held out)) is the "
                      "Wilcoxon test's over the chunks of the whole score"
                      + (" or, when smaller, its best residual channel's times the N + C channels (its note names "
                         "the channel)" if s.channel_holdout else "")
                      + "; both p values of a term searched joint by joint or cable by cable are times its places "
                      "(2 for every joint or cable, 2 N or 2 C on one), and a one-joint term is held to the better "
                      "of that and its joint's torque channel in its band, both times 2 more (its note says "
                      "'measured on its own channel' for the latter)",
        "look_alikes": "encompassing test between the leader and every other significant candidate: fitted "
                       "together, the one that adds nothing significant to the other (improvement >= "
                       f"{s.min_improvement / 2:g}, p < {s.alpha:g}) is dropped; if neither adds, the verdict lists "
                       "both (ambiguous)",
        "selection": f"forward selection, at most {s.max_steps} findings; one-parameter shapes found earlier re-tuned "
                     "at each step",
    }


@dataclass(frozen=True, eq=False)
class Diagnosis:
    """The whole diagnosis of one log (see :meth:`to_dict` for the stable JSON fields).

    ``steps``: the forward-selection steps (:class:`~identification.diagnosis.selection.Step`);
    ``findings``: one :class:`Finding` per accepted effect; ``summaries``: the models compared
    (each step's baseline, then the final extension); ``extended``: the final model;
    ``timings``: seconds per stage; ``data``: the measured data diagnosed.
    """

    source: str
    model: ModelSpec
    split: Split | None
    steps: tuple
    findings: tuple
    summaries: tuple
    extended: ExtendedModel | None
    timings: dict
    settings: DiagnosisSettings
    data: MeasuredData | None = None
    leftover: Leftover | None = None
    notes: tuple = ()
    gaps: tuple = ()               # support.Gap: what the log cannot separate
    excitation: ExcitationSummary | None = None

    @classmethod
    def without_fit(cls, source: str, model: ModelSpec, settings: DiagnosisSettings, gaps: tuple,
                    excitation: ExcitationSummary | None, notes: tuple = (),
                    data: MeasuredData | None = None) -> "Diagnosis":
        """The diagnosis of a log that cannot support even the baseline's fit (its fatal ``gaps``
        say why): verdict ``insufficient_excitation``, no split, steps, models or findings."""
        return cls(source, model, None, (), (), (), None, {}, settings, data, None, tuple(notes), tuple(gaps),
                   excitation)

    @property
    def insufficient(self) -> bool:
        """The log cannot support a verdict (a fatal gap)."""
        return any(g.fatal for g in self.gaps)

    @property
    def verdict(self) -> str | list[str]:
        """``insufficient_excitation`` when the log cannot support a verdict; else the names the
        forward steps found (one name, or a list: several findings, or look-alikes the data
        cannot tell apart), "none" when nothing was found, with ``UNEXPLAINED`` when the final
        model leaves structure beyond noise: alone instead of "none", appended to the names
        otherwise (a name whose gain does not stand without that structure, the leftover's
        ``borrowed``, is left out).  ``insufficient_excitation`` also instead of "none" when a
        candidate passed its tests but was refused (:attr:`unattributed`): the model does not
        explain the data to within its noise, and the log cannot say what it lacks."""
        if self.insufficient:
            return INSUFFICIENT_EXCITATION
        names = []
        for st in self.steps:
            if st.chosen is None:
                break
            for n in (st.verdict if isinstance(st.verdict, list) else [st.verdict]):
                if n not in names and (self.leftover is None or n not in self.leftover.borrowed):
                    names.append(n)
        if self.leftover is not None and self.leftover.significant:
            names.append(UNEXPLAINED)
        if not names:
            return INSUFFICIENT_EXCITATION if self.unattributed else NONE
        return names[0] if len(names) == 1 else names

    @property
    def unattributed(self) -> tuple:
        """The candidates that passed their tests but were not named because the log cannot
        separate them from the baseline (``CandidateScore.refused``: a rest elongation on a cable
        whose tension never spans 15 N): a gain beyond noise that the log cannot attribute."""
        return tuple(c for st in self.steps for c in st.candidates if c.refused)

    def margins(self) -> dict:
        """How far the verdict is from flipping, in borderline bands (> 1: clear): per step, the
        candidate closest to its significance decision (either side: a named effect's weakest
        test, a rejected one's largest shortfall; :func:`~identification.diagnosis.statistics.
        in_band`), and the structure test's closest decision."""
        out = {}
        for i, st in enumerate(self.steps):
            valid = [c for c in st.candidates if np.isfinite(c.margin)]
            if valid:
                c = min(valid, key=lambda c: abs(c.margin))
                out[f"step_{i + 1}"] = {"candidate": c.term.name, "margin_in_bands": c.margin,
                                        "named": c is st.chosen, "margins": c.margins}
        if self.leftover is not None:
            out["structure"] = self.leftover.margin_dict()
        return out

    @property
    def borderline(self) -> bool:
        """A decision of this verdict lies within one borderline band of its threshold."""
        return any(abs(m.get("margin_in_bands", np.inf)) < 1.0 for m in self.margins().values())

    @property
    def baseline(self) -> ModelSummary | None:
        return self.summaries[0] if self.summaries else None

    @property
    def final(self) -> ModelSummary | None:
        return self.summaries[-1] if self.summaries else None

    def to_dict(self) -> dict:
        return jsonable({"verdict": self.verdict, "borderline": self.borderline, "margins": self.margins(),
                         "gaps": [g.to_dict() for g in self.gaps],
                         "excitation": None if self.excitation is None else self.excitation.to_dict(),
                         "findings": [f.to_dict() for f in self.findings],
                         UNEXPLAINED: None if self.leftover is None else self.leftover.to_dict(),
                         "notes": list(self.notes),
                         "baseline": self.baseline and self.baseline.to_dict(),
                         "final": self.final and self.final.to_dict(),
                         "extended_model": self.extended and self.extended.to_dict(),
                         "steps": [s.to_dict(i) for i, s in enumerate(self.steps)],
                         "split": self.split and self.split.to_dict(), "source": self.source, "timings_s": self.timings,
                         "method": method_text(self.settings), "settings": self.settings.to_dict()})

    def write_json(self, path: str | os.PathLike) -> None:
        atomic_write_json(path, self.to_dict())

    def write_model(self, path: str | os.PathLike) -> None:
        """The final model (terms, plant parameters, effects) as JSON; ``--model`` reads it back.
        ValueError when there is none (the log could not support the baseline's fit)."""
        if self.extended is None:
            raise ValueError("no model: the log is too short or too still for a fit (insufficient_excitation)")
        atomic_write_json(path, self.extended.to_dict())

