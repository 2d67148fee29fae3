"""Coverage of identify's sigmas: eq (50) (the paper's) against the calibrated ones, over seeds.

For each log (the paper's 15 s control test under law 2, and the 85 s identification trajectory
under law 1) one closed-loop run of the default MuJoCo plant is made with a perfect camera, and
``--seeds`` logs are made from it by adding the camera's Gaussian noise (1 deg per frame and
joint).  That equals as many plant seeds: the camera noise is the plant's only random draw and the
controller never sees the camera (two plant seeds give bit-identical motor topics).  Each log is
identified; per parameter group the table gives the share of estimates within 1 and 2 sigma of
the plant's value for

* eq (50): the least-squares value with eq (50)'s sigma (the paper's);
* HAC: the least-squares value with the Newey-West sigma alone;
* bootstrap: the bias-corrected value with the camera-noise bootstrap's sigma alone;
* first order: the bias-corrected value with the larger of HAC and the bootstrap sigma without its
  second-order term (``identify`` before that term);
* calibrated: what ``identify`` reports, the bias-corrected value with the larger of the two;

and the bias of the least-squares and corrected values over their spread across seeds.  The
elastic model's k and c_a have no true value (a linear fit of a tension-dependent stiffness).
The time of one identification with and without the bootstrap is printed as a ratio.

The camera-noise seeds are 9100, 9101, ... on both logs; the bootstrap's second-order term was
chosen on seeds 9000-9007 of both logs, which the table does not use.

    python benchmarks/bench_coverage.py       # 30 + 20 seeds (about 25 min of CPU)
    python benchmarks/bench_coverage.py --write-docs docs/identification.md
    # or one process per log, then the table from both:
    python benchmarks/bench_coverage.py --logs control-test --json ct.json &
    python benchmarks/bench_coverage.py --logs identification --json id.json; wait
    python benchmarks/bench_coverage.py --logs "" --diagnosis-seeds 5 --json diag.json
    python benchmarks/bench_coverage.py --from-json ct.json id.json diag.json --write-docs docs/identification.md

``--diagnosis-seeds N`` adds the coverage of ``neck-sim diagnose``'s payload mass (eq (50) of its
weighted fit, not calibrated) on N blind logs of the tests' generator (a 68-82 g payload, level 1,
seeds 1..N; one forward step, no re-simulation).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

from identification.paper import IdentificationSettings, identify
from identification.preprocessing import Measurements, prepare
from neck_sim.params import default_params

GROUPS = (("friction", "f_s"), ("elastic", "f_s"), ("variable", "k"), ("variable", "lambda"), ("variable", "c_a"))
SEED_BASE = 9100


def _first_order(u, sym):
    """The calibrated sigma without the bootstrap's second-order term."""
    d2 = u.group("bias_second_order", sym) if u.bias_second_order is not None else 0.0
    boot = np.sqrt(np.maximum(u.group("sigma_bootstrap", sym) ** 2 - d2 ** 2, 0.0))
    model = u.group("sigma_model", sym) if u.sigma_model is not None else 0.0
    return np.hypot(np.maximum(boot, u.group("sigma_hac", sym)), model)


METHODS = (("eq (50), paper", "value_ls", "sigma_eq50"), ("HAC", "value_ls", "sigma_hac"),
           ("bootstrap", "value", "sigma_bootstrap"), ("first order", "value", _first_order),
           ("calibrated", "value", "sigma"))
START, END = "<!-- coverage-table:start -->", "<!-- coverage-table:end -->"


def quiet_run(name: str, tmp: str):
    """Measurements of one closed-loop run with a perfect camera, and the plant's parameters."""
    from controllers.closed_loop import run_closed_loop
    from controllers.computed_torque import ComputedTorqueController
    from controllers.trajectories import identification_trajectory, make_trajectory
    from neck_sim.logs import read_log
    from neck_sim.plant import Plant

    p = default_params(3)
    traj, law = ((make_trajectory("control-test", p), 2) if name == "control-test"
                 else (identification_trajectory(p), 1))
    path = os.path.join(tmp, f"{name}.mcap")
    run_closed_loop(Plant(p.replace(**{"sensors.camera_noise": 0.0}), seed=0), ComputedTorqueController(p, law=law),
                    traj, log_path=path, progress=False)
    return Measurements.from_log(read_log(path, topics=("motors", "camera"))), p, float(traj.duration)


