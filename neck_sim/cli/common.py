"""Arguments shared by several commands."""

from __future__ import annotations

from neck_sim import params as P


def add_params_arguments(parser) -> None:
    """``--params PATH`` and ``--n-joints N``: which neck a command works on."""
    parser.add_argument("--params", metavar="PATH",
                        help="parameter file (.json/.toml, see `neck-sim params -o`); default: the paper's neck")
    parser.add_argument("--n-joints", type=int, default=None,
                        help="number of X-joints N (default 3, or the parameter file's)")


def params_from_args(args) -> P.NeckParams:
    """The parameters chosen by :func:`add_params_arguments`' options."""
    if args.n_joints is not None and args.n_joints < 1:
        raise ValueError(f"--n-joints: must be >= 1, got {args.n_joints}")
    if args.params:
        params = P.load(args.params)
        if args.n_joints is not None and args.n_joints != params.n_joints:
            raise ValueError(f"--n-joints {args.n_joints} contradicts {args.params} (n_joints = {params.n_joints})")
        return params
    return P.default_params(3 if args.n_joints is None else args.n_joints)
