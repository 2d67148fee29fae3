"""Detection power of ``neck-sim diagnose`` on blind logs that share no code with its candidates.

The logs come from the open-world generator of the tests (``tests/open_world/generator.py``: a
nominal plant whose hidden effect is a MuJoCo model field or a formula of the generator's own,
never an import of ``neck_sim.effects`` or of the diagnosis).  For every case x seed x magnitude
level (fractions of the generator's test magnitudes, each seed drawing a factor in [0.8, 1.25]
and the affected cable / joint / spring), simulate a 12.2 s log, diagnose it blind (one forward
step, alpha_hat and the structure tests, no re-simulation: the tests' setting) and record the verdict, the location
and the fitted magnitude.  Prints Markdown:

* per effect, the detection limit: the smallest level from which at least 90 % of the logs are
  named correctly (first name of the verdict) at that level and every higher one, with the
  magnitudes there and the median relative error of the fitted magnitude;
* what each out-of-vocabulary effect gets (correct: the verdict contains ``unexplained`` and is
  not a single wrong name);
* false alarms on the noise-only controls;
* the time of a whole diagnosis of a 60 s log on one core (``--timing-only`` or by default).

The blind logs are simulated and diagnosed on a campaign executor (:mod:`neck_sim.campaign`):
local worker processes (``--workers``), or a Dask cluster (``--cluster tcp://HOST:PORT``).

Also: two effects hidden at once (``--pairs default``: the generator's ``PAIRS``, two forward
steps, correct when both are named), the share of logs whose verdict is the hidden name alone,
borderline verdicts, and the same on a random multisine (``--excitations sequences,multisine``).

Usage: ``python benchmarks/bench_detection.py [--seeds 1,2,3] [--levels 0.25,0.5,1,2] [--workers 2]
[--cluster tcp://HOST:PORT] [--negatives 20] [--cases a,b] [--pairs default] [--excitations
sequences,multisine] [--jsonl PATH] [--from-jsonl PATH] [--docs docs/diagnosis.md] [--skip-timing]``;
``--from-jsonl`` prints the tables of a previous run; ``--docs`` writes them, with the commit
measured, between the ``bench_detection`` markers of a Markdown page.

``--jsonl PATH`` gets one line per log as that log finishes (on local workers; on a Dask cluster,
whose workers need not share this disk, at the end): an interrupted run keeps what it did, and a
rerun with the same ``--jsonl`` skips the logs already there (case, seed, level, excitation; a log
whose diagnosis raised is run again) and prints the tables of every log it asked for.
"""

from __future__ import annotations

import argparse
import fcntl
import json
import os
import sys
import tempfile
import time

import numpy as np

_ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
sys.path[:0] = [_ROOT, os.path.join(_ROOT, "tests")]     # this checkout's code, not the installed one


def _names(verdict) -> list:
    return list(verdict) if isinstance(verdict, list) else [verdict]


def correct(expect: str, names: list) -> bool:
    """A named effect: the verdict's first name; two effects at once (``a+b``): both names in the
    verdict; out of vocabulary: ``unexplained`` in the verdict (alone or with other names, never a
    single wrong name)."""
    from open_world.generator import UNEXPLAINED

    if expect == UNEXPLAINED:
        return UNEXPLAINED in names
    if "+" in expect:
        return set(expect.split("+")) <= set(names)
    return names[0] == expect


def alone(expect: str, names: list) -> bool:
    """The verdict is exactly what was hidden: the name alone (both names for a pair, in any
    order; ``unexplained`` alone or beside nothing else for an effect outside the vocabulary)."""
    return sorted(names) == sorted(expect.split("+"))


def _one(job):
    """One blind log, simulated and diagnosed on a campaign worker (in its own scratch directory)."""
    with tempfile.TemporaryDirectory(prefix="neck-sim-blind-") as directory:
        try:
            return _one_in(job, directory)
        except Exception as exc:       # one failing log is a row of the table, not the end of the campaign
            name, seed, level, excitation = (*job, "sequences")[:4]
            return {"case": name, "seed": seed, "level": level, "excitation": excitation, "expect": "?",
                    "magnitude": 0.0, "symbol": None, "fitted": None, "description": f"failed: {exc}",
                    "verdict": f"failed: {type(exc).__name__}", "correct": False, "alone": False, "borderline": False,
                    "located": None, "improvement": 0.0, "leftover": [], "t_sim": 0.0, "t_diag": 0.0}