def truth(p, symbol):
    return np.array({"f_s": p.friction.f_s, "k": p.cables.k, "lambda": p.cables.lam, "c_a": p.cables.c_a}[symbol])


def run_log(name: str, seeds: int, replicates: int, tmp: str) -> dict:
    m, p, duration = quiet_run(name, tmp)
    noise = np.radians(1.0)
    runs, t_cal, t_plain = [], [], []
    for seed in range(seeds):
        rng = np.random.default_rng(SEED_BASE + seed)
        noisy = Measurements(m.t_motor, m.theta, m.force, m.t_camera,
                             m.alpha_camera + noise * rng.normal(size=m.alpha_camera.shape))
        prep = prepare(noisy, p)
        t0 = time.perf_counter()
        runs.append(identify(prep, p, IdentificationSettings(reconstruct_alpha=False, bootstrap=replicates,
                                                              seed=seed)).uncertainty)
        t_cal.append(time.perf_counter() - t0)
        if seed < 3:
            t0 = time.perf_counter()
            identify(prep, p, IdentificationSettings(reconstruct_alpha=False, bootstrap=0))
            t_plain.append(time.perf_counter() - t0)
    rows = []
    for model, sym in GROUPS:
        tr = truth(p, sym)
        row = {"group": f"{sym} ({model})"}
        for label, val, sig in METHODS:
            z = np.array([(u[model].group(val, sym) - tr)
                          / (sig(u[model], sym) if callable(sig) else u[model].group(sig, sym)) for u in runs])
            row[label] = (float(np.mean(np.abs(z) < 1)), float(np.mean(np.abs(z) < 2)))
        for label, val in (("bias/spread LS", "value_ls"), ("bias/spread corrected", "value")):
            v = np.array([u[model].group(val, sym) for u in runs])
            row[label] = float(np.mean(np.abs(v.mean(0) - tr) / v.std(0, ddof=1)))
        row["identified"] = float(np.mean([u[model].group("identified", sym) for u in runs]))
        rows.append(row)
    return {"log": name, "commit": _commit(), "duration_s": duration, "seeds": seeds, "replicates": replicates,
            "rows": rows,
            "identify_s": float(np.median(t_cal)), "identify_eq50_hac_s": float(np.median(t_plain))}


def run_diagnosis(seeds: int) -> dict:
    """Coverage of the diagnosis's payload mass and its eq (50) sigma on the generator's logs."""
    sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "tests"))
    from identification.diagnosis import DiagnosisSettings, diagnose_log
    from open_world.generator import make_spec, simulate

    rows = []
    for seed in range(1, seeds + 1):
        spec = make_spec("payload", seed, 1.0)
        with tempfile.TemporaryDirectory() as tmp:
            path = os.path.join(tmp, "payload.mcap")
            simulate(path, spec, seed)
            diag = diagnose_log(path, model=spec.model, settings=DiagnosisSettings(max_steps=1, resimulate=False))
        f = diag.findings[0] if diag.findings else None
        par = f.parameters.get(spec.symbol) if f is not None else None
        rows.append({"seed": seed, "truth": float(spec.magnitude), "verdict": str(diag.verdict),
                     "value": None if par is None else par.value, "sigma": None if par is None else par.sigma})
    return {"log": "diagnosis", "commit": _commit(), "seeds": seeds, "rows": rows}


def diagnosis_table(r: dict) -> str:
    z = np.array([(x["value"] - x["truth"]) / x["sigma"] for x in r["rows"] if x["sigma"]])
    named = sum(x["value"] is not None for x in r["rows"])
    return "\n".join([
        f"**diagnosis** (`neck-sim diagnose`'s payload mass on {r['seeds']} blind payload logs of the tests' generator, "
        f"seeds 1-{r['seeds']}, code at commit {r.get('commit', 'unknown')}; sigma: eq (50) of its weighted fit, "
        "not calibrated)", "",
        "| parameter | payload named | within 1 sigma / 2 sigma | \\|error\\| / sigma per log |", "|---|---|---|---|",
        f"| payload mass | {named}/{r['seeds']} | {np.mean(np.abs(z) < 1):.2f} / {np.mean(np.abs(z) < 2):.2f} | "
        + ", ".join(f"{abs(v):.2f}" for v in z) + " |", ""])


