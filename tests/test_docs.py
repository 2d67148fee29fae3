"""Every command and Python snippet in the documentation runs as printed.

The fenced code blocks of ``README.md`` and ``docs/*.md`` (whatever pages exist) are extracted and
run, one test per file, in a fresh temporary directory, in document order:

* ```` ```bash ```` blocks run with ``bash -e -o pipefail``; ``neck-sim`` on their PATH is a shim
  that runs ``python -m neck_sim.cli`` of the checkout under test (not an installed copy);
* ```` ```python ```` blocks run in one namespace per file (a later block sees an earlier block's
  names), in a separate Python process whose ``neck_sim`` is the checkout's;
* other fences (```` ```text ````, ```` ```toml ````, bare ```` ``` ````) are never run.

Markers, on the last non-blank line before a block's opening fence:

* ``<!-- doc-test: skip (reason) -->``: never run (installs, hardware, files the reader must
  bring); the reason is required;
* ``<!-- doc-test: slow -->``: run only when ``NECK_SIM_SLOW_DOCS=1`` (CI runs the rest).

A file whose blocks are all skipped (or slow, in CI) still has its markers checked.
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import textwrap
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SLOW = os.environ.get("NECK_SIM_SLOW_DOCS") == "1"
RUN_LANGS = {"bash", "python"}
MARKER = re.compile(r"^<!--\s*doc-test:\s*(?P<kind>skip|slow)\s*(?P<reason>\(.*\))?\s*-->$")
FENCE = re.compile(r"^(?P<indent>\s*)(?P<fence>`{3,}|~{3,})(?P<info>[^`]*)$")
TIMEOUT_S = 900


@dataclass(frozen=True)
class Block:
    """One fenced code block: its language, code, 1-based line of the opening fence, marker."""

    lang: str
    code: str
    line: int
    marker: str | None = None  # "skip", "slow" or None


def doc_files() -> list[Path]:
    """README.md and every docs/*.md that exists now (other pages included)."""
    files = [ROOT / "README.md"] + sorted((ROOT / "docs").glob("*.md"))
    return [f for f in files if f.is_file()]


def extract_blocks(text: str, name: str = "<doc>") -> list[Block]:
    """Every fenced block of a Markdown text with its marker; raises ValueError on a malformed
    marker (unknown kind, a skip without its reason) or an unclosed fence."""
    lines = text.split("\n")
    blocks: list[Block] = []
    last_nonblank = ""
    i = 0
    while i < len(lines):
        m = FENCE.match(lines[i])
        stripped = lines[i].strip()
        if stripped.startswith("<!--") and "doc-test" in stripped:
            mm = MARKER.match(stripped)
            if mm is None or (mm["kind"] == "skip" and not mm["reason"]):
                raise ValueError(f"{name}:{i + 1}: malformed doc-test marker {stripped!r} "
                                 "(use <!-- doc-test: skip (reason) --> or <!-- doc-test: slow -->)")
        if m is None:
            if stripped:
                last_nonblank = stripped
            i += 1
            continue
        fence, indent = m["fence"], m["indent"]
        lang = m["info"].strip().split()[0].lower() if m["info"].strip() else ""
        start = i
        body = []
        i += 1
        while i < len(lines) and not (lines[i].strip().startswith(fence[0] * len(fence))
                                      and set(lines[i].strip()) == {fence[0]}):
            body.append(lines[i][len(indent):] if lines[i].startswith(indent) else lines[i])
            i += 1
        if i >= len(lines):
            raise ValueError(f"{name}:{start + 1}: unclosed code fence")
        mm = MARKER.match(last_nonblank)
        blocks.append(Block(lang, "\n".join(body) + "\n", start + 1, mm["kind"] if mm else None))
        last_nonblank = ""
        i += 1
    return blocks


def runnable(blocks: list[Block], slow: bool = SLOW) -> list[Block]:
    """The blocks a run executes: bash and python blocks, minus skipped ones (and slow ones
    unless ``slow``)."""
    return [b for b in blocks if b.lang in RUN_LANGS and b.marker != "skip" and (slow or b.marker != "slow")]


# The runner executes one file's blocks in order in the current directory: python blocks by exec
# in one namespace, bash blocks as subprocesses.  It prints a line naming the block that failed.
RUNNER = textwrap.dedent("""
    import json, subprocess, sys, traceback
    blocks = json.load(open(sys.argv[1]))
    namespace = {"__name__": "__main__"}
    for b in blocks:
        where = f"{b['file']}:{b['line']} ({b['lang']} block)"
        print(f"=== {where}", flush=True)
        if b["lang"] == "python":
            try:
                exec(compile(b["code"], where, "exec"), namespace)
            except SystemExit as e:
                if e.code not in (0, None):
                    print(f"DOC-TEST FAILED: {where}: SystemExit({e.code!r})", flush=True)
                    sys.exit(1)
            except BaseException:
                traceback.print_exc()
                sys.stdout.flush()
                print(f"DOC-TEST FAILED: {where}", flush=True)
                sys.exit(1)
        else:
            rc = subprocess.run(["bash", "-e", "-o", "pipefail", "-c", b["code"]]).returncode
            if rc != 0:
                print(f"DOC-TEST FAILED: {where}: exit status {rc}", flush=True)
                sys.exit(1)
""")


def run_blocks(blocks: list[Block], name: str, workdir: Path, root: Path = ROOT) -> subprocess.CompletedProcess:
    """Run ``blocks`` of file ``name`` in ``workdir`` against the checkout at ``root``."""
    shim_dir = workdir / ".doc-test-bin"
    shim_dir.mkdir()
    shim = shim_dir / "neck-sim"
    shim.write_text(f'#!/bin/sh\nexec "{sys.executable}" -m neck_sim.cli "$@"\n')
    shim.chmod(0o755)
    for exe in ("python", "python3"):  # the interpreter under test, not whatever PATH finds
        (shim_dir / exe).symlink_to(sys.executable)
    (workdir / ".doc-test-blocks.json").write_text(json.dumps(
        [{"file": name, "line": b.line, "lang": b.lang, "code": b.code} for b in blocks]))
    (workdir / ".doc-test-runner.py").write_text(RUNNER)
    env = dict(os.environ)
    env["PATH"] = f"{shim_dir}{os.pathsep}{env.get('PATH', '')}"
    env["PYTHONPATH"] = os.pathsep.join([str(root)] + ([env["PYTHONPATH"]] if env.get("PYTHONPATH") else []))
    env.setdefault("MPLBACKEND", "Agg")
    return subprocess.run([sys.executable, ".doc-test-runner.py", ".doc-test-blocks.json"], cwd=workdir,
                          env=env, capture_output=True, text=True, timeout=TIMEOUT_S)


@pytest.mark.parametrize("path", doc_files(), ids=lambda p: str(p.relative_to(ROOT)))
def test_doc_blocks_run_as_printed(path: Path, tmp_path: Path):
    name = str(path.relative_to(ROOT))
    every = extract_blocks(path.read_text(encoding="utf-8"), name)
    blocks = runnable(every)
    if not blocks:
        slow = sum(b.marker == "slow" for b in every)
        pytest.skip(f"{name}: no block to run" + (f" ({slow} slow: NECK_SIM_SLOW_DOCS=1 runs them)" if slow else ""))
    proc = run_blocks(blocks, name, tmp_path)
    tail = (proc.stdout[-6000:] + "\n--- stderr ---\n" + proc.stderr[-6000:])
    assert proc.returncode == 0, f"{name}: a code block failed as printed\n{tail}"
    assert proc.stdout.count("=== ") == len(blocks), tail


# --- the extractor and runner themselves ---------------------------------------------------------

SAMPLE = """\
Intro.

```bash
echo one > a.txt
```

<!-- doc-test: skip (needs hardware) -->
```bash
exit 3
```

<!-- doc-test: slow -->

```python
SLOW_NAME = 1
```

```python
x = open("a.txt").read().strip()
```

```text
not run
```

```python
assert x == "one"
```
"""


def test_extract_blocks_reads_languages_lines_and_markers():
    blocks = extract_blocks(SAMPLE)
    assert [(b.lang, b.line, b.marker) for b in blocks] == [
        ("bash", 3, None), ("bash", 8, "skip"), ("python", 14, "slow"), ("python", 18, None),
        ("text", 22, None), ("python", 26, None)]
    assert [b.line for b in runnable(blocks, slow=False)] == [3, 18, 26]
    assert [b.line for b in runnable(blocks, slow=True)] == [3, 14, 18, 26]


def test_extract_blocks_refuses_bad_markers_and_unclosed_fences():
    with pytest.raises(ValueError, match="malformed"):
        extract_blocks("<!-- doc-test: skip -->\n```bash\nls\n```\n")
    with pytest.raises(ValueError, match="malformed"):
        extract_blocks("<!-- doc-test: sometimes -->\n```bash\nls\n```\n")
    with pytest.raises(ValueError, match="unclosed"):
        extract_blocks("```python\nx = 1\n")


def test_runner_keeps_order_and_namespace_and_names_the_failing_block(tmp_path):
    blocks = runnable(extract_blocks(SAMPLE), slow=False)
    (tmp_path / "ok").mkdir()
    ok = run_blocks(blocks, "sample.md", tmp_path / "ok")
    assert ok.returncode == 0, ok.stdout + ok.stderr
    bad = extract_blocks("```python\ny = 1\n```\n\n```bash\nneck-sim no-such-command\n```\n")
    (tmp_path / "bad").mkdir()
    proc = run_blocks(bad, "bad.md", tmp_path / "bad")
    assert proc.returncode == 1
    assert "DOC-TEST FAILED: bad.md:5 (bash block)" in proc.stdout
    # the shim runs this checkout's CLI: a bad command is its one-line usage error (exit 2)
    assert "exit status 2" in proc.stdout


# Pages other work is writing; a link to one of them is accepted while the page does not exist yet.
PENDING_PAGES = {"install.md", "campaigns.md", "live-view.md", "identification.md", "diagnosis.md",
                 "reliability.md", "your-own-neck.md"}
LINK = re.compile(r"\]\((?P<target>[^)#\s]+)(?:#[^)\s]*)?\)")


def broken_links(path: Path) -> list[str]:
    """Relative Markdown links of ``path`` whose file does not exist (pending pages excepted)."""
    out = []
    for m in LINK.finditer(path.read_text(encoding="utf-8")):
        target = m["target"]
        if re.match(r"^[a-z]+:", target):
            continue
        dest = (path.parent / target).resolve()
        if not dest.exists() and dest.name not in PENDING_PAGES:
            out.append(target)
    return out


@pytest.mark.parametrize("path", doc_files(), ids=lambda p: str(p.relative_to(ROOT)))
def test_relative_links_resolve(path: Path):
    assert broken_links(path) == []


def test_broken_links_are_found(tmp_path):
    page = tmp_path / "page.md"
    (tmp_path / "there.md").write_text("x")
    page.write_text("[a](there.md) [b](missing.md#part) [c](https://example.org) [d](install.md)")
    assert broken_links(page) == ["missing.md"]
