"""Any neck: identification and diagnosis of the 10-joint, 4-cable neck against the paper's 3-joint one.

Both logs come from the same generator (``tests/open_world/generator.py``, ``simulate_reachable``:
the nominal plant moved through the equilibria of tension waypoints by inverse statics and a
motor PID, no hidden effect), with the same waypoint schedule, so they have the same duration
(about 60 s) and rates.  Per neck, timed here in one run (best of ``--repeat``):

* ``identify``: ``identify_log`` (the paper's eqs 44-57) without the §5.5 alpha_hat reconstruction
  (which eq 35 cannot do with fewer cables than joints, so it would favour the 10-joint neck);
* ``diagnose``: ``diagnose_log`` with the CLI's settings (3 steps, open-loop re-simulation of the
  held-out blocks) without alpha_hat, for the same reason.

Printed: seconds per neck and the ratio 10x4 / 3-joint (target: at most 1.5 each), and the
identified values of the 10x4 neck against its plant's, per cable.

``--detection``: the blind diagnosis matrix on the 10x4 neck instead: per seed, a clean log and
one log per hidden effect (``tests/open_world/generator.py``: MuJoCo fields and formulas of its
own, never the candidates' code; 15.6 s reachable-path runs), diagnosed blind (one step, no
re-simulation) from the nominal model; printed: verdict, where, magnitude against the hidden one,
and the hidden effect's own candidate at step 1 whether named or not (its fit at the hidden place,
training F-test and held-out Wilcoxon p as the step tests them, its cross-validated improvement,
where its largest |value| / sigma sits, the joint of a one-joint (located) candidate and, when
it is held to its joint's torque channel (``identification/diagnosis/materiality.py``), that
channel's cross-validated improvement; its p values are then that channel's).

    python benchmarks/bench_any_neck.py                     # about 6 min on 2 cores (logs made once)
    python benchmarks/bench_any_neck.py --dir /tmp/necks    # keep the logs between runs
    python benchmarks/bench_any_neck.py --dir /tmp/necks --only identify --repeat 3   # identify alone, 1 min
    python benchmarks/bench_any_neck.py --dir /tmp/necks --only identify --repeat 3 --cpu   # CPU seconds
    python benchmarks/bench_any_neck.py --detection --seeds 1 2 3   # 1-2.5 min per case on a shared 2-core machine
    python benchmarks/bench_any_neck.py --detection --moves 16 --cases spring_error none   # 30.8 s logs
    python benchmarks/bench_any_neck.py --detection --moves 31 --cases spring_error none   # 59.3 s logs
    python benchmarks/bench_any_neck.py --detection --seeds 1 2 3 --cases dry_friction --look-alikes --travel
    python benchmarks/bench_any_neck.py --detection --undecided --cases joint_friction none    # + "not decided" lines
    python benchmarks/bench_any_neck.py --detection --moves 31 --sigma --cases joint_friction  # + value, sigma, note
    python benchmarks/bench_any_neck.py --detection --moves 31 --sigma --seeds 3 7 6 8 --cases viscous_friction  # fast cables
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time

import numpy as np

_ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
sys.path[:0] = [_ROOT, os.path.join(_ROOT, "tests")]     # this checkout's code, not the installed one

MOVES = 31             # 31 moves of 1.5 s + 0.4 s holds: 59.3 s
NECKS = ("paper", "neck10x4")


def make_log(directory: str, neck: str, seed: int = 0) -> str:
    from open_world.generator import make_spec, simulate_reachable

    from neck_sim.params import example_params

    path = os.path.join(directory, f"{neck}_{MOVES}moves_seed{seed}.mcap")
    if not os.path.exists(path):
        t0 = time.perf_counter()
        simulate_reachable(path, make_spec("none", seed, params=example_params(neck)), seed, moves=MOVES)
        print(f"simulated {path} in {time.perf_counter() - t0:.0f} s", file=sys.stderr)
    return path


#: Hidden effects of the matrix and their level (x the generator's test magnitude): a side spring
#: 50 % off on this neck's inverse-statics controller loses the neck at take-up, so 20 %.  Viscous
#: friction (MuJoCo damping on a motor slide) is read on its settled fit where its cable is fast.
DETECTION = {"none": 1.0, "spring_error": 0.4, "payload": 1.0, "joint_friction": 1.0, "dry_friction": 1.0,
             "actuation_delay": 1.0, "viscous_friction": 1.0}


def detection(directory: str, seeds, moves: int = 8, cases=None, look_alikes: bool = False,
              travel: bool = False, undecided: bool = False, sigma: bool = False) -> None:
    from open_world.generator import make_spec, simulate_reachable

    from identification.diagnosis import DiagnosisSettings, diagnose_log
    from neck_sim.params import example_params

    p = example_params("neck10x4")
    print(f"{'case':16} {'seed':>4}  {'hidden':48} {'verdict':28} {'where':>8} {'estimate':>10} {'hidden':>9}  its candidate at step 1")
    for seed in seeds:
        for name, level in DETECTION.items():
            if cases and name not in cases:
                continue
            spec = make_spec(name, seed, level=level, params=p)
            stem = "detect" if moves == 8 else f"detect{moves}moves"
            path = os.path.join(directory, f"{stem}_{name}_{seed}.mcap")
            try:
                if not os.path.exists(path):
                    simulate_reachable(path, spec, seed, moves=moves)
                diag = diagnose_log(path, model=spec.model, settings=DiagnosisSettings(resimulate=False, max_steps=1),
                                    progress=False)
            except Exception as exc:            # a lost run is a row of the table, not the end of it
                print(f"{name:16} {seed:4d}  {spec.description:48} failed: {str(exc).splitlines()[0][:80]}")
                continue
            verdict = diag.verdict if isinstance(diag.verdict, str) else "/".join(diag.verdict)
            where, est = "", float("nan")
            if diag.findings:
                f = diag.findings[0]
                where = ",".join(f"j{j}" for j in f.joints or ()) or ",".join(f"c{c}" for c in f.cables or ()) or "-"
                if spec.symbol in f.parameters:
                    est = f.parameters[spec.symbol].value
            print(f"{name:16} {seed:4d}  {spec.description:48} {verdict:28} {where:>8} {est:10.4g} "
                  f"{spec.magnitude:9.4g}  {_candidate_fit(diag, spec)}{_resolved_pair(path, diag, spec)}",
                  flush=True)
            if sigma and diag.findings and spec.symbol in diag.findings[0].parameters:
                print(f"    {_sigma_line(diag.findings[0].parameters[spec.symbol], spec)}", flush=True)
            if travel and name == "dry_friction" and diag.findings:
                print(f"    {_travel_line(diag, spec)}", flush=True)
            if look_alikes:
                from identification.diagnosis.report import look_alike_lines

                for line in look_alike_lines(diag):
                    print(f"    {line}", flush=True)
            if undecided:           # the summary's lines on one-joint terms the log is too short to decide
                from identification.diagnosis.materiality import undecided_lines
                for line in undecided_lines(diag):
                    print(f"{'':22}{line.strip()}", flush=True)


def _candidate_fit(diag, spec) -> str:
    """The hidden effect's own candidate at step 1, named or not: its fitted value +- sigma of the
    hidden parameter, and the parameter of its effect with the largest |value| / sigma (where the
    candidate would locate it)."""
    if spec.symbol is None or not diag.steps:
        return ""
    for c in diag.steps[0].candidates:
        if c.term.name != spec.expect or c.fit is None:
            continue
        joint = c.term.identification.joint_of(dict(c.term.shape))
        if spec.symbol not in c.fit.names:
            if joint is not None:                    # a one-joint candidate on another joint
                return f"one joint: {joint} (p {c.p_train:.2g})"
            continue
        names = list(c.fit.names)
        i = names.index(spec.symbol)
        own = [k for k, n in enumerate(names) if n.split("(")[0] == spec.symbol.split("(")[0]]
        top = max(own, key=lambda k: abs(c.fit.value[k]) / max(c.fit.sigma[k], 1e-300))
        form = f"; one joint: {joint}" if joint is not None else ""
        if "own channel" in c.note:        # held to its joint's torque channel (materiality.py)
            form += f", own channel {c.note.split('improvement ')[1].split(' %')[0]} %"
        return (f"{c.fit.value[i]:.4g} +- {c.fit.sigma[i]:.2g} (p {c.p_train:.2g}, {c.p_holdout:.2g}; "
                f"improvement {100 * c.improvement:.1f} %; top {names[top]}{form})")
    return ""


def _sigma_line(p, spec) -> str:
    """A named finding's hidden parameter ``p`` with its sigma and label as the report prints them
    (a hinge's includes its form error, ``identification/diagnosis/hinge_size.py``), its error
    against the hidden magnitude in sigmas and its sigma relative to its value."""
    from identification.diagnosis.parameters import note_label

    return (f"{spec.symbol} = {p.value:.4g} +- {p.sigma:.2g} {p.unit}{note_label(p.note)}: error "
            f"{100 * (p.value / spec.magnitude - 1):+.1f} % = {(p.value - spec.magnitude) / p.sigma:+.2f} sigma, "
            f"sigma / value {p.sigma / abs(p.value):.2f}; {p.note}")


def _travel_line(diag, spec) -> str:
    """A named dry friction's f_travel (``columns/dry_friction.travel_mean_friction``) on the hidden
    cable against the hidden law's own mean force per unit of travel over the same encoder speeds
    (the generator's F tanh(theta_dot / 0.3), written here, not the candidate's law)."""
    cable = spec.cables[0]
    got = diag.findings[0].parameters.get(f"f_travel({cable + 1})")
    if got is None:
        return "f_travel: not reported"
    v = np.abs(diag.data.theta_dot_fast[:, cable])
    hidden = float(np.sum(spec.magnitude * np.tanh(v / 0.3) * v) / np.sum(v))
    return (f"f_travel({cable + 1}) {got.value:.4g} +- {got.sigma:.2g} N, the hidden law's over the same speeds "
            f"{hidden:.4g} N ({100 * (got.value / hidden - 1):+.1f} %)")


def _resolved_pair(path: str, diag, spec) -> str:
    """For a one-joint spring_error candidate on the hidden joint: the combination of its two side
    springs that the joint's torque row resolves (``spring_error.resolved_stiffness`` at the log's
    camera poses), fitted against hidden, and the other combination's relative sensitivity."""
    from identification.diagnosis.columns.spring_error import resolved_stiffness
    from neck_sim.logs import read_log

    if spec.expect != "spring_error" or not diag.steps:
        return ""
    own = next((c for c in diag.steps[0].candidates if c.term.name == spec.expect and c.fit is not None), None)
    joint = None if own is None else own.term.identification.joint_of(dict(own.term.shape))
    if joint != spec.joints[0] + 1:
        return ""
    u, ratio = resolved_stiffness(read_log(path, topics=("camera",)).camera.alpha, spec.params, joint)
    names = list(own.fit.names)
    fitted = u @ [own.fit.value[names.index(f"dk({joint}{side})")] for side in "LR"]
    hidden = u @ [spec.magnitude if spec.symbol.endswith(side + ")") else 0.0 for side in "LR"]
    return (f"; seen by j{joint}'s row ({u[0]:+.2f} L {u[1]:+.2f} R): {fitted:.4g} of {hidden:.4g} "
            f"({100 * (fitted / hidden - 1):+.1f} %), other side combination x{ratio:.2f}")