def _commit() -> str:
    """The checkout's commit (with "+changes" when its tracked files differ from it)."""
    here = os.path.dirname(os.path.abspath(__file__))
    run = lambda *a: subprocess.run(["git", *a], capture_output=True, text=True, cwd=here).stdout.strip()  # noqa: E731
    commit = run("rev-parse", "--short", "HEAD") or "unknown"
    return commit + ("+changes" if run("status", "--porcelain", "--untracked-files=no") else "")


def table(results) -> str:
    lines = []
    for r in results:
        if r["log"] == "diagnosis":
            lines.append(diagnosis_table(r))
            continue
        lines += [f"**{r['log']}** ({r['duration_s']:.0f} s log, {r['seeds']} camera-noise seeds, "
                  f"code at commit {r.get('commit', 'unknown')}, "
                  f"{r['replicates']} + {max(r['replicates'] // 2, 2)} bootstrap replicates at the camera's noise "
                  f"variance and twice it; share within 1 sigma / 2 sigma of the plant's value, "
                  f"nominal 0.68 / 0.95)", "",
                  "| parameters | " + " | ".join(m[0] for m in METHODS) + " | bias/spread, LS -> corrected | identified |",
                  "|---" * (len(METHODS) + 3) + "|"]
        for row in r["rows"]:
            cells = " | ".join(f"{row[m[0]][0]:.2f} / {row[m[0]][1]:.2f}" for m in METHODS)
            lines.append(f"| {row['group']} | {cells} | {row['bias/spread LS']:.2f} -> "
                         f"{row['bias/spread corrected']:.2f} | {100 * row['identified']:.0f} % |")
        lines.append("")
    return "\n".join(lines)


def write_docs(path: str, text: str) -> None:
    from neck_sim.atomic import atomic_write_bytes

    doc = open(path, encoding="utf-8").read()
    if START not in doc or END not in doc:
        raise SystemExit(f"{path}: no {START} ... {END} markers to write the table between")
    head, rest = doc.split(START, 1)
    _, tail = rest.split(END, 1)
    body = ("\n<!-- written by benchmarks/bench_coverage.py; do not edit by hand -->\n\n"
            f"{text}\n")
    atomic_write_bytes(path, (head + START + body + END + tail).encode("utf-8"))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=30)
    ap.add_argument("--seeds-long", type=int, default=20, help="seeds of the 85 s identification log")
    ap.add_argument("--replicates", type=int, default=40,
                    help="camera-noise bootstrap replicates per log (half as many again at twice the noise variance)")
    ap.add_argument("--logs", default="control-test,identification")
    ap.add_argument("--diagnosis-seeds", type=int, default=0,
                    help="also measure the diagnosis's payload sigma on this many generator logs")
    ap.add_argument("--write-docs", metavar="MD", help="write the table between the coverage markers of MD")
    ap.add_argument("--json", metavar="PATH", help="also write the results as JSON")
    ap.add_argument("--from-json", metavar="PATH", nargs="+",
                    help="tabulate results saved by --json (e.g. one process per log) instead of running")
    args = ap.parse_args(argv)
    results = []
    if args.from_json:
        import json

        for path in args.from_json:
            with open(path, encoding="utf-8") as fh:
                results += json.load(fh)
    with tempfile.TemporaryDirectory() as tmp:
        for name in [] if args.from_json else [n for n in args.logs.split(",") if n.strip()]:
            name = name.strip()
            r = run_log(name, args.seeds_long if name == "identification" else args.seeds, args.replicates, tmp)
            results.append(r)
            print(table([r]), flush=True)
        if args.diagnosis_seeds:
            r = run_diagnosis(args.diagnosis_seeds)
            results.append(r)
            print(table([r]), flush=True)
    text = table(results)
    for r in results:
        if r["log"] == "diagnosis":
            continue
        text += (f"\nWall-clock time of one identification ({r['log']}, no alpha_hat, median over the seeds, "
                 f"on the machine as loaded during the run): {r['identify_s']:.2f} s with the "
                 f"calibrated sigmas, {r['identify_eq50_hac_s']:.2f} s with eq (50) and HAC only "
                 f"(x{r['identify_s'] / r['identify_eq50_hac_s']:.1f}).\n")
    print(text)
    if args.json:
        from neck_sim.atomic import atomic_write_json

        atomic_write_json(args.json, results)
    if args.write_docs:
        write_docs(args.write_docs, text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
