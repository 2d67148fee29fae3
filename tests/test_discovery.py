"""Blind tests of the diagnosis: hide an effect in the plant, diagnose the log.

The effects that the open-world generator hides by mechanisms of its own (friction laws, springs,
payload, delays, pretension, joint friction, camera delay) are tested in
``test_discovery_open.py``; here remain the cable effects the plant hides through its native C
callback (eq 54 cables, the pulley friction's C kernel) and the paper's story.

Every log is a 20.8 s identification-like run (3 of the §5.2.2 sequences, 0.9 s moves) of the
MuJoCo plant with one effect hidden at the test magnitude of ``identification.diagnosis.blind.MAGNITUDES``
(times a factor in [0.8, 1.25]) on a cable or joint drawn from the seed; the forms differ from
the candidates' own where the vocabulary allows (another Stribeck speed and smoothing, a sharper
or a tanh-smoothed dry-friction sign, friction on one cable only, another pulley smoothing, a
delay off the search grid).  The diagnosis reads the log blind (measured topics only) and must

* name the hidden effect (exactly, not as one of an ambiguous pair),
* improve the cross-validated held-out score by at least ``MARGIN`` (5 %),
* locate it (the cable or joint) and estimate its magnitude within a stated tolerance
  (the truth comes from the blind case, the estimate from the fit: two independent numbers).

The noise-only control must give ``none``; from a rigid frictionless model the default plant
must give the paper's story: dry friction, then cable elasticity, then tension stiffening.
Logs are made once per module (about 1.5 s each); a fast diagnosis (one step, no re-simulation,
no alpha_hat) takes 1-3 s.
"""

from __future__ import annotations

import re

import numpy as np
import pytest

from identification.diagnosis.blind import make_case
from identification.diagnosis import DiagnosisSettings, diagnose_log

SEED = 3
MARGIN = 0.05
FAST = DiagnosisSettings(max_steps=1, resimulate=False, alpha_hat=False)


@pytest.fixture(scope="module")
def blind(tmp_path_factory):
    """name -> (BlindCase, log path), simulated on first use."""
    directory = tmp_path_factory.mktemp("blind")
    cache = {}

    def get(name: str):
        if name not in cache:
            cache[name] = make_case(name, SEED, directory / f"{name.replace(':', '_')}.mcap",
                                    write_truth=name == "none")
        return cache[name]

    return get


def _param(finding, name):
    return finding.parameters[name].value


# effect -> check of the finding against the hidden truth (case.effects / case.params)
def _check_pulley(f, case):
    j = case.cables[0]
    assert _param(f, f"mu({j + 1})") == pytest.approx(case.effects.pulley_friction.mu, rel=0.25)


def _check_elasticity(f, case):
    k = np.array([_param(f, f"k({i + 1})") for i in range(4)])
    # a linear cable fitted to the plant's stiffening cables (Table 1 vs Table 2): between the
    # plant's small-tension stiffness k and its stiffness at 80 N, k + lambda 80
    plant_k = np.asarray(case.effects.cable_elasticity.k)
    assert np.all(k > plant_k) and np.all(k < plant_k + np.asarray(case.params.cables.lam) * 80.0)


def _check_stiffening(f, case):
    lam = np.array([_param(f, f"lambda({i + 1})") for i in range(4)])
    np.testing.assert_allclose(lam, case.effects.tension_stiffening.lam, rtol=0.3)


CHECKS = {"pulley_friction": _check_pulley, "cable_elasticity": _check_elasticity,
          "tension_stiffening": _check_stiffening}


@pytest.mark.parametrize("name", list(CHECKS))
def test_hidden_effect_is_named_located_and_measured(blind, name):
    case, path = blind(name)
    diag = diagnose_log(path, model=",".join(case.model) or "rigid", settings=FAST)
    # first name: a one-step diagnosis of elastic cables from a rigid model leaves the plant's
    # tension stiffening, which the structure tests may add as "unexplained"
    first = diag.verdict[0] if isinstance(diag.verdict, list) else diag.verdict
    assert first == case.expect, (case.description, diag.to_dict()["steps"][0]["candidates"][:3])
    finding = diag.findings[0]
    assert finding.effect == case.expect
    assert finding.evidence.improvement >= MARGIN
    assert finding.evidence.significant
    if case.joints:
        assert finding.joints == [j + 1 for j in case.joints]
    elif case.cables:
        assert finding.cables == [c + 1 for c in case.cables]
    CHECKS[name](finding, case)
    # the extended model predicts the held-out residual of its own kind better
    g = finding.gain
    kind = "elongation_m" if name in ("cable_elasticity", "tension_stiffening", "pretension") else "torque_Nm"
    assert np.mean(getattr(g.after.residual_rms_crossvalidated, kind)) < \
        np.mean(getattr(g.before.residual_rms_crossvalidated, kind))


def test_negative_control_gives_none(blind):
    case, path = blind("none")
    diag = diagnose_log(path, model="paper", settings=FAST)
    assert diag.verdict == "none"
    assert diag.findings == ()
    best = max(c.improvement for c in diag.steps[0].candidates)
    assert best < 0.02


def test_paper_story_from_a_rigid_frictionless_model(blind):
    """§5: friction first (eqs 46-47), then elasticity (Table 1), then stiffening (Table 2)."""
    _, path = blind("none")
    diag = diagnose_log(path, model="rigid", settings=DiagnosisSettings(max_steps=4, resimulate=False))
    assert [f.effect for f in diag.findings] == ["dry_friction", "cable_elasticity", "tension_stiffening"]
    assert diag.steps[-1].verdict == "none"
    # each step removes most of the error it targets
    f1, f2, f3 = diag.findings
    t1 = (f1.gain.before.residual_rms_crossvalidated, f1.gain.after.residual_rms_crossvalidated)
    assert np.mean(t1[1].torque_Nm) < 0.1 * np.mean(t1[0].torque_Nm)
    e2 = (f2.gain.before.residual_rms_crossvalidated, f2.gain.after.residual_rms_crossvalidated)
    assert np.mean(e2[1].elongation_m) < 0.4 * np.mean(e2[0].elongation_m)
    e3 = (f3.gain.before.residual_rms_crossvalidated, f3.gain.after.residual_rms_crossvalidated)
    assert np.mean(e3[1].tension_N) < 0.5 * np.mean(e3[0].tension_N)
    # the identified friction is the plant's (Table 1), and alpha_hat improves as in §5.5
    fs = [_param(f1, f"f_s({i + 1})") for i in range(4)]
    np.testing.assert_allclose(fs, diag.data.params.friction.f_s, rtol=0.05)
    # beside f_s, the law's mean force per unit of each cable's travel over this log, written here
    speed = np.abs(diag.data.theta_dot_fast)
    law = np.asarray(fs) * (2 / np.pi) * np.arctan(_param(f1, "c_s") * speed)
    travel = [_param(f1, f"f_travel({i + 1})") for i in range(4)]
    np.testing.assert_allclose(travel, (law * speed).sum(axis=0) / speed.sum(axis=0), rtol=1e-9)
    # its sigma is f_s's eq (50) sigma scaled, and the summary labels it so, as it labels f_s
    from identification.diagnosis.report import format_summary
    summary = format_summary(diag)
    assert all(re.search(rf"f_travel\({i + 1}\) = \S+ ± \S+ N \(eq 50\)", summary) for i in range(4)), summary
    a0 = diag.baseline.alpha_hat_vs_camera.holdout.mean_abs_deg
    a1 = diag.final.alpha_hat_vs_camera.holdout.mean_abs_deg
    assert a1 < 0.75 * a0
