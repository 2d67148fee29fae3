"""`neck-sim replay LOG`: re-simulate a log open loop with its commanded forces, report the drift."""

from __future__ import annotations

import argparse
import json
import os

from neck_sim.cli.common import (add_force_range_argument, add_implausible_params_argument, check_paths,
                                 load_params_file, nonnegative_float)

HELP = "re-simulate a log open loop from its initial state and commanded forces; report the drift"


def _parse_change(text: str) -> tuple[str, object]:
    key, sep, value = text.partition("=")
    if not sep or "." not in key:
        raise ValueError(f"--set {text!r}: expected group.field=VALUE, e.g. friction.c_s=0.6")
    try:
        parsed = json.loads(value)
    except json.JSONDecodeError:
        raise ValueError(f"--set {text!r}: VALUE must be a number or a JSON list") from None
    return key.strip(), tuple(parsed) if isinstance(parsed, list) else parsed


def _check_plausible_changes(changes: dict, *, accept: bool) -> None:
    """Refuse a ``--set`` value that reads as a unit mistake (the parameter file's check,
    :func:`neck_sim.params.implausible_values`), or warn when ``accept``."""
    from neck_sim.params import implausible_values

    nested: dict = {}
    for key, value in changes.items():
        group, _, field = key.partition(".")
        nested.setdefault(group, {})[field] = value
    for text in implausible_values(nested):
        if not accept:
            raise ValueError(f"--set {text} (pass --accept-implausible-params to use it anyway)")
        print(f"warning: --set {text} (accepted: --accept-implausible-params)")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("log", metavar="LOG", help="MCAP log with /neck/motors (and /neck/truth for alpha drift)")
    parser.add_argument("-o", "--output", metavar="MCAP", help="replay log (default: LOG with -replay.mcap)")
    parser.add_argument("--no-output", action="store_true", help="do not write the replay log")
    parser.add_argument("--set", action="append", default=[], metavar="GROUP.FIELD=VALUE",
                        help="change a plant parameter, e.g. --set friction.c_s=0.6 --set cables.k=[5000,5000,5000,2000]")
    parser.add_argument("--params", metavar="PATH", help="plant parameter file instead of the recorded one")
    add_implausible_params_argument(parser)
    parser.add_argument("--no-effects", action="store_true", help="replay without the recorded effects")
    parser.add_argument("--max-alpha-drift", type=nonnegative_float, metavar="DEG",
                        help="exit with status 1 when a joint angle drifts by more than DEG degrees")
    parser.add_argument("--json", metavar="PATH", help="also write the drift numbers as JSON")
    add_force_range_argument(parser)
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")


def run(args: argparse.Namespace) -> int:
    import math

    from neck_sim.atomic import atomic_write_json
    from neck_sim.effects import Effects
    from neck_sim.replay import replay

    output = None
    if not args.no_output:
        output = args.output or os.path.splitext(args.log)[0] + "-replay.mcap"
    check_paths(inputs={"LOG": args.log, "--params": args.params}, files={"-o": output, "--json": args.json})
    changes = dict(_parse_change(s) for s in args.set)
    _check_plausible_changes(changes, accept=args.accept_implausible_params)
    res = replay(args.log, params=load_params_file(args.params, accept_implausible=args.accept_implausible_params)
                 if args.params else None,
                 effects=Effects() if args.no_effects else None, changes=changes or None, output=output,
                 progress=not args.no_progress, accept_out_of_range_forces=args.accept_out_of_range_forces)
    for note in res.notes:
        print(f"note: {note}")
    if changes:
        print("changed: " + ", ".join(f"{k} = {v}" for k, v in changes.items()))
    print(f"replayed {len(res.t)} control steps ({res.t[-1] - res.t[0]:.3f} s)")
    print(res.table())
    if output:
        print(f"wrote {output}")
    alpha = res.max_alpha_drift()
    if args.json:
        data = {"steps": len(res.t), "max_theta_drift_rad": res.max_theta_drift().tolist(),
                "max_alpha_drift_rad": None if alpha is None else alpha.tolist(), "notes": list(res.notes),
                "changes": {k: list(v) if isinstance(v, tuple) else v for k, v in changes.items()}, "output": output}
        atomic_write_json(args.json, data)
    if args.max_alpha_drift is not None:
        if alpha is None:
            raise ValueError(f"{args.log}: no /neck/truth, alpha drift cannot be measured")
        worst = math.degrees(float(alpha.max()))
        if worst > args.max_alpha_drift:
            print(f"alpha drift {worst:.3g} deg exceeds {args.max_alpha_drift:g} deg")
            return 1
    return 0
