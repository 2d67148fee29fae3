"""Discrepancy discovery: what the model gets wrong, which effect causes it, and the gain of adding it.

``diagnose_log(log)`` reads only the measured topics of a log (motors, camera) and its ``neck``
record and runs, from a baseline model (the paper's: arctan friction + variable-stiffness cables,
or any :class:`~identification.diagnosis.candidates.ModelSpec`, e.g. ``"rigid"`` for eq 25):

1. **Split** (:func:`split_samples`) the slow-grid samples into contiguous blocks of about three
   moves (half a §5.2.2 sequence), cut in the middle of holds found from the motor speeds, and
   deal the blocks to K = 3 folds in turn.  Never at random: neighbouring samples are correlated.
   Residuals are **cross-validated**: each block is predicted by the model fitted on the other
   folds, so every sample is held out once.  The *primary* split (train on folds 0 and 2, hold
   out fold 1) gives the parameters, the shape searches, the training F-test, the written model
   and the alpha_hat and re-simulation comparisons.
2. **Baseline**: fit the model (:func:`identification.diagnosis.candidates.fit_model`) and evaluate its
   residuals -- joint torque (eq 51), cable tension (eq 42/54, N) and elongation (m) --,
   alpha_hat against the camera (eq 35 with the model's elongation) and an open-loop
   re-simulation of the plant driven by the logged forces.
3. **Candidates**: every effect of the vocabulary not yet in the model (and whose prerequisite
   is: Stribeck needs dry friction, stiffening and pretension need elastic cables), added with
   its parameters per cable where it is per cable, its shape parameters chosen on the training
   folds (a grid refined by a bounded 1-D search, scipy's ``minimize_scalar``; a bounded search
   per cable for the rest elongation), then cross-validated.
4. **Score** ``S``: the mean square residual of each channel (N joint torques, m cable
   elongations) divided by the square of the baseline's primary training RMS of that channel,
   averaged within each residual type and then over the two types (each equation type counts
   one half, as the paper's weight W = 100 balances them).  A candidate is **significant** when
   all of these hold:

   * cross-validated (held-out) improvement ``1 - S_cand / S_base >= min_improvement`` (2 %);
   * a one-sided Wilcoxon signed-rank test of the per-chunk score reductions over chunks of
     ``chunk_s`` (0.25 s, within blocks) gives p < ``alpha`` (0.01);
   * a training F-test counting the added parameters (linear ones plus searched shape
     parameters), with one effective sample per 1/(2 f_c) s per channel (f_c: the common filter
     cutoff: the residuals are low-passed), gives p < ``alpha``;
   * its fitted magnitudes have the physical sign (a friction that helps the motion is a shape
     correction of another friction, not this effect).

   The verdict is the significant candidate with the largest improvement, ``none`` when there is
   none.  **Look-alikes** are settled by an encompassing test: the leader A and each other
   significant candidate B are fitted together; if B adds nothing significant to A but A adds to
   B, A stands; if A adds nothing to B but B adds to A, B replaces A; if neither adds to the other
   the data cannot tell them apart and the verdict lists both (ambiguous), never a guess.
5. **Extension and gain**: the model plus the verdict is written as plant parameters and effects
   (:func:`identification.diagnosis.candidates.plant_model`) and compared with the baseline on held-out
   data: cross-validated residual RMS per type, alpha_hat error against the camera, re-simulation
   error in theta and alpha.  Forward selection repeats 3-5 from the extended model until nothing
   significant remains (at most ``max_steps`` findings).

The result (:class:`Diagnosis`) is typed: ``verdict``, ``findings`` (:class:`Finding`: effect,
cables or joints, parameters, evidence, :class:`Gain`), ``baseline`` and ``final``
(:class:`ModelSummary`), ``extended`` (:class:`ExtendedModel`), ``steps``.  Its ``to_dict()`` has
the stable JSON fields ``verdict`` (an effect name, a list of names when ambiguous, or "none"),
``findings`` (ordered; each with ``effect``, ``cables``, ``parameters``, ``evidence``, ``gain``)
and ``baseline`` (plus ``final``, ``extended_model``, ``steps``, ``split``, ``settings`` and
``method``, the method text written from the settings used).

The stages, one module each: :mod:`~identification.diagnosis.settings`,
:mod:`~identification.diagnosis.split`, :mod:`~identification.diagnosis.statistics`,
:mod:`~identification.diagnosis.fitting`, :mod:`~identification.diagnosis.search`,
:mod:`~identification.diagnosis.candidate`, :mod:`~identification.diagnosis.selection`,
:mod:`~identification.diagnosis.gains`, :mod:`~identification.diagnosis.resimulation`,
:mod:`~identification.diagnosis.parameters`, :mod:`~identification.diagnosis.result`,
:mod:`~identification.diagnosis.pipeline`.  What they work on: the log's data
(:mod:`~identification.diagnosis.measured`), the model and its fit
(:mod:`~identification.diagnosis.candidates`), each effect's columns over the typed data
protocol (:mod:`~identification.diagnosis.columns`, one module per effect), the report
(:mod:`~identification.diagnosis.report`); the blind-test generator
(:mod:`~identification.diagnosis.blind`) with its hiding forms
(:mod:`~identification.diagnosis.blind_forms`, one per effect).
"""

from identification.diagnosis.candidate import CandidateScore
from identification.diagnosis.gains import AlphaHatErrors, AngleErrors, ResidualRMS, alpha_hat_errors
from identification.diagnosis.parameters import Parameter
from identification.diagnosis.pipeline import diagnose, diagnose_log
from identification.diagnosis.resimulation import Resimulation, ResimulationErrors, resimulate
from identification.diagnosis.result import Diagnosis, ExtendedModel, Finding, Gain, ModelSummary, method_text
from identification.diagnosis.selection import Step
from identification.diagnosis.settings import MODEL_SHORTCUTS, DiagnosisSettings, parse_model
from identification.diagnosis.split import Split, split_samples
from identification.diagnosis.statistics import channel_weights, score

__all__ = ["DiagnosisSettings", "Split", "split_samples", "CandidateScore", "Step", "Diagnosis", "Finding", "Gain",
           "ModelSummary", "ExtendedModel", "Parameter", "ResidualRMS", "AngleErrors", "AlphaHatErrors", "Resimulation",
           "ResimulationErrors", "diagnose", "diagnose_log", "parse_model", "MODEL_SHORTCUTS", "method_text", "score",
           "channel_weights", "resimulate", "alpha_hat_errors"]
