"""Output-error identification against mujoco.sysid, on one log and in one process.

The log is the paper's identification run (85 s, law 1, the default MuJoCo plant, seed 0),
simulated first unless ``--log`` names one; ``--duration S`` keeps its first S seconds.  On it:

* the baseline: the paper's least squares (eqs 44-57, friction and variable-stiffness models), whose
  estimate is the start of both fits below and whose CPU the ratios are against;
* (a) ``mujoco.sysid``: its ``optimize`` (MuJoCo's box-constrained Gauss-Newton,
  ``optimizer="mujoco"``, vectorised finite-difference Jacobian) and ``calculate_intervals``,
  driven through neck-sim's plant: the residual of a parameter vector (or of the Jacobian's
  columns, all at once) is the noise-weighted encoder and camera misfit of
  :func:`identification.output_error.problem.residuals`, simulated by the rollout engine
  (:func:`identification.output_error.rollouts.rollout`) on the same threads.  The plant's eq (54)
  and eq (37) parameters live in its C callback, not in the MjModel that sysid's own rollout edits,
  hence the engine.  Optional dependency: ``pip install .[sysid]``;
* (b) neck-sim's output-error fit (:func:`identification.output_error.identify.identify_output_error`)
  on 1 and 2 rollout threads.

Both fit the same 16 parameters (f_s, k, lambda, c_a per cable) from the same start on the same
integrator.  Printed side by side: the largest relative error per group against the plant's truth,
rollouts, CPU and wall time; then the per-rollout cost of the engine (``mujoco.batch`` threads)
against a lockstep :class:`~neck_sim.batch.PlantBatch` and serial :meth:`Plant.step`, measured on
the same parameter sets, and the cost of one rollout on the cheaper model the fit's
Jacobian takes its f_s, k and lambda columns from (``OutputErrorSettings.jacobian_timestep``;
its rollouts are counted among the fit's and named in the breakdown).

    python benchmarks/bench_output_error.py                    # the whole 85 s run (long: sysid)
    python benchmarks/bench_output_error.py --duration 10      # its first 10 s
    python benchmarks/bench_output_error.py --no-sysid --json out.json
    python benchmarks/bench_output_error.py --log LOG --duration 30 --no-one-thread --cost-sets 1
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))   # this checkout's code

from identification.output_error import rollouts as engine                   # noqa: E402
from neck_sim.logs import read_log                                           # noqa: E402
from neck_sim.params import default_params, from_dict                        # noqa: E402

GROUPS = (("f_s", "friction", "f_s"), ("k", "cables", "k"), ("lambda", "cables", "lam"), ("c_a", "cables", "c_a"))


def simulate_log(path: str, seed: int = 0) -> str:
    """The identification run (law 1, default plant) logged at ``path``."""
    from controllers.closed_loop import run_closed_loop
    from controllers.computed_torque import ComputedTorqueController
    from controllers.trajectories import identification_trajectory
    from neck_sim.plant import Plant

    p = default_params(3)
    run_closed_loop(Plant(p, seed=seed), ComputedTorqueController(p, law=1), identification_trajectory(p),
                    log_path=path, progress=False)
    return path


def errors(values: dict, truth) -> dict:
    """Largest |relative error| (%) per group against the plant's truth."""
    out = {}
    for sym, sec, fld in GROUPS:
        v = values.get(sym)
        t = np.asarray(getattr(getattr(truth, sec), fld), dtype=float)
        out[sym] = None if v is None else float(100 * np.max(np.abs((np.asarray(v) - t) / t)))
    return out


class _Clock:
    """CPU (every thread of the process) and wall seconds of a block."""

    def __enter__(self):
        self.cpu0, self.wall0 = time.process_time(), time.perf_counter()
        return self

    def __exit__(self, *exc):
        self.cpu, self.wall = time.process_time() - self.cpu0, time.perf_counter() - self.wall0


def least_squares(log):
    from identification.paper import IdentificationSettings, identify_log

    with _Clock() as c:
        ls = identify_log(log, IdentificationSettings(bootstrap=0, reconstruct_alpha=False),
                          models=("friction", "variable"))
    values = {"f_s": ls.friction.group("f_s"), "k": ls.variable.group("k"), "lambda": ls.variable.group("lambda"),
              "c_a": ls.variable.group("c_a")}
    return ls, values, c


