"""`neck-sim simulate`: the paper's control tests (§6.3, §7) and Table 3 on the simulated plant, and
any neck of any routing moved by a controller that can move it (:mod:`controllers.selection`).

A run whose neck leaves its joint range |alpha| <= alpha_max is refused, never logged: before the
run when the statics of the plant (with its ``--effect`` effects) already say so
(:func:`controllers.reachable_paths.check_plant_holds`, for ``inverse-statics``), else during it,
at the first recorded sample out of range (``stop_outside_range`` of
:func:`controllers.closed_loop.run_lockstep`), with one line naming the time, the joint and the
angle, exit status 2 and no log.  Refused rather than logged under a flag: outside the range the
paper's model no longer describes the neck, the log contract refuses such angles and
``neck-sim check`` cannot evaluate them, so the log would serve no later command.

Several runs (``--law 1 2 3``, ``--table3``) are all or nothing: every log path is checked before
the first run, the logs are written under temporary names beside their targets and published
together when the last run has succeeded (:class:`_StagedLogs`), so a run refused after others
have finished leaves no log of the command, and a file that was at a log's path stays as it was.
"""

from __future__ import annotations

import argparse

from neck_sim.cli.common import (add_params_arguments, check_paths, nonnegative_float, nonnegative_int, params_from_args,
                                 positive_float)

import os

HELP = "run a control law closed loop on the simulated neck, log MCAP, print the paper's metrics"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from controllers.selection import CONTROLLERS, LQR_FROM_JOINTS, TRAJECTORY_NAMES

    parser.add_argument("--trajectory", default=None, metavar="NAME",
                        help=f"reference: {', '.join(TRAJECTORY_NAMES)} (default control-test for the paper's laws, "
                             "shapes -- C and S curves and a head reach through reachable poses -- for "
                             "inverse-statics; identification with --table3; identification on a neck the paper's "
                             "laws cannot move is its own excitation through reachable poses)")
    parser.add_argument("--law", type=int, nargs="+", choices=(1, 2, 3), default=None, metavar="{1,2,3}",
                        help="control law(s) of §6.3: 1 no friction, 2 friction, 3 friction + elastic "
                             "estimator (default 2; several run one after the other)")
    parser.add_argument("--controller", default=None, metavar="NAME",
                        help="auto (default), " + "; ".join(f"{k}: {v}" for k, v in CONTROLLERS.items())
                             + f". auto: inverse-statics for a routing other than the paper's, elastic-lqr for "
                               f"N >= {LQR_FROM_JOINTS} on elastic cables without --law, else computed-torque")
    parser.add_argument("--effect", action="append", default=None, metavar="NAME=VALUE[@INDEX]",
                        help="simulate the neck with an effect of the vocabulary (`neck-sim effects`) added: VALUE "
                             "sets its main parameter in SI units, @INDEX (1-based) puts it on one cable or joint, "
                             "e.g. payload=0.05, dry_friction=25@2, actuation_delay=0.01, spring_error=0.5@3; "
                             "repeatable; the log's run record lists them, its neck record stays nominal")
    parser.add_argument("-o", "--output", metavar="LOG",
                        help="MCAP log path (several runs: the run's label is added before .mcap); "
                             "default logs/simulate-<trajectory>-<run>-<time>.mcap")
    parser.add_argument("--no-log", action="store_true", help="do not write MCAP logs")
    parser.add_argument("--json", metavar="PATH", help="write the metrics as JSON")
    parser.add_argument("--plots", metavar="DIR", help="write figures 11-16 as PNG into DIR")
    parser.add_argument("--duration-scale", type=positive_float, default=1.0, metavar="S",
                        help="scale every move and hold duration (default 1: 2.5 s moves, 1 s holds)")
    parser.add_argument("--table3", action="store_true",
                        help="Table 3: the law with/without pulleys in its model on rigid- and "
                             "identified-cable plants (4 runs)")
    parser.add_argument("--rigid-cables", action="store_true", help="plant with rigid cables (control tests)")
    parser.add_argument("--no-pulleys", action="store_true",
                        help="controller model with r = 0 (the plant keeps its pulleys)")
    parser.add_argument("--cable-model", choices=("inextensible", "constant", "variable"),
                        help="override the law's estimator cable model")
    parser.add_argument("--t-min", type=nonnegative_float, metavar="N", help="minimal cable tension of eq (65) (default 8.5 N)")
    add_params_arguments(parser)
    parser.add_argument("--seed", type=nonnegative_int, default=0, help="camera-noise seed")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    add_live_arguments(parser)


