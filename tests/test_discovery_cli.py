"""`neck-sim diagnose`: measured topics only, stable JSON, report, extended model, bad input."""

from __future__ import annotations

import json

import numpy as np
import pytest
from mcap.reader import make_reader
from mcap.writer import Writer

from identification.diagnosis.blind import make_case
from identification.diagnosis.candidates import ModelSpec, Term
from identification.diagnosis import DiagnosisSettings, diagnose_log, parse_model, split_samples, score
from identification.diagnosis.statistics import wilcoxon_p
from neck_sim.cli import main
from neck_sim.effects import Effects
from neck_sim.logs import LogWriter, read_log

FAST = DiagnosisSettings(max_steps=1, resimulate=False, alpha_hat=False)


@pytest.fixture(scope="module")
def viscous_log(tmp_path_factory):
    """A blind log with hidden viscous friction, with the simulation truth and the run record."""
    path = tmp_path_factory.mktemp("diag") / "viscous.mcap"
    case, p = make_case("viscous_friction", 5, path, write_truth=True)
    return case, p


def _strip(src, dst, keep=("/neck/motors", "/neck/camera"), edit=None):
    """Copy only the measured topics and the ``neck`` record (no truth, reference, estimate, run
    record, attachments), with the mcap library itself; ``edit(topic, payload) -> payload`` may
    change messages on the way."""
    with open(src, "rb") as fh, open(dst, "wb") as out:
        reader = make_reader(fh)
        w = Writer(out)
        w.start()
        summary = reader.get_summary()
        ids = {}
        for ch in summary.channels.values():
            if ch.topic in keep:
                sc = summary.schemas[ch.schema_id]
                sid = w.register_schema(sc.name, sc.encoding, sc.data)
                ids[ch.id] = w.register_channel(ch.topic, ch.message_encoding, sid)
        for m in reader.iter_metadata():
            if m.name == "neck":
                w.add_metadata(m.name, dict(m.metadata))
        for _, ch, msg in reader.iter_messages(topics=list(keep)):
            data = msg.data if edit is None else edit(ch.topic, msg.data)
            w.add_message(ids[ch.id], msg.log_time, data, msg.publish_time)
        w.finish()


def _comparable(diag) -> str:
    d = diag.to_dict()
    d.pop("source")
    d.pop("timings_s")
    return json.dumps(d, sort_keys=True)


def test_simulation_only_topics_and_metadata_change_nothing(viscous_log, tmp_path):
    _, path = viscous_log
    full = read_log(path)
    assert full.truth is not None and full.reference is not None and full.run_info   # there was something to strip
    stripped = tmp_path / "stripped.mcap"
    _strip(path, stripped)
    bare = read_log(stripped)
    assert bare.truth is None and bare.reference is None and not bare.run_info and not bare.attachments
    a = diagnose_log(path, settings=FAST)
    b = diagnose_log(stripped, settings=FAST)
    assert a.verdict == "viscous_friction"
    assert _comparable(a) == _comparable(b)


