"""Plant speed: one control period of the simulated neck against bare ``mj_step`` (target: under 1.5x bare mj_step).

Measured in the same run, interleaved, best of ``--repeat`` loops of ``--periods`` control
periods (short loops: the minimum filters out a shared machine's load), with a smooth
controller-like force (N + 1 cables, 25 +- 10 N):

* baseline -- bare ``mj_step(model, data, n_sub)`` of the *same* MJCF (``plant.xml`` compiled
  again: static linear cables, eq-37 slope as motor damping) with no user callback installed;
* plant -- ``plant.step(f)`` + ``encoders()`` + ``truth()`` + ``camera_frame()`` (sub-steps,
  native callback, sensors), the cost of one control period; target ratio < 1.5;
* the same with the pure-Python callback backend;
* a breakdown (where the time goes): physics with the callback, Python overhead of ``step``,
  sensors; the period's physics as the one C call of ``PlantBatch`` (``neck_step_batch``) against
  the same MuJoCo calls made from Python; the native callback's own cost;
* the real-time factor (simulated s per wall-clock s) at the default timestep, the largest that
  keeps the dynamics check of ``neck_sim.crossval`` true (``--check-timesteps`` re-runs its 10 s hold at 1e-3 and
  5e-4 s to show it).

    python benchmarks/bench_plant.py [--periods 250] [--repeat 40] [--check-timesteps] [--profile]
"""

from __future__ import annotations

import argparse
import time

import mujoco
import numpy as np

from bench_analytic import best_of  # benchmarks/ is on sys.path when this runs as a script
from neck_sim import plant as P
from neck_sim.batch import PlantBatch
from neck_sim.native import DISPATCH
from neck_sim.params import default_params


def forces(n_cables: int, periods: int, rate: float) -> np.ndarray:
    t = np.arange(periods) / rate
    phase = np.arange(n_cables)
    return 25.0 + 10.0 * np.sin(2 * np.pi * 0.5 * t[:, None] + phase)


def plant_loop(plant, f):
    step, enc, truth, cam = plant.step, plant.encoders, plant.truth, plant.camera_frame

    def run():
        plant.reset(np.zeros(plant.n_joints))
        for fk in f:
            step(fk)
            enc()
            truth()
            cam()
    return run


def bare_loop(plant, f):
    """The same MJCF, compiled afresh (static biases), stepped with no callback installed."""
    model = mujoco.MjModel.from_xml_string(plant.xml)
    data = mujoco.MjData(model)
    n1, nsub = plant.n_joints + 1, plant.substeps

    def run():
        saved = mujoco.get_mjcb_control()
        mujoco.set_mjcb_control(None)
        try:
            mujoco.mj_resetData(model, data)
            for fk in f:
                data.ctrl[:n1] = fk
                mujoco.mj_step(model, data, nsub)
        finally:
            mujoco.set_mjcb_control(saved)
    return run


def physics_loop(plant, f):
    """Only the stepping calls of Plant.step, with the plant's callback installed."""
    m, d, n1, nsub = plant.model, plant.data, plant.n_joints + 1, plant.substeps

    def run():
        plant.reset(np.zeros(plant.n_joints))
        prev = DISPATCH.enter(plant.backend)
        try:
            for fk in f:
                d.ctrl[:n1] = fk
                mujoco.mj_step2(m, d)
                mujoco.mj_step(m, d, nsub - 1)
                mujoco.mj_step1(m, d)
        finally:
            DISPATCH.leave(prev)
    return run


def native_loop(plant, f):
    """Only the C call of the plant's period (``neck_step_batch``, K = 1, no camera or delay schedule)."""
    # the batch's C arguments point at its own arrays (kept alive by run) and at the plant's model,
    # data and struct; the plant's resets leave them valid
    batch = PlantBatch([plant])
    batch.close()
    fused = batch.fused_step()
    args = [int(a) for a in fused.args]         # ctypes takes Python ints for C ints and pointers
    step = DISPATCH.lib.step_batch

    def run():
        plant.reset(np.zeros(plant.n_joints))
        prev = DISPATCH.enter(plant.backend)
        try:
            for fk in f:
                fused.forces[0] = fk
                step(*args)
        finally:
            DISPATCH.leave(prev)
    return run


def callback_us(plant, calls: int = 20000) -> tuple[float, float]:
    """(us per call of the native callback on the plant's current state, calls per control period):
    ctypes calls of ``neck_control`` less ctypes calls of a trivial function of the same library."""
    lib = DISPATCH.lib
    m, d = plant.model._address, plant.data._address
    struct = plant.native.struct
    before = struct.calls
    plant.step(np.full(plant.params.n_cables, 20.0))
    per_period = struct.calls - before

    def control():
        for _ in range(calls):
            lib.neck_control(m, d)

    def trivial():
        for _ in range(calls):
            lib.neck_registered()
    return 1e6 * (best_of(control, 5) - best_of(trivial, 5)) / calls, per_period