def job_key(row_or_job) -> tuple:
    """(case, seed, level, excitation) of a job or of a JSONL row: what a rerun skips when done."""
    if isinstance(row_or_job, dict):
        r = row_or_job
        return r["case"], int(r["seed"]), float(r["level"]), r.get("excitation", "sequences")
    name, seed, level, excitation = (*row_or_job, "sequences")[:4]
    return name, int(seed), float(level), excitation


def read_jsonl(path: str) -> list:
    """The rows of a JSONL file (none when it does not exist yet); a torn last line (a run killed
    mid-write) is skipped."""
    if not os.path.exists(path):
        return []
    rows = []
    with open(path) as fh:
        for line in fh:
            try:
                rows.append(json.loads(line))
            except json.JSONDecodeError:
                continue
    return rows


def append_jsonl(path: str, rows: list) -> None:
    """Append whole lines under an exclusive lock, in one write: workers finishing together never
    interleave their lines, and a line torn by a killed run is ended (and skipped when read)."""
    data = "".join(json.dumps(r) + "\n" for r in rows).encode()
    fd = os.open(path, os.O_RDWR | os.O_APPEND | os.O_CREAT, 0o644)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        end = os.lseek(fd, 0, os.SEEK_END)
        if end and os.pread(fd, 1, end - 1) != b"\n":     # a line torn by a killed run: end it first
            data = b"\n" + data
        os.write(fd, data)
        os.fsync(fd)
    finally:
        os.close(fd)


class Recorded:
    """``_one`` that appends its row to ``path`` as soon as the log is diagnosed (picklable: it
    travels to the local workers, which share this disk)."""

    def __init__(self, path: str):
        self.path = path

    def __call__(self, job):
        row = _one(job)
        append_jsonl(self.path, [row])
        return row


def _one_in(job, directory):
    name, seed, level, excitation = (*job, "sequences")[:4]
    from identification.diagnosis import DiagnosisSettings, diagnose_log
    from open_world.generator import Multisine, combine, make_spec, simulate

    parts = [make_spec(n, seed, level) for n in name.split("+")]
    spec = parts[0] if len(parts) == 1 else combine(parts)
    path = os.path.join(directory, f"{name}_{seed}_{level}.mcap")
    t0 = time.perf_counter()
    try:
        simulate(path, spec, seed, excitation=Multisine.draw(spec.params, seed, duration=12.2)
                 if excitation == "multisine" else None)
    except RuntimeError as exc:             # the servo cannot hold this plant
        return {"case": name, "seed": seed, "level": level, "expect": spec.expect, "magnitude": spec.magnitude,
                "description": f"simulation failed: {exc}", "verdict": "simulation failed", "correct": False,
                "alone": False, "excitation": excitation, "borderline": False,
                "t_sim": 0.0, "t_diag": 0.0}
    t_sim = time.perf_counter() - t0
    t0 = time.perf_counter()
    # one forward step per hidden effect (two for a pair); out of vocabulary: one
    diag = diagnose_log(path, model=spec.model, settings=DiagnosisSettings(max_steps=len(parts), resimulate=False))
    t_diag = time.perf_counter() - t0
    os.unlink(path)
    names = _names(diag.verdict)
    f = diag.findings[0] if diag.findings else None
    fitted = None
    if f is not None and spec.symbol is not None and spec.symbol in f.parameters and names[0] == spec.expect:
        fitted = f.parameters[spec.symbol].value
    where = (f.joints or f.cables) if f is not None else None
    truth_where = [j + 1 for j in spec.joints] or [c + 1 for c in spec.cables] or None
    lo = diag.leftover
    places = {f"cable {c + 1}" for c in spec.cables} | {f"joint {j + 1}" for j in spec.joints}
    return {"gaps": [g.describe() for g in diag.gaps if g.where in places],     # what the log lacks where it acts
            "case": name, "seed": seed, "level": level, "excitation": excitation, "expect": spec.expect,
            "magnitude": spec.magnitude, "symbol": spec.symbol, "fitted": fitted, "description": spec.description,
            "verdict": "+".join(names), "correct": correct(spec.expect, names), "alone": alone(spec.expect, names),
            "borderline": diag.borderline,
            "located": (where == truth_where) if (f is not None and truth_where) else None,
            "improvement": f.evidence.improvement if f else
            max((c.improvement for c in diag.steps[0].candidates), default=0.0),
            "leftover": [x.describe() for x in lo.found[:2]] if lo is not None else [],
            "t_sim": t_sim, "t_diag": t_diag}


def bears_on(effect: str, gap: str) -> bool:
    """A gap line (``Gap.describe()``) that says the log cannot show ``effect``: a conditioning
    line about it, or a cable's tension range for a rest elongation or lambda."""
    if f"({effect})" in gap:
        return True
    return ("a rest elongation cannot be separated" in gap if effect == "pretension"
            else "lambda(" in gap and "cannot be separated" in gap if effect == "tension_stiffening" else False)