def add_live_arguments(parser: argparse.ArgumentParser) -> None:
    """--live, --live-pace, --live-port (docs/live-view.md)."""
    parser.add_argument("--live", action="store_true",
                        help="serve the run to Foxglove at ws://127.0.0.1:PORT (needs foxglove-sdk: "
                             "pip install 'neck-sim[live]'); the run starts when Foxglove connects")
    parser.add_argument("--live-pace", choices=("realtime", "fast"), default="realtime",
                        help="with --live: play at 1x simulated time, or as fast as it runs (default realtime)")
    parser.add_argument("--live-port", type=nonnegative_int, default=8765, metavar="PORT",
                        help="with --live: the WebSocket port on 127.0.0.1 (default 8765; 0: a free port)")


def _log_namer(args, trajectory: str, several: bool):
    from controllers.experiments import default_log_path
    if args.no_log:
        if args.output:
            raise ValueError("-o/--output and --no-log contradict each other")
        return None
    if args.output is None:
        return lambda label: default_log_path(trajectory, label)
    if not args.output.endswith(".mcap"):
        raise ValueError(f"{args.output}: log files end in .mcap")
    if not several:
        return lambda label: args.output
    return lambda label: f"{args.output[:-5]}-{label}.mcap"


def _check_options(args, controller: str) -> None:
    """Options that contradict the chosen controller or each other: one line each."""
    if args.table3 and (args.rigid_cables or args.no_pulleys):
        raise ValueError("--table3 chooses plant cables and controller pulleys itself; drop --rigid-cables/--no-pulleys")
    if controller == "elastic-lqr" and (args.law or args.table3 or args.cable_model):
        raise ValueError("--controller elastic-lqr has its own feedback: drop --law, --table3 and --cable-model")
    if controller == "inverse-statics":
        given = [opt for opt, v in (("--law", args.law), ("--table3", args.table3), ("--cable-model", args.cable_model),
                                    ("--t-min", args.t_min is not None), ("--rigid-cables", args.rigid_cables)) if v]
        if given:
            raise ValueError(f"--controller inverse-statics holds poses through the cables' elasticity with its own "
                             f"feedback and tensions: drop {', '.join(given)}")
    if args.table3 and len(args.law or [2]) != 1:
        raise ValueError("--table3 runs one law (give a single --law)")
    twice = sorted({law for law in args.law or [] if args.law.count(law) > 1})
    if twice:
        raise ValueError(f"--law {' '.join(map(str, args.law))}: law {twice[0]} given twice (each law runs once)")


def _log_labels(args, controller: str, laws: list[int]) -> dict[str, str]:
    """The labels :func:`controllers.experiments.control_tests` and ``table3`` give their runs'
    logs, in run order, each with the run's name for the user."""
    from controllers.experiments import TABLE3_CASES, control_log_labels, table3_log_label
    if args.table3:
        return {table3_log_label(kind, pulleys): f"the {kind}-cable run {'with' if pulleys else 'without'} pulleys"
                for kind, pulleys in TABLE3_CASES}
    labels = control_log_labels(controller, laws)
    if controller != "computed-torque":
        return {labels[0]: controller}
    return {label: f"law {int(law)}" for law, label in zip(laws, labels)}


