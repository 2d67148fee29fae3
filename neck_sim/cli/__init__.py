"""The ``neck-sim`` command line.

This package is the composer: it is the only part of ``neck_sim`` allowed to import
``controllers`` and ``identification`` (``tests/test_layers.py`` holds that).  Each command
lives in its own module of this package exposing ``HELP``, ``add_arguments(parser)`` and
``run(args) -> int``; the table below registers it.  Modules are imported only when their command
runs, so ``neck-sim --help`` stays fast.

Exit status: 0 success; 1 a check the command ran failed (drift, tolerance); 2 a user error (bad
option, input or output path; one line naming the problem, no traceback); 130 Ctrl-C and 143
SIGTERM (one line; temporary files removed); 70 an internal error (one line, and the full
traceback written to a file whose path the line gives).
"""

from __future__ import annotations

import argparse
import contextlib
import datetime
import importlib
import os
import signal
import sys
import tempfile
import threading
import traceback

# name -> module (inside neck_sim.cli) implementing it
COMMANDS: dict[str, str] = {
    "reproduce": "reproduce_cmd",
    "params": "params_cmd",
    "pulleys": "pulleys_cmd",
    "crossval": "crossval_cmd",
    "import": "import_cmd",
    "check": "check_cmd",
    "replay": "replay_cmd",
    "identify": "identify_cmd",
    "simulate": "simulate_cmd",
    "diagnose": "diagnose_cmd",
    "effects": "effects_cmd",
    "render": "render_cmd",
    "design": "design_cmd",
}


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="neck-sim",
        description="neck-sim: a MuJoCo testbed for cable-driven tensegrity necks (the paper's 3-X bird neck).",
        epilog="Start with `neck-sim reproduce` (add --quick for a short run); `neck-sim COMMAND --help` for details.")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for name, module in COMMANDS.items():
        mod = importlib.import_module(f"neck_sim.cli.{module}")
        p = sub.add_parser(name, help=mod.HELP, description=mod.HELP)
        mod.add_arguments(p)
        p.set_defaults(_run=mod.run)
    return parser


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised like Ctrl-C so that every ``finally`` and writer cleanup runs."""


def _raise_terminated(signum, frame):
    raise Terminated()


@contextlib.contextmanager
def _sigterm_as_exception():
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGTERM, _raise_terminated)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def write_traceback(exc: BaseException) -> str:
    """Write the full traceback of ``exc`` with the command line to a file; returns its path."""
    stamp = datetime.datetime.now().strftime("%Y%m%d-%H%M%S")
    fd, path = tempfile.mkstemp(prefix=f"neck-sim-traceback-{stamp}-", suffix=".txt")
    with os.fdopen(fd, "w") as fh:
        fh.write(f"command line: {sys.argv!r}\npython {sys.version}\n\n")
        fh.write("".join(traceback.format_exception(exc)))
    return path


def _import_mujoco_without_opengl() -> None:
    """Import MuJoCo with its OpenGL platform disabled, unless the user chose one (``MUJOCO_GL``).

    No command draws in its own process (``neck_sim.render`` renders in a child that picks its
    backend), and MuJoCo's default GLFW platform costs a probe subprocess at import (about 50 ms
    of a command's start).  The variable is restored at once, so children see the user's choice.
    """
    if "mujoco" in sys.modules or os.environ.get("MUJOCO_GL"):
        return
    os.environ["MUJOCO_GL"] = "disable"
    try:
        import mujoco  # noqa: F401
    finally:
        del os.environ["MUJOCO_GL"]


def main(argv: list[str] | None = None) -> int:
    try:
        args = build_parser().parse_args(argv)
    except SystemExit as exc:       # --help (0) or a bad option (2, argparse printed the usage)
        return exc.code if isinstance(exc.code, int) else 2
    name = f"neck-sim {args.command}"
    from neck_sim.cli.common import closed_stdout_error
    if (closed := closed_stdout_error(name)) is not None:
        print(closed, file=sys.stderr)
        return 2
    _import_mujoco_without_opengl()
    try:
        with _sigterm_as_exception():
            return int(args._run(args) or 0)
    except Terminated:
        print(f"{name}: terminated (SIGTERM); unfinished output files were removed", file=sys.stderr)
        return 143
    except KeyboardInterrupt:
        print(f"{name}: interrupted (Ctrl-C); unfinished output files were removed", file=sys.stderr)
        return 130
    except (ValueError, OSError, RuntimeError) as exc:
        # Errors from bad input name their problem; show that, not a traceback.
        print(f"{name}: error: {exc}", file=sys.stderr)
        return 2
    except Exception as exc:        # a bug: one line here, the whole story in a file
        path = write_traceback(exc)
        print(f"{name}: internal error: {type(exc).__name__}: {exc} (a bug in neck-sim; please report it with "
              f"the full traceback written to {path})", file=sys.stderr)
        return 70


if __name__ == "__main__":
    sys.exit(main())
