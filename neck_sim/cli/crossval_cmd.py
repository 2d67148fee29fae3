"""`neck-sim crossval`: the MuJoCo model against the analytic model (issue 3, item 4)."""

from __future__ import annotations

import math

HELP = ("compare the MuJoCo neck with the analytic model (cable lengths, Z, M, g) at random poses; "
        "exit code 1 when an error exceeds its threshold")


def add_arguments(parser) -> None:
    parser.add_argument("--n-joints", type=int, default=3, help="number of X-joints N (default 3)")
    parser.add_argument("--samples", type=int, default=200, help="random poses (default 200)")
    parser.add_argument("--range-deg", type=float, default=60.0,
                        help="poses uniform in [-range, range]^N degrees (default 60)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--params", metavar="PATH", help="parameter file (.json/.toml); default: the paper's neck")
    parser.add_argument("--json", metavar="PATH", help="also write the table as JSON (atomically)")
    parser.add_argument("--dynamics", action="store_true",
                        help="also run the dynamics check: 10 s of constant antagonistic forces (loop gaps, "
                             "tensions) and the free response against the analytic eqs 29-30 over 1 s")
    parser.add_argument("--timestep", type=float, default=None, help="physics timestep for --dynamics (s)")


def run(args) -> int:
    from neck_sim import params as P
    from neck_sim.crossval import crossval, format_table

    if args.params:
        params = P.load(args.params)
        if args.n_joints != 3 and args.n_joints != params.n_joints:
            raise ValueError(f"--n-joints {args.n_joints} contradicts {args.params} (n_joints = {params.n_joints})")
    else:
        if args.n_joints < 1:
            raise ValueError(f"--n-joints: must be >= 1, got {args.n_joints}")
        params = P.default_params(args.n_joints)
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
        import json
        from neck_sim.params import atomic_write_bytes
        atomic_write_bytes(args.json, (json.dumps(payload, indent=2) + "\n").encode())
    return 0 if ok else 1
