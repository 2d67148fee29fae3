"""`neck-sim identify LOG`: the paper's §5 identification of friction and cable stiffness from a log."""

from __future__ import annotations

import sys

from neck_sim.cli.common import (add_force_range_argument, add_implausible_params_argument, check_params_fit_log,
                                 check_paths, load_params_file, nonnegative_float, positive_float,
                                 report_input_warnings)

HELP = "identify motor friction and cable stiffness from a log's measured topics (paper §5, Tables 1-2)"


def add_arguments(parser) -> None:
    parser.add_argument("log", metavar="LOG", help="MCAP log with /neck/motors and /neck/camera")
    parser.add_argument("--params", metavar="FILE",
                        help="nominal constants and routing (.json/.toml, 'neck-sim params' format) instead of the "
                             "log's neck record; the tables compare with its friction and cable values per cable")
    parser.add_argument("--json", metavar="PATH", help="write the identified values, sigmas and errors as JSON")
    parser.add_argument("--plots", metavar="DIR", help="write figures 4-8 as PNG files into DIR")
    parser.add_argument("--start", type=nonnegative_float, default=None, help="use the log from this time on (s)")
    parser.add_argument("--end", type=nonnegative_float, default=None, help="use the log up to this time (s)")
    parser.add_argument("--models", default="friction,elastic,variable",
                        help="comma-separated subset of friction,elastic,variable (default: %(default)s, all three)")
    parser.add_argument("--motor-cutoff", type=positive_float, default=None, metavar="HZ",
                        help="Butterworth cutoff for encoders and forces (default: residual analysis)")
    parser.add_argument("--camera-cutoff", type=positive_float, default=None, metavar="HZ",
                        help="Butterworth cutoff for the camera angles (default: residual analysis)")
    parser.add_argument("--weight", type=positive_float, default=100.0, help="weight W of the torque rows, eqs (44)-(45)")
    parser.add_argument("--slack-threshold", type=nonnegative_float, default=2.0, metavar="N",
                        help="tension (eq 41) below which a cable sample counts as slack and is left out")
    add_force_range_argument(parser)
    add_implausible_params_argument(parser)
    parser.add_argument("--no-alpha", action="store_true", help="skip the alpha_hat reconstruction of §5.5")
    parser.add_argument("--bootstrap", type=int, default=None, metavar="N",
                        help="camera-noise replicates behind the calibrated sigmas (default 40, and half as many again "
                             "at twice the noise variance; 0: HAC sigma only, no bias correction); see "
                             "docs/identification.md")
    parser.add_argument("--simulators", action="store_true",
                        help="also replay the log's /neck/reference on a rigid frictionless plant and on the "
                             "identified plant and compare with the log (§5.6, figure 9; minutes)")
    parser.add_argument("--law", type=int, default=1, choices=(1, 2, 3),
                        help="control law the logged run used, for --simulators (default 1, the paper's)")


def run(args) -> int:
    check_paths(inputs={"LOG": args.log, "--params": args.params}, files={"--json": args.json}, dirs={"--plots": args.plots})
    from identification.paper import IdentificationSettings, format_tables, identify_log
    from identification.preprocessing import PreprocessSettings
    from neck_sim.logs import read_log
    from neck_sim.logs.reader import require_camera_frames
    from neck_sim.atomic import atomic_write_json

    params = load_params_file(args.params, accept_implausible=args.accept_implausible_params) if args.params else None
    models = tuple(m.strip() for m in args.models.split(",") if m.strip())
    if args.bootstrap is not None and (args.bootstrap < 0 or args.bootstrap == 1):
        raise ValueError(f"--bootstrap: must be 0 or at least 2 replicates, got {args.bootstrap}")
    extra = {} if args.bootstrap is None else {"bootstrap": args.bootstrap}
    settings = IdentificationSettings(
        **extra, weight=args.weight, slack_threshold=args.slack_threshold, reconstruct_alpha=not args.no_alpha,
        preprocess=PreprocessSettings(motor_cutoff_hz=args.motor_cutoff, camera_cutoff_hz=args.camera_cutoff))
    topics = ("motors", "camera", "reference") if args.simulators else ("motors", "camera")
    # the camera's joint angles give the joint torques of eq 38 and the elongations of eq 27
    log = read_log(args.log, start=args.start, end=args.end, topics=topics, require=("motors", "camera"),
                   accept_out_of_range_forces=args.accept_out_of_range_forces)
    require_camera_frames(log)
    if params is not None:
        check_params_fit_log(params, log, args.params)
    nominal = params or log.params
    if args.simulators and not nominal.routing.is_paper_kind(nominal.n_joints):
        raise ValueError(f"--simulators: cannot handle this log's routing ({nominal.n_joints} joints, "
                         f"{nominal.n_cables} cables): the §5.6 comparison replays the run under the paper's "
                         f"computed-torque law, which needs the paper's routing; identify without --simulators")
    print(f"identifying from {args.log}: {log.motors.t.size} motor samples, {log.camera.t.size} camera frames",
          file=sys.stderr)
    result = identify_log(log, settings, params=params, models=models)
    print(format_tables(result, reference=f"--params {args.params}" if args.params else "nominal"))
    summary = result.to_dict()
    summary.update(report_input_warnings(log.warnings))
    comparison = None
    if args.simulators:
        from identification.simulator import compare_simulators

        comparison = compare_simulators(log, result, law=args.law)
        print("\n§5.6 simulators against the logged run\n" + comparison.table())
        summary["simulators"] = comparison.to_dict()
    if args.json:
        atomic_write_json(args.json, summary)
        print(f"wrote {args.json}", file=sys.stderr)
    if args.plots:
        import os

        from identification.plots import figure_simulator, save_figure, save_identification_figures

        paths = save_identification_figures(result, args.plots)
        if comparison is not None:
            paths.append(save_figure(figure_simulator(comparison.series), os.path.join(args.plots, "fig9_simulators.png")))
        for path in paths:
            print(f"wrote {path}", file=sys.stderr)
    return 0
