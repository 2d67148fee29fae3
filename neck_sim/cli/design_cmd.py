"""`neck-sim design`: compare cable routings for one neck."""

from __future__ import annotations

import argparse
import os
from typing import TYPE_CHECKING

from neck_sim.cli.common import add_params_arguments, check_paths, nonnegative_int, params_from_args

if TYPE_CHECKING:
    from neck_sim.params import NeckParams

# without --params or --n-joints: the paper's next neck, ten X-joints
DEFAULT_N_JOINTS = 10

HELP = (f"compare cable routings for one neck (default: the {DEFAULT_N_JOINTS}-X neck): reachable workspace, stiffness, "
        "holding forces, friction spread; writes DIR/report.md, DIR/results.json and figures")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_params_arguments(parser, default_n_joints=DEFAULT_N_JOINTS)
    parser.add_argument("-o", "--out", metavar="DIR", default="design-report",
                        help="output directory (default ./design-report)")
    parser.add_argument("--cables", type=int, default=4, metavar="M",
                        help="cable count of the proposed strategies (even, >= 4; default %(default)s)")
    parser.add_argument("--samples", type=int, default=500, metavar="K",
                        help="tension samples per routing (default %(default)s)")
    parser.add_argument("--seed", type=nonnegative_int, default=0, help="seed of the tension samples")
    parser.add_argument("--no-strategies", action="store_true",
                        help="evaluate only the parameter file's routing")


def neck_params(args: argparse.Namespace) -> NeckParams:
    """The neck to study: ``--params`` / ``--n-joints``, else the paper's design with
    :data:`DEFAULT_N_JOINTS` X-joints (sets ``args.n_joints`` then)."""
    if args.params is None and args.n_joints is None:
        args.n_joints = DEFAULT_N_JOINTS
    return params_from_args(args)


def _candidates(params, args):
    from neck_sim.design import Strategy, routing_strategies

    given = Strategy("given", "the routing of the parameter file" if args.params else "the paper's routing, N + 1 cables",
                     params)
    if args.no_strategies:
        return [given]
    proposed = routing_strategies(params, args.cables)
    mine = sorted(params.routing.segment_cases(params.n_joints).tolist())
    for k, s in enumerate(proposed):
        if sorted(s.params.routing.segment_cases(params.n_joints).tolist()) == mine:
            # the file holds this strategy (up to cable order): evaluate the file's own constants
            proposed[k] = Strategy(s.name, s.description + " (the parameter file's routing)", params)
            return proposed
    return [given] + proposed


def run(args: argparse.Namespace) -> int:
    from tqdm.auto import tqdm

    from neck_sim.design import evaluate
    from neck_sim.design_report import OUTPUT_FILES, write_report

    check_paths(inputs={"--params": args.params}, dirs={"-o": args.out})
    if args.samples < 1:
        raise ValueError(f"--samples: need at least 1, got {args.samples}")
    params = neck_params(args)
    out = os.path.abspath(args.out)
    if args.params and os.path.abspath(args.params) in {os.path.join(out, f) for f in OUTPUT_FILES}:
        raise ValueError(f"-o {args.out}: would write over the parameter file {args.params}")
    candidates = _candidates(params, args)
    results = []
    for strategy in tqdm(candidates, desc="routings", unit="routing"):
        results.append(evaluate(strategy, args.samples, seed=args.seed, progress=True))
    source = args.params or f"default {params.n_joints}-joint neck"
    write_report(results, out, samples=args.samples, seed=args.seed, source=source)
    for r in results:
        w = r.summary["workspace"]
        print(f"{r.strategy.name:>10}: feasible {100 * w['feasible_fraction']:5.1f} %, head area "
              f"{w['head_area_cm2']:6.0f} cm^2, straight min eig K_theta "
              + ", ".join(f"{s['min_eig_motor']:.2f}" for s in r.summary["straight"].values())
              + " N m/rad at pretensions " + ", ".join(r.summary["straight"]) + " N")
    print(f"report: {os.path.join(out, 'report.md')}")
    return 0
