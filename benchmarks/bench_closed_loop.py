"""Closed-loop speed: control step, closed-loop period, logging share, whole process, lockstep.

Everything is measured in one run and printed as ratios to baselines measured in the same run
(shared machines are noisy; ratios travel, seconds do not), as the least CPU time of ``--repeat``
interleaved runs (CPU time is what one core spends, whatever else shares the machine):

* bare ``mj_step`` x n_sub of the plant's MJCF without callback, and the plant period
  (``plant.step`` + sensors) -- the baselines of ``bench_plant.py``;
* the compiled control step alone (eq 35, eq 59, M, g, Z, eq 66, eqs 63-65), target <= 50 us for N = 3;
* a closed-loop period of ``run_closed_loop`` (law 2, no log), target <= 1.5x the plant period;
* the same with an MCAP log: the log's share of the run, target <= 15 %;
* ``neck-sim simulate --trajectory identification --law 2 -o run.mcap`` as a fresh process
  (imports, numba cache load, plant build, 85 s simulated, log), its real-time factor from the
  process's CPU time (target >= 20x) and its cold start (imports + first control step);
* lockstep batches of K = 1, 8, 64 runs (different seeds, every fourth with an actuation delay,
  every fourth with a camera delay): cost per run and period, as a ratio to the same K runs made
  one at a time and to bare ``mj_step``;
* with ``--baseline-tree DIR`` (another checkout, e.g. ``/work/main``), the whole-process run of
  that tree too, interleaved with this one's (before / after).

    python benchmarks/bench_closed_loop.py [--repeat 3] [--skip-process] [--k 1 8 64] [--baseline-tree DIR]

The closed-loop timings run two 2.5 s moves with 1 s holds (8 s simulated, law 2); the lockstep
batches two 0.7 s moves with 0.3 s holds (2.6 s simulated per run).
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

from bench_analytic import best_of as best_cpu  # noqa: E402  (benchmarks/ is on sys.path as a script)
from bench_plant import bare_loop, forces, plant_loop  # noqa: E402
from controllers.closed_loop import run_closed_loop, run_lockstep  # noqa: E402
from controllers.computed_torque import ComputedTorqueController, reference_table  # noqa: E402
from controllers.trajectories import cycloidal_path, make_trajectory  # noqa: E402
from neck_sim.analytic import motor_angles_rigid  # noqa: E402
from neck_sim.params import default_params  # noqa: E402
from neck_sim.plant import Plant  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def best_of(fun, repeat: int) -> float:
    """Least CPU time (s) of ``repeat`` calls: what one core spends, whatever else shares it."""
    return best_cpu(fun, repeat, time.process_time)


def control_step_us(params, traj, repeat: int) -> float:
    """us per compiled control step on the reference's own rigid encoder angles."""
    ctrl = ComputedTorqueController(params, 2)
    rate = params.control.rate_hz
    times = np.arange(int(traj.duration * rate)) / rate
    ref = ctrl.motor_reference(traj.sample(times))
    table = reference_table(ref)
    out = np.zeros((len(times), 7 * params.n_joints + 4))
    theta = motor_angles_rigid(ref.alpha, params)

    def run():
        ctrl.reset(ref.alpha[0], theta[0])
        for k in range(len(times)):
            ctrl.step_into(theta[k], k, table, out)
    run()
    return 1e6 * best_of(run, repeat) / len(times)


def closed_loop_s(params, traj, log_dir: str | None):
    plant = Plant(params)
    ctrl = ComputedTorqueController(params, 2)
    path = None if log_dir is None else os.path.join(log_dir, "run.mcap")
    return lambda: run_closed_loop(plant, ctrl, traj, progress=False, log_path=path)


def process_run(seed: int = 0, tree: str = ROOT) -> tuple[float, float, float]:
    """(wall s, CPU s, simulated s) of `neck-sim simulate --trajectory identification --law 2 -o` run
    from checkout ``tree`` (default this one)."""
    env = dict(os.environ, PYTHONPATH=tree + os.pathsep + os.environ.get("PYTHONPATH", ""))
    if tree != ROOT:       # its own caches: nothing written into that tree, no eviction of this tree's library
        env["NECK_SIM_CACHE"] = os.path.join(tempfile.gettempdir(), "neck_sim_bench_baseline_cache")
        env["NUMBA_CACHE_DIR"] = os.path.join(tempfile.gettempdir(), "neck_sim_bench_baseline_numba")
    with tempfile.TemporaryDirectory() as tmp:
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        t0 = time.perf_counter()
        subprocess.run([sys.executable, "-m", "neck_sim.cli", "simulate", "--trajectory", "identification",
                        "--law", "2", "-o", os.path.join(tmp, "run.mcap"), "--no-progress", "--seed", str(seed)],
                       check=True, env=env, stdout=subprocess.DEVNULL, cwd=tree)
        wall = time.perf_counter() - t0
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu, make_trajectory("identification", default_params(3)).duration