def test_cli_json_report_and_extended_model(viscous_log, tmp_path, capsys):
    case, path = viscous_log
    js, rep, ext = tmp_path / "d.json", tmp_path / "report", tmp_path / "model.json"
    code = main(["diagnose", str(path), "--steps", "1", "--json", str(js), "--report", str(rep),
                 "--extended", str(ext), "--quiet", "--alpha", "0.05", "--min-improvement", "0.03"])
    assert code == 0
    assert "verdict: viscous_friction" in capsys.readouterr().out
    d = json.loads(js.read_text())
    assert d["verdict"] == "viscous_friction"
    # the method text says what was used
    assert d["settings"]["alpha"] == 0.05 and d["settings"]["min_improvement"] == 0.03
    assert "alpha (0.05)" in d["method"]["significance"] and "min_improvement (0.03)" in d["method"]["significance"]
    assert "0.01" not in d["method"]["significance"]
    f = d["findings"][0]
    assert {"effect", "cables", "parameters", "evidence", "gain"} <= set(f)
    assert f["cables"] == [case.cables[0] + 1]
    assert set(d["baseline"]) >= {"model", "parameters", "residual_rms_crossvalidated", "alpha_hat_vs_camera",
                                  "resimulation"}
    # the extended model re-simulates the held-out blocks better (open loop, logged forces): alpha error
    # against the camera halved, encoder error down by a quarter
    before, after = f["gain"]["resimulation_holdout"]["before"], f["gain"]["resimulation_holdout"]["after"]
    assert after["alpha_mean_abs_deg"] < 0.5 * before["alpha_mean_abs_deg"]
    assert np.mean(after["theta_rms_rad"]) < 0.75 * np.mean(before["theta_rms_rad"])
    # report: Markdown with the figures it names
    md = (rep / "report.md").read_text()
    for png in ("residuals_torque.png", "residuals_cable.png", "candidates.png", "alpha_hat.png", "resimulation.png"):
        assert f"]({png})" in md and (rep / png).stat().st_size > 10_000
    # the written model is a plant: viscous friction on the found cable, and --model reads it back
    model = json.loads(ext.read_text())
    eff = Effects.from_dict(model["effects"])
    c_v = eff.viscous_friction.per_cable(4)
    assert c_v[case.cables[0]] == pytest.approx(case.effects.viscous_friction.c_v, rel=0.25)
    assert parse_model(str(ext)).names == ("dry_friction", "cable_elasticity", "tension_stiffening",
                                           "viscous_friction")
    again = diagnose_log(path, model=str(ext), settings=FAST)
    assert again.verdict == "none"


def test_bad_input_is_named(tmp_path, params):
    with pytest.raises(ValueError, match="unknown bogus"):
        parse_model("dry_friction,bogus")
    with pytest.raises(ValueError, match="needs dry_friction"):
        ModelSpec.of("stribeck_friction")
    with pytest.raises(ValueError, match="unknown effect"):
        Term("magic")
    with pytest.raises(ValueError, match="cannot read"):
        parse_model(str(tmp_path / "missing.json"))
    bad = tmp_path / "bad.json"
    bad.write_text("{}")
    with pytest.raises(ValueError, match="'model' list"):
        parse_model(str(bad))
    with pytest.raises(ValueError):
        DiagnosisSettings(candidates=("viscous", ))
    # a log without camera frames: the CLI names the missing topic
    path = tmp_path / "nocam.mcap"
    with LogWriter(path, params) as w:
        for k in range(200):
            w.motors(k * 0.002, np.zeros(4), np.full(4, 10.0))
    assert main(["diagnose", str(path), "--quiet"]) == 2


def test_split_cuts_blocks_in_holds_and_folds_them():
    rate = 31.25
    t = np.arange(0, 30, 1 / rate)
    # 12 moves of 2 s separated by 0.5 s holds
    period = 2.5
    activity = np.where((t % period) < 2.0, 1.0 + np.sin(np.pi * (t % period) / 2.0), 0.0)
    s = split_samples(t, activity, DiagnosisSettings())
    # 3 moves per block would leave 4 blocks, fewer than two per fold: 2 moves per block
    assert len(s.blocks) == 6 and s.method.startswith("blocks of 2 moves")
    for a, _, _ in s.blocks[1:]:
        assert (a % period) >= 2.0 - 1e-9          # every block starts in a hold
    assert [f for _, _, f in s.blocks] == [0, 1, 2, 0, 1, 2]
    s3 = split_samples(np.arange(0, 60, 1 / rate), np.where((np.arange(0, 60, 1 / rate) % period) < 2.0, 1.0, 0.0),
                       DiagnosisSettings())
    assert len(s3.blocks) == 8 and s3.method.startswith("blocks of 3 moves")
    # a log without holds is cut into equal blocks
    s4 = split_samples(t, 1.0 + np.sin(t), DiagnosisSettings())
    assert len(s4.blocks) == 6 and "equal blocks" in s4.method
    assert np.array_equal(s.train, s.fold != 1) and s.holdout.sum() > 0
    # chunks never straddle two blocks
    for c in np.unique(s.chunk):
        assert np.unique(s.block[s.chunk == c]).size == 1


