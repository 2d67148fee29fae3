"""Blind tests of the diagnosis on logs whose hidden effects share no code with its candidates.

The logs come from :mod:`open_world.generator` (MuJoCo model fields and formulas of its own; it
never imports :mod:`neck_sim.effects` or the diagnosis), three seeds per effect, the affected
cable / joint / spring and the magnitude (x 0.8..1.25) drawn from the seed.  Checks: the verdict
names the hidden effect (``unexplained`` for the effects outside the vocabulary, never a single
wrong name), where it acts, and its magnitude within 10 % (or the stated physical resolution).

Speed: 12.2 s logs and a one-step diagnosis without the open-loop re-simulation (neither is what
is tested here; the structure tests run on the one-step model); every candidate of the
vocabulary is tried.
"""

from __future__ import annotations

import ast
import os

import pytest

from identification.diagnosis import DiagnosisSettings, diagnose_log
from open_world.generator import OUT_OF_VOCABULARY, UNEXPLAINED, Multisine, make_spec, simulate

#: Seeds 1-2 in CI; seed 3 too with NECK_SIM_FULL_GRID=1 (``benchmarks/bench_detection.py --seeds
#: 1,2,3`` prints the whole table; the suite's time budget holds two).
SEEDS = (1, 2, 3) if os.environ.get("NECK_SIM_FULL_GRID") == "1" else (1, 2)
NAMED = ("spring_error", "joint_friction", "camera_delay", "viscous_friction", "dry_friction", "stribeck_friction",
         "payload", "actuation_delay", "actuation_delay_one", "pretension")
FAST = DiagnosisSettings(resimulate=False, max_steps=1)

#: Relative tolerance of each magnitude, 10 % unless stated.  (Joint friction holds 10 %: the
#: hinge forces MuJoCo applies along these logs saturate at the set frictionloss above ~0.1 rad/s
#: and the candidate's tanh column reads 1.01-1.08 of it.)  (The Stribeck bump has no magnitude
#: of the candidate's form: name and cable only.)
TOLERANCE = {name: 0.10 for name in NAMED}
#: Absolute tolerances where a physical resolution sets them: the rest elongation's profile sigma
#: is 0.3-1 mm on these 12 s logs (m)
ABSOLUTE = {"pretension": 0.5e-3}


def _lazy_diagnoses(root, excitation=None):
    """(name, seed) -> (spec, diagnosis), simulated into ``root`` and diagnosed once when first
    asked; ``excitation(spec, seed)`` the generator's excitation (None: its §5.2.2 sequences)."""
    cache = {}

    def get(name, seed):
        if (name, seed) not in cache:
            spec = make_spec(name, seed)
            extra = {} if excitation is None else {"excitation": excitation(spec, seed)}
            path = simulate(root / f"{name}_{seed}.mcap", spec, seed, **extra)
            cache[name, seed] = spec, diagnose_log(path, model=spec.model, settings=FAST)
        return cache[name, seed]

    return get


@pytest.fixture(scope="module")
def diagnosed(tmp_path_factory):
    """(name, seed) -> (spec, diagnosis) on the generator's sequences."""
    return _lazy_diagnoses(tmp_path_factory.mktemp("open_world"))


def _names(verdict) -> list:
    return list(verdict) if isinstance(verdict, list) else [verdict]


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("name", NAMED)
def test_hidden_effect_is_named_located_and_sized(diagnosed, name, seed):
    spec, diag = diagnosed(name, seed)
    assert _names(diag.verdict)[0] == spec.expect, (spec.description, diag.verdict)
    f = diag.findings[0]
    if spec.cables:
        assert f.cables == [c + 1 for c in spec.cables], spec.description
    if spec.joints:
        assert f.joints == [j + 1 for j in spec.joints], spec.description
    if spec.symbol is not None:
        fitted = f.parameters[spec.symbol].value
        tol = {"abs": ABSOLUTE[name]} if name in ABSOLUTE else {"rel": TOLERANCE[name]}
        assert fitted == pytest.approx(spec.magnitude, **tol), (spec.description, fitted)


@pytest.mark.parametrize("seed", SEEDS)
def test_noise_only_logs_stay_none(diagnosed, seed):
    spec, diag = diagnosed("none", seed)
    assert diag.verdict == "none", (diag.verdict, diag.leftover.found[:3])


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("name", OUT_OF_VOCABULARY)
def test_out_of_vocabulary_effect_is_unexplained(diagnosed, name, seed):
    spec, diag = diagnosed(name, seed)
    names = _names(diag.verdict)
    assert UNEXPLAINED in names, (spec.description, diag.verdict)
    where = diag.leftover.found[0]
    assert where.z > diag.leftover.z_threshold and where.channel and where.feature
    assert diag.to_dict()["unexplained"]["significant"]


