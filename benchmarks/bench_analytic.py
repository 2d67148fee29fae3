"""Analytic model speed: cable lengths + Z for a batch of configurations.

Prints each timing as a ratio to one numpy evaluation of the side lengths (eqs 1, 2) of the same
batch, measured in the same run (machines are noisy; ratios travel, seconds do not).  One core.

    python benchmarks/bench_analytic.py [--batch 100000] [--repeat 7]
"""

from __future__ import annotations

import argparse
import os

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import time  # noqa: E402

import numpy as np  # noqa: E402

import neck_sim.analytic as an  # noqa: E402
from neck_sim.params import default_params  # noqa: E402


def best_of(fun, repeat: int, clock=time.perf_counter) -> float:
    """Least time of ``repeat`` calls of ``fun`` by ``clock`` (wall clock; time.process_time for CPU)."""
    best = np.inf
    for _ in range(repeat):
        t0 = clock()
        fun()
        best = min(best, clock() - t0)
    return best


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--batch", type=int, default=100_000)
    ap.add_argument("--repeat", type=int, default=7)
    ap.add_argument("--n-joints", type=int, default=3)
    args = ap.parse_args(argv)
    p = default_params(args.n_joints)
    alpha = np.random.default_rng(0).uniform(-np.pi / 3, np.pi / 3, (args.batch, args.n_joints))
    b, L = p.geometry.b, p.geometry.L

    def baseline():  # eqs (1), (2) in plain numpy
        s, c = np.sin(alpha / 2), np.cos(alpha / 2)
        q = np.sqrt(L * L - (b * c) ** 2)
        return q - b * s, q + b * s

    cases = {
        "side lengths, numpy (baseline)": baseline,
        "cable_lengths": lambda: an.cable_lengths(alpha, p),
        "transmission_matrix (Z)": lambda: an.transmission_matrix(alpha, p),
        "cable_lengths + Z": lambda: (an.cable_lengths(alpha, p), an.transmission_matrix(alpha, p)),
        "cable_kinematics (l, Z, Zdot)": lambda: an.cable_kinematics(alpha, alpha, p),
        "mass_matrix (with motors)": lambda: an.mass_matrix(alpha, p),
    }
    times = {name: best_of(fun, args.repeat) for name, fun in cases.items()}
    base = times["side lengths, numpy (baseline)"]
    print(f"batch {args.batch} x {args.n_joints} joints, best of {args.repeat}")
    print(f"{'computation':<34} {'ratio':>8} {'seconds':>9}")
    for name, t in times.items():
        print(f"{name:<34} {t / base:8.1f} {t:9.4f}")
    z = times["transmission_matrix (Z)"]
    print(f"target: Z for 1e5 configurations under 0.1 s on one core -> "
          f"{'met' if z * 1e5 / args.batch < 0.1 else 'NOT met'} ({z * 1e5 / args.batch:.3f} s per 1e5)")


if __name__ == "__main__":
    main()
