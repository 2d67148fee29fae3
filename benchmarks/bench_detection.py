"""Detection power of ``neck-sim diagnose`` (issue 7, item 7).

For every blind case of :mod:`identification.blind` (each effect of the vocabulary, its variant
forms, and the noise-only control) x seeds x magnitude levels (fractions of the test magnitudes
``identification.blind.MAGNITUDES``), simulate a 20.8 s identification-like log, diagnose it blind
(one step, the fast path of the tests) and record the verdict.  Prints Markdown:

* the confusion matrix (hidden effect x verdict) per level;
* per effect, the detection limit: the smallest level (and magnitude) from which every seed is
  named correctly at that level and all higher ones;
* false alarms on the noise-only controls;
* the time of a whole diagnosis (3 forward steps, alpha_hat, re-simulations) of a 60 s log on one
  core, next to the paper's identification (``identification.paper.identify_log``) of the same
  log measured in the same run (the ratio is the number to compare between machines);
* the paper's story on the paper's own experiment (identification trajectory, law 1, closed loop).

The blind logs are simulated and diagnosed on a campaign executor (:mod:`controllers.campaign`):
local worker processes (``--workers``), or a Dask cluster (``--cluster tcp://HOST:PORT``).

Usage: ``python benchmarks/bench_detection.py [--seeds 1,2,3] [--levels 0.25,0.5,1] [--workers 2]
[--cluster tcp://HOST:PORT] [--negatives 6] [--json PATH] [--skip-timing]``.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time

import numpy as np


def _one(job):
    """One blind log, simulated and diagnosed on a campaign worker (in its own scratch directory)."""
    with tempfile.TemporaryDirectory(prefix="neck-sim-blind-") as directory:
        return _one_in(job, directory)


def _one_in(job, directory):
    name, seed, level = job
    from identification.blind import MAGNITUDES, make_case
    from identification.diagnosis import DiagnosisSettings, diagnose_log

    path = os.path.join(directory, f"{name.replace(':', '_')}_{seed}_{level}.mcap")
    t0 = time.perf_counter()
    try:
        case, _ = make_case(name, seed, path, level=level)
    except RuntimeError as exc:             # the servo cannot hold this plant (e.g. a long delay)
        return {"case": name, "seed": seed, "level": level, "expect": name, "magnitude": None,
                "nominal_magnitude": MAGNITUDES.get(name, 0.0) * level, "description": f"simulation failed: {exc}",
                "verdict": "simulation failed", "improvement": 0.0, "located": None, "t_sim": 0.0, "t_diag": 0.0}
    t_sim = time.perf_counter() - t0
    t0 = time.perf_counter()
    diag = diagnose_log(path, model=",".join(case.model) or "rigid",
                        settings=DiagnosisSettings(max_steps=1, resimulate=False, alpha_hat=False))
    t_diag = time.perf_counter() - t0
    os.unlink(path)
    v = diag.verdict
    f = diag.findings[0] if diag.findings else None
    where = None
    if f is not None:
        where = f.joints or f.cables
    truth_where = [j + 1 for j in case.joints] or [c + 1 for c in case.cables] or None
    return {"case": name, "seed": seed, "level": level, "expect": case.expect, "magnitude": case.magnitude,
            "nominal_magnitude": MAGNITUDES.get(name, 0.0) * level, "description": case.description,
            "verdict": v if isinstance(v, str) else "ambiguous:" + "+".join(v),
            "improvement": f.evidence.improvement if f else
            max((c.improvement for c in diag.steps[0].candidates), default=0.0),
            # located: effects hidden on one cable or joint (not those on every cable, nor payload or delay)
            "located": (where == truth_where) if (f and truth_where and len(truth_where) == 1) else None,
            "t_sim": t_sim, "t_diag": t_diag}


def _units(name: str) -> str:
    from identification.blind import blind_forms

    form = blind_forms().get(name)
    return form[0].blind_unit if form else ""


def confusion_tables(results, levels) -> str:
    from neck_sim import effects

    cols = [effects.NONE] + list(effects.names()) + ["ambiguous"]
    short = {effects.NONE: "none", "ambiguous": "ambig",
             **{c.name: c.abbreviation or c.name for c in effects.registered()}}
    out = []
    cases = list(dict.fromkeys(r["case"] for r in results))
    for level in levels:
        rows = [r for r in results if r["level"] == level or r["case"] == "none"]
        out.append(f"\n**Confusion matrix at level {level:g} x the test magnitude** (rows: hidden, columns: verdict; "
                   f"counts over seeds)\n")
        out.append("| hidden \\ verdict | " + " | ".join(short[c] for c in cols) + " |")
        out.append("|---" * (len(cols) + 1) + "|")
        for case in cases:
            rs = [r for r in rows if r["case"] == case]
            if case == "none" and level != levels[-1]:
                continue
            counts = {c: 0 for c in cols}
            for r in rs:
                if r["verdict"] == "simulation failed":
                    continue
                key = "ambiguous" if r["verdict"].startswith("ambiguous") else r["verdict"]
                counts[key] = counts.get(key, 0) + 1
            out.append(f"| {case} | " + " | ".join(str(counts[c]) if counts[c] else "." for c in cols) + " |")
    return "\n".join(out)


def limit_table(results, levels) -> str:
    from identification.blind import MAGNITUDES

    lines = ["\n**Detection limits** (smallest tested level from which every seed is named correctly at that "
             "level and above; magnitudes are the level times the test magnitude, each seed drawing a factor in "
             "[0.8, 1.25])\n",
             "| hidden effect | test magnitude | detection limit (level) | magnitude at the limit | correct / runs "
             "per level | located correctly | mean held-out improvement at the test level |",
             "|---|---|---|---|---|---|---|"]
    for case in [c for c in dict.fromkeys(r["case"] for r in results) if c != "none"]:
        per_level = {}
        for L in levels:
            rs = [r for r in results if r["case"] == case and r["level"] == L and r["verdict"] != "simulation failed"]
            per_level[L] = (sum(r["verdict"] == r["expect"] for r in rs), len(rs))
        limit = None
        for L in sorted(levels, reverse=True):
            ok, n = per_level[L]
            if n == 0:                  # not simulable at this level (e.g. stiffening past the cable's pole)
                continue
            if ok == n:
                limit = L
            else:
                break
        loc = [r["located"] for r in results if r["case"] == case and r["located"] is not None]
        ref = 1.0 if 1.0 in levels else max(levels)
        top = [r for r in results if r["case"] == case and r["level"] == ref and r["verdict"] != "simulation failed"]
        unit = _units(case)
        mag = MAGNITUDES[case]
        lines.append(f"| {case} | {mag:g} {unit} | {limit if limit is not None else '> ' + str(max(levels))} | "
                     f"{(f'{mag * limit:.3g} {unit}') if limit is not None else '-'} | "
                     + ", ".join(f"{L:g}: {per_level[L][0]}/{per_level[L][1]}" if per_level[L][1] else
                                 f"{L:g}: not simulable" for L in levels)
                     + f" | {f'{sum(loc)}/{len(loc)}' if loc else '-'} | "
                     f"{100 * np.mean([r['improvement'] for r in top]):.1f} % |")
    return "\n".join(lines)


def timing(progress: bool = True) -> str:
    """Whole diagnosis of a 60 s log on one core, and the paper's identification of the same log."""
    from identification.blind import excitation_trajectory, hidden_effect, run_log
    from identification.diagnosis import DiagnosisSettings, diagnose_log
    from identification.paper import identify_log
    from neck_sim.logs import read_log

    try:
        os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})
        core = "pinned to one core"
    except (AttributeError, OSError):
        core = "not pinned (no sched_setaffinity)"
    case = hidden_effect("viscous_friction", 7)
    traj = excitation_trajectory(case.params, sequences=4, move_time=2.0, hold_time=0.5)
    with tempfile.TemporaryDirectory() as d:
        path = os.path.join(d, "sixty.mcap")
        t0 = time.perf_counter()
        run_log(path, case.params, case.effects, trajectory=traj, seed=7, write_truth=False)
        t_sim = time.perf_counter() - t0
        log = read_log(path, topics=("motors", "camera"))
        t0 = time.perf_counter()
        identify_log(log)
        t_ident = time.perf_counter() - t0
        t0 = time.perf_counter()
        diag = diagnose_log(log, settings=DiagnosisSettings(max_steps=3), progress=progress)
        t_diag = time.perf_counter() - t0
    dur = float(log.motors.t[-1] - log.motors.t[0])
    tm = diag.timings
    return "\n".join([
        f"\n**Timing** ({core}; {dur:.1f} s log with hidden viscous friction, verdict `{diag.verdict}`)\n",
        "| step | time (s) |", "|---|---|",
        f"| simulate the log (plant + servo + MCAP) | {t_sim:.1f} |",
        f"| paper identification (`identify_log`, baseline of this run) | {t_ident:.1f} |",
        f"| whole diagnosis (3 steps, alpha_hat, 2 re-simulations) | {t_diag:.1f} |",
        "| of which: " + ", ".join(f"{k} {v:.1f}" for k, v in tm.items()) + " | |",
        f"| ratio diagnosis / identification | {t_diag / t_ident:.2f} |",
        f"| ratio diagnosis / log duration (target < 1) | {t_diag / dur:.2f} |"])


