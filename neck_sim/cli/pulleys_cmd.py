"""`neck-sim pulleys`: the paper's §5.6 pulley indicators recomputed."""

from __future__ import annotations


import argparse

from neck_sim import params as P
from neck_sim.atomic import atomic_write_json
from neck_sim.cli.common import check_paths, nonnegative_int, positive_int

HELP = "recompute the paper's pulley indicators (torque 16 percent, eq 35 increments 13 percent)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--n-joints", type=positive_int, default=3, metavar="N",
                        help="X-joints of the paper's neck to study")
    parser.add_argument("--samples", type=positive_int, default=100_000, metavar="K",
                        help="random poses and force vectors the indicators are averaged over")
    parser.add_argument("--seed", type=nonnegative_int, default=0, help="seed of the random samples")
    parser.add_argument("--json", metavar="PATH", help="also write the numbers as JSON")


def run(args: argparse.Namespace) -> int:
    from neck_sim.pulley_study import pulley_effect    # numba kernels: only when the command runs

    check_paths(files={"--json": args.json})
    eff = pulley_effect(P.default_params(args.n_joints), args.samples, args.seed)
    print(f"{'indicator':<44} {'neck-sim':>9} {'median':>8} {'paper':>6}")
    print(f"{'joint torque |Zf - Z0 f| / |Zf|':<44} {100 * eff.torque_rel_diff:8.1f}% "
          f"{100 * eff.torque_rel_diff_median:7.1f}% {'16%':>6}")
    print(f"{'eq (35) increment |da - da0| / |da|':<44} {100 * eff.increment_rel_diff:8.1f}% "
          f"{100 * eff.increment_rel_diff_median:7.1f}% {'13%':>6}")
    if args.json:
        atomic_write_json(args.json, eff._asdict())
    return 0
