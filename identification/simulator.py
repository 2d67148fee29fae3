"""The simulator comparison of §5.6 (figure 9): does the identified model predict the experiment?

The measured run's reference trajectory is replayed closed loop, with the same control law, on
two simulated plants:

* ``rigid, no friction``: the paper's first simulator, inextensible cables (``Plant(...,
  rigid_cables=True)``) and no motor friction;
* ``identified``: friction f_s from eqs (44)-(45), variable stiffness k, lambda from eqs (54)-(57),
  and the damping the paper put in its simulator, c_a = ``control.c_a_estimator`` (3000 N s/m:
  the identified damping is not trustworthy, §5.3).

Each is compared with the measured run sample by sample: mean |f_sim - f_meas| (N), mean
|theta_sim - theta_meas| (rad) and mean |alpha_sim - alpha_camera| (deg, the simulator's joint
angles against the measured camera frames, so the camera's own noise, about 0.8 deg mean, is a
floor).  Only measured topics of the log are read: motors, camera and the reference.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from neck_sim.params import NeckParams

__all__ = ["SampledTrajectory", "identified_params", "SimulatorComparison", "compare_simulators"]


class SampledTrajectory:
    """A reference trajectory given by samples (e.g. the log's /neck/reference), cubic-spline
    interpolated; the interface of ``controllers.trajectories.Trajectory`` (sample, duration,
    check_workspace).  Times are shifted so that the first sample is t = 0."""

    def __init__(self, t, alpha_d, name: str = "logged reference"):
        from scipy.interpolate import CubicSpline

        t = np.asarray(t, dtype=float)
        a = np.asarray(alpha_d, dtype=float)
        if t.ndim != 1 or a.ndim != 2 or a.shape[0] != t.size or t.size < 4:
            raise ValueError(f"reference: expected t (T >= 4,) and alpha_d (T, N), got {t.shape} and {a.shape}")
        if not (np.all(np.isfinite(t)) and np.all(np.isfinite(a))) or np.any(np.diff(t) <= 0):
            raise ValueError("reference: times must be finite and increasing, angles finite")
        self.name = name
        self._t0 = float(t[0])
        self._spline = CubicSpline(t - t[0], a, axis=0)
        self.poses = a
        self.times = t - t[0]

    @property
    def duration(self) -> float:
        return float(self.times[-1])

    @property
    def n_joints(self) -> int:
        return int(self.poses.shape[1])

    def sample(self, t):
        from controllers.trajectories import TrajectorySample

        tc = np.clip(np.asarray(t, dtype=float), 0.0, self.duration)
        return TrajectorySample(self._spline(tc), self._spline(tc, 1), self._spline(tc, 2))

    def check_workspace(self, params: NeckParams) -> None:
        if self.n_joints != params.n_joints:
            raise ValueError(f"{self.name}: {self.n_joints} joints, the neck has {params.n_joints}")
        worst = float(np.abs(self.poses).max())
        if worst > params.geometry.alpha_max:
            raise ValueError(f"{self.name}: reaches {np.degrees(worst):.1f} deg, outside the workspace")


def identified_params(nominal: NeckParams, result) -> NeckParams:
    """``nominal`` with the identified friction and variable-stiffness cables (c_a: the paper's 3000)."""
    var = result.variable
    if var is None:
        raise ValueError("identified simulator: needs the variable-stiffness model (eqs 54-57) in the result")
    n1 = nominal.n_cables
    return nominal.replace(**{
        "friction.f_s": tuple(np.maximum(result.f_s, 0.0)),
        "cables.k": tuple(var.group("k")),
        "cables.lam": tuple(np.maximum(var.group("lambda"), 0.0)),
        "cables.c_a": (nominal.control.c_a_estimator,) * n1,
    })


@dataclass(frozen=True, eq=False)
class SimulatorComparison:
    """Per simulator: mean |force diff| (N), |theta diff| (rad), |alpha - camera| (deg), mean force (N)."""

    rows: dict                       # name -> {"force": N, "theta": rad, "alpha_deg": deg, "mean_force": N}
    measured_mean_force: float
    series: dict = field(default_factory=dict)   # name -> (t, force) for figure 9

    def table(self) -> str:
        lines = [f"{'simulator':24} {'|df| (N)':>9} {'|dtheta| (rad)':>15} {'|alpha-cam| (deg)':>18} {'mean f (N)':>11}"]
        for name, r in self.rows.items():
            lines.append(f"{name:24} {r['force']:9.2f} {r['theta']:15.3f} {r['alpha_deg']:18.2f} {r['mean_force']:11.2f}")
        lines.append(f"{'measured run':24} {'':9} {'':15} {'':18} {self.measured_mean_force:11.2f}")
        return "\n".join(lines)

    def to_dict(self) -> dict:
        return {"simulators": self.rows, "measured_mean_force": self.measured_mean_force}


def compare_simulators(log, result, *, law: int = 1, trajectory=None, seed: int = 0,
                       progress: bool = True) -> SimulatorComparison:
    """Replay the log's reference on the two simulators of §5.6 and compare with the log.

    ``log``: :class:`neck_sim.logs.Log` of the measured run (motors, camera, reference, read from
    its start); ``result``: its :class:`~identification.paper.IdentificationResult`; ``law``: the
    control law the run used (the paper identified under law 1); ``trajectory``: the reference if
    known exactly (default: spline of /neck/reference).
    """
    from controllers.closed_loop import run_closed_loop
    from controllers.computed_torque import ComputedTorqueController
    from neck_sim.plant import Plant

    if log.camera is None:
        raise ValueError("simulator comparison: the log has no /neck/camera frames to compare joint angles with")
    if trajectory is None:
        if log.reference is None:
            raise ValueError("simulator comparison: the log has no /neck/reference topic; pass the trajectory")
        trajectory = SampledTrajectory(log.reference.t, log.reference.alpha_d)
    nominal = log.params
    t_meas, f_meas, th_meas = log.motors.t - log.motors.t[0], log.motors.force, log.motors.theta
    plants = {
        "rigid, no friction": Plant(nominal.replace(**{"friction.f_s": (0.0,) * nominal.n_cables}), seed=seed,
                                    rigid_cables=True),
        "identified": Plant(identified_params(nominal, result), seed=seed),
    }
    rows, series = {}, {"measured": (t_meas, f_meas)}
    cam_t = log.camera.t - log.motors.t[0]
    for name, plant in plants.items():
        run = run_closed_loop(plant, ComputedTorqueController(nominal, law=law), trajectory, progress=progress)
        n = min(run.t.size, t_meas.size)
        in_run = (cam_t >= run.t[0]) & (cam_t <= run.t[n - 1])
        a_sim = np.stack([np.interp(cam_t[in_run], run.t[:n], run.alpha[:n, j]) for j in range(run.alpha.shape[1])], 1)
        rows[name] = {"force": float(np.mean(np.abs(run.force[:n] - f_meas[:n]))),
                      "theta": float(np.mean(np.abs(run.theta[:n] - th_meas[:n]))),
                      "alpha_deg": float(np.degrees(np.mean(np.abs(a_sim - log.camera.alpha[in_run])))),
                      "mean_force": float(np.mean(run.force[:n]))}
        series[name] = (run.t[:n], run.force[:n])
    return SimulatorComparison(rows, float(np.mean(f_meas)), series)
