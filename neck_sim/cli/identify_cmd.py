"""`neck-sim identify LOG [LOG ...]`: friction and cable stiffness from logs, by the paper's §5 least
squares (one log) or by output error (re-simulating the logged forces; several logs, one parameter set)."""

from __future__ import annotations

import sys

from identification.output_error.settings import OutputErrorSettings
from neck_sim.cli.common import (add_force_range_argument, add_implausible_params_argument, check_params_fit_log,
                                 check_paths, load_params_file, nonnegative_float, positive_float, positive_int,
                                 report_input_warnings)

HELP = ("identify motor friction and cable stiffness from a log's measured topics (paper §5, Tables 1-2; "
        "--method output-error: re-simulate the logs, several at once)")
METHODS = ("least-squares", "output-error")


def add_arguments(parser) -> None:
    parser.add_argument("log", metavar="LOG", nargs="+",
                        help="MCAP log with /neck/motors and /neck/camera (several: --method output-error only)")
    parser.add_argument("--method", choices=METHODS, default="least-squares",
                        help="least-squares: the paper's inverse-model fit (eqs 44-57), one log, seconds; "
                             "output-error: from that estimate, re-simulate the logged forces through the plant and "
                             "fit f_s, k, lambda, c_a per cable to the encoders and camera (minutes; several logs "
                             "share one parameter set); see docs/identification.md (default: %(default)s)")
    parser.add_argument("--model", metavar="FILE",
                        help="output-error: fit this extended model (written by 'neck-sim diagnose --extended'): its "
                             "constants and effects, the effects' magnitudes fitted too")
    parser.add_argument("--integrator", default=None, metavar="NAME",
                        help="output-error: implicitfast, implicit or discrete, the MuJoCo integrator of every re-simulation of the fit (default: the plant's "
                             "choice for the nominal constants (the log's neck record or --model), kept for the whole fit)")
    parser.add_argument("--max-evaluations", type=positive_int, default=None, metavar="N",
                        help=f"output-error: trial steps of the solver (each one rollout per log, besides the "
                             f"finite-difference Jacobians; default {OutputErrorSettings.max_evaluations})")
    parser.add_argument("--exact-jacobian", action="store_true",
                        help="output-error: every finite-difference Jacobian column from rollouts of the fit's own "
                             "model (default: the f_s, k and lambda columns from a 2 ms discrete model, about 0.4 "
                             "of a rollout's CPU; the fit's minimiser is the same, see docs/identification.md)")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar (output-error)")
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


def output_error_settings(args) -> OutputErrorSettings:
    """The output-error fit's settings from the parsed options (a bad value refused in one line
    naming its option)."""
    kw: dict = {} if args.max_evaluations is None else {"max_evaluations": args.max_evaluations}
    if args.exact_jacobian:
        kw["jacobian_timestep"] = None
    try:
        return OutputErrorSettings(integrator=args.integrator, **kw)
    except ValueError as exc:
        raise ValueError(f"--{exc}") from None


def _check_method_options(args) -> None:
    """One-line refusals of options that do not go with the method."""
    oe = args.method == "output-error"
    if len(args.log) > 1 and not oe:
        raise ValueError(f"LOG: least squares identifies one log at a time (got {len(args.log)}); fit several "
                         "together with --method output-error")
    for opt, given in (("--model", args.model), ("--integrator", args.integrator),
                       ("--max-evaluations", args.max_evaluations), ("--exact-jacobian", args.exact_jacobian or None)):
        if given is not None and not oe:
            raise ValueError(f"{opt}: only with --method output-error")
    if oe and args.start:
        raise ValueError("--start: output error re-simulates each log from rest at its start; a window that begins "
                         "inside a moving run cannot be replayed (use --end to shorten it)")
    if oe and args.simulators and len(args.log) > 1:
        raise ValueError("--simulators: compares one log; give one LOG or leave --simulators out")
    if len(set(args.log)) < len(args.log):
        raise ValueError("LOG: the same log given twice (it would count its data twice)")


def run(args) -> int:
    _check_method_options(args)
    inputs = {("LOG" if i == 0 else f"LOG {i + 1}"): p for i, p in enumerate(args.log)}
    figures = None
    if args.plots:
        from identification.plots import FIGURE_FILES

        figures = {"--plots": FIGURE_FILES}
    check_paths(inputs={**inputs, "--params": args.params, "--model": args.model}, files={"--json": args.json},
                dirs={"--plots": args.plots}, contents=figures)
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
    oe = args.method == "output-error"
    model = None
    if args.model:
        from identification.output_error.identify import load_extended_model

        model = load_extended_model(args.model)
    oe_settings = output_error_settings(args) if oe else None
    # the camera's joint angles give the joint torques of eq 38 and the elongations of eq 27; the
    # output-error re-simulation starts at the first /neck/reference pose when the log has one
    topics = ("motors", "camera", "reference") if (args.simulators or oe) else ("motors", "camera")
    logs, results = [], []
    for path in args.log:
        log = read_log(path, start=args.start, end=args.end, topics=topics, require=("motors", "camera"),
                       accept_out_of_range_forces=args.accept_out_of_range_forces)
        require_camera_frames(log)
        if params is not None:
            check_params_fit_log(params, log, args.params)
        logs.append(log)
    if oe and len(logs) > 1:
        from identification.output_error.problem import same_neck

        for log in logs[1:]:
            same_neck(logs[0].params, log.params, str(log.path), str(logs[0].path))
    log = logs[0]
    nominal = params or log.params
    if args.simulators and not nominal.routing.is_paper_kind(nominal.n_joints):
        raise ValueError(f"--simulators: cannot handle this log's routing ({nominal.n_joints} joints, "
                         f"{nominal.n_cables} cables): the §5.6 comparison replays the run under the paper's "
                         f"computed-torque law, which needs the paper's routing; identify without --simulators")
    for path, lg in zip(args.log, logs):
        print(f"identifying from {path}: {lg.motors.t.size} motor samples, {lg.camera.t.size} camera frames",
              file=sys.stderr)
        results.append(identify_log(lg, settings, params=params, models=models))
    result = results[0]
    print(format_tables(result, reference=f"--params {args.params}" if args.params else "nominal"))
    summary = result.to_dict()
    summary.update(report_input_warnings(log.warnings))
    if oe:
        from identification.output_error.identify import identify_output_error
        from identification.output_error.report import format_output_error

        if len(logs) > 1:
            summary["least_squares_per_log"] = {str(p): r.to_dict() for p, r in zip(args.log[1:], results[1:])}
        fitted, _ = identify_output_error(logs, params, model=model, settings=oe_settings, least_squares=results,
                                          progress=not args.no_progress)
        print("\n" + format_output_error(fitted, model.params if model else nominal,
                                         reference_name="--model" if model else
                                         (f"--params" if args.params else "nominal")))
        summary["output_error"] = fitted.to_dict()
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

        from identification.plots import FIGURE_FILES, figure_simulator, save_figure, save_identification_figures

        paths = save_identification_figures(result, args.plots)
        if comparison is not None:
            paths.append(save_figure(figure_simulator(comparison.series), os.path.join(args.plots, FIGURE_FILES[5])))
        for path in paths:
            print(f"wrote {path}", file=sys.stderr)
    return 0
