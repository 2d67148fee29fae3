"""One contract over every name the three package faces export (``neck_sim``, ``controllers``,
``identification``), in the style of dm_control's ``suite_test.py``: each name imports, says what it
is (a docstring, or a ``#:`` comment for a constant), annotates its parameters and return when
callable, comes from a module that ``tests/test_typing.py`` type-checks, and is named in the
documentation (README.md or docs/).  The usage example of each face's docstring runs as written,
and importing the faces loads none of the heavy dependencies (``neck-sim --help`` imports
``neck_sim``).
"""

import ast
import enum
import importlib
import inspect
import pathlib
import re
import subprocess
import sys
import textwrap

import pytest

from test_typing import PUBLIC_MODULES

ROOT = pathlib.Path(__file__).resolve().parents[1]
FACES = ("neck_sim", "controllers", "identification")
EXPORTS = [(face, name) for face in FACES for name in importlib.import_module(face).__all__]

def usage_example(doc):
    """The indented block after ``Usage::`` in a docstring, dedented."""
    lines = doc.split("Usage::", 1)[1].splitlines()[1:]
    block = []
    for line in lines:
        if line.strip() and not line.startswith(" "):
            break
        block.append(line)
    return textwrap.dedent("\n".join(block)).strip() + "\n"


def documentation():
    return (ROOT / "README.md").read_text() + "".join(p.read_text() for p in sorted((ROOT / "docs").glob("*.md")))


def defining_module(face, name):
    value = getattr(importlib.import_module(face), name)
    if inspect.ismodule(value):
        return value.__name__
    if callable(value):
        return value.__module__
    return importlib.import_module(face)._SOURCES[name]


def has_doc_comment(module, name):
    """A constant's ``#:`` comment on the line above its assignment (Sphinx's convention)."""
    lines = inspect.getsource(importlib.import_module(module)).splitlines()
    for i, line in enumerate(lines):
        if re.match(rf"{re.escape(name)}\s*(:[^=]*)?=", line):
            return i > 0 and lines[i - 1].lstrip().startswith("#:")
    return False


def missing_annotations(fn):
    """Parameters (self, cls aside) and the return of ``fn`` that carry no annotation."""
    sig = inspect.signature(fn)
    missing = [p.name for p in sig.parameters.values()
               if p.annotation is inspect.Parameter.empty and p.name not in ("self", "cls")]
    return missing + (["return"] if sig.return_annotation is inspect.Signature.empty else [])


@pytest.mark.parametrize("face", FACES)
def test_all_matches_what_the_face_resolves(face):
    module = importlib.import_module(face)
    assert len(module.__all__) == len(set(module.__all__))
    assert set(module.__all__) == set(module._SOURCES), face
    assert set(module.__all__) <= set(dir(module))
    with pytest.raises(AttributeError, match=f"module '{face}' has no attribute 'no_such_name'"):
        getattr(module, "no_such_name")


@pytest.mark.parametrize("face, name", EXPORTS)
def test_export_imports_and_says_what_it_is(face, name):
    value = getattr(importlib.import_module(face), name)
    if isinstance(value, type):
        # the class's own docstring: a dataclass or a named tuple without one gets its signature
        node = ast.parse(textwrap.dedent(inspect.getsource(value))).body[0]
        assert ast.get_docstring(node), f"{face}.{name}: no docstring"
    elif callable(value) or inspect.ismodule(value):
        assert (inspect.getdoc(value) or "").strip(), f"{face}.{name}: no docstring"
    else:
        assert has_doc_comment(defining_module(face, name), name), f"{face}.{name}: no '#:' comment"


@pytest.mark.parametrize("face, name", EXPORTS)
def test_export_is_annotated(face, name):
    value = getattr(importlib.import_module(face), name)
    if inspect.ismodule(value) or not callable(value):
        return
    if isinstance(value, type) and issubclass(value, tuple) and hasattr(value, "_fields"):
        missing = [f for f in value._fields if f not in value.__annotations__]     # a named tuple's fields
        assert not missing, f"{face}.{name}: unannotated fields {missing}"
        return
    if isinstance(value, type):
        own = [vars(value)[m] for m in ("__init__", "__new__") if m in vars(value)]
        if not own or issubclass(value, (BaseException, enum.Enum)) and "__init__" not in vars(value):
            return          # a constructor of Python's (Exception's message, Enum's value, object's)
        fn = own[0]
    else:
        fn = value
    assert not missing_annotations(fn), f"{face}.{name}: unannotated {missing_annotations(fn)}"


@pytest.mark.parametrize("face, name", EXPORTS)
def test_export_comes_from_a_typed_module(face, name):
    module = defining_module(face, name)
    assert module in PUBLIC_MODULES, \
        f"{face}.{name} is defined in {module}, which tests/test_typing.py does not check"


def test_every_export_is_documented():
    text = documentation()
    missing = [f"{face}.{name}" for face, name in EXPORTS if not re.search(rf"(?<![\w]){re.escape(name)}\b", text)]
    assert not missing, "exported but named nowhere in README.md or docs/: " + ", ".join(missing)


@pytest.mark.parametrize("face", FACES)
def test_usage_example_runs(face, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)             # the identification example writes its log here
    code = usage_example(importlib.import_module(face).__doc__)
    assert f"import {face}" in code or f"from {face} import" in code
    exec(compile(code, f"<{face} usage example>", "exec"), {})


def test_faces_import_nothing_heavy():
    heavy = ("mujoco", "numba", "scipy", "numpy", "matplotlib", "dask")
    code = (f"import sys, neck_sim, controllers, identification, neck_sim.cli; "
            f"print(sorted(m for m in {heavy!r} if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]", out.stdout + out.stderr


# -- the helpers themselves ----------------------------------------------------------------------

def test_usage_example_stops_at_the_next_paragraph():
    doc = "Title.\n\nUsage::\n\n    a = 1\n\n    b = a\n\nNext paragraph.\n    not code\n"
    assert usage_example(doc) == "a = 1\n\nb = a\n"


def test_missing_annotations_both_ways():
    def typed(x: int, *rest: int, y: str = "", **kw: float) -> int: ...

    def untyped(x, y: int): ...

    assert missing_annotations(typed) == []
    assert missing_annotations(untyped) == ["x", "return"]