class _StagedLogs:
    """The ``log_path`` of the command's runs: each log is written (atomically, by its LogWriter)
    under a temporary name beside its target, and :meth:`publish` moves them all to their names
    once every run has succeeded; :meth:`discard` removes them after a refusal.  ``namer`` None
    (``--no-log``): no log; the labels are recorded either way (``labels``: the runs started, the
    last one under way)."""

    def __init__(self, namer) -> None:
        self.namer = namer
        self.staged: dict[str, str] = {}       # temporary -> target
        self.labels: list[str] = []

    def __call__(self, label: str) -> str | None:
        from neck_sim.atomic import temp_file_beside
        self.labels.append(label)
        if self.namer is None:
            return None
        target = self.namer(label)
        fd, tmp = temp_file_beside(target)
        os.close(fd)
        self.staged[tmp] = target
        return tmp

    def publish(self, labelled: dict) -> dict:
        """Every log under its name; ``labelled``'s results with their log paths renamed too."""
        import dataclasses

        from neck_sim.atomic import publish
        for tmp, target in self.staged.items():
            publish(tmp, target)
        names, self.staged = self.staged, {}
        return {label: dataclasses.replace(res, log_path=names.get(res.log_path, res.log_path))
                for label, res in labelled.items()}

    def discard(self) -> None:
        from neck_sim.atomic import discard
        for tmp in self.staged:
            discard(tmp)
        self.staged.clear()

    def named(self, text: str) -> str:
        """``text`` with the temporary names replaced by the logs' names."""
        for tmp, target in self.staged.items():
            text = text.replace(tmp, target)
        return text


def _left_range(exc: RuntimeError, args) -> str | None:
    """A run stopped because its neck left the joint range: its message with what to do about it;
    None for any other failure."""
    from neck_sim.joint_range import JointRangeError
    if not isinstance(exc.__cause__, JointRangeError):
        return None
    lighter = f"smaller --effect values than {' '.join(args.effect)}, " if args.effect else ""
    return (f"{exc}; no log written: try {lighter}slower moves (a larger --duration-scale than "
            f"{args.duration_scale:g}) or another --trajectory")


def _refusal(exc: BaseException, args, controller: str, n_joints: int, staged: _StagedLogs,
             names: dict[str, str]) -> BaseException:
    """The one line for a failed run (``exc`` itself when there is nothing to add): the logs'
    names, not their temporary ones; what to do about it; and, of several runs, the one that
    failed and those whose logs are discarded with it."""
    if not isinstance(exc, (RuntimeError, OSError)):
        return exc
    text = staged.named(str(exc))
    if isinstance(exc, RuntimeError):
        if controller == "computed-torque" and not args.table3 and not args.rigid_cables and n_joints >= 6:
            # README, Known limitations: the paper's laws do not damp long necks' cable-motor-gravity mode
            text += " (on elastic cables the paper's laws lose necks of 6 or more joints: try --controller elastic-lqr)"
        else:
            text = _left_range(exc, args) or text
    ran = [names.get(label, label) for label in staged.labels]
    if len(names) > 1 and ran:
        done = ", ".join(ran[:-1])
        text = f"{ran[-1]}: {text}" if not done else f"{ran[-1]}, run after {done}: {text}"
        if done and staged.namer is not None:
            text += (f"; the log{'s' if len(ran) > 2 else ''} of {done} {'are' if len(ran) > 2 else 'is'} discarded "
                     "too (all runs or no log)")
    if text == str(exc):
        return exc
    return type(exc)(text) if isinstance(exc, OSError) else RuntimeError(text)


def _plant_factory(effects, timestep):
    """Plants with the ``--effect`` effects and the controller's physics timestep (None: the
    default plant)."""
    if not effects.active() and timestep is None:
        return None
    from neck_sim.plant import Plant
    return lambda params, rigid_cables, seed: Plant(params, effects=effects, seed=seed, timestep=timestep,
                                                    rigid_cables=rigid_cables)