def test_generator_shares_no_code_with_the_candidates():
    """The generator's own imports: nothing from the effect modules or the diagnosis."""
    import open_world.generator as gen

    tree = ast.parse(open(gen.__file__).read())
    imported = [n.module for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)]
    imported += [a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names]
    forbidden = ("neck_sim.effects", "identification.diagnosis")
    assert imported and not [m for m in imported if m.startswith(forbidden)], imported
    assert os.path.basename(gen.__file__) == "generator.py"


@pytest.mark.parametrize("seed", (1, 2))
def test_backlash_is_named_on_its_cable_never_as_an_actuation_delay(tmp_path, seed):
    """Gear backlash hidden by the generator's own formula (a smooth play between encoder and
    drum) on a right cable at 2 x its test band (0.48-0.75 mm of cable): ``backlash`` is the first
    name, on that cable, never an actuation delay alone; its band within 40 % (the generator's
    smooth swing against the candidate's clipped play)."""
    spec = make_spec("backlash", seed, level=2.0)
    diag = diagnose_log(simulate(tmp_path / "backlash.mcap", spec, seed), model=spec.model, settings=FAST)
    names = _names(diag.verdict)
    assert names[0] == "backlash" and names != ["actuation_delay"], (spec.description, diag.verdict)
    f = diag.findings[0]
    assert f.cables == [c + 1 for c in spec.cables], spec.description
    assert f.parameters[spec.symbol].value == pytest.approx(spec.magnitude, rel=0.4), spec.description


@pytest.mark.parametrize("seed", (1, 3))
def test_viscous_friction_on_the_soft_left_cable_is_named_alone(diagnosed, seed):
    """Motor-slide damping on cable 4 (the long soft left one): ``viscous_friction`` alone.  Seed 3
    fits -0.033 N s/rad on cable 3 beside 0.127 on cable 4 (cross-talk of antagonist motors, not an
    unphysical sign); seed 1 leaves a leftover of 0.11 of what the name removed from joint torque 3
    (the fitted form's own mismatch, below ``FORM_MISMATCH``)."""
    spec, diag = diagnosed("viscous_friction_left", seed)
    assert diag.verdict == "viscous_friction", (spec.description, diag.verdict)
    f = diag.findings[0]
    c_v = [f.parameters[f"c_v({i})"].value for i in range(1, 5)]
    assert 4 in f.cables and max(c_v) == c_v[3], (f.cables, c_v)


@pytest.mark.parametrize("seed", (3,))
def test_cable_hysteresis_is_unexplained_without_a_borrowed_name(diagnosed, seed):
    """A cable's own hysteresis (out of the vocabulary): ``unexplained`` alone.  Its best rest
    elongation sits on the bound of the pretension's range (-1 mm), so the name is not lent.
    (Seed 2 gives ``none``, seed 1 ``unexplained`` even without the bound rule: the bench's
    table; seed 3 is the one the rule decides.)"""
    spec, diag = diagnosed("cable_hysteresis", seed)
    assert diag.verdict == UNEXPLAINED, (spec.description, diag.verdict)


def test_a_name_whose_gain_needs_the_leftover_is_borrowed(tmp_path, monkeypatch):
    """Creep (out of the vocabulary) with the pretension's bound rule switched off: the pretension
    it lends gains 10 % against the baseline, but with the leftover's structure (the cables'
    drift in time) regressed out of both models its gain fails the candidate's tests: the verdict
    is ``unexplained`` alone, the pretension listed as borrowed."""
    from identification.diagnosis.columns.pretension import PretensionColumns

    monkeypatch.setattr(PretensionColumns, "shape_violation", classmethod(lambda cls, shape: ""))
    spec = make_spec("creep", 1)
    diag = diagnose_log(simulate(tmp_path / "creep.mcap", spec, 1), model=spec.model, settings=FAST)
    assert diag.findings and diag.findings[0].effect == "pretension", diag.steps[0].verdict
    assert diag.leftover.borrowed == ("pretension",)
    assert diag.verdict == UNEXPLAINED, diag.verdict
    assert diag.to_dict()[UNEXPLAINED]["borrowed"] == ["pretension"]


@pytest.mark.parametrize("case, seed, level", [("backlash", 2, 0.5), ("backlash_all", 1, 1.0)])
def test_small_backlash_is_named_alone(tmp_path, case, seed, level):
    """0.15 mm of play on motor 2 (half the test band), 0.24 mm on every motor: ``backlash``
    alone, on the motor that has it, found by the dry friction read at the drum's speed."""
    spec = make_spec(case, seed, level=level)
    diag = diagnose_log(simulate(tmp_path / "backlash.mcap", spec, seed), model=spec.model, settings=FAST)
    assert diag.verdict == "backlash", (spec.description, diag.verdict)
    if case == "backlash":
        assert diag.findings[0].cables == [c + 1 for c in spec.cables], spec.description


