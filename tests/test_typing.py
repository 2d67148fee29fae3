"""The public modules are typed: every public function and method annotates each parameter and its
return, mypy (pinned in the ``test`` extras, configured in pyproject.toml) finds no error in them,
and the three packages ship ``py.typed`` so that a user's type checker reads the annotations.

``PUBLIC_MODULES`` lists the modules held to this; a module joins it once annotated.  Public means
no leading underscore (``__init__`` and ``__call__`` count: they are how a class is used) and, in a
module with ``__all__``, listed there; a method is public when its class is.
"""

import ast
import os
import pathlib
import subprocess
import sys
import tomllib

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
PACKAGES = ("neck_sim", "controllers", "identification")

PUBLIC_MODULES = [
    "neck_sim.analytic", "neck_sim.analytic.cables", "neck_sim.analytic.cable_law", "neck_sim.analytic.dynamics",
    "neck_sim.analytic.estimation", "neck_sim.analytic.geometry", "neck_sim.analytic.statics",
    "neck_sim.analytic.workspace",
    "neck_sim.cli", "neck_sim.cli.check_cmd", "neck_sim.cli.common", "neck_sim.cli.crossval_cmd",
    "neck_sim.cli.design_cmd", "neck_sim.cli.diagnose_cmd", "neck_sim.cli.effects_cmd", "neck_sim.cli.import_cmd",
    "neck_sim.cli.params_cmd", "neck_sim.cli.pulleys_cmd", "neck_sim.cli.render_cmd",
    "neck_sim.cli.replay_cmd", "neck_sim.cli.reproduce_cmd", "neck_sim.cli.simulate_cmd",
    "neck_sim.atomic", "neck_sim.cache", "neck_sim.check", "neck_sim.csv_import", "neck_sim.design",
    "neck_sim.design_report", "neck_sim.effect_option", "neck_sim.live", "neck_sim.pulley_study", "neck_sim.render",
    "neck_sim.experiments", "neck_sim.experiments.reproduce", "neck_sim.experiments.summary",
    "controllers.elastic_lqr", "controllers.estimators", "controllers.plots", "controllers.reachable_paths",
    "controllers.selection", "controllers.tension", "controllers.underactuated",
    "identification.excitation", "identification.gaps", "identification.least_squares", "identification.plots",
    "identification.paper", "identification.filtering", "identification.preprocessing", "identification.regressors",
    "identification.simulator", "identification.uncertainty",
    # the package faces and the modules they export from
    "neck_sim", "controllers", "identification",
    "neck_sim.validation", "neck_sim.lazy", "neck_sim.params", "neck_sim.plant", "neck_sim.plant_spec", "neck_sim.effects",
    "neck_sim.effects.base", "neck_sim.logs", "neck_sim.logs.contract", "neck_sim.logs.reader",
    "neck_sim.logs.writer", "neck_sim.trajectory",
    "controllers.computed_torque", "controllers.trajectories", "controllers.run_result", "controllers.parallel",
    "neck_sim.batch", "neck_sim.recorder", "neck_sim.replay", "controllers.closed_loop", "controllers.experiments",
    "identification.diagnosis.pipeline", "identification.diagnosis.result", "identification.diagnosis.settings",
    "identification.diagnosis.parameters", "identification.output_error.fit",
]


def module_path(root, name):
    base = root.joinpath(*name.split("."))
    return base / "__init__.py" if base.is_dir() else base.with_suffix(".py")


def _exported(tree):
    for node in tree.body:
        if isinstance(node, (ast.Assign, ast.AnnAssign)):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            if any(isinstance(t, ast.Name) and t.id == "__all__" for t in targets):
                return set(ast.literal_eval(node.value))
    return None


def _public(name):
    return not name.startswith("_") or name in ("__init__", "__call__")


def _missing(node, method):
    args = node.args
    params = args.posonlyargs + args.args
    static = any(isinstance(d, ast.Name) and d.id == "staticmethod" for d in node.decorator_list)
    if method and not static and params:
        params = params[1:]       # self or cls
    params = params + args.kwonlyargs + [a for a in (args.vararg, args.kwarg) if a]
    missing = [p.arg for p in params if p.annotation is None]
    return missing + (["return"] if node.returns is None else [])


