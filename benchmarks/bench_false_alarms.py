"""False alarms of ``neck-sim diagnose`` on clean logs: no effect hidden, diagnosed against the plant's own model.

Grid: every trajectory of ``neck-sim simulate`` (control test, identification) x every control law
(1, 2, 3) x move durations x1 and x0.5 (``duration_scale``) x seeds (camera noise), each log
diagnosed whole and cut to its first 10 s (``read_log(end=10)``); plus an excitation the tool did
not design: a random multisine in joint space (``tests/open_world/generator.py``'s
:class:`Multisine`, a servo around the nominal feed-forward) of 12 and 24 s, one draw per seed.
A correct verdict is ``none`` or ``insufficient_excitation``; anything else is a false alarm.
The diagnosis runs one forward step without re-simulation (the tests' setting: a clean log's
verdict is decided at the first step).

Prints a Markdown table (verdict counts per row) and the false-alarm total.  Logs can be kept in
``--logs DIR`` (reused when present: re-diagnosing after a change of the method skips the
simulations).  ``--jsonl PATH`` gets each log's results as soon as that log is diagnosed; a rerun
with the same ``PATH`` skips the logs it already holds, so a grid interrupted after an hour
resumes where it stopped.

Usage: ``python benchmarks/bench_false_alarms.py [--seeds 0,1,2,3,4] [--workers 2] [--logs DIR]
[--only control-test,identification,multisine] [--laws 1,2,3] [--scales 1,0.5] [--jsonl PATH]
[--from-jsonl PATH] [--docs docs/diagnosis.md]``.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time

_ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
sys.path[:0] = [_ROOT, os.path.join(_ROOT, "tests")]     # this checkout's code, not the installed one

OK = ("none", "insufficient_excitation")
CROP_S = 10.0


def _names(verdict) -> list:
    return list(verdict) if isinstance(verdict, list) else [verdict]


def make_log(job, path) -> float:
    """Simulate the clean log of ``job`` into ``path`` (kept when it exists); its duration (s)."""
    kind, law, scale, seed = job
    if not os.path.exists(path):
        tmp = path + ".part.mcap"
        if kind == "multisine":
            from neck_sim.params import default_params
            from open_world.generator import Multisine, make_spec, simulate

            p = default_params()
            simulate(tmp, make_spec("none", seed), seed, excitation=Multisine.draw(p, seed, duration=float(law)))
        else:
            from controllers.parallel import RunSpec, run_one
            from neck_sim.params import default_params

            run_one(RunSpec(f"{kind} law {law}", default_params(), law=law, trajectory=kind, duration_scale=scale,
                            seed=seed, log_path=tmp))
        os.replace(tmp, path)
    from neck_sim.logs import read_log
    return float(read_log(path, topics=("motors",)).motors.t[-1])


def diagnose_clean(path, end: float | None = None):
    """The diagnosis of a clean log (tests' setting) from the paper's model, over [0, end] s."""
    from identification.diagnosis import DiagnosisSettings, diagnose_log
    from neck_sim.logs import read_log

    log = read_log(path, end=end, topics=("motors", "camera"), require=("motors", "camera"))
    return diagnose_log(log, settings=DiagnosisSettings(max_steps=1, resimulate=False))


def _key(r) -> tuple:
    return (r["excitation"], int(r["law"]), float(r["scale"]), int(r["seed"]))


def _one(job_and_dir):
    from identification.diagnosis.materiality import undecided_lines

    job, logs, jsonl = job_and_dir
    kind, law, scale, seed = job
    with tempfile.TemporaryDirectory(prefix="neck-sim-clean-") as scratch:
        where = logs or scratch
        path = os.path.join(where, f"{kind}_{law}_{scale:g}_{seed}.mcap")
        t0 = time.perf_counter()
        duration = make_log(job, path)
        t_sim = time.perf_counter() - t0
        out = []
        ends = [None] + ([CROP_S] if duration > CROP_S + 2 else [])
        for end in ends:
            t0 = time.perf_counter()
            diag = diagnose_clean(path, end)
            names = _names(diag.verdict)
            top = max(diag.steps[0].candidates if diag.steps else (), key=lambda c: c.improvement, default=None)
            out.append({"excitation": kind, "law": law, "scale": scale, "seed": seed,
                        "length_s": round(min(duration, end or duration), 1), "verdict": "+".join(names),
                        "correct": "+".join(names) in OK,
                        "reasons": [g.describe() for g in getattr(diag, "gaps", ())][:3],
                        "best_candidate": None if top is None else top.term.name,
                        "best_improvement": None if top is None else top.improvement,
                        "leftover": [x.describe() for x in diag.leftover.found[:2]] if diag.leftover else [],
                        "not_named": [n for n in diag.notes if "but is not named" in n],
                        # a "record a longer log" line on a clean log is a false alarm too
                        "undecided": undecided_lines(diag),
                        "t_sim": t_sim, "t_diag": time.perf_counter() - t0})
        if jsonl:                       # both crops of a log in one locked write: a log is whole or absent
            from bench_detection import append_jsonl
            append_jsonl(jsonl, out)
        return out


def table(results) -> str:
    rows = {}
    for r in results:
        what = ("random multisine (generator)" if r["excitation"] == "multisine"
                else f"{r['excitation']}, law {r['law']}, x{r['scale']:g}")
        rows.setdefault((what, r["length_s"] if r["excitation"] == "multisine" or r["length_s"] <= CROP_S
                         else "whole"), []).append(r)
    lines = ["| excitation | log | logs | verdicts (count) | false alarms |", "|---|---|---|---|---|"]
    for (what, length), rs in rows.items():
        counts = {}
        for r in rs:
            counts[r["verdict"]] = counts.get(r["verdict"], 0) + 1
        lens = sorted({r["length_s"] for r in rs})
        span = f"{lens[0]:g} s" if len(lens) == 1 else f"{lens[0]:g}-{lens[-1]:g} s"
        lines.append(f"| {what} | {'first 10 s' if length == CROP_S else span} | {len(rs)} | "
                     + ", ".join(f"`{v}` x {k}" for v, k in sorted(counts.items(), key=lambda kv: -kv[1]))
                     + f" | {sum(not r['correct'] for r in rs)} |")
    fa = [r for r in results if not r["correct"]]
    lines.append(f"\nFalse alarms: {len(fa)} of {len(results)} diagnoses "
                 f"({sum(r['verdict'] == 'none' for r in results)} `none`, "
                 f"{sum(r['verdict'] == 'insufficient_excitation' for r in results)} `insufficient_excitation`).")
    for r in fa:
        what = "multisine" if r["excitation"] == "multisine" else f"{r['excitation']} law {r['law']} x{r['scale']:g}"
        lines.append(f"- {what} seed {r['seed']} ({r['length_s']} s): "
                     f"`{r['verdict']}`" + (f" -- {r['leftover'][0]}" if r["leftover"] else ""))
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="0,1,2,3,4")
    ap.add_argument("--only", default="control-test,identification,multisine")
    ap.add_argument("--laws", default="1,2,3")
    ap.add_argument("--scales", default="1,0.5")
    ap.add_argument("--multisine-lengths", default="12,24", help="multisine durations (s)")
    ap.add_argument("--workers", type=int, default=None)
    ap.add_argument("--logs", default=None, help="keep (and reuse) the simulated logs in this directory")
    ap.add_argument("--jsonl", default=None, help="append each log's results here as it finishes; a rerun with "
                    "the same file skips the logs it holds (resumes an interrupted grid)")
    ap.add_argument("--from-jsonl", default=None)
    ap.add_argument("--docs", default=None, help="write the table into this Markdown file between its markers")
    ap.add_argument("--commit", default=None, help="with --from-jsonl: the commit the results were measured on")
    args = ap.parse_args(argv)
    command = "python benchmarks/bench_false_alarms.py " + " ".join(argv or sys.argv[1:])
    from bench_detection import read_jsonl, write_docs

    if args.from_jsonl:
        text = table(read_jsonl(args.from_jsonl))
        print(text)
        if args.docs:
            write_docs(args.docs, text, command, "bench_false_alarms", commit=args.commit)
        return 0
    from neck_sim.campaign import ExecutorSpec, run_campaign

    seeds = [int(x) for x in args.seeds.split(",")]
    kinds = args.only.split(",")
    jobs = []
    for kind in kinds:
        if kind == "multisine":
            jobs += [("multisine", int(float(d)), 1.0, s) for d in args.multisine_lengths.split(",") for s in seeds]
        else:
            jobs += [(kind, int(law), float(sc), s) for law in args.laws.split(",") for sc in args.scales.split(",")
                     for s in seeds]
    if args.logs:
        os.makedirs(args.logs, exist_ok=True)
    held = [r for r in read_jsonl(args.jsonl) if _key(r) in set(jobs)] if args.jsonl else []
    todo = [j for j in jobs if j not in {_key(r) for r in held}]
    if held:
        print(f"{len(jobs) - len(todo)} of {len(jobs)} logs already in {args.jsonl}; running the other {len(todo)}")
    where = ExecutorSpec(workers=args.workers)
    t0 = time.perf_counter()
    done = run_campaign(_one, [(j, args.logs, args.jsonl) for j in todo], where,
                        labels=[" ".join(map(str, j)) for j in todo], desc="clean logs")
    results = held + [r for rs in done for r in rs]
    text = (f"{len(results)} diagnoses of {len(jobs)} clean logs ({len(todo)} run now, in {time.perf_counter() - t0:.0f} s on "
            f"{where.describe()}).\n\n" + table(results))
    print(text)
    if args.docs:
        write_docs(args.docs, text, command, "bench_false_alarms")
    return 0


if __name__ == "__main__":
    sys.exit(main())
