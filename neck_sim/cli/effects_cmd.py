"""`neck-sim effects`: the effect vocabulary (what the plant can hide and the diagnosis names)."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from neck_sim.effects import Effect

HELP = "list the effect vocabulary: what each effect is, its fitted parameters (units), shapes and prerequisites"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--markdown", action="store_true", help="print a Markdown table")


def describe(cls: type[Effect]) -> tuple[str, str, str, str]:
    """(parameters, shapes, requires, plant) of an effect class, as text (its fitted parameters
    and shapes from its columns, none when the diagnosis has no columns for it)."""
    from identification.diagnosis import columns

    fit = columns.get(cls.name) if cls.name in columns.names() else columns.EffectColumns
    params = ", ".join(f"{c.symbol} [{c.unit}]" + ("" if c.per == "one" else f" per {c.per}") for c in fit.columns)
    shapes = ", ".join(f"{s.name} [{s.unit}]" + (f" per cable in {list(s.grid)}" if s.per_cable and s.grid else
                                                 f" {s.default:g} in {list(s.grid)}" if s.grid else
                                                 f" per cable in {list(s.bounds)}" if s.per_cable else "")
                       for s in fit.shapes)
    plant = cls.kind + (" (paper's model)" if cls.baseline else "")
    return params or "-", shapes or "-", ", ".join(cls.requires) or "-", plant


def run(args: argparse.Namespace) -> int:
    from neck_sim import effects

    rows = [(cls.name, cls.description, *describe(cls)) for cls in effects.registered()]
    head = ("effect", "description", "fitted parameters", "shapes", "requires", "acts on")
    if args.markdown:
        print("| " + " | ".join(head) + " |\n" + "|---" * len(head) + "|")
        for r in rows:
            print("| " + " | ".join(r) + " |")
    else:
        for name, desc, params, shapes, req, plant in rows:
            print(f"{name:20s} {desc}\n{'':20s} fitted: {params}; shapes: {shapes}; requires: {req}; acts on: {plant}")
    print(f"\n{effects.INSUFFICIENT_EXCITATION}: the log cannot support a verdict (too short, too still): what it "
          "lacks and what to record")
    print(f"{effects.NONE}: the model explains the data")
    print(f"{effects.UNEXPLAINED}: the model leaves structure in the residuals beyond noise that no effect above "
          "explains (alone, or after the effects named)")
    return 0
