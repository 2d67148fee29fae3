"""The model core never imports controllers or identification; only the composition layer
(neck_sim.cli, neck_sim.experiments) composes them."""

import ast
import pathlib

ROOT = pathlib.Path(__file__).resolve().parents[1]


def imported_roots(path):
    tree = ast.parse(path.read_text())
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            yield from (a.name.split(".")[0] for a in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            yield node.module.split(".")[0]


COMPOSITION = {"cli", "experiments"}


def test_core_does_not_import_upper_layers():
    offenders = []
    files = [f for f in (ROOT / "neck_sim").rglob("*.py")
             if f.relative_to(ROOT / "neck_sim").parts[0] not in COMPOSITION]
    assert len(files) > 5
    for f in files:
        bad = {"controllers", "identification"} & set(imported_roots(f))
        if bad:
            offenders.append(f"{f.relative_to(ROOT)} imports {sorted(bad)}")
    assert not offenders, offenders


def test_controllers_do_not_import_identification():
    for f in (ROOT / "controllers").rglob("*.py"):
        assert "identification" not in set(imported_roots(f)), f


def test_composition_layer_is_where_workflows_live():
    """The workflows import the upper layers (so the rule above exempts real composition code) and
    the CLI modules call them rather than running the stages themselves."""
    assert {"controllers", "identification"} <= set(imported_roots(ROOT / "neck_sim/experiments/reproduce.py"))
    cmd = set(imported_roots(ROOT / "neck_sim/cli/reproduce_cmd.py"))
    assert "neck_sim" in cmd and not {"controllers", "identification"} & cmd
