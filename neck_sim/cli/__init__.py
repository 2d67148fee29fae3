"""The ``neck-sim`` command line.

This package is the composer: it is the only part of ``neck_sim`` allowed to import
``controllers`` and ``identification`` (``tests/test_layers.py`` holds that).  Each command
lives in its own module of this package exposing ``HELP``, ``add_arguments(parser)`` and
``run(args) -> int``; the table below registers it.  Modules are imported only when their command
runs, so ``neck-sim --help`` stays fast.

Exit status: 0 success; 1 a check the command ran failed (drift, tolerance); 2 a user error (bad
option, input or output path; one line naming the problem, no traceback); 130 Ctrl-C and 143
SIGTERM (one line; temporary files removed); 141 the reader of standard output went away (``neck-sim
params | head -1``: nothing printed); 70 an internal error (one line, and the full traceback written
to a file whose path the line gives).
"""

from __future__ import annotations

import sys


def _interrupted_hook(exc_type, exc, tb, _default=sys.excepthook):
    """A Ctrl-C that reaches the top level (while modules load, before :func:`main` runs) prints one
    line instead of a traceback; Python then still exits by SIGINT."""
    if issubclass(exc_type, KeyboardInterrupt):
        print("neck-sim: interrupted (Ctrl-C)", file=sys.stderr)
    else:
        _default(exc_type, exc, tb)


# first thing, so that a Ctrl-C during the imports below (and the commands' imports) is one line
sys.excepthook = _interrupted_hook

import argparse
import contextlib
import datetime
import importlib
import os
import select
import signal
import tempfile
import threading
import traceback
from typing import NoReturn

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


def package_version() -> str:
    """The installed distribution's version (``neck-sim --version``)."""
    from importlib.metadata import PackageNotFoundError, version
    try:
        return version("neck-sim")
    except PackageNotFoundError:
        return "unknown (not installed)"


def one_line(text: str | BaseException) -> str:
    """``text`` on one line: its lines joined with '; ' (after a ':' or '(' with a space)."""
    lines = [line.strip() for line in str(text).splitlines() if line.strip()]
    out = ""
    for line in lines:
        out += line if not out else (" " if out.endswith((":", "(")) else "; ") + line
    return out


class OneLineParser(argparse.ArgumentParser):
    """argparse with a one-line error (the option, the problem, where to look) instead of the usage."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: error: {one_line(message)} (see `{self.prog} --help`)\n")


class DefaultsFormatter(argparse.HelpFormatter):
    """Help that states every option's default: the argparse value is appended to a help text that
    does not already say what the default is (``tests/test_cli_contract.py`` checks those that do)."""

    def _get_help_string(self, action):
        text = action.help or ""
        default = action.default
        if ("default" in text.lower() or default is None or default is False or default == []
                or default is argparse.SUPPRESS or not action.option_strings):
            return text
        return f"{text} (default: %(default)s)"


def build_parser() -> argparse.ArgumentParser:
    parser = OneLineParser(
        prog="neck-sim",
        description="neck-sim: a MuJoCo testbed for cable-driven tensegrity necks (the paper's 3-X bird neck).",
        epilog="Start with `neck-sim reproduce` (add --quick for a short run); `neck-sim COMMAND --help` for details.")
    parser.add_argument("--version", action="version", version=f"%(prog)s {package_version()}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for name, module in COMMANDS.items():
        mod = importlib.import_module(f"neck_sim.cli.{module}")
        p = sub.add_parser(name, help=mod.HELP, description=mod.HELP, formatter_class=DefaultsFormatter)
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


def _stdout_gone() -> bool:
    """True when standard output is a pipe or socket whose reader has closed it."""
    try:
        poller = select.poll()
        poller.register(sys.stdout.fileno(), select.POLLOUT)
        return any(ev & select.POLLERR for _, ev in poller.poll(0))
    except (AttributeError, OSError, ValueError):
        return False


def _silence_stdout() -> None:
    """Point the closed standard output at /dev/null so that the flush at exit stays quiet (the
    recipe of Python's ``signal`` documentation, note on SIGPIPE)."""
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, sys.stdout.fileno())
    os.close(devnull)


def main(argv: list[str] | None = None) -> int:
    name = "neck-sim"
    try:
        try:
            args = build_parser().parse_args(argv)
        except SystemExit as exc:   # --help, --version (0) or a bad option (2, one line printed)
            return exc.code if isinstance(exc.code, int) else 2
        name = f"neck-sim {args.command}"
        from neck_sim.cli.common import closed_stdout_error
        if (closed := closed_stdout_error(name)) is not None:
            print(closed, file=sys.stderr)
            return 2
        _import_mujoco_without_opengl()
        with _sigterm_as_exception():
            code = int(args._run(args) or 0)
        sys.stdout.flush()
        return code
    except BrokenPipeError as exc:
        if not _stdout_gone():
            return _user_error(name, exc)
        _silence_stdout()
        return 141
    except Terminated:
        print(f"{name}: terminated (SIGTERM); unfinished output files were removed", file=sys.stderr)
        return 143
    except KeyboardInterrupt:
        print(f"{name}: interrupted (Ctrl-C); unfinished output files were removed", file=sys.stderr)
        return 130
    except (ValueError, OSError, RuntimeError) as exc:
        return _user_error(name, exc)
    except Exception as exc:        # a bug: one line here, the whole story in a file
        if _caused_by_interrupt(exc):
            # a Ctrl-C inside an extension module's import (mujoco: "initialization failed")
            print(f"{name}: interrupted (Ctrl-C); unfinished output files were removed", file=sys.stderr)
            return 130
        path = write_traceback(exc)
        print(f"{name}: internal error: {type(exc).__name__}: {one_line(exc)} (a bug in neck-sim; please report "
              f"it with the full traceback written to {path})", file=sys.stderr)
        return 70


def _caused_by_interrupt(exc: BaseException) -> bool:
    """True when ``exc`` was raised while handling, or because of, a KeyboardInterrupt."""
    seen = set()
    link: BaseException | None = exc
    while link is not None and id(link) not in seen:
        if isinstance(link, KeyboardInterrupt):
            return True
        seen.add(id(link))
        link = link.__cause__ or link.__context__
    return False


def _user_error(name: str, exc: BaseException) -> int:
    """Errors from bad input name their problem: show that on one line, not a traceback."""
    text: str | BaseException = exc
    if isinstance(exc, OSError) and exc.filename and exc.strerror:      # "[Errno 2] ...: 'x'" -> "x: ..."
        text = f"{exc.filename}: {exc.strerror}"
    geometry = sys.modules.get("neck_sim.analytic.geometry")      # loaded whenever its PoseRangeError was raised
    if geometry is not None and isinstance(exc, geometry.PoseRangeError):      # its own text advises Python callers
        text = (f"{exc.problem}: the paper's model does not hold there (a simulated run that left its workspace, "
                "which `neck-sim simulate` refuses)")
    print(f"{name}: error: {one_line(text)}", file=sys.stderr)
    return 2


if __name__ == "__main__":
    sys.exit(main())
