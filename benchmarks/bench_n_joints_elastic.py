"""The control test on elastic cables for N = 1 ... 10: law 2 against the elastic LQR.

Prints, per neck and controller, the paper's metrics (e = mean |alpha_hat - alpha_d| and the
truth's mean |alpha - alpha_d|, deg), samples at f_max, slack samples, or where the run stopped.
Not a speed benchmark: the numbers of the README's "Any number of joints" and Known limitations.
``--linear`` prints instead, per N, the least damped mode of law 2 linearised at the straight pose
(eq 35's alpha_hat, eq 59's PID, eqs 63-66 with the binding cable held at its bound) on the
model the LQR is designed on, and that of the LQR.

    python benchmarks/bench_n_joints_elastic.py [--scale 0.3] [--n 1 5 10] [--law 2 lqr] [--linear]
"""

from __future__ import annotations

import argparse

import numpy as np

from controllers.closed_loop import run_closed_loop
from controllers.computed_torque import ComputedTorqueController
from controllers.elastic_lqr import ElasticLQRController, closed_loop_rates, linearise
from controllers.tension import distribute_tensions
from neck_sim.analytic import gravity_spring_torque
from neck_sim.analytic.statics import potential_hessian
from controllers.trajectories import make_trajectory
from neck_sim.params import default_params
from neck_sim.plant import Plant

CONTROLLERS = {"2": lambda p: ComputedTorqueController(p, 2), "lqr": ElasticLQRController}


def law2_rates(p, friction_scale: float) -> np.ndarray:
    """Continuous eigenvalues (1/s) of law 2 on the linearised neck, least damped first."""
    n, m = p.n_joints, p.n_cables
    lin = linearise(p, friction_scale=friction_scale)
    A, B = lin.state_space()
    Z = lin.Z
    binding = int(distribute_tensions(Z, gravity_spring_torque(np.zeros(n), p), np.full(m, p.actuation.t_min),
                                      1e12).binding)
    # eqs (63)-(64) with the binding cable's force fixed: Z T = I, row `binding` of T zero
    Z1i = np.linalg.inv(Z[:, :n])
    v = np.append(-Z1i @ Z[:, n], 1.0)
    U = np.vstack([Z1i, np.zeros((1, n))])
    T = U - np.outer(v, U[binding]) / v[binding]
    w = p.control.omega
    kp, kv, ki = 3 * w * w, 3 * w, w ** 3
    Zp = np.linalg.solve(Z @ Z.T, Z)                       # eq (35): alpha_hat = Zp s
    Mt = lin.Mn + lin.m_r * Z @ Z.T                        # eq (24) with the motors
    size = A.shape[0]
    Ac = np.zeros((size + n, size + n))
    Ac[:size, :size] = A
    Ac[:size, n:n + m] += B @ T @ (potential_hessian(np.zeros(n), p) - kp * Mt) @ Zp
    Ac[:size, 2 * n + m:size] += B @ T @ (-kv * Mt) @ Zp
    Ac[:size, size:] += B @ T @ (-ki * Mt)
    Ac[size:, n:n + m] = Zp
    ev = np.linalg.eigvals(Ac)
    return ev[np.argsort(-ev.real)]


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scale", type=float, default=0.3, help="duration scale (0.3: tests' 0.75 s moves; 1: paper)")
    ap.add_argument("--n", type=int, nargs="+", default=list(range(1, 11)))
    ap.add_argument("--law", nargs="+", default=list(CONTROLLERS), choices=list(CONTROLLERS))
    ap.add_argument("--linear", action="store_true", help="linearised modes instead of runs")
    args = ap.parse_args(argv)
    if args.linear:
        for n in args.n:
            p = default_params(n)
            ctrl = ElasticLQRController(p)
            for scale in (0.01, 1.0):
                law2 = law2_rates(p, scale)[0]
                lqr = closed_loop_rates(linearise(p, friction_scale=scale), ctrl.K, ctrl.dt)[0]
                print(f"N = {n:2d}, friction x{scale:g}: law 2 {law2.real:+.3f} 1/s at {abs(law2.imag):.2f} rad/s, "
                      f"LQR {lqr.real:+.3f} 1/s at {abs(lqr.imag):.2f} rad/s")
        return
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
