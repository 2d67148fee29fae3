"""The README's results table is the summary of the reproduction it cites, written by the code."""

from __future__ import annotations

import json
from pathlib import Path

from neck_sim.experiments.summary import main, summary_table

ROOT = Path(__file__).resolve().parents[1]


def test_readme_results_table_is_the_summary_of_docs_results_json():
    results = json.loads((ROOT / "docs" / "results.json").read_text())
    table = summary_table(results)
    assert table in (ROOT / "README.md").read_text(), (
        "README's results table differs from `python -m neck_sim.experiments.summary docs/results.json`:\n" + table)


def test_summary_reads_the_numbers_it_names(tmp_path, capsys):
    results = json.loads((ROOT / "docs" / "results.json").read_text())
    results["control_tests"]["law 2"]["tracking_error"] = 0.123
    results["identification"]["models"]["variable"]["parameters"]["k(4)"]["value"] = 4321.0
    table = summary_table(results)
    assert "| 0.49 / 0.12 / 0.19 |" in table and "/ 4321 |" in table
    path = tmp_path / "results.json"
    path.write_text(json.dumps(results))
    assert main([str(path)]) == 0 and capsys.readouterr().out == table
    path.write_text("{}")
    assert main([str(path)]) == 2
    assert len(capsys.readouterr().err.strip().splitlines()) == 1