def test_rest_elongation_on_a_random_multisine_is_named_alone(tmp_path):
    """The representative slice of the random-multisine table (``benchmarks/bench_detection.py
    --excitations multisine``): encoder 1 zeroed 2.7 mm early, seed 1.  Cable 1 spans 12-45 N of
    tension, and the baseline's k(1), lambda(1) explain 99.6 % of the rest elongation's column:
    a true one, above the 99.0 % of the §5.2.2 sequences; ``pretension`` alone, on cable 1.  (Its
    size is not held here: 3.34 mm for 2.69 mm, the column that collinear leaves it loose.)"""
    spec = make_spec("pretension", 1)
    path = simulate(tmp_path / "multisine.mcap", spec, 1, excitation=Multisine.draw(spec.params, 1, duration=12.2))
    diag = diagnose_log(path, model=spec.model, settings=FAST)
    assert diag.verdict == "pretension", (spec.description, diag.verdict, diag.notes)
    assert diag.findings[0].cables == [1], spec.description


def test_a_rest_elongation_the_log_cannot_show_gets_a_gap_line(diagnosed):
    """Encoder 4 (the soft left cable) zeroed 2.1 mm early, seed 1: its rest elongation runs to the
    5 mm bound while k(4) falls to absorb it, 99.8 % of its column explained by k(4) and
    lambda(4).  Unless the verdict names it, one gap line says the log cannot show it on cable 4
    and what to record."""
    spec, diag = diagnosed("pretension_left", 1)
    named = _names(diag.verdict)[0] == "pretension"
    line = next((g.describe() for g in diag.gaps if g.kind == "conditioning" and g.where == "cable 4"), "")
    told = any(n.startswith("pretension could not be told from the baseline") for n in diag.notes)
    assert named or ("x0(4) (pretension) cannot be separated from k(4)" in line
                     and "record moves that pull it to" in line and told), (diag.verdict, line, diag.notes)


@pytest.fixture(scope="module")
def multisine(tmp_path_factory):
    """(name, seed) -> (spec, diagnosis) on the generator's 12.2 s random multisine in joint space."""
    return _lazy_diagnoses(tmp_path_factory.mktemp("multisine"),
                           lambda spec, seed: Multisine.draw(spec.params, seed, duration=12.2))


def test_a_one_cable_friction_is_held_out_on_its_own_channel(multisine):
    """A Stribeck bump of 7.7 N on cable 2, multisine seed 2: 11.6 % of the whole score, F-test
    p 5e-6, but the held-out chunks pooled over the 7 channels give p 0.0013 against 0.001; on its
    best channel (joint torque 2) p 2.5e-9, 1.8e-8 times its 7 channels.  ``stribeck_friction``
    alone, on cable 2, held out there."""
    spec, diag = multisine("stribeck_friction", 2)
    assert diag.verdict == "stribeck_friction", (spec.description, diag.verdict, diag.notes)
    assert diag.findings[0].cables == [c + 1 for c in spec.cables], spec.description
    assert "held out on its best channel" in diag.findings[0].evidence.note


def test_a_gain_the_log_cannot_attribute_is_insufficient_excitation(multisine):
    """Encoder 3 zeroed 3.1 mm early, multisine seed 2: cable 3 spans 15-29 N, short of the 15 N
    that separates a rest elongation from k(3) and lambda(3).  The pretension passes its tests
    but cannot be named: not ``none`` (the model does not explain the data), but
    ``insufficient_excitation`` with the gap line that says what to record."""
    spec, diag = multisine("pretension", 2)
    assert diag.verdict == "insufficient_excitation", (spec.description, diag.verdict, diag.notes)
    assert [c.term.name for c in diag.unattributed] == ["pretension"] and not diag.findings
    line = next(g.describe() for g in diag.gaps if g.where == "cable 3")
    assert "record moves that pull it to" in line and not diag.insufficient


def test_a_smooth_gear_play_leaves_no_leftover_beside_backlash(multisine):
    """0.29 mm of the generator's smooth play on motor 2, multisine seed 2: the play operator
    fitted with a band of 0.17 mm leaves joint torque 2 following motor acceleration 2 (rho 0.80),
    0.55 of what the finding removed there, within the form mismatch a vocabulary effect leaves
    (``FORM_MISMATCH``): ``backlash`` alone, on cable 2."""
    spec, diag = multisine("backlash", 2)
    assert diag.verdict == "backlash", (spec.description, diag.verdict)
    assert diag.findings[0].cables == [c + 1 for c in spec.cables], spec.description


