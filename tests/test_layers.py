"""The layers and the house rules, read from the source (AST and text), never by importing it.

- The model core never imports controllers or identification; only the composition layer
  (neck_sim.cli, neck_sim.experiments) composes them.
- No module of one top-level package imports a private name (leading underscore, as a module or
  as an attribute) of another package, the composition layer included: a package's private
  helpers can then change without reading the other packages.
- No import circle between modules (imports that run when the module loads).
- No module of the three packages over 500 lines.
- No reference to an issue number in code, comments or docstrings: a reader of the source cannot
  follow it; the reason or the measurement is written out instead.

Each rule is a plain function over a source root, so it is checked both on the repository and on a
small synthetic tree that holds one offender and one look-alike that is allowed.
"""

import ast
import pathlib
import re

ROOT = pathlib.Path(__file__).resolve().parents[1]
PACKAGES = ("neck_sim", "controllers", "identification")
MAX_LINES = 500


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


# -- the module table ---------------------------------------------------------------------------

def modules(root):
    """Dotted module name -> (file, is_package) for every ``.py`` file of the three packages."""
    table = {}
    for pkg in PACKAGES:
        for f in sorted((root / pkg).rglob("*.py")):
            parts = list(f.relative_to(root).with_suffix("").parts)
            is_package = parts[-1] == "__init__"
            if is_package:
                parts.pop()
            table[".".join(parts)] = (f, is_package)
    return table


def _absolute(node, name, is_package):
    """The absolute module named by an ``ImportFrom`` in module ``name`` (relative levels resolved)."""
    if node.level == 0:
        return node.module
    base = name.split(".")
    # a package's own ``from . import x`` is relative to the package itself, a module's to its parent
    base = base[:len(base) - node.level + (1 if is_package else 0)]
    return ".".join(base + ([node.module] if node.module else []))


def _is_private(part):
    return part.startswith("_") and not (part.startswith("__") and part.endswith("__"))


# -- no private name across packages ------------------------------------------------------------

def private_cross_imports(root):
    """``module: what`` for every private name a module imports from (or reads off a module of)
    another of the three packages, wherever the import stands (functions included)."""
    table = modules(root)
    offenders = []
    for name, (path, is_package) in table.items():
        own = name.split(".")[0]
        tree = ast.parse(path.read_text(), str(path))
        module_aliases = {}      # local name -> module of another package it is bound to
        for node in ast.walk(tree):
            targets = []
            if isinstance(node, ast.Import):
                for a in node.names:
                    targets.append((a.name, None))
                    if a.name.split(".")[0] != own and a.name.split(".")[0] in PACKAGES:
                        module_aliases[a.asname or a.name.split(".")[0]] = a.asname and a.name
            elif isinstance(node, ast.ImportFrom):
                mod = _absolute(node, name, is_package)
                if not mod:
                    continue
                for a in node.names:
                    if a.name == "*":
                        continue
                    targets.append((mod, a.name))
                    if mod.split(".")[0] != own and f"{mod}.{a.name}" in table:
                        module_aliases[a.asname or a.name] = f"{mod}.{a.name}"
            for mod, attr in targets:
                top = mod.split(".")[0]
                if top == own or top not in PACKAGES:
                    continue
                parts = mod.split(".") + ([attr] if attr else [])
                if any(_is_private(p) for p in parts):
                    offenders.append(f"{name}: {'.'.join(parts)}")
        for node in ast.walk(tree):
            # ``plant._DISPATCH`` after ``from neck_sim import plant``; ``neck_sim.plant._x`` too
            if isinstance(node, ast.Attribute) and _is_private(node.attr):
                chain, base = [node.attr], node.value
                while isinstance(base, ast.Attribute):
                    chain.append(base.attr)
                    base = base.value
                if isinstance(base, ast.Name) and base.id in module_aliases:
                    head = module_aliases[base.id] or base.id
                    offenders.append(f"{name}: {'.'.join([head] + list(reversed(chain)))}")
    return sorted(set(offenders))


def test_no_private_name_crosses_packages():
    assert len(modules(ROOT)) > 50
    offenders = private_cross_imports(ROOT)
    assert not offenders, "private names imported from another package:\n" + "\n".join(offenders)


# -- no import circle ---------------------------------------------------------------------------