def report(results, levels, seeds, how: str) -> None:
    neg = [r for r in results if r["case"] == "none"]
    failed = [r for r in results if r["verdict"] == "simulation failed"]
    print(f"# Detection power of the diagnosis\n\n{len(results)} blind logs (20.8 s each), seeds {seeds}, "
          f"levels {levels}; {how}; diagnosis (fast path) "
          f"{np.mean([r['t_diag'] for r in results if r['t_diag']]):.1f} s per log on average.")
    if failed:
        print("\nSimulations that failed (left out): " + "; ".join(f"{r['case']} seed {r['seed']} level {r['level']}"
                                                                  for r in failed))
    print(confusion_tables(results, levels))
    print(limit_table(results, levels))
    fa = [r for r in neg if r["verdict"] != "none"]
    print(f"\n**Noise-only controls**: {len(neg) - len(fa)}/{len(neg)} give `none`"
          + (f"; false alarms: {', '.join(r['verdict'] + ' (seed ' + str(r['seed']) + ')' for r in fa)}" if fa else "")
          + f"; largest candidate improvement {100 * max(r['improvement'] for r in neg):.1f} %.")


def story(progress: bool = True) -> str:
    """The paper's story on the paper's own experiment: the §5.2.2 identification trajectory (85 s)
    run closed loop with control law 1 (t_min = 15 N) on the default plant, diagnosed from the
    rigid frictionless model of eq (25)."""
    from controllers.closed_loop import run_closed_loop
    from controllers.computed_torque import ComputedTorqueController
    from controllers.trajectories import identification_trajectory
    from identification.diagnosis import DiagnosisSettings, diagnose_log
    from neck_sim.effects import CableElasticity, DryFriction, TensionStiffening
    from neck_sim.params import default_params
    from neck_sim.plant import Plant

    p = default_params(3)
    with tempfile.TemporaryDirectory() as d:
        path = os.path.join(d, "identification.mcap")
        run_closed_loop(Plant(p, seed=11), ComputedTorqueController(p, 1, t_min=15.0), identification_trajectory(p),
                        log_path=path, progress=progress)
        t0 = time.perf_counter()
        diag = diagnose_log(path, model="rigid", settings=DiagnosisSettings(max_steps=4), progress=progress)
        t_diag = time.perf_counter() - t0
    lines = [f"\n**The paper's story** (identification trajectory, 85 s, law 1, default plant; diagnosis from the "
             f"rigid frictionless model in {t_diag:.0f} s): steps "
             + " -> ".join(f"`{f.effect}`" for f in diag.findings) + f" -> `{diag.steps[-1].verdict}`\n",
             "| step | effect | held-out improvement | identified | plant |", "|---|---|---|---|---|"]
    truth = {DryFriction.name: ("f_s", p.friction.f_s), CableElasticity.name: ("k", p.cables.k_linear),
             TensionStiffening.name: ("lambda", p.cables.lam)}
    for f in diag.findings:
        sym, ref = truth.get(f.effect, (None, None))
        vals = [v.value for k, v in f.parameters.items() if sym and k.split("(")[0] == sym]
        ident = ", ".join(f"{v:.4g}" for v in vals)
        plant = ", ".join(f"{v:.4g}" for v in ref) if ref is not None else ""
        if f.effect == CableElasticity.name:
            plant = "(Table 1, linear fit of the paper: " + plant + ")"
        lines.append(f"| {f.step} | {f.effect} | {100 * f.evidence.improvement:.1f} % | "
                     f"{sym}: {ident} | {plant} |")
    b, a = diag.baseline, diag.final
    lines.append(f"\nalpha_hat against the camera (held out, mean |error|): "
                 f"{b.alpha_hat_vs_camera.holdout.mean_abs_deg:.2f} deg (rigid) -> "
                 f"{a.alpha_hat_vs_camera.holdout.mean_abs_deg:.2f} deg (final); paper (eq 35): 2.79 -> 1.36 deg")
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="1,2,3")
    ap.add_argument("--levels", default="0.25,0.5,1")
    ap.add_argument("--negatives", type=int, default=6, help="noise-only controls (seeds 1..K)")
    ap.add_argument("--cases", default=None, help="comma-separated blind cases (default: all)")
    ap.add_argument("--workers", type=int, default=None, help="local worker processes (default: one per core)")
    ap.add_argument("--cluster", default=None, metavar="tcp://HOST:PORT", help="run on this Dask scheduler")
    ap.add_argument("--json", default=None)
    ap.add_argument("--skip-timing", action="store_true")
    ap.add_argument("--from-json", default=None, help="print the tables of a previous --json run (no simulation)")
    ap.add_argument("--timing-only", action="store_true", help="only the 60 s timing")
    args = ap.parse_args(argv)
    if args.timing_only:
        print(timing())
        print(story())
        return 0
    from controllers.campaign import ExecutorSpec, run_campaign
    from identification.blind import CASES

    seeds = [int(s) for s in args.seeds.split(",")]
    levels = sorted(float(x) for x in args.levels.split(","))
    cases = [c for c in (args.cases.split(",") if args.cases else CASES) if c != "none"]
    if args.from_json:
        with open(args.from_json) as fh:
            results = json.load(fh)
        levels = sorted({r["level"] for r in results if r["case"] != "none"})
        seeds = sorted({r["seed"] for r in results if r["case"] != "none"})
        report(results, levels, seeds, "from " + args.from_json)
        return 0
    where = ExecutorSpec(workers=args.workers, cluster=args.cluster)
    jobs = [(c, s, L) for c in cases for s in seeds for L in levels]
    jobs += [("none", s, 1.0) for s in range(1, args.negatives + 1)]
    t0 = time.perf_counter()
    results = run_campaign(_one, jobs, where, labels=[f"{c} seed {s} level {L:g}" for c, s, L in jobs],
                           desc="blind diagnoses")
    wall = time.perf_counter() - t0
    report(results, levels, seeds, f"{wall:.0f} s on {where.describe()}")
    if not args.skip_timing:
        print(timing())
        print(story())
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(results, fh, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
