"""Identification: speed, and (``--study``) the recovery, noise, excitation and simulator numbers.

Speed: ``identify_log`` on the paper's 84 s identification trajectory (a synthetic flat-output
run written as MCAP), as a ratio to reading that log (``read_log``), both measured here.

Study (minutes of simulation): the paper's identification trajectory, closed
loop under law 1 on the default MuJoCo plant (seed 0), identified from its measured topics;
the same with a perfect camera (what the 1 deg camera noise costs); a camera-noise Monte Carlo on
the flat-output model (the spread the eq (50) sigmas should describe); the excitation optimised
for the condition number and run on the plant; the §5.6 simulator comparison.

    python benchmarks/bench_identify.py            # speed only (about 20 s)
    python benchmarks/bench_identify.py --study    # everything (about 10 min on 2 cores)
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time

import numpy as np

from controllers.trajectories import identification_trajectory
from identification.excitation import (optimise_identification_trajectory, predict_run,
                                       synthetic_measurements)
from identification.paper import IdentificationSettings, format_tables, identify, identify_log
from identification.preprocessing import prepare
from neck_sim.logs import LogWriter, read_log
from neck_sim.params import default_params


def _best(fn, repeat=3):
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return min(times), out


def speed(tmp: str) -> dict:
    p = default_params(3)
    traj = identification_trajectory(p)
    t = np.arange(0.0, traj.duration, 1.0 / p.control.rate_hz)
    s = traj.sample(t)
    meas = synthetic_measurements(predict_run(s.alpha, s.alpha_dot, s.alpha_ddot, t, p), p, np.random.default_rng(0))
    path = os.path.join(tmp, "synthetic.mcap")
    with LogWriter(path, p) as w:
        for i in range(meas.t_motor.size):
            w.motors(meas.t_motor[i], meas.theta[i], meas.force[i])
        for i in range(meas.t_camera.size):
            w.camera(meas.t_camera[i], meas.alpha_camera[i])
    t_read, log = _best(lambda: read_log(path, topics=("motors", "camera")))
    t_prep, _ = _best(lambda: prepare(meas, p))
    t_fit, _ = _best(lambda: identify_log(log, IdentificationSettings(reconstruct_alpha=False)), 2)
    t_all, _ = _best(lambda: identify_log(log), 1)
    out = {"log_s": float(traj.duration), "read_log_s": t_read, "prepare_s": t_prep, "identify_no_alpha_s": t_fit,
           "identify_s": t_all}
    print(f"log of {traj.duration:.0f} s (42500 motor samples, 2550 camera frames)")
    print(f"{'step':34} {'time (s)':>9} {'x read_log':>11}")
    for name, v in (("read_log (baseline)", t_read), ("prepare (filter, decimate, eq 27)", t_prep),
                    ("identify, Tables 1-2 and errors", t_fit), ("identify with §5.5 alpha_hat", t_all)):
        print(f"{name:34} {v:9.3f} {v / t_read:11.1f}")
    return out


def _closed_loop(traj, params, path, *, law=1, seed=0):
    from controllers.closed_loop import run_closed_loop
    from controllers.computed_torque import ComputedTorqueController
    from neck_sim.plant import Plant

    run_closed_loop(Plant(params, seed=seed), ComputedTorqueController(default_params(params.n_joints), law=law),
                    traj, log_path=path, progress=True)
    return path


def _errors(result, truth) -> dict:
    pct = lambda v, t: (100 * (np.asarray(v) / np.asarray(t) - 1)).round(2).tolist()  # noqa: E731
    v = result.variable
    return {"f_s (44-45) %": pct(result.elastic.group("f_s"), truth.friction.f_s),
            "f_s (46-47) %": pct(result.friction.group("f_s"), truth.friction.f_s),
            "k %": pct(v.group("k"), truth.cables.k), "lambda %": pct(v.group("lambda"), truth.cables.lam),
            "c_a (N s/m)": v.group("c_a").round(1).tolist(),
            "rel sigma k %": v.group_rel_sigma("k").round(2).tolist(),
            "rel sigma lambda %": v.group_rel_sigma("lambda").round(2).tolist(),
            "rel sigma f_s (44-45) %": result.elastic.group_rel_sigma("f_s").round(2).tolist(),
            "cond_scaled variable": round(v.cond_scaled, 2), "cond_scaled elastic": round(result.elastic.cond_scaled, 2),
            "camera cutoff Hz": round(result.prepared.cutoffs["camera"].hz, 2)}


def _print_errors(title, e):
    print(f"\n{title}")
    for k, v in e.items():
        print(f"  {k:26} {v}")


def monte_carlo(amplitudes, params, seeds: int) -> dict:
    """Spread of k, lambda over camera-noise seeds on the flat-output model (no plant)."""
    from identification.excitation import sequences_trajectory

    traj = sequences_trajectory(amplitudes)
    t = np.arange(0.0, traj.duration, 1.0 / params.control.rate_hz)
    s = traj.sample(t)
    run = predict_run(s.alpha, s.alpha_dot, s.alpha_ddot, t, params)
    errs, rels = [], []
    for seed in range(seeds):
        r = identify(synthetic_measurements(run, params, np.random.default_rng(seed)), params,
                     IdentificationSettings(reconstruct_alpha=False), models=("elastic", "variable"))
        v = r.variable
        errs.append(np.r_[v.group("k") / params.cables.k - 1, v.group("lambda") / params.cables.lam - 1])
        rels.append(np.r_[v.group_rel_sigma("k"), v.group_rel_sigma("lambda")])
    e = 100 * np.asarray(errs)
    return {"mean %": e.mean(0).round(2).tolist(), "std %": e.std(0).round(2).tolist(),
            "max |err| %": np.abs(e).max(0).round(2).tolist(), "eq (50) rel sigma %": np.mean(rels, 0).round(2).tolist()}


def study(tmp: str, seeds: int, out_dir: str | None) -> dict:
    from identification.excitation import paper_amplitudes
    from identification.plots import figure_simulator, save_figure, save_identification_figures
    from identification.simulator import compare_simulators

    p = default_params(3)
    report = {}
    paper_traj = identification_trajectory(p)
    paper_log = _closed_loop(paper_traj, p, os.path.join(tmp, "paper.mcap"))
    log = read_log(paper_log, topics=("motors", "camera", "reference"))
    res = identify_log(log)
    print("\n" + format_tables(res, truth=p))
    report["paper trajectory"] = _errors(res, p)
    report["paper trajectory tables"] = res.to_dict()
    _print_errors("paper trajectory, camera noise 1 deg: error vs plant", report["paper trajectory"])
    if out_dir:
        save_identification_figures(res, out_dir)

    quiet = p.replace(**{"sensors.camera_noise": 0.0})
    quiet_log = _closed_loop(paper_traj, quiet, os.path.join(tmp, "quiet.mcap"))
    res_q = identify_log(read_log(quiet_log, topics=("motors", "camera")))
    report["paper trajectory, perfect camera"] = _errors(res_q, p)
    _print_errors("paper trajectory, perfect camera: error vs plant", report["paper trajectory, perfect camera"])

    t0 = time.perf_counter()
    opt = optimise_identification_trajectory(p)
    report["excitation"] = {
        "optimisation_s": round(time.perf_counter() - t0, 1), "evaluations": opt.evaluations,
        "amplitudes_deg": np.degrees(opt.amplitudes).round(1).tolist(),
        "predicted cond_scaled (friction, elastic, variable), paper": [round(x, 2) for x in opt.initial_quality[:3]],
        "predicted cond_scaled (friction, elastic, variable), optimised": [round(x, 2) for x in opt.quality[:3]]}
    opt_log = _closed_loop(opt.trajectory, p, os.path.join(tmp, "optimised.mcap"))
    res_o = identify_log(read_log(opt_log, topics=("motors", "camera")))
    report["optimised trajectory"] = _errors(res_o, p)
    _print_errors("optimised trajectory: error vs plant", report["optimised trajectory"])
    print("\nexcitation:", json.dumps(report["excitation"], indent=1))

    report["monte carlo, paper"] = monte_carlo(paper_amplitudes(3), p, seeds)
    report["monte carlo, optimised"] = monte_carlo(opt.amplitudes, p, seeds)
    for k in ("monte carlo, paper", "monte carlo, optimised"):
        _print_errors(f"{k}: k(1..4), lambda(1..4) over {seeds} camera-noise seeds (flat-output model)", report[k])

    cmp = compare_simulators(log, res, law=1)
    print("\n§5.6 simulator comparison (paper trajectory, law 1)\n" + cmp.table())
    report["simulators"] = cmp.to_dict()
    if out_dir:
        save_figure(figure_simulator(cmp.series), os.path.join(out_dir, "fig9_simulators.png"))
    return report


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--study", action="store_true", help="also run the recovery/noise/excitation/simulator study")
    ap.add_argument("--seeds", type=int, default=10, help="camera-noise seeds of the Monte Carlo")
    ap.add_argument("--plots", metavar="DIR", help="write figures 4-9 of the study")
    ap.add_argument("--json", metavar="PATH", help="write all numbers as JSON")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        out = {"speed": speed(tmp)}
        if args.study:
            out.update(study(tmp, args.seeds, args.plots))
    if args.json:
        from neck_sim.atomic import atomic_write_json

        atomic_write_json(args.json, out, indent=1, default=float)
    return 0


if __name__ == "__main__":
    sys.exit(main())