def output_error(log, ls, threads: int, max_evaluations: int):
    from identification.output_error.identify import identify_output_error
    from identification.output_error.settings import OutputErrorSettings

    os.environ[engine.THREADS_ENV] = str(threads)
    try:
        with _Clock() as c:
            res, _ = identify_output_error([log], least_squares=[ls],
                                           settings=OutputErrorSettings(max_evaluations=max_evaluations))
    finally:
        del os.environ[engine.THREADS_ENV]
    return {sym: res.group(sym) for sym, _, _ in GROUPS}, res.rollouts, c, res


def sysid(log, ls, threads: int, max_iter: int):
    """mujoco.sysid's optimize and intervals on the same residual, start and integrator."""
    from mujoco import sysid as mjsysid

    from identification.output_error.fit import SCALE_FLOOR, choose_integrator
    from identification.output_error.identify import start_point
    from identification.output_error.problem import Layout, Measured, noise_sigmas, residuals
    from identification.output_error.settings import OutputErrorSettings

    nominal = log.params
    meas = Measured.from_log(log, nominal)
    layout = Layout.of(nominal)
    x0, _ = start_point(layout, [ls])
    integrator = choose_integrator(layout, OutputErrorSettings())
    sigmas = noise_sigmas(nominal)
    count, engine_cpu = [0], [0.0]

    def residual_fn(x, _params):
        cpu0 = time.process_time()
        X = np.asarray(x, dtype=float)
        cols = X.reshape(-1, 1) if X.ndim == 1 else X
        sets = [layout.plant(cols[:, i]) for i in range(cols.shape[1])]
        out = engine.rollout(meas.replay, [s[0] for s in sets], [s[1] for s in sets], integrator=integrator,
                             nthread=threads, quantise=False)
        count[0] += len(sets)
        R = []
        for i in range(len(sets)):
            r = residuals([meas], [(out.encoders[i], out.camera_alpha[i])], sigmas)
            R.append(np.concatenate([r["encoders"], r["camera"]]))
        R = np.stack(R, axis=1)
        engine_cpu[0] += time.process_time() - cpu0
        return [R[:, 0] if X.ndim == 1 else R], None, None

    # the fit's box below (0); above, ten times the fit's parameter scale (sysid's optimiser
    # needs a finite box)
    floor = np.array([SCALE_FLOOR[n.split("(")[0]] for n in layout.names])
    params = mjsysid.ParameterDict({"x": mjsysid.Parameter("x", x0, layout.lower, 10 * np.maximum(np.abs(x0), floor))})
    from identification.threads import single_thread

    # the fit's BLAS setting (one thread: OpenBLAS threads only spin on these small products)
    with single_thread(), _Clock() as c:
        try:
            opt, result = mjsysid.optimize(params, residual_fn, optimizer="mujoco", verbose=False, max_iters=max_iter)
            x = opt.as_vector()
            r_star, _, _ = residual_fn(x, opt)
            _, ci = mjsysid.calculate_intervals(r_star, np.asarray(result.jac))
            status = "ok"
        except Exception as exc:          # a crash is a result of this arm, reported in the table
            x, ci, status = None, None, f"crashed: {type(exc).__name__}: {str(exc).splitlines()[0][:120]}"
    values = {} if x is None else {sym: layout.group(x, sym) for sym, _, _ in GROUPS}
    return values, count[0], c, status, engine_cpu[0]


