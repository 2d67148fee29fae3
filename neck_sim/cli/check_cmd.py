"""`neck-sim check LOG`: a simulated log's truth against the analytic model."""

from __future__ import annotations

import argparse

HELP = "check a simulated log's truth against the analytic model (cable lengths, torques, elongation sign)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("log", metavar="LOG", help="MCAP log with /neck/truth and /neck/motors")
    parser.add_argument("--json", metavar="PATH", help="also write the result as JSON")


def run(args: argparse.Namespace) -> int:
    from neck_sim.cli.common import check_paths
    check_paths(inputs={"LOG": args.log}, files={"--json": args.json})
    from neck_sim.check import check_log
    from neck_sim.atomic import atomic_write_json

    result = check_log(args.log)
    print(f"{args.log}: model constants from the {result.params_source}")
    print(result.table())
    print("all relations within tolerance" if result.passed else "some relations exceed their tolerance")
    if args.json:
        atomic_write_json(args.json, result.as_dict())
    return 0 if result.passed else 1
