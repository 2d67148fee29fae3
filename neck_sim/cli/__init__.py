"""The ``neck-sim`` command line.

This package is the composer: it is the only part of ``neck_sim`` allowed to import
``controllers`` and ``identification`` (``tests/test_layers.py`` holds that).  Each command
lives in its own module of this package exposing ``HELP``, ``add_arguments(parser)`` and
``run(args) -> int``; the table below registers it.  Modules are imported only when their command
runs, so ``neck-sim --help`` stays fast.
"""

from __future__ import annotations

import argparse
import importlib
import sys

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


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return int(args._run(args) or 0)
    except (ValueError, OSError, RuntimeError) as exc:
        # Errors from bad input name their problem; show that, not a traceback.
        print(f"neck-sim {args.command}: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
