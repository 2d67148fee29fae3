"""`neck-sim crossval`: the MuJoCo model against the analytic model."""

from __future__ import annotations

import argparse
import math

from neck_sim.cli.common import (add_params_arguments, check_paths, nonnegative_int, params_from_args, positive_float,
                                 positive_int)

HELP = ("compare the MuJoCo neck with the analytic model (cable lengths, Z, M, g) at random poses; "
        "exit code 1 when an error exceeds its threshold")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_params_arguments(parser)
    parser.add_argument("--samples", type=positive_int, default=200, help="random poses (default 200)")
    parser.add_argument("--range-deg", type=positive_float, default=60.0,
                        help="poses uniform in [-range, range]^N degrees (default 60)")
    parser.add_argument("--seed", type=nonnegative_int, default=0, help="seed of the random poses")
    parser.add_argument("--json", metavar="PATH", help="also write the table as JSON (atomically)")
    parser.add_argument("--dynamics", action="store_true",
                        help="also run the dynamics check: 10 s of constant antagonistic forces (loop gaps, "
                             "tensions) and the free response against the analytic eqs 29-30 over 1 s")
    parser.add_argument("--timestep", type=positive_float, default=None, help="physics timestep for --dynamics (s)")


def run(args: argparse.Namespace) -> int:
    from neck_sim.crossval import crossval, format_table

    check_paths(inputs={"--params": args.params}, files={"--json": args.json})
    params = params_from_args(args)
    report = crossval(params, samples=args.samples, seed=args.seed, alpha_range=math.radians(args.range_deg),
                      progress=args.samples >= 500)
    print(format_table(report))
    ok = report.ok
    payload = report.to_dict()
    if args.dynamics:
        from neck_sim.crossval import dynamics_check, format_dynamics
        dyn = dynamics_check(params, timestep=args.timestep, progress=True)
        print(format_dynamics(dyn))
        ok = ok and dyn.ok
        payload["dynamics"] = {**dyn._asdict(), "ok": dyn.ok}
    if args.json:
        from neck_sim.atomic import atomic_write_json
        atomic_write_json(args.json, payload)
    return 0 if ok else 1