def _load_time_imports(body):
    """Import statements that run when the module loads: not in a function, not under
    ``if TYPE_CHECKING:`` (which mypy reads and Python skips)."""
    for node in body:
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            yield node
        elif isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            continue
        elif isinstance(node, ast.If):
            test = node.test
            checking = (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
                isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING")
            if not checking:
                yield from _load_time_imports(node.body)
            yield from _load_time_imports(node.orelse)
        elif isinstance(node, ast.Try):
            for block in (node.body, node.orelse, node.finalbody, *(h.body for h in node.handlers)):
                yield from _load_time_imports(block)
        elif isinstance(node, (ast.With, ast.For, ast.While, ast.ClassDef)):
            yield from _load_time_imports(node.body)
            yield from _load_time_imports(getattr(node, "orelse", []))


def _every_import(body):
    for node in body:
        yield from (n for n in ast.walk(node) if isinstance(n, (ast.Import, ast.ImportFrom)))


def import_graph(root, deferred=False):
    """Module -> modules of the three packages it imports at load time (``deferred``: anywhere,
    inside functions and under ``TYPE_CHECKING`` too).  An edge goes to the module
    named (``from a.b import c`` goes to ``a.b.c`` when that is a module, else to ``a.b``); the
    parent packages Python runs first are not edges, so a package face that re-exports its own
    modules is no circle with them."""
    table = modules(root)
    graph = {name: set() for name in table}
    for name, (path, is_package) in table.items():
        tree = ast.parse(path.read_text(), str(path))
        for node in (_every_import if deferred else _load_time_imports)(tree.body):
            if isinstance(node, ast.Import):
                named = [a.name for a in node.names]
            else:
                mod = _absolute(node, name, is_package)
                named = [f"{mod}.{a.name}" if f"{mod}.{a.name}" in table else mod for a in node.names]
            graph[name] |= {m for m in named if m in table and m != name}
    return graph


def import_cycles(root, deferred=False):
    """Each circle as ``a -> b -> a`` (one per strongly connected component, Tarjan's algorithm)."""
    graph = import_graph(root, deferred)
    index, low, stack, on_stack, components = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = set()
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.add(w)
                if w == v:
                    break
            if len(component) > 1:
                components.append(component)

    for v in sorted(graph):
        if v not in index:
            visit(v)
    cycles = []
    for component in components:
        start = min(component)
        # breadth-first from start back to start inside the component: the shortest circle
        paths, seen = {start: [start]}, {start}
        frontier, cycle = [start], None
        while frontier and cycle is None:
            nxt = []
            for v in frontier:
                for w in sorted(graph[v] & component):
                    if w == start:
                        cycle = paths[v] + [start]
                        break
                    if w not in seen:
                        seen.add(w)
                        paths[w] = paths[v] + [w]
                        nxt.append(w)
                if cycle:
                    break
            frontier = nxt
        cycles.append(" -> ".join(cycle) + (f"  (component: {sorted(component)})"
                                            if len(component) > len(cycle) - 1 else ""))
    return sorted(cycles)


def test_no_import_circle():
    cycles = import_cycles(ROOT)
    assert not cycles, "import circles:\n" + "\n".join(cycles)


def test_no_import_circle_hidden_in_a_function():
    """An import moved into a function to break a circle keeps the two modules unable to be
    understood (or moved) apart; the shared part belongs in a third module."""
    cycles = import_cycles(ROOT, deferred=True)
    assert not cycles, "import circles through deferred imports:\n" + "\n".join(cycles)


# -- no module over 500 lines -------------------------------------------------------------------

def long_modules(root, limit=MAX_LINES):
    return sorted(f"{path.relative_to(root)}: {n} lines"
                  for path, _ in modules(root).values()
                  if (n := len(path.read_text().splitlines())) > limit)


def test_no_module_over_500_lines():
    offenders = long_modules(ROOT)
    assert not offenders, f"modules over {MAX_LINES} lines:\n" + "\n".join(offenders)


# -- no issue numbers ---------------------------------------------------------------------------

# the word followed by a number (spaced, hyphenated, underscored or with "#"), and a bare "#"
# before a number that is not an HTML entity's "&#"
ISSUE_REFERENCE = re.compile(r"\bissues?[\s_-]*#?\d+|(?<![\w&#])#\d+\b", re.IGNORECASE)
SCANNED = PACKAGES + ("benchmarks", "tests")


def issue_references(root):
    hits = []
    for top in SCANNED:
        for f in sorted((root / top).rglob("*.py")):
            for lineno, line in enumerate(f.read_text().splitlines(), 1):
                hits += [(f.relative_to(root).as_posix(), lineno, m.group(0)) for m in ISSUE_REFERENCE.finditer(line)]
    return [f"{path}:{lineno}: {text!r}" for path, lineno, text in sorted(hits)]


def test_no_issue_references():
    hits = issue_references(ROOT)
    assert not hits, "issue numbers a reader cannot follow (write the reason instead):\n" + "\n".join(hits)


# -- the checkers themselves, on a synthetic tree -----------------------------------------------

def _tree(root, files):
    for rel, text in files.items():
        path = root / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    for pkg in PACKAGES:
        (root / pkg).mkdir(exist_ok=True)
        (root / pkg / "__init__.py").touch()
    return root


def test_private_import_checker_both_ways(tmp_path):
    root = _tree(tmp_path, {
        "neck_sim/plant.py": "_DISPATCH = 1\nPlant = 2\n",
        "neck_sim/_kernel.py": "x = 1\n",
        "neck_sim/sub/__init__.py": "from ._helper import y\n",       # inside its own package
        "neck_sim/sub/_helper.py": "y = 1\n",
        "controllers/ok.py": "from neck_sim.plant import Plant\nimport neck_sim\nneck_sim.__file__\n",
        "controllers/own.py": "from ._mine import z\nfrom controllers._mine import z\n",
        "controllers/_mine.py": "z = 1\n",
        "controllers/bad_attr.py": "def f():\n    from neck_sim.plant import _DISPATCH\n",
        "controllers/bad_module.py": "import neck_sim._kernel\n",
        "identification/bad_read.py": "from neck_sim import plant\nplant._DISPATCH\n",
        "identification/bad_chain.py": "import neck_sim.plant\nneck_sim.plant._DISPATCH\n",
        "identification/bad_rel.py": "from neck_sim.sub import _helper\n",
    })
    assert private_cross_imports(root) == [
        "controllers.bad_attr: neck_sim.plant._DISPATCH",
        "controllers.bad_module: neck_sim._kernel",
        "identification.bad_chain: neck_sim.plant._DISPATCH",
        "identification.bad_read: neck_sim.plant._DISPATCH",
        "identification.bad_rel: neck_sim.sub._helper",
    ]
    (root / "identification/bad_read.py").unlink()
    (root / "identification/bad_chain.py").unlink()
    (root / "identification/bad_rel.py").unlink()
    (root / "controllers/bad_attr.py").unlink()
    (root / "controllers/bad_module.py").unlink()
    assert private_cross_imports(root) == []


def test_cycle_checker_both_ways(tmp_path):
    root = _tree(tmp_path, {
        "controllers/trajectories.py": "from controllers.computed_torque import ct\n",
        "controllers/computed_torque.py": "from .trajectories import make\n",
        # a face re-exporting its modules, imports inside functions and under TYPE_CHECKING: no circle
        "neck_sim/__init__.py": "from neck_sim.plant import Plant\n",
        "neck_sim/plant.py": "from typing import TYPE_CHECKING\nimport neck_sim.params\n"
                             "if TYPE_CHECKING:\n    from neck_sim.env import Env\n",
        "neck_sim/params.py": "def f():\n    from neck_sim import plant\n",
        "neck_sim/env.py": "from neck_sim.plant import Plant\n",
    })
    assert import_cycles(root) == ["controllers.computed_torque -> controllers.trajectories -> "
                                   "controllers.computed_torque"]
    (root / "controllers/computed_torque.py").write_text("def g():\n    from .trajectories import make\n")
    assert import_cycles(root) == []
    assert import_cycles(root, deferred=True) == [
        "controllers.computed_torque -> controllers.trajectories -> controllers.computed_torque",
        # the function-level and TYPE_CHECKING imports make one component of three modules
        "neck_sim.env -> neck_sim.plant -> neck_sim.env  "
        "(component: ['neck_sim.env', 'neck_sim.params', 'neck_sim.plant'])"]
    # a circle through three modules is named whole
    (root / "neck_sim/params.py").write_text("import neck_sim.env\n")
    assert import_cycles(root) == ["neck_sim.env -> neck_sim.plant -> neck_sim.params -> neck_sim.env"]


def test_length_checker_both_ways(tmp_path):
    root = _tree(tmp_path, {"neck_sim/short.py": "x = 1\n" * MAX_LINES,
                            "identification/long.py": "x = 1\n" * (MAX_LINES + 1)})
    assert long_modules(root) == [f"identification/long.py: {MAX_LINES + 1} lines"]
    (root / "identification/long.py").write_text("x = 1\n" * MAX_LINES)
    assert long_modules(root) == []


def test_issue_reference_checker_both_ways(tmp_path):
    word, h = "issue", "#"    # kept apart so that this file does not match its own rule
    root = _tree(tmp_path, {
        "neck_sim/a.py": f'"""Statics ({word} 15, item 3)."""\nx = 1  # see {word.title()}-3\n',
        "benchmarks/b.py": f"# {word} {h}12 and {h}7 too\n",
        "tests/test_c.py": f"'''{word}_4'''\n",
        # look-alikes that are not references: a colour, an HTML entity, words, "# 3 cables"
        "controllers/ok.py": f"c = '{h}1f77b4'\ne = '&{h}39;'\n# the {word} asked for 3 cables\n# 3 N\n",
    })
    assert [hit.split(": ")[0] for hit in issue_references(root)] == [
        "benchmarks/b.py:1", "benchmarks/b.py:1", "neck_sim/a.py:1", "neck_sim/a.py:2", "tests/test_c.py:1"]
    for rel in ("neck_sim/a.py", "benchmarks/b.py", "tests/test_c.py"):
        (root / rel).write_text("x = 1\n")
    assert issue_references(root) == []