def best(fn, repeat: int, clock=time.perf_counter):
    times, out = [], None
    for _ in range(repeat):
        t0 = clock()
        out = fn()
        times.append(clock() - t0)
    return min(times), out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--dir", help="directory for the logs (default: a temporary one)")
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--only", choices=("identify", "diagnose"),
                    help="time this one alone (the other's column prints nan)")
    ap.add_argument("--cpu", action="store_true",
                    help="time by the process's CPU seconds (all its threads) instead of the wall clock: the "
                         "work done, which other processes on a shared machine disturb less")
    ap.add_argument("--detection", action="store_true", help="the blind diagnosis matrix on the 10x4 neck")
    ap.add_argument("--seeds", type=int, nargs="+", default=[1])
    ap.add_argument("--moves", type=int, default=8,
                    help="--detection: waypoint moves per log (8: 15.6 s, the tests' logs; 16: 30.8 s, the "
                         "one-joint spring's test log; 31: 59.3 s)")
    ap.add_argument("--cases", nargs="+", choices=sorted(DETECTION), help="--detection: only these cases")
    ap.add_argument("--look-alikes", action="store_true",
                    help="--detection: print the report's look-alike lines (alternatives, what would separate them)")
    ap.add_argument("--travel", action="store_true",
                    help="--detection: for dry friction, print f_travel against the hidden law's travel mean")
    ap.add_argument("--sigma", action="store_true",
                    help="--detection: print the named finding's hidden parameter with its sigma and note")
    ap.add_argument("--undecided", action="store_true",
                    help="--detection: also print the summary's lines on one-joint terms the log is too short "
                         "to decide")
    args = ap.parse_args(argv)

    from identification.diagnosis import DiagnosisSettings, diagnose_log
    from identification.paper import IdentificationSettings, identify_log
    from neck_sim.logs import read_log

    tmp = None if args.dir else tempfile.TemporaryDirectory()
    directory = args.dir or tmp.name
    os.makedirs(directory, exist_ok=True)
    if args.detection:
        detection(directory, args.seeds, args.moves, args.cases, args.look_alikes, args.travel, args.undecided,
                  args.sigma)
        if tmp is not None:
            tmp.cleanup()
        return 0
    rows, results = {}, {}
    clock = time.process_time if args.cpu else time.perf_counter
    for neck in NECKS:
        path = make_log(directory, neck)
        log = read_log(path, topics=("motors", "camera"))
        t_id, res, t_dg, verdict = float("nan"), None, float("nan"), "-"
        if args.only != "diagnose":
            t_id, res = best(lambda: identify_log(log, IdentificationSettings(reconstruct_alpha=False)), args.repeat,
                             clock)
        if args.only != "identify":
            t_dg, diag = best(lambda: diagnose_log(log, settings=DiagnosisSettings(alpha_hat=False), progress=False),
                              args.repeat, clock)
            verdict = diag.verdict
        duration = float(log.motors.t[-1] - log.motors.t[0])
        rows[neck] = (duration, t_id, t_dg, verdict)
        results[neck] = (log.params, res)
    unit, w = ("CPU s", 17) if args.cpu else ("s", 13)
    print(f"{'neck':10} {'log (s)':>8} {'identify (' + unit + ')':>{w}} {'diagnose (' + unit + ')':>{w}}  verdict")
    for neck, (dur, t_id, t_dg, verdict) in rows.items():
        print(f"{neck:10} {dur:8.1f} {t_id:{w}.2f} {t_dg:{w}.2f}  {verdict}")
    a, b = rows["neck10x4"], rows["paper"]
    print(f"ratio 10x4 / 3-joint: identify {a[1] / b[1]:.2f}, diagnose {a[2] / b[2]:.2f} (target <= 1.5 each)")
    p, res = results["neck10x4"]
    if res is not None:
        print("\n10x4 identified vs plant, relative error (%) per cable:")
        for label, got, true in (("f_s", res.f_s, p.friction.f_s), ("k", res.variable.group("k"), p.cables.k),
                                 ("lambda", res.variable.group("lambda"), p.cables.lam),
                                 ("k + lambda 60 N", res.variable.group("k") + 60.0 * res.variable.group("lambda"),
                                  np.asarray(p.cables.k) + 60.0 * np.asarray(p.cables.lam))):
            err = 100.0 * (np.asarray(got) / np.asarray(true) - 1.0)
            print(f"  {label:16}" + "".join(f"{e:+8.1f}" for e in err))
    if tmp is not None:
        tmp.cleanup()
    return 0


if __name__ == "__main__":
    sys.exit(main())