def limit_table(results, levels) -> str:
    from open_world.generator import UNEXPLAINED

    lines = ["| hidden effect (generator's mechanism) | detection limit (level) | magnitudes at the limit | "
             "correct / runs per level | named alone (all levels) | located | median magnitude error |",
             "|---|---|---|---|---|---|---|"]
    cases = [c for c in dict.fromkeys(r["case"] for r in results) if c != "none"]
    for case in cases:
        rs_case = [r for r in results if r["case"] == case]
        if rs_case[0]["expect"] == UNEXPLAINED or "+" in case:
            continue
        per_level = {}
        for L in levels:
            rs = [r for r in rs_case if r["level"] == L and r["verdict"] != "simulation failed"]
            per_level[L] = (sum(r["correct"] for r in rs), len(rs))
        limit = None
        for L in sorted(levels, reverse=True):
            ok, n = per_level[L]
            if n and ok >= 0.9 * n:
                limit = L
            elif n:
                break
        mags = sorted(r["magnitude"] for r in rs_case if r["level"] == limit) if limit is not None else []
        loc = [r["located"] for r in rs_case if r.get("located") is not None]
        err = [abs(r["fitted"] / r["magnitude"] - 1) for r in rs_case if r.get("fitted") is not None and r["magnitude"]]
        desc = rs_case[0]["description"]
        lines.append(f"| {case} ({desc}) | {limit if limit is not None else '> ' + format(max(levels), 'g')} | "
                     + (f"{mags[0]:.3g}..{mags[-1]:.3g}" if mags else "-") + " | "
                     + ", ".join(f"{L:g}: {per_level[L][0]}/{per_level[L][1]}" for L in levels if per_level[L][1])
                     + f" | {sum(r.get('alone', False) for r in rs_case)}/{len(rs_case)}"
                     + f" | {f'{sum(loc)}/{len(loc)}' if loc else '-'} | "
                     + (f"{100 * np.median(err):.1f} % (max {100 * max(err):.1f} %)" if err else "-") + " |")
    return "\n".join(lines)


def pairs_table(results) -> str:
    """Two effects hidden at once: verdict counts, both named, exactly both."""
    lines = ["| hidden effects | level | verdicts (count) | both named | exactly both |", "|---|---|---|---|---|"]
    for case in dict.fromkeys(r["case"] for r in results if "+" in r["case"]):
        for L in sorted({r["level"] for r in results if r["case"] == case}):
            rs = [r for r in results if r["case"] == case and r["level"] == L]
            counts = {}
            for r in rs:
                counts[r["verdict"]] = counts.get(r["verdict"], 0) + 1
            lines.append(f"| {rs[0]['description']} | {L:g} | "
                         + ", ".join(f"`{v}` x {k}" for v, k in sorted(counts.items(), key=lambda kv: -kv[1]))
                         + f" | {sum(r['correct'] for r in rs)}/{len(rs)} | {sum(r['alone'] for r in rs)}/{len(rs)} |")
    pr = [r for r in results if "+" in r["case"]]
    if pr:
        lines.append(f"\nBoth named in {sum(r['correct'] for r in pr)}/{len(pr)} logs "
                     f"({100 * np.mean([r['correct'] for r in pr]):.0f} %), exactly both in "
                     f"{sum(r['alone'] for r in pr)}/{len(pr)}.")
    return "\n".join(lines)


def out_of_vocabulary_table(results) -> str:
    from open_world.generator import UNEXPLAINED

    lines = ["| effect outside the vocabulary | level | verdicts (count) | correct |", "|---|---|---|---|"]
    for case in dict.fromkeys(r["case"] for r in results if r["expect"] == UNEXPLAINED):
        for L in sorted({r["level"] for r in results if r["case"] == case}):
            rs = [r for r in results if r["case"] == case and r["level"] == L]
            counts = {}
            for r in rs:
                counts[r["verdict"]] = counts.get(r["verdict"], 0) + 1
            lines.append(f"| {case} ({rs[0]['description']}) | {L:g} | "
                         + ", ".join(f"`{v}` x {k}" for v, k in sorted(counts.items(), key=lambda kv: -kv[1]))
                         + f" | {sum(r['correct'] for r in rs)}/{len(rs)} |")
    return "\n".join(lines)


