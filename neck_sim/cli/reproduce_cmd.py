"""`neck-sim reproduce`: the main job -- the paper reproduced in simulation, in one report."""

from __future__ import annotations

import argparse

HELP = ("reproduce the paper in simulation: cross-validation, identification (Tables 1-2), control tests, "
        "Table 3, diagnosis, figures; writes report.md, results.json and the MCAP logs")


from neck_sim.cli.common import nonnegative_int, positive_float, positive_int


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--out", default="reproduce", metavar="DIR", help="output directory (default ./reproduce, in the current directory; a checkout's .gitignore "
                             "ignores it at the root)")
    parser.add_argument("--quick", action="store_true",
                        help="half-length trajectories and fewer samples: the same stages in about a third of the time")
    parser.add_argument("--seed", type=nonnegative_int, default=0, help="plant seed (camera noise) (default 0)")
    parser.add_argument("--workers", type=positive_int, default=None,
                        help="local worker processes for the closed-loop runs (default: one per core; 1: serial)")
    parser.add_argument("--cluster", default=None, metavar="tcp://HOST:PORT",
                        help="run the closed-loop runs and the simulator comparison on this Dask scheduler "
                             "(docs/campaigns.md: `dask scheduler --host 127.0.0.1`, workers with `dask worker "
                             "ADDRESS --host 127.0.0.1 --nthreads 1`); jobs fail after 30 s without any worker")
    parser.add_argument("--duration-scale", type=positive_float, default=None, metavar="S",
                        help="scale every trajectory's duration (default 1, or 0.5 with --quick)")
    parser.add_argument("--no-render", action="store_true", help="skip the offscreen rendering of figure 10")
    parser.add_argument("--no-progress", action="store_true", help="no progress output")


def run(args: argparse.Namespace) -> int:
    from neck_sim.cli.common import check_paths
    check_paths(dirs={"--out": args.out})
    from neck_sim.experiments import ReproduceSettings, reproduce

    settings = ReproduceSettings(out=args.out, quick=args.quick, seed=args.seed, workers=args.workers,
                                 cluster=args.cluster, scale=args.duration_scale,
                                 progress=not args.no_progress, render=not args.no_render)
    rep = reproduce(settings)
    print(f"wrote {rep.report_path} and {rep.results_path} ({sum(rep.timings.values()):.0f} s; "
          f"logs in {rep.out}/logs)")
    return 0