def run(args: argparse.Namespace) -> int:
    if args.live:
        return _run_live(args)
    from controllers import experiments as ex
    from controllers.selection import choose_controller, make_run_trajectory, plant_timestep
    from neck_sim.effect_option import parse_effects

    figures = None
    if args.plots:
        from controllers.plots import SUMMARY_FILES

        figures = {"--plots": SUMMARY_FILES}
    check_paths(inputs={"--params": args.params}, files={"-o": args.output, "--json": args.json},
                dirs={"--plots": args.plots}, contents=figures)
    params = params_from_args(args)
    effects = parse_effects(args.effect, params)
    choice = choose_controller(params, args.controller, laws=args.law, rigid_cables=args.rigid_cables,
                               cable_model=args.cable_model, table3=args.table3)
    controller = choice.name
    _check_options(args, controller)
    print(choice.line)
    if effects.active():
        print(f"plant effects: {', '.join(args.effect)} (the log's run record lists them; its neck record is nominal)")
    lqr = controller == "elastic-lqr"
    laws = args.law or [2]
    name = args.trajectory or ("identification" if args.table3 else None)
    traj = make_run_trajectory(name, params, controller, args.duration_scale, effects if effects.active() else None)
    name = name or traj.name.split(" ")[0]
    kwargs = {}
    if args.t_min is not None:
        kwargs["t_min"] = args.t_min
    if args.cable_model is not None:
        kwargs["cable_model"] = args.cable_model
    progress = not args.no_progress
    factory = _plant_factory(effects, plant_timestep(controller))
    print(f"{traj.name} trajectory: {traj.duration:g} s at {params.control.rate_hz:g} Hz, N = {params.n_joints}"
          + ("" if params.n_cables == params.n_joints + 1 else f", {params.n_cables} cables"))

    names = _log_labels(args, controller, laws)
    namer = _log_namer(args, name, len(names) > 1)
    if namer is not None and args.output and len(names) > 1:
        # every run's log path, refused before the first run rather than after the others
        check_paths(inputs={"--params": args.params}, dirs={"--plots": args.plots}, contents=figures,
                    files={"--json": args.json, **{f"-o ({label})": namer(label) for label in names}})
    staged = _StagedLogs(namer)
    try:
        # every run done: the logs published together
        if args.table3:
            results = staged.publish(ex.table3(params, traj, laws[0], log_path=staged, progress=progress,
                                               seed=args.seed, controller_kwargs=kwargs, plant_factory=factory,
                                               stop_outside_range=True))
        else:
            ctrl_params = params.replace(**{"geometry.r": 0.0}) if args.no_pulleys else params
            labelled = staged.publish(ex.control_tests(
                params, traj, laws, log_path=staged, progress=progress, seed=args.seed, rigid_cables=args.rigid_cables,
                controller_params=ctrl_params, controller_kwargs=kwargs, controller=controller, plant_factory=factory,
                stop_outside_range=True))
    except BaseException as exc:
        refusal = _refusal(exc, args, controller, params.n_joints, staged, names)
        staged.discard()
        if refusal is exc:
            raise
        raise refusal from exc
    if args.table3:
        labelled = {f"{kind} cables, {'pulleys' if pul else 'no pulleys'}": res for (kind, pul), res in results.items()}
        print(ex.format_control_table(labelled, compare_with_paper=False))
        print()
        print(ex.format_table3(results))
    else:
        # the paper's §7 numbers only make sense beside the same experiment
        same = (name == "control-test" and args.duration_scale == 1.0 and not args.rigid_cables
                and not args.no_pulleys and params.n_joints == 3 and not kwargs and not args.params and not lqr
                and controller == "computed-torque" and not effects.active())
        print(ex.format_control_table(labelled, compare_with_paper=same))
    for label, res in labelled.items():
        if res.log_path:
            print(f"log ({label}): {res.log_path}")
    if args.json:
        from neck_sim.atomic import atomic_write_json
        payload = {label: res.summary() for label, res in labelled.items()}
        atomic_write_json(args.json, payload)
        print(f"metrics: {args.json}")
    if args.plots:
        from controllers.plots import save_run_plots
        paths = save_run_plots(labelled, args.plots)
        print(f"plots: {len(paths)} PNG files in {os.path.abspath(args.plots)}")
    return 0


def _run_live(args) -> int:
    """The command with a live view open around its runs (they feed it between compiled chunks)."""
    from neck_sim.live import LiveView

    if args.live_port > 65535:
        raise ValueError(f"--live-port: expected a TCP port 0..65535, got {args.live_port}")
    with LiveView(params_from_args(args), port=args.live_port, pace=args.live_pace) as view:
        print(f"live view: {view.url} -- in Foxglove: Open connection > Foxglove WebSocket > {view.url}; "
              "the run starts when it connects (Ctrl-C to stop)", flush=True)
        view.wait_for_client()
        args.live = False
        return run(args)