def rollout_cost(log, truth, sets: int, threads: tuple) -> list:
    """Per-rollout CPU and wall of ``sets`` parameter sets around the truth: the engine on each
    thread count, a lockstep PlantBatch, serial Plant.step (one set)."""
    from identification.output_error.rollouts import Experiment, cable_params
    from neck_sim.plant import Plant, PlantBatch

    exp = Experiment.from_log(log)
    scale = 1.0 + 0.01 * np.arange(sets)[:, None]
    params = cable_params(truth, f_s=np.array(truth.friction.f_s) * scale, k=truth.cables.k, lam=truth.cables.lam,
                          c_a=truth.cables.c_a)
    rows = []
    for n in threads:
        with _Clock() as c:
            engine.rollout(exp, params, integrator="implicitfast", nthread=n)
        rows.append((f"mujoco.batch threads, {n} thread{'s' if n > 1 else ''}", c.cpu / sets, c.wall / sets))
    from identification.output_error.settings import OutputErrorSettings

    s = OutputErrorSettings()
    with _Clock() as c:
        engine.rollout(exp, params, integrator=s.jacobian_integrator, timestep=s.jacobian_timestep, nthread=1)
    rows.append((f"Jacobian's coarse model ({1e3 * s.jacobian_timestep:g} ms, {s.jacobian_integrator}), 1 thr.",
                 c.cpu / sets, c.wall / sets))
    plants = [Plant(p, integrator="implicitfast") for p in params]
    with _Clock() as c:
        for p in plants:
            p.reset(alpha0=exp.alpha0)
        with PlantBatch(plants) as batch:
            f = np.empty((sets, exp.force.shape[1]))
            for k in range(exp.n_periods):
                f[:] = exp.force[k]
                batch.step(f)
    rows.append(("lockstep PlantBatch (one C call per period)", c.cpu / sets, c.wall / sets))
    plant = plants[0]
    with _Clock() as c:
        plant.reset(alpha0=exp.alpha0)
        for k in range(exp.n_periods):
            plant.step(exp.force[k])
    rows.append(("serial Plant.step (one set)", c.cpu, c.wall))
    return rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--log", help="an identification log (default: simulate the paper's run into a temporary file)")
    ap.add_argument("--duration", type=float, default=None, help="keep the log's first S seconds")
    ap.add_argument("--no-sysid", action="store_true", help="skip mujoco.sysid")
    ap.add_argument("--sysid-max-iter", type=int, default=100, help="mujoco.sysid's Gauss-Newton iterations")
    ap.add_argument("--max-evaluations", type=int, default=30, help="the output-error fit's trial steps")
    ap.add_argument("--cost-sets", type=int, default=4, help="parameter sets of the per-rollout cost")
    ap.add_argument("--one-thread", action=argparse.BooleanOptionalAction, default=True,
                    help="also fit on 1 rollout thread (the scaling row; --no-one-thread on long windows)")
    ap.add_argument("--json", help="write the numbers as JSON")
    args = ap.parse_args(argv)

    with tempfile.TemporaryDirectory() as tmp:
        path = args.log or simulate_log(os.path.join(tmp, "identification.mcap"))
        log = read_log(path, topics=("motors", "camera", "reference"), end=args.duration)
        recorded = read_log(path, topics=("motors",), end=0.01).run_value("plant_params")
    if recorded is None:
        print(f"{path}: no plant_params in its run record: the truth is unknown, errors are not measured",
              file=sys.stderr)
        return 2
    truth = from_dict(recorded)
    T, F = len(log.motors.t), len(log.camera.t)
    print(f"log: {os.path.basename(path)}, {T / log.params.control.rate_hz:.1f} s ({T} motor samples, {F} camera "
          f"frames), 16 parameters (f_s, k, lambda, c_a x 4 cables), start: the least squares")
    print(f"load average at the start (1, 5, 15 min): {', '.join(f'{v:.2f}' for v in os.getloadavg())}")
    ls, ls_values, ls_clock = least_squares(log)
    head = f"{'method':38} {'f_s %':>8} {'k %':>8} {'lambda %':>9} {'c_a %':>8} {'rollouts':>9} {'CPU s':>8} " \
           f"{'wall s':>8} {'CPU/LS':>7}"
    print("largest |relative error| per group against the plant's truth (rows printed as measured)")
    print(head)
    print("-" * len(head), flush=True)
    rows = []

    def row(name, err, n, clock, note=""):
        rows.append((name, err, n, clock, note))
        cell = lambda v: f"{v:8.3f}" if v is not None else f"{'-':>8}"   # noqa: E731
        print(f"{name:38} {cell(err['f_s'])} {cell(err['k'])} {cell(err['lambda']):>9} {cell(err['c_a'])} "
              f"{'' if n is None else n:>9} {clock.cpu:8.1f} {clock.wall:8.1f} {clock.cpu / ls_clock.cpu:7.1f}"
              + (f"  {note}" if note else ""), flush=True)

    row("least squares (eqs 44-57), baseline", errors(ls_values, truth), None, ls_clock)
    oe, breakdown, coarse_counts = {}, [], {}
    for threads in (2, 1) if args.one_thread else (2,):
        values, n, clock, res = output_error(log, ls, threads, args.max_evaluations)
        oe[threads] = clock
        row(f"neck-sim output-error, {threads} thread{'s' if threads > 1 else ''}", errors(values, truth), n, clock,
            "" if res.converged else "not converged")
        breakdown.append((f"output-error, {threads} thread{'s' if threads > 1 else ''}", clock.cpu, res.rollout_cpu_s,
                          n, f"{res.trial_steps} trial steps, {res.iterations} finite-difference Jacobian(s); "
                             f"{res.coarse_rollouts} of the rollouts on the Jacobian's coarse model"))
        coarse_counts[threads] = res.coarse_rollouts
    summary = {"oe_wall_1_over_2_threads": oe[1].wall / oe[2].wall} if 1 in oe else {}
    cost = rollout_cost(log, truth, args.cost_sets, (1, 2))
    sys_row = None
    if not args.no_sysid:
        try:
            import mujoco.sysid as mjsysid
            have = hasattr(mjsysid, "optimize")
        except ImportError:
            have = False
        if have:
            values, n, clock, status, engine_cpu = sysid(log, ls, 2, args.sysid_max_iter)
            row("mujoco.sysid (GN), 2 threads", errors(values, truth), n, clock, "" if status == "ok" else status)
            sys_row = rows[-1]
            breakdown.append(("mujoco.sysid, 2 threads", clock.cpu, engine_cpu, n, "residual_fn: rollouts + residuals"))
        else:
            print("mujoco.sysid is not installed with its extras (pip install .[sysid]): skipped", file=sys.stderr)
    if sys_row is not None:
        summary["oe_cpu_over_sysid"] = oe[2].cpu / sys_row[3].cpu
        print(f"output-error CPU / mujoco.sysid CPU (2 threads): {summary['oe_cpu_over_sysid']:.3f} (target <= 0.1)")
    if 1 in oe:
        print(f"output-error wall time, 1 thread / 2 threads: {summary['oe_wall_1_over_2_threads']:.2f}")
    print(f"load average at the end (1, 5, 15 min): {', '.join(f'{v:.2f}' for v in os.getloadavg())}")
    print("\nwhere the CPU goes (the same engine, plants built per rollout, for both methods)")
    head = f"{'fit':28} {'CPU s':>8} {'rollouts':>9} {'in rollouts':>12} {'per rollout':>12} {'rest':>7}  what"
    print(head)
    print("-" * len(head))
    for name, cpu, in_rollouts, n, what in breakdown:
        print(f"{name:28} {cpu:8.1f} {n:9d} {in_rollouts:12.1f} {in_rollouts / n:12.3f} {cpu - in_rollouts:7.2f}  {what}")
    print(f"\nper rollout ({args.cost_sets} parameter sets, {T / log.params.control.rate_hz:.1f} s each)")
    width = max(len("engine"), *(len(name) for name, _, _ in cost))
    head = f"{'engine':{width}} {'CPU s':>8} {'wall s':>8} {'wall / batch 1 thread':>22}"
    print(head)
    print("-" * len(head))
    for name, cpu, wall in cost:
        print(f"{name:{width}} {cpu:8.3f} {wall:8.3f} {wall / cost[0][2]:22.2f}")
    if args.json:
        from neck_sim.atomic import atomic_write_json

        atomic_write_json(args.json, {
            "log_s": T / log.params.control.rate_hz, "summary": summary, "load_average_end": list(os.getloadavg()),
            "cpu_breakdown": [{"fit": name, "cpu_s": cpu, "rollouts_cpu_s": r, "rollouts": n}
                              for name, cpu, r, n, _ in breakdown],
            "oe_coarse_rollouts": coarse_counts,
            "fits": [{"method": name, "max_rel_error_pct": err, "rollouts": n, "cpu_s": clock.cpu,
                      "wall_s": clock.wall, "note": note} for name, err, n, clock, note in rows],
            "per_rollout": [{"engine": name, "cpu_s": cpu, "wall_s": wall} for name, cpu, wall in cost]})
    return 0


if __name__ == "__main__":
    sys.exit(main())
