"""`neck-sim reproduce` end to end at a short duration scale (every stage, every output)."""

import json

import pytest

from neck_sim.cli import main
from neck_sim.experiments import ReproduceSettings


@pytest.mark.slow
def test_reproduce_writes_the_whole_report(tmp_path, capsys):
    out = tmp_path / "repro"
    assert main(["reproduce", "--duration-scale", "0.15", "--out", str(out), "--no-progress"]) == 0
    report = (out / "report.md").read_text()
    for heading in ("## 1. MuJoCo model", "## 2. The pulleys", "## 3. Control tests", "Table 3",
                    "## 4. Identification", "Table 1", "Table 2", "## 5. Diagnosis", "## Figures"):
        assert heading in report, heading
    results = json.loads((out / "results.json").read_text())
    assert results["crossval"]["ok"] is True
    assert set(results["control_tests"]) == {"law 1", "law 2", "law 3"}
    assert len(results["table3"]) == 4
    assert results["identification"]["models"]["variable"] is not None
    assert results["diagnosis"]["verdict"] not in (None, "none")
    assert "error" not in results["simulators"]
    logs = sorted(p.name for p in (out / "logs").iterdir())
    assert len(logs) == 8 and all(name.endswith(".mcap") for name in logs)
    figures = {p.name for p in (out / "figures").iterdir()}
    assert {"fig4_torques.png", "fig8_alpha.png", "fig9_simulators.png", "forces.png"} <= figures
    assert (out / "diagnosis" / "report.md").exists() and (out / "neck3x.xml").exists()
    # every figure the report links exists
    for line in report.splitlines():
        if line.startswith("![") and "](" in line:
            assert (out / line.split("](")[1].rstrip(")")).exists(), line


def test_bad_duration_scale():
    with pytest.raises(ValueError, match="duration scale"):
        ReproduceSettings(scale=0.0)


def test_paper_runs_are_the_papers_experiments(tmp_path, params):
    """The workflow's closed-loop runs: the identification run (law 1), the §7 control tests (laws 1-3)
    and Table 3 (law 2 on the identification trajectory; r = 0 in the controller only without pulleys)."""
    from neck_sim.experiments import paper_runs

    specs = paper_runs(params, ReproduceSettings(quick=True, seed=4), str(tmp_path))
    by = {s.label: s for s in specs}
    assert len(by) == 8 and by["identification"].law == 1 and by["identification"].trajectory == "identification"
    assert [by[f"law {k}"].law for k in (1, 2, 3)] == [1, 2, 3]
    table3 = [s for s in specs if s.label.startswith("table3")]
    assert len(table3) == 4 and all(s.law == 2 and s.trajectory == "identification" for s in table3)
    assert sum(s.rigid_cables for s in table3) == 2
    for s in table3:
        pulleys = "no-pulleys" not in s.label
        assert (s.controller_params is None) == pulleys
        if not pulleys:
            assert s.controller_params.geometry.r == 0.0 and s.params.geometry.r > 0
    assert all(s.seed == 4 and s.duration_scale == 0.5 and s.log_path.startswith(str(tmp_path)) for s in specs)
    assert len({s.log_path for s in specs}) == 8
