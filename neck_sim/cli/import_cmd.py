"""`neck-sim import`: prototype CSV files -> a contract MCAP log."""

from __future__ import annotations

import argparse

from neck_sim.cli.common import add_force_range_argument, add_implausible_params_argument

HELP = "turn the prototype's motors/camera CSV files into an MCAP log (columns: see --help)"

EPILOG = """CSV columns (header row, any order, extra columns ignored, SI units; N joints and m cables from
the --params routing, m = N + 1 on the paper's):
  motors:    t, theta1..theta{m} (rad), force1..force{m} (N)         -> /neck/motors
  camera:    t, alpha1..alpha{N} (rad)                               -> /neck/camera
  reference: t, alpha_d1..alpha_d{N} (rad)                           -> /neck/reference
  estimate:  t, alpha_hat1..alpha_hat{N} (rad)                       -> /neck/estimate
t is seconds since the start of the run (or use --shift-time)."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    import argparse
    parser.formatter_class = argparse.RawDescriptionHelpFormatter
    parser.epilog = EPILOG
    parser.add_argument("--motors", required=True, metavar="CSV", help="encoders and commanded forces")
    parser.add_argument("--camera", metavar="CSV", help="joint angles from video (needed by identification)")
    parser.add_argument("--reference", metavar="CSV", help="desired joint angles (optional)")
    parser.add_argument("--estimate", metavar="CSV", help="online joint-angle estimate (optional)")
    parser.add_argument("--params", metavar="PATH", help="parameter file (.json/.toml) with the nominal constants "
                                                         "(default: the 3-joint prototype)")
    add_implausible_params_argument(parser)
    parser.add_argument("--shift-time", action="store_true", help="subtract the earliest time of the files")
    add_force_range_argument(parser)
    parser.add_argument("-o", "--output", required=True, metavar="MCAP", help="log to write")


def run(args: argparse.Namespace) -> int:
    from neck_sim import params as P
    from neck_sim.cli.common import check_paths, load_params_file

    check_paths(inputs={"--motors": args.motors, "--camera": args.camera, "--reference": args.reference,
                        "--estimate": args.estimate, "--params": args.params}, files={"-o": args.output})
    from neck_sim.csv_import import import_csv

    params = (load_params_file(args.params, accept_implausible=args.accept_implausible_params) if args.params
              else P.default_params(3))
    if args.camera is None:
        print("note: no --camera file: the log cannot be used for identification or diagnosis")
    res = import_csv(args.motors, args.output, camera=args.camera, reference=args.reference,
                     estimate=args.estimate, params=params, shift_time=args.shift_time,
                     accept_out_of_range_forces=args.accept_out_of_range_forces)
    counts = ", ".join(f"{k} {v}" for k, v in res.counts.items())
    print(f"wrote {res.path}: {counts} samples over {res.duration:.3f} s (N = {params.n_joints} joints, "
          f"m = {params.n_cables} cables)")
    if res.time_shift:
        print(f"times shifted by {-res.time_shift:+.6f} s")
    for kind, cols in res.ignored_columns.items():
        if cols:
            print(f"ignored {kind} columns: {', '.join(cols)}")
    return 0