def unannotated(path):
    """``file:line name: what`` for each public function or method whose parameters or return
    lack an annotation."""
    tree = ast.parse(path.read_text(), str(path))
    exported = _exported(tree)
    found = []

    def visit(body, prefix, method):
        for node in body:
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and _public(node.name):
                if missing := _missing(node, method):
                    found.append(f"{path.name}:{node.lineno} {prefix}{node.name}: {', '.join(missing)}")
            elif isinstance(node, ast.ClassDef) and not node.name.startswith("_"):
                visit(node.body, f"{prefix}{node.name}.", True)

    top = [n for n in tree.body if not isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef))
           or exported is None or n.name in exported]
    visit(top, "", False)
    return found


def run_mypy(files, cwd=ROOT):
    """mypy with the project's configuration: (exit code, output).  In CI (``$CI`` set: a fresh
    clone, nothing survives the run) it writes no incremental cache, which would cost 10 % more."""
    ci = ["--no-incremental", "--cache-dir", os.devnull] if os.environ.get("CI") else []
    proc = subprocess.run([sys.executable, "-m", "mypy", "--config-file", str(ROOT / "pyproject.toml"), *ci,
                           *map(str, files)], cwd=cwd, capture_output=True, text=True)
    return proc.returncode, proc.stdout + proc.stderr


def test_public_modules_exist():
    assert len(PUBLIC_MODULES) == len(set(PUBLIC_MODULES))
    missing = [m for m in PUBLIC_MODULES if not module_path(ROOT, m).is_file()]
    assert not missing, f"listed but not found: {missing}"


def test_public_functions_are_annotated():
    found = [f"{m}: {line}" for m in PUBLIC_MODULES for line in unannotated(module_path(ROOT, m))]
    assert not found, "unannotated public parameters or returns:\n" + "\n".join(found)


def test_mypy_finds_no_error_in_the_public_modules():
    code, out = run_mypy([module_path(ROOT, m) for m in PUBLIC_MODULES])
    assert code == 0, out


def test_py_typed_is_shipped():
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())
    data = config["tool"]["setuptools"]["package-data"]
    for pkg in PACKAGES:
        assert (ROOT / pkg / "py.typed").is_file(), pkg
        assert "py.typed" in data.get(pkg, []), f"pyproject package-data does not ship {pkg}/py.typed"
    assert any(dep.startswith("mypy==") for dep in config["project"]["optional-dependencies"]["test"])


# -- the checkers themselves, on a synthetic module ---------------------------------------------

def test_annotation_checker_both_ways(tmp_path):
    path = tmp_path / "mod.py"
    path.write_text(
        "__all__ = ['f', 'C', 'g']\n"
        "def f(x: int, *args: int, y, **kw: int) -> int: ...\n"         # y missing
        "def g(x: int): ...\n"                                           # return missing
        "def h(x): ...\n"                                                # not in __all__
        "def _p(x): ...\n"
        "class C:\n"
        "    def __init__(self, a) -> None: ...\n"                       # a missing
        "    def m(self, b: float) -> float: ...\n"
        "    @staticmethod\n"
        "    def s(c) -> None: ...\n"                                    # c missing
        "    def _q(self, d): ...\n"
        "    def __repr__(self): ...\n"
        "    class Inner:\n"
        "        def n(self, *rest) -> None: ...\n")                     # rest missing
    assert unannotated(path) == ["mod.py:2 f: y", "mod.py:3 g: return", "mod.py:7 C.__init__: a",
                                 "mod.py:10 C.s: c", "mod.py:14 C.Inner.n: rest"]
    path.write_text("def f(x: int, *args: int, y: str = '', **kw: int) -> int: ...\n"
                    "class C:\n"
                    "    def __init__(self, a: int) -> None: ...\n"
                    "    @classmethod\n"
                    "    def make(cls) -> 'C': ...\n"
                    "def _p(x): ...\n")
    assert unannotated(path) == []


@pytest.mark.parametrize("text, fails", [("x: int = 1\n", False), ("x: int = 'one'\n", True)])
def test_mypy_run_fails_on_a_type_error(tmp_path, text, fails):
    """The project's configuration reports errors (and the run's exit code says so)."""
    (tmp_path / "mod.py").write_text(text)
    code, out = run_mypy([tmp_path / "mod.py"], cwd=tmp_path)
    assert (code != 0) == fails, out