def sensors_loop(plant, periods):
    enc, truth, cam = plant.encoders, plant.truth, plant.camera_frame

    def run():
        for _ in range(periods):
            enc()
            truth()
            cam()
    return run


def hold_gap(params, timestep: float) -> float:
    from neck_sim.crossval import _default_case
    a0, f = _default_case(params)
    pl = P.Plant(params, timestep=timestep)
    pl.reset(a0)
    gap = 0.0
    for _ in range(int(10 * params.control.rate_hz)):
        pl.step(f)
        gap = max(gap, pl.truth().loop_gap)
    return gap


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--periods", type=int, default=250)
    ap.add_argument("--repeat", type=int, default=40)
    ap.add_argument("--n-joints", type=int, default=3)
    ap.add_argument("--check-timesteps", action="store_true", help="re-run the 10 s hold of the dynamics check at 1e-3 and 5e-4 s")
    ap.add_argument("--profile", action="store_true", help="cProfile of the plant loop (top 12 by own time)")
    args = ap.parse_args(argv)
    p = default_params(args.n_joints)
    rate = p.control.rate_hz
    f = forces(p.n_cables, args.periods, rate)
    plant = P.Plant(p, backend="native" if P.native_available() else "python")
    K = args.periods
    us = lambda s: 1e6 * s / K                                     # noqa: E731

    # Interleaved, best of each: a shared machine's load drifts, and drifts alike for all four.
    loops = [bare_loop(plant, f), plant_loop(plant, f), physics_loop(plant, f), sensors_loop(plant, K)]
    native = plant.backend == "native"
    if native:
        loops.append(native_loop(plant, f))
    best = [np.inf] * len(loops)
    for _ in range(args.repeat):
        for i, fun in enumerate(loops):
            best[i] = min(best[i], best_of(fun, 1))
    bare, full, phys, sens = best[:4]
    print(f"neck N = {p.n_joints}, timestep {plant.timestep:g} s, {plant.substeps} sub-steps per control period "
          f"({1e3 / rate:g} ms), backend {plant.backend}, {K} periods, best of {args.repeat}")
    print(f"{'':44}{'us/period':>10} {'ratio':>7}")
    print(f"{'bare mj_step x n_sub (baseline, no callback)':44}{us(bare):10.1f} {1.0:7.2f}")
    print(f"{'plant period (step + encoders/truth/camera)':44}{us(full):10.1f} {full / bare:7.2f}   target < 1.5")
    print(f"{'  physics + native callback (step2/step/step1)':44}{us(phys):10.1f} {phys / bare:7.2f}")
    print(f"{'  Python overhead of Plant.step':44}{us(full - phys - sens):10.1f} {(full - phys - sens) / bare:7.2f}")
    print(f"{'  sensors (encoders, truth, camera_frame)':44}{us(sens):10.1f} {sens / bare:7.2f}")
    if native:
        c_call = best[4]
        print(f"{'  the period in C (neck_step_batch, K = 1)':44}{us(c_call):10.1f} {c_call / bare:7.2f}   "
              f"the same steps called from Python: {phys / c_call:.2f}x")
        cb, per_period = callback_us(plant)
        cb_period = cb * per_period
        print(f"{'  native callback (x calls per period)':44}{cb_period:10.1f} {cb_period / us(bare):7.2f}   "
              f"{cb:.2f} us x {per_period}")
    print(f"real-time factor: {(K / rate) / full:.1f} simulated s per wall-clock s")
    if P.native_available():
        Kp = max(50, K // 10)
        previous = P.get_backend()
        try:
            P.set_backend("python")
            py = best_of(plant_loop(plant, f[:Kp]), max(1, args.repeat // 2))
        finally:
            P.set_backend(previous)
        print(f"{'plant period, pure-Python callback backend':44}{1e6 * py / Kp:10.1f} {py / Kp / (bare / K):7.2f}")
    if args.profile:
        import cProfile
        import pstats
        prof = cProfile.Profile()
        prof.runcall(plant_loop(plant, f))
        pstats.Stats(prof).sort_stats("tottime").print_stats(12)
    if args.check_timesteps:
        for dt in (1e-3, 5e-4):
            t0 = time.perf_counter()
            gap = hold_gap(p, dt)
            print(f"dynamics-check hold at timestep {dt:g} s: max loop gap {gap:.2e} m "
                  f"({'ok' if gap < 1e-4 else 'over 1e-4'}; {time.perf_counter() - t0:.1f} s)")


if __name__ == "__main__":
    main()
