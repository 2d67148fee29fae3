"""Stiff cables: what a control period costs as the cable damping c_a grows.

Measured in the same run, interleaved, best of ``--repeat`` loops of ``--periods`` control periods
(the loops of ``bench_plant.py``), at the default 0.5 ms timestep:

* baseline -- bare ``mj_step`` of the default plant's MJCF (c_a = 50 N s/m, no callback);
* the plant at c_a = 50 N s/m (the default: ``implicitfast``, the same path as before stiff
  cables were supported, so its ratio is the "speed at c_a = 50 unchanged" check);
* the same plant forced onto the ``discrete`` integrator (what every plant would pay if the
  switch were unconditional);
* the plant at c_a = 300 and 3000 N s/m (``discrete``, chosen by ``neck_sim.mjcf.integrator_for``);
* with ``--control``, the paper's 15 s control test (law 2) at each c_a, wall time and real-time
  factor (controller included).

    python benchmarks/bench_stiff_cables.py [--periods 250] [--repeat 20] [--control]
"""

from __future__ import annotations

import argparse
import time

import mujoco
import numpy as np

from bench_analytic import best_of  # benchmarks/ is on sys.path when this runs as a script
from bench_plant import bare_loop, forces, plant_loop
from neck_sim import plant as P
from neck_sim.params import default_params

DAMPINGS = (50.0, 300.0, 3000.0)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--periods", type=int, default=250)
    ap.add_argument("--repeat", type=int, default=20)
    ap.add_argument("--control", action="store_true", help="also run the 15 s control test at each c_a")
    args = ap.parse_args(argv)
    base = default_params(3)
    f = forces(base.n_cables, args.periods, base.control.rate_hz)
    plants = {c: P.Plant(base.replace(**{"cables.c_a": (c,) * base.n_cables})) for c in DAMPINGS}
    forced = P.Plant(base)
    forced.model.opt.integrator = mujoco.mjtIntegrator.mjINT_DISCRETE
    rows = [("bare mj_step, default MJCF (baseline)", bare_loop(plants[50.0], f))]
    rows += [(f"plant, c_a = {c:g} N s/m ({_integrator(pl)})", plant_loop(pl, f)) for c, pl in plants.items()]
    rows.insert(2, ("plant, c_a = 50 N s/m forced to discrete", plant_loop(forced, f)))
    best = [np.inf] * len(rows)
    for _ in range(args.repeat):
        for i, (_, fun) in enumerate(rows):
            best[i] = min(best[i], best_of(fun, 1))
    K = args.periods
    print(f"timestep {forced.timestep:g} s, {forced.substeps} sub-steps per control period, backend "
          f"{forced.backend}, {K} periods, best of {args.repeat}")
    print(f"{'':48}{'us/period':>10} {'vs bare':>8} {'vs c_a=50':>10}")
    c50 = best[1]
    for (name, _), b in zip(rows, best):
        print(f"{name:48}{1e6 * b / K:10.1f} {b / best[0]:8.2f} {b / c50:10.2f}")
    if args.control:
        from controllers.parallel import RunSpec, run_one

        print("\ncontrol test (law 2, 15 s), whole closed loop:")
        for c, pl in plants.items():
            t0 = time.perf_counter()
            run = run_one(RunSpec(f"c_a {c:g}", pl.params, law=2))
            wall = time.perf_counter() - t0
            print(f"  c_a = {c:6g} N s/m: {wall:6.1f} s, {run.t[-1] / wall:5.1f}x real time, tracking "
                  f"{run.metrics.tracking_error:.3f} deg, slack samples {run.metrics.slack_samples}")


def _integrator(plant) -> str:
    return mujoco.mjtIntegrator(plant.model.opt.integrator).name[len("mjINT_"):].lower()


if __name__ == "__main__":
    main()