def cold_start() -> float:
    """CPU s of a fresh process: imports, numba cache load and one control step."""
    code = ("import numpy as np\nfrom controllers.computed_torque import ComputedTorqueController\n"
            "from controllers.trajectories import make_trajectory\nimport neck_sim.plant, neck_sim.logs\n"
            "c = ComputedTorqueController()\nc.reset()\n"
            "c.step(np.zeros(4), c.motor_reference(make_trajectory('control-test', c.params).sample(0.0)))\n")
    env = dict(os.environ, PYTHONPATH=ROOT + os.pathsep + os.environ.get("PYTHONPATH", ""))
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    subprocess.run([sys.executable, "-c", code], check=True, env=env)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--k", type=int, nargs="+", default=[1, 8, 64], help="lockstep batch sizes")
    ap.add_argument("--skip-process", action="store_true", help="no whole-process run (85 s simulated)")
    ap.add_argument("--baseline-tree", help="another checkout whose whole-process run is measured too (before)")
    args = ap.parse_args(argv)
    p = default_params(3)
    rate = p.control.rate_hz
    traj = cycloidal_path(np.radians([[0.0, 0.0, 0.0], [30.0, -20.0, 25.0], [-15.0, 25.0, -20.0]]), 2.5, 1.0)
    periods = int(round(traj.duration * rate)) + 1

    plant = Plant(p)
    f = forces(p.n_cables, periods, rate)
    with tempfile.TemporaryDirectory() as tmp:
        loops = {"bare": bare_loop(plant, f), "plant": plant_loop(plant, f),
                 "loop": closed_loop_s(p, traj, None), "logged": closed_loop_s(p, traj, tmp)}
        for fun in loops.values():                 # warm-up: kernels loaded, caches filled
            fun()
        best = {name: np.inf for name in loops}
        for _ in range(args.repeat):               # interleaved: a drifting load hits all alike
            for name, fun in loops.items():
                best[name] = min(best[name], best_of(fun, 1))
    per = {name: 1e6 * t / periods for name, t in best.items()}
    step = control_step_us(p, traj, args.repeat)

    print(f"N = 3, {periods} control periods of {1e3 / rate:g} ms, best of {args.repeat}, one core")
    print(f"{'':48}{'us/period':>10} {'/ mj_step':>10} {'/ plant':>8}")

    def row(label, us, note=""):
        print(f"{label:48}{us:10.1f} {us / per['bare']:10.2f} {us / per['plant']:8.2f}   {note}")
    row("bare mj_step x n_sub (no callback)", per["bare"])
    row("plant period (step + encoders/truth/camera)", per["plant"])
    row("compiled control step alone", step, "target <= 50 us")
    row("closed-loop period, no log", per["loop"], "target <= 1.5x plant")
    row("closed-loop period, MCAP log", per["logged"])
    share = (per["logged"] - per["loop"]) / per["logged"]
    print(f"MCAP writing: {100 * share:.1f} % of a logged closed-loop run (target <= 15 %)")

    lockstep_batches(p, args.k, args.repeat, row)

    if not args.skip_process:
        cold = cold_start()
        trees = [("this tree", ROOT)] + ([("baseline " + args.baseline_tree, args.baseline_tree)]
                                         if args.baseline_tree else [])
        runs = {label: (np.inf, np.inf, 0.0) for label, _ in trees}
        if args.baseline_tree:
            process_run(tree=args.baseline_tree)      # warm-up: its compile caches filled
        for _ in range(args.repeat if args.baseline_tree else 1):     # interleaved, least CPU of each
            for label, tree in trees:
                r = process_run(tree=tree)
                runs[label] = min(runs[label], r, key=lambda x: x[1])
        print(f"cold start (imports, kernels from the numba cache, one control step): {cold:.2f} s CPU")
        for label, (wall, cpu, sim) in runs.items():
            print(f"neck-sim simulate --trajectory identification --law 2 -o run.mcap ({label}): {sim:g} s simulated "
                  f"in {cpu:.2f} s CPU ({wall:.2f} s wall): {sim / cpu:.1f}x real time on one core (target >= 20x)")
        print(f"the plant period alone would give {1e6 / per['plant'] * (1 / rate):.1f}x, bare mj_step "
              f"{1e6 / per['bare'] * (1 / rate):.1f}x")


def lockstep_batches(p, sizes, repeat: int, row) -> None:
    """Cost per run and period of run_lockstep for each K in ``sizes`` (K different plants), against
    the same K runs made one at a time (K = 1 each) in the same run, interleaved."""
    from neck_sim import effects as E

    traj = cycloidal_path(np.radians([[0.0, 0.0, 0.0], [30.0, -20.0, 25.0], [-15.0, 25.0, -20.0]]), 0.7, 0.3)
    periods = int(round(traj.duration * p.control.rate_hz)) + 1
    effects = [E.Effects(), E.Effects(actuation_delay=E.ActuationDelay(0.004)), E.Effects(),
               E.Effects(camera_delay=E.CameraDelay(0.033))]

    def runs(K, together: bool):
        plants = [Plant(p, effects=effects[s % 4], seed=s) for s in range(K)]
        ctrls = [ComputedTorqueController(p, 2) for _ in range(K)]
        if together:
            return lambda: run_lockstep(plants, ctrls, [traj] * K, progress=False)
        return lambda: [run_lockstep([pl], [c], [traj], progress=False) for pl, c in zip(plants, ctrls)]
    runs(1, True)()                              # warm-up
    for K in sizes:
        funs = {"together": runs(K, True), "alone": runs(K, False)}
        best = {name: np.inf for name in funs}
        for _ in range(repeat):
            for name, fun in funs.items():
                best[name] = min(best[name], best_of(fun, 1))
        us = {name: 1e6 * t / (K * periods) for name, t in best.items()}
        row(f"lockstep K = {K}: per run and period", us["together"],
            f"{us['together'] / us['alone']:.2f}x the same {K} run{'s' if K > 1 else ''} one at a time "
            f"({us['alone']:.1f} us)")


if __name__ == "__main__":
    main()
