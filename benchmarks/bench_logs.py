"""Log speed: write and read back a 100 s run of a 3-joint neck (every topic).

The run has /neck/motors, /neck/reference, /neck/estimate, /neck/truth at 500 Hz, /neck/camera at
30 Hz and the Foxglove /tf and /neck/scene messages at 30 Hz, with full-precision numbers.  Prints
each timing in seconds and as a ratio to a baseline measured in the same run: iterating every
message of the file with the ``mcap`` library's reader without decoding it.  The target is
reading (all topics into numpy) under 1 s.

    python benchmarks/bench_logs.py [--seconds 100] [--repeat 3]
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time

import numpy as np
from mcap.reader import make_reader

from bench_analytic import best_of  # benchmarks/ is on sys.path when this runs as a script
from neck_sim.logs import LogWriter, read_log
from neck_sim.params import default_params


def write_run(path: str, seconds: float, n_joints: int = 3) -> int:
    """A synthetic run with smooth, full-precision signals; returns the number of control steps."""
    p = default_params(n_joints)
    rate = p.control.rate_hz
    steps = int(seconds * rate)
    t = np.arange(steps) / rate
    rng = np.random.default_rng(0)
    alpha = 0.5 * np.sin(np.outer(t, rng.uniform(0.5, 2.0, n_joints)))
    theta = np.cumsum(rng.normal(size=(steps, n_joints + 1)), axis=0) * 1e-2
    force = 20 + 10 * np.sin(np.outer(t, rng.uniform(0.5, 2.0, n_joints + 1)))
    cam_every = int(round(rate / p.sensors.camera_rate_hz))
    with LogWriter(path, p, mjcf_xml="<mujoco/>", run_info={"seed": 0}) as w:
        for k in range(steps):
            w.motors(t[k], theta[k], force[k])
            if k % cam_every == 0:
                w.camera(t[k], alpha[k] + 1e-3)
            w.reference(t[k], alpha[k])
            w.estimate(t[k], alpha[k] - 1e-3)
            w.truth(t[k], alpha[k], alpha[k] * 2, force[k] - 1, force[k] * 1e-4)
    return steps


def raw_iteration(path: str) -> int:
    n = 0
    with open(path, "rb") as fh:
        for _ in make_reader(fh).iter_messages(log_time_order=False):
            n += 1
    return n


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=100.0)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "run.mcap")
        t0 = time.perf_counter()
        steps = write_run(path, args.seconds)
        t_write = time.perf_counter() - t0
        size = os.path.getsize(path)
        n_messages = raw_iteration(path)
        t_raw = best_of(lambda: raw_iteration(path), args.repeat)
        t_read = best_of(lambda: read_log(path), args.repeat)
        t_window = best_of(lambda: read_log(path, start=args.seconds / 2, end=args.seconds / 2 + 1.0), args.repeat)
        t_motors = best_of(lambda: read_log(path, topics=("motors",)), args.repeat)
        log = read_log(path)
        assert log.motors.t.shape == (steps,) and log.truth.tension.shape == (steps, 4)
    print(f"{args.seconds:g} s run, 3 joints: {steps} control steps, {n_messages} messages, {size / 1e6:.1f} MB")
    print(f"{'operation':<44} {'seconds':>8} {'ratio':>7}")
    print(f"{'baseline: mcap iter_messages, no decoding':<44} {t_raw:8.3f} {1.0:7.2f}")
    print(f"{'read_log, every topic into numpy':<44} {t_read:8.3f} {t_read / t_raw:7.2f}")
    print(f"{'read_log, motors only':<44} {t_motors:8.3f} {t_motors / t_raw:7.2f}")
    print(f"{'read_log, 1 s window (chunk index)':<44} {t_window:8.3f} {t_window / t_raw:7.3f}")
    print(f"{'write (LogWriter, incl. Foxglove messages)':<44} {t_write:8.3f} {t_write / t_raw:7.2f}")
    print(f"read under 1 s: {'yes' if t_read < 1.0 else 'NO'} ({t_read:.3f} s)")


if __name__ == "__main__":
    main()
