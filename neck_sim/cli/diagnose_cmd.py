"""`neck-sim diagnose LOG`: what the model gets wrong, which effect causes it, and the gain of adding it."""

from __future__ import annotations

import argparse
import os
import sys
from typing import Any

from neck_sim.cli.common import (add_force_range_argument, add_implausible_params_argument, check_params_fit_log,
                                 check_paths, load_params_file, nonnegative_float, positive_int, probability)

HELP = ("diagnose a log against a model: residuals, the missing effect (verdict), the extended model and its "
        "gain on held-out data")

MODEL_HELP = ("baseline model (default: %(default)s): 'paper' (arctan friction + variable-stiffness cables), 'rigid' (rigid "
              "cables, no friction, eq 25), 'rigid-friction', 'linear' (Table 1's constant stiffness), a "
              "comma-separated list of effect names, or a model.json written by a previous diagnosis")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("log", metavar="LOG", help="MCAP log with /neck/motors and /neck/camera")
    parser.add_argument("--model", metavar="MODEL", default="paper", help=MODEL_HELP)
    parser.add_argument("--params", metavar="FILE",
                        help="nominal constants (.json/.toml, 'neck-sim params' format) instead of the log's neck "
                             "record; their friction and cable values only seed the fit (those are what is fitted)")
    add_implausible_params_argument(parser)
    parser.add_argument("--json", metavar="PATH", help="write the diagnosis (verdict, findings, baseline, ...) as JSON")
    parser.add_argument("--report", metavar="DIR", help="write report.md, figures and model.json into DIR")
    parser.add_argument("--extended", metavar="PATH", help="write the final (extended) model as JSON")
    parser.add_argument("--steps", type=positive_int, default=3, metavar="K",
                        help="forward selection: at most K findings (default 3; 1 = the verdict only)")
    parser.add_argument("--start", type=nonnegative_float, default=None, help="use the log from this time on (s)")
    parser.add_argument("--end", type=nonnegative_float, default=None, help="use the log up to this time (s)")
    parser.add_argument("--alpha", type=probability, default=0.01, help="significance level of the tests (default 0.01)")
    parser.add_argument("--min-improvement", type=nonnegative_float, default=0.02,
                        help="smallest held-out score improvement that counts (default 0.02)")
    parser.add_argument("--candidates", default=None,
                        help="comma-separated effects to consider (default: the whole vocabulary)")
    add_force_range_argument(parser)
    parser.add_argument("--no-resim", action="store_true", help="skip the open-loop re-simulations")
    parser.add_argument("--quiet", action="store_true", help="no progress bars")


def run(args: argparse.Namespace) -> int:
    from identification.diagnosis import DiagnosisSettings, diagnose_log, parse_model
    from identification.diagnosis.report import REPORT_FILES, format_summary, write_report
    from neck_sim.logs import read_log
    from neck_sim.logs.reader import require_camera_frames

    check_paths(inputs={"LOG": args.log, "--params": args.params,
                        "--model": args.model if os.path.exists(args.model) else None},
                files={"--json": args.json, "--extended": args.extended}, dirs={"--report": args.report},
                contents={"--report": REPORT_FILES})
    model = parse_model(args.model)              # fail early on a bad --model
    params = load_params_file(args.params, accept_implausible=args.accept_implausible_params) if args.params else None
    kw: dict[str, Any] = {}
    if args.candidates:
        kw["candidates"] = tuple(c.strip() for c in args.candidates.split(",") if c.strip())
    settings = DiagnosisSettings(max_steps=args.steps, alpha=args.alpha, min_improvement=args.min_improvement,
                                 resimulate=not args.no_resim, **kw)
    log = read_log(args.log, start=args.start, end=args.end, topics=("motors", "camera"),
                   require=("motors", "camera"), accept_out_of_range_forces=args.accept_out_of_range_forces)
    require_camera_frames(log)
    if log.motors is None or log.camera is None:        # read_log required both
        raise ValueError(f"{args.log}: needs /neck/motors and /neck/camera")
    if params is not None:
        check_params_fit_log(params, log, args.params)
    print(f"diagnosing {args.log}: {log.motors.t.size} motor samples, {log.camera.t.size} camera frames, "
          f"model: {model.describe()}", file=sys.stderr)
    diag = diagnose_log(log, model, settings, params=params, progress=not args.quiet)
    print(format_summary(diag))               # its notes name what the reader accepted on request
    if args.json:
        diag.write_json(args.json)
        print(f"wrote {args.json}", file=sys.stderr)
    if args.extended and diag.extended is not None:
        diag.write_model(args.extended)
        print(f"wrote {args.extended}", file=sys.stderr)
    elif args.extended:
        print(f"no model written to {args.extended}: nothing could be fitted ({diag.verdict})", file=sys.stderr)
    if args.report:
        for path in write_report(diag, args.report):
            print(f"wrote {path}", file=sys.stderr)
    return 0