def report(results, how: str) -> str:
    """The Markdown tables of one run (every excitation in turn)."""
    out = []
    for excitation in dict.fromkeys(r.get("excitation", "sequences") for r in results):
        rx = [r for r in results if r.get("excitation", "sequences") == excitation]
        levels = sorted({r["level"] for r in rx if r["case"] != "none"})
        seeds = sorted({r["seed"] for r in rx if r["case"] != "none"})
        neg = [r for r in rx if r["case"] == "none"]
        diag_t = [r["t_diag"] for r in rx if r["t_diag"]]
        what = ("the §5.2.2 sequences of the generator" if excitation == "sequences"
                else "a random multisine in joint space (an excitation the tool did not design)")
        out.append(f"### Excitation: {what}\n\n{len(rx)} blind logs (12.2 s each) from "
                   f"tests/open_world/generator.py, seeds {seeds}, levels {levels}; {how}; diagnosis "
                   f"{np.mean(diag_t) if diag_t else 0:.1f} s per log on average.\n")
        single = [r for r in rx if "+" not in r["case"]]
        ins = [r for r in single if r["case"] != "none" and r["expect"] != "unexplained"]
        if ins:
            out.append("**Effects of the vocabulary** (correct: the verdict's first name; named alone: the verdict "
                       "is that name and nothing else)\n")
            out.append(limit_table(rx, levels))
            why = [(r, [g for g in r.get("gaps", []) if bears_on(r["expect"], g)]) for r in ins if not r["correct"]]
            why = [(r, g) for r, g in why if g]
            if why:
                out.append("\nNot named, and the log's gap lines that say it cannot show the effect where it acts:\n")
                out += [f"- {r['case']} seed {r['seed']} level {r['level']:g}: `{r['verdict']}`; " + "; ".join(g)
                        for r, g in why]
            out.append(f"\nNamed alone in {sum(r['alone'] for r in ins)}/{len(ins)} logs "
                       f"({100 * np.mean([r['alone'] for r in ins]):.0f} %); first name right in "
                       f"{sum(r['correct'] for r in ins)}/{len(ins)}; borderline verdicts "
                       f"{sum(r.get('borderline', False) for r in ins)}.")
        if any("+" in r["case"] for r in rx):
            out.append("\n**Two effects hidden at once** (two forward steps)\n")
            out.append(pairs_table(rx))
        if any(r["expect"] == "unexplained" for r in rx):
            out.append("\n**Effects outside the vocabulary** (correct: `unexplained` in the verdict)\n")
            out.append(out_of_vocabulary_table(rx))
        fa = [r for r in neg if r["verdict"] not in ("none", "insufficient_excitation")]
        if neg:
            out.append(f"\n**Noise-only controls**: {len(neg) - len(fa)}/{len(neg)} give `none`"
                       + (f"; false alarms: {', '.join(r['verdict'] + ' (seed ' + str(r['seed']) + ')' for r in fa)}"
                          if fa else "")
                       + f"; largest candidate improvement {100 * max(r['improvement'] for r in neg):.1f} %.\n")
    return "\n".join(out)


def write_docs(path: str, text: str, command: str, name: str = "bench_detection", commit: str | None = None,
               script: str | None = None) -> None:
    """Put the tables between the markers ``<!-- name: begin -->`` and ``<!-- name: end -->`` of
    ``path`` (atomic), with the commit measured (``commit``: the one a ``--from-jsonl`` run's
    results were measured on; default the checkout's HEAD) and the benchmark that wrote them
    (``script``, default ``name``)."""
    BEGIN, END = f"<!-- {name}: begin -->", f"<!-- {name}: end -->"
    import subprocess

    from neck_sim.atomic import atomic_write_bytes

    root = os.path.dirname(os.path.abspath(path))
    try:
        head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=root, capture_output=True, text=True,
                              check=True).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=root,
                               capture_output=True, text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        head, dirty = "unknown", ""
    if commit is not None:                 # results of an earlier run: its commit, not the checkout's state
        head, dirty = commit, ""
    block = (f"{BEGIN}\n<!-- written by benchmarks/{script or name}.py; do not edit by hand -->\n\n"
             f"Measured on commit `{head}`{' (with uncommitted changes)' if dirty else ''} by `{command}`.\n\n"
             f"{text}\n{END}")
    with open(path) as fh:
        old = fh.read()
    if BEGIN not in old or END not in old:
        raise SystemExit(f"--docs {path}: no {BEGIN} ... {END} markers")
    new = old[:old.index(BEGIN)] + block + old[old.index(END) + len(END):]
    atomic_write_bytes(path, new.encode())


