"""`neck-sim params`: show or write the parameter set with units and sources."""

from __future__ import annotations

import argparse

from neck_sim import params as P
from neck_sim.cli.common import add_implausible_params_argument

HELP = "print every constant with unit and source, or write a parameter file to edit"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--n-joints", type=int, default=None, help="number of X-joints N (default 3)")
    parser.add_argument("--load", metavar="PATH", help="show this parameter file (.json/.toml) instead of the defaults")
    add_implausible_params_argument(parser)
    parser.add_argument("--example", choices=sorted(P.EXAMPLES),
                        help="start from an example neck: "
                             + "; ".join(f"{k}: {v[2]}" for k, v in P.EXAMPLES.items()))
    parser.add_argument("-o", "--output", metavar="PATH", help="write the parameters to PATH (.json or .toml)")


def run(args: argparse.Namespace) -> int:
    from neck_sim.cli.common import add_implausible_params_argument, check_paths, load_params_file
    check_paths(inputs={"--load": args.load}, files={"-o": args.output})
    chosen = [opt for opt, given in (("--load", args.load), ("--example", args.example),
                                     ("--n-joints", args.n_joints is not None)) if given]
    if len(chosen) > 1:
        raise ValueError(f"{' and '.join(chosen)}: choose one source of parameters")
    if args.load:
        params = load_params_file(args.load, "--load", accept_implausible=args.accept_implausible_params)
    elif args.example:
        params = P.example_params(args.example)
    else:
        params = P.default_params(3 if args.n_joints is None else args.n_joints)
    if args.output:
        P.save(params, args.output)
        print(f"wrote {args.output}")
    else:
        print(P.describe(params))
    return 0