def test_score_and_paired_test():
    rng = np.random.default_rng(0)
    res = rng.normal(size=(400, 3))
    scales = np.array([1.0, 2.0, 0.5])
    # 1 joint, 2 cables: the torque channel weighs one half, each cable channel one quarter
    ms = np.mean(res ** 2, 0) / scales ** 2
    expected = 0.5 * ms[0] + 0.25 * (ms[1] + ms[2])
    assert score(res, np.ones(400, bool), scales, 1) == pytest.approx(expected)
    # 2 joints, 1 cable (not N + 1): each torque channel one quarter, the cable one half
    assert score(res, np.ones(400, bool), scales, 2) == pytest.approx(0.25 * (ms[0] + ms[1]) + 0.5 * ms[2])
    res[::7, 0] = np.nan                            # slack samples are left out
    assert np.isfinite(score(res, np.ones(400, bool), scales, 1))
    assert wilcoxon_p(np.abs(rng.normal(size=30)) + 0.1) < 1e-5
    assert wilcoxon_p(rng.normal(size=30)) > 1e-3
    assert wilcoxon_p(np.zeros(30)) == 1.0


def test_look_alikes_are_told_apart_or_reported_together(monkeypatch):
    """The decision rule of a step (encompassing tests stubbed): never a guess between look-alikes."""
    import identification.diagnosis.selection as disc

    def cand(name, imp):
        return disc.CandidateScore(Term(name, ()), None, 4, 0.9, 0.9, imp, imp, {}, 1e-6, 1e-6, True, True)

    viscous, stribeck, payload = cand("viscous_friction", 0.20), cand("stribeck_friction", 0.15), cand("payload", 0.1)
    outcomes = {}
    monkeypatch.setattr(disc, "encompass", lambda ctx, a, b: disc.EncompassingTest(a.term.name, b.term.name, None, None,
                                                                                   **outcomes[b.term.name]))
    # stribeck adds nothing to viscous, viscous adds to stribeck: viscous stands
    outcomes.update(stribeck_friction={"a_adds": True, "b_adds": False}, payload={"a_adds": True, "b_adds": True})
    assert disc.decide(None, [stribeck, viscous, payload])[0] == "viscous_friction"
    # neither adds to the other: ambiguous, both names
    outcomes["stribeck_friction"] = {"a_adds": False, "b_adds": False}
    assert disc.decide(None, [stribeck, viscous, payload])[0] == ["viscous_friction", "stribeck_friction"]
    # the runner-up explains all the leader does and more: it replaces the leader
    outcomes["stribeck_friction"] = {"a_adds": False, "b_adds": True}
    verdict, chosen, _ = disc.decide(None, [stribeck, viscous, payload])
    assert verdict == "stribeck_friction" and chosen is stribeck
    # nothing significant: none
    weak = disc.CandidateScore(Term("payload", ()), None, 1, 1, 1, 0.01, 0.01, {}, 0.5, 0.5, True, False)
    assert disc.decide(None, [weak])[0] == "none"


def test_accepted_out_of_range_forces_are_named_in_every_output(viscous_log, tmp_path, capsys):
    """Forces accepted on request are said in the summary, the JSON and the report."""
    _, path = viscous_log
    spiked = tmp_path / "spiked.mcap"
    seen = {"motors": 0}

    def spike(topic, data):            # motors sample 1000: cable 2 at -5 N
        if topic == "/neck/motors":
            seen["motors"] += 1
            if seen["motors"] == 1001:
                sample = json.loads(data)
                sample["force"][1] = -5.0
                return json.dumps(sample).encode()
        return data

    _strip(path, spiked, edit=spike)
    assert main(["diagnose", str(spiked), "--quiet"]) == 2
    assert "--accept-out-of-range-forces" in capsys.readouterr().err
    js, rep = tmp_path / "d.json", tmp_path / "report"
    code = main(["diagnose", str(spiked), "--steps", "1", "--no-resim", "--candidates", "viscous_friction",
                 "--accept-out-of-range-forces", "--json", str(js), "--report", str(rep), "--quiet"])
    out = capsys.readouterr().out
    assert code == 0
    said = [line for line in out.splitlines() if "accepted out-of-range forces" in line]
    assert len(said) == 1 and "sample 1000" in said[0] and "force2" in said[0]
    assert any("accepted out-of-range forces" in n and "sample 1000" in n for n in json.loads(js.read_text())["notes"])
    assert "accepted out-of-range forces" in (rep / "report.md").read_text()