def test_a_spring_error_beside_a_friction_is_scored_on_its_joint(tmp_path):
    """A Stribeck bump on cable 3 and joint 2's right spring 200 -> 110 N/m, multisine seed 3, two
    steps: at step 2 the spring error on every joint passes its training F-test but loses 0.3 %
    held out (joints 1 and 3 fit noise); on joint 2 alone it gains 10.9 %.  Both named, nothing
    left over."""
    from open_world.generator import combine

    spec = combine([make_spec("stribeck_friction", 3), make_spec("spring_error", 3)])
    path = simulate(tmp_path / "pair.mcap", spec, 3, excitation=Multisine.draw(spec.params, 3, duration=12.2))
    diag = diagnose_log(path, model=spec.model, settings=DiagnosisSettings(resimulate=False, max_steps=2))
    assert diag.verdict == ["stribeck_friction", "spring_error"], (spec.description, diag.verdict)
    assert diag.findings[1].joints == [2]


def test_a_pair_with_a_friction_on_one_cable_fits_it_there(tmp_path):
    """A Stribeck bump of 7.7 N on cable 2 and joint 1's left spring 600 -> 307 N/m, multisine
    seed 2, two steps: at step 2 the bump fitted on every cable loses 13 % of the whole score held
    out (the other cables' columns fit noise); on cable 2 alone, with its 2 C places, it gains
    15 %.  Both named, the friction on cable 2."""
    from open_world.generator import combine

    spec = combine([make_spec("stribeck_friction", 2), make_spec("spring_error", 2)])
    path = simulate(tmp_path / "pair.mcap", spec, 2, excitation=Multisine.draw(spec.params, 2, duration=12.2))
    diag = diagnose_log(path, model=spec.model, settings=DiagnosisSettings(resimulate=False, max_steps=2))
    assert sorted(_names(diag.verdict)) == ["spring_error", "stribeck_friction"], (spec.description, diag.verdict)
    friction = next(f for f in diag.findings if f.effect == "stribeck_friction")
    assert friction.cables == [2], friction.cables


def test_a_play_on_every_motor_is_not_read_as_a_camera_delay(multisine):
    """0.35 mm of play on every motor, multisine seed 2: no cable's band passes an F-test at 1 % on
    its own cable law (p 0.012-0.17), and the band of cable 1 alone gains 11 % where a 6 ms camera
    delay gains 16 %; every cable at its band gains 53 %, and the camera delay adds nothing to it.
    ``backlash`` alone, with a band on at least three cables."""
    spec, diag = multisine("backlash_all", 2)
    assert diag.verdict == "backlash", (spec.description, diag.verdict)
    assert len(diag.findings[0].cables) >= 3, diag.findings[0].cables


def test_a_candidates_note_quotes_the_held_out_p_it_reports(tmp_path):
    """A hinge of joint 3 (multisine seed 2), two steps.  At step 2 the spring error on joint 3 is
    held to its own channel (held-out p 0.92 with its factors), while its best channel, cable 1,
    gives 0.72 with 42 places: the note quoted that p beside the own channel's as if it were the one
    reported.  On every candidate of both steps: a note naming the best channel quotes the p the
    candidate reports, which is that channel's one-sided Wilcoxon p (recomputed here from the stored
    cross-validated residuals) times the N + C channels, the term's places and, for a one-joint
    term, the 2 comparisons it may be held to; a candidate held to its own channel names no other."""
    import re

    import numpy as np

    from identification.diagnosis.candidate import channel_names
    from identification.diagnosis.statistics import channel_wilcoxon_p

    spec = make_spec("joint_friction", 2)
    path = simulate(tmp_path / "hinge.mcap", spec, 2, excitation=Multisine.draw(spec.params, 2, duration=12.2))
    diag = diagnose_log(path, model=spec.model, settings=DiagnosisSettings(resimulate=False, max_steps=2))
    n, C = diag.data.n, diag.data.C
    quoted, own = 0, 0
    for st in diag.steps:
        for c in st.candidates:
            if c.fit is None:
                continue
            ident = c.term.identification
            if c.note.startswith("measured on its own channel"):
                own += 1
                assert "best channel" not in c.note, (c.term, c.p_holdout, c.note)
            found = re.search(r"held out on its best channel \((.+?)\): Wilcoxon p (\S+) with (\d+) places", c.note)
            if found is None:
                continue
            quoted += 1
            p = channel_wilcoxon_p(st.base.cv, c.model.cv, diag.split)
            k = int(np.argmin(p))
            factor = (n + C) * ident.places(dict(c.term.shape), n, C) * (1 if ident.joint_of(dict(c.term.shape)) is None
                                                                         else 2)
            assert found.group(1) == channel_names(n, C)[k] and int(found.group(3)) == factor, (c.term, c.note)
            assert c.p_holdout == pytest.approx(min(1.0, factor * p[k]), rel=1e-12), (c.term, c.note)
            assert found.group(2) == f"{c.p_holdout:.2g}", (c.term, c.p_holdout, c.note)
    assert quoted >= 5 and own >= 1, (quoted, own)