def timing(progress: bool = True) -> str:
    """Whole diagnosis of a 60 s log on one core, and the paper's identification of the same log."""
    from identification.diagnosis.blind import excitation_trajectory, hidden_effect, run_log
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
    from open_world.generator import CASES

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="1,2,3")
    ap.add_argument("--levels", default="0.25,0.5,1,2")
    ap.add_argument("--negatives", type=int, default=20, help="noise-only controls (seeds 1..K)")
    ap.add_argument("--cases", default=None, help=f"comma-separated cases (default: all of {', '.join(CASES)})")
    ap.add_argument("--workers", type=int, default=None, help="local worker processes (default: one per core)")
    ap.add_argument("--cluster", default=None, metavar="tcp://HOST:PORT", help="run on this Dask scheduler")
    ap.add_argument("--jsonl", default=None, help="append the results to this file (one JSON line per log)")
    ap.add_argument("--skip-timing", action="store_true")
    ap.add_argument("--from-jsonl", default=None, help="print the tables of a previous --jsonl run (no simulation)")
    ap.add_argument("--timing-only", action="store_true", help="only the 60 s timing")
    ap.add_argument("--pairs", default="", help="comma-separated pairs a+b hidden at once (or 'default': "
                    "open_world.generator.PAIRS)")
    ap.add_argument("--excitations", default="sequences", help="sequences,multisine")
    ap.add_argument("--multisine-cases", default=None, help="cases run on the multisine (default: --cases)")
    ap.add_argument("--docs", default=None, help="write the tables into this Markdown file between its markers")
    ap.add_argument("--commit", default=None, help="with --from-jsonl: the commit the results were measured on")
    ap.add_argument("--block", default="bench_detection", help="with --docs: the markers' name (one block per "
                    "excitation keeps each table with the commit it measured)")
    args = ap.parse_args(argv)
    if args.timing_only:
        print(timing())
        print(story())
        return 0
    if args.from_jsonl:
        with open(args.from_jsonl) as fh:
            results = [json.loads(line) for line in fh if line.strip()]
        text = report(results, "from " + args.from_jsonl)
        print(text)
        if args.docs:
            write_docs(args.docs, text, "python benchmarks/bench_detection.py " + " ".join(argv or sys.argv[1:]),
                       name=args.block, commit=args.commit, script="bench_detection")
        return 0
    from neck_sim.campaign import ExecutorSpec, run_campaign

    seeds = [int(x) for x in args.seeds.split(",")]
    levels = sorted(float(x) for x in args.levels.split(","))
    cases = [c for c in (args.cases.split(",") if args.cases else CASES) if c != "none"]
    where = ExecutorSpec(workers=args.workers, cluster=args.cluster)
    from open_world.generator import PAIRS

    pairs = list(PAIRS) if args.pairs == "default" else [x for x in args.pairs.split(",") if x]
    jobs = []
    for excitation in args.excitations.split(","):
        on = cases if excitation == "sequences" or not args.multisine_cases else args.multisine_cases.split(",")
        jobs += [("none", s, 1.0, excitation) for s in range(1, args.negatives + 1)]
        jobs += [(c, s, L, excitation) for L in sorted(levels, reverse=True) for c in on for s in seeds]
        jobs += [(c, s, 1.0, excitation) for c in pairs for s in seeds]
    wanted = {job_key(j) for j in jobs}
    done = {}
    if args.jsonl:
        for r in read_jsonl(args.jsonl):          # the last row of a log wins
            if job_key(r) in wanted and not str(r.get("verdict", "")).startswith("failed"):
                done[job_key(r)] = r
        if done:
            print(f"{args.jsonl}: {len(done)} of the {len(jobs)} logs already there, skipped", file=sys.stderr)
    todo = [j for j in jobs if job_key(j) not in done]
    fn = Recorded(args.jsonl) if args.jsonl and args.cluster is None else _one
    t0 = time.perf_counter()
    fresh = run_campaign(fn, todo, where, labels=[f"{c} seed {s} level {L:g} {e}" for c, s, L, e in todo],
                         desc="blind diagnoses") if todo else []
    wall = time.perf_counter() - t0
    if args.jsonl and args.cluster is not None:
        append_jsonl(args.jsonl, fresh)
    by_key = {**done, **{job_key(r): r for r in fresh}}
    results = [by_key[job_key(j)] for j in jobs if job_key(j) in by_key]
    text = report(results, f"{wall:.0f} s on {where.describe()} for the {len(fresh)} logs run now"
                  + (f", {len(done)} read back from {args.jsonl}" if done else ""))
    print(text)
    if args.docs:
        write_docs(args.docs, text, "python benchmarks/bench_detection.py " + " ".join(argv or sys.argv[1:]),
                   name=args.block, script="bench_detection")
    if not args.skip_timing:
        print(timing())
        print(story())
    return 0


if __name__ == "__main__":
    sys.exit(main())
