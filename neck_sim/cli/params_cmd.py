"""`neck-sim params`: show or write the parameter set with units and sources."""

from __future__ import annotations

from neck_sim import params as P

HELP = "print every constant with unit and source, or write a parameter file to edit"


def add_arguments(parser) -> None:
    parser.add_argument("--n-joints", type=int, default=3, help="number of X-joints N (default 3)")
    parser.add_argument("--load", metavar="PATH", help="show this parameter file (.json/.toml) instead of the defaults")
    parser.add_argument("-o", "--output", metavar="PATH", help="write the parameters to PATH (.json or .toml)")


def run(args) -> int:
    from neck_sim.cli.common import check_paths, load_params_file
    check_paths(inputs={"--load": args.load}, files={"-o": args.output})
    params = load_params_file(args.load, "--load") if args.load else P.default_params(args.n_joints)
    if args.output:
        P.save(params, args.output)
        print(f"wrote {args.output}")
    else:
        print(P.describe(params))
    return 0
