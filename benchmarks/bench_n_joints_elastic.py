"""The control test on elastic cables for N = 1 ... 10: law 2 against the elastic LQR.

Prints, per neck and controller, the paper's metrics (e = mean |alpha_hat - alpha_d| and the
truth's mean |alpha - alpha_d|, deg), samples at f_max, slack samples, or where the run stopped.
Not a speed benchmark: the numbers of the README's "Any number of joints" and Known limitations.

    python benchmarks/bench_n_joints_elastic.py [--scale 0.3] [--n 1 5 10] [--law 2 lqr]
"""

from __future__ import annotations

import argparse

from controllers.closed_loop import run_closed_loop
from controllers.computed_torque import ComputedTorqueController
from controllers.elastic_lqr import ElasticLQRController
from controllers.trajectories import make_trajectory
from neck_sim.params import default_params
from neck_sim.plant import Plant

CONTROLLERS = {"2": lambda p: ComputedTorqueController(p, 2), "lqr": ElasticLQRController}


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scale", type=float, default=0.3, help="duration scale (0.3: tests' 0.75 s moves; 1: paper)")
    ap.add_argument("--n", type=int, nargs="+", default=list(range(1, 11)))
    ap.add_argument("--law", nargs="+", default=list(CONTROLLERS), choices=list(CONTROLLERS))
    args = ap.parse_args(argv)
    for n in args.n:
        p = default_params(n)
        traj = make_trajectory("control-test", p, args.scale)
        for law in args.law:
            try:
                m = run_closed_loop(Plant(p), CONTROLLERS[law](p), traj, progress=False).metrics
                out = (f"e {m.tracking_error:.3f}  truth {m.tracking_error_true:.3f} deg  f_max {m.saturated_samples}"
                       f"  slack {m.slack_samples} / {m.samples}")
            except RuntimeError as exc:
                out = f"stopped: {exc}"[:110]
            print(f"N = {n:2d} {traj.name:18s} {law:>3s}: {out}", flush=True)


if __name__ == "__main__":
    main()
