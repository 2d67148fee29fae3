"""The simulator comparison of §5.6 (figure 9): does the identified model predict the experiment?

The measured run's reference trajectory is replayed closed loop, with the same control law, on
two simulated plants:

* ``rigid, no friction``: the paper's first simulator, inextensible cables (``Plant(...,
  rigid_cables=True)``) and no motor friction;
* ``identified``: friction f_s from eqs (44)-(45), variable stiffness k, lambda from eqs (54)-(57),
  and a fixed cable damping (``damping``, 20 N s/m) in place of the identified one, which is not
  significant (values of either sign, |c_a| <= about 30 N s/m, relative sigma 50-200 %).  The
  paper did the same with 3000 N s/m (§5.3).  On the MuJoCo plant the replay is insensitive to
  the damping between 10 and 100 N s/m (the same force, theta and alpha differences to 0.01),
  while zero damping diverged 45 s into the paper's trajectory, 300 N s/m already changes the
  response (theta differences of 1.7 rad instead of 0.02) and 1000 N s/m or more diverges (the
  damping acts on bars of 1e-5 kg m^2 through Z^2), so the paper's value cannot be used here.

Each is compared with the measured run sample by sample: mean |f_sim - f_meas| (N), mean
|theta_sim - theta_meas| (rad) and mean |alpha_sim - alpha_camera| (deg, the simulator's joint
angles against the measured camera frames, so the camera's own noise, about 0.8 deg mean, is a
floor).  Only measured topics of the log are read: motors, camera and the reference.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, ClassVar

import numpy as np
import numpy.typing as npt

from scipy.interpolate import CubicSpline

from neck_sim.params import NeckParams
from neck_sim.trajectory import Trajectory, TrajectorySample

if TYPE_CHECKING:
    from identification.paper import IdentificationResult
    from neck_sim.logs import Log

__all__ = ["SampledTrajectory", "identified_params", "SimulatorComparison", "compare_simulators"]


@dataclass(frozen=True, eq=False)
class SampledTrajectory(Trajectory):
    """A reference given by samples (``times`` from 0, ``poses`` (T, N)), e.g. the log's
    /neck/reference, interpolated by a cubic spline for the velocities and accelerations."""

    if TYPE_CHECKING:       # an instance attribute set in __post_init__; ClassVar keeps it out of the fields
        _spline: ClassVar[CubicSpline]

    def __post_init__(self):
        super().__post_init__()
        if self.times.size < 4:
            raise ValueError(f"{self.name}: need at least 4 samples, got {self.times.size}")
        object.__setattr__(self, "_spline", CubicSpline(self.times, self.poses, axis=0))

    @classmethod
    def from_samples(cls, t: npt.ArrayLike, alpha_d: npt.ArrayLike,
                     name: str = "logged reference") -> "SampledTrajectory":
        """From logged times (any start) and desired angles (T, N); time is shifted to start at 0."""
        t = np.asarray(t, dtype=float)
        return cls(t - t[0], np.asarray(alpha_d, dtype=float), name)

    def sample(self, t: npt.ArrayLike) -> TrajectorySample:
        tc = np.clip(np.asarray(t, dtype=float), 0.0, self.duration)
        return TrajectorySample(self._spline(tc), self._spline(tc, 1), self._spline(tc, 2))


def identified_params(nominal: NeckParams, result: IdentificationResult, damping: float = 20.0) -> NeckParams:
    """``nominal`` with the identified friction and variable-stiffness cables (negative values -> 0)
    and the cable damping ``damping`` N s/m (see the module docstring)."""
    var = result.variable
    if var is None:
        raise ValueError("identified simulator: needs the variable-stiffness model (eqs 54-57) in the result")
    return nominal.replace(**{
        "friction.f_s": tuple(np.maximum(result.f_s, 0.0)),
        "cables.k": tuple(var.group("k")),
        "cables.lam": tuple(np.maximum(var.group("lambda"), 0.0)),
        "cables.c_a": (float(damping),) * nominal.n_cables,
    })


@dataclass(frozen=True, eq=False)
class SimulatorComparison:
    """Per simulator: mean |force diff| (N), |theta diff| (rad), |alpha - camera| (deg), mean force (N),
    or NaNs and "failed": the reason when its closed loop stopped."""

    rows: dict                       # name -> {"force": N, "theta": rad, "alpha_deg": deg, "mean_force": N}
    measured_mean_force: float
    series: dict = field(default_factory=dict)   # name -> (t, force) for figure 9

    def table(self) -> str:
        lines = [f"{'simulator':24} {'|df| (N)':>9} {'|dtheta| (rad)':>15} {'|alpha-cam| (deg)':>18} {'mean f (N)':>11}"]
        for name, r in self.rows.items():
            if "failed" in r:
                lines.append(f"{name:24} failed: {r['failed']}")
                continue
            lines.append(f"{name:24} {r['force']:9.2f} {r['theta']:15.3f} {r['alpha_deg']:18.2f} {r['mean_force']:11.2f}")
        lines.append(f"{'measured run':24} {'':9} {'':15} {'':18} {self.measured_mean_force:11.2f}")
        return "\n".join(lines)

    def to_dict(self) -> dict:
        """JSON-ready (NaN of a failed simulator as None)."""
        clean = {name: {k: (None if isinstance(v, float) and not np.isfinite(v) else v) for k, v in r.items()}
                 for name, r in self.rows.items()}
        return {"simulators": clean, "measured_mean_force": self.measured_mean_force}


def compare_simulators(log: Log, result: IdentificationResult, *, law: int = 1, trajectory: Trajectory | None = None,
                       seed: int = 0, damping: float = 20.0, progress: bool = True) -> SimulatorComparison:
    """Replay the log's reference on the two simulators of §5.6 and compare with the log.

    ``log``: :class:`neck_sim.logs.Log` of the measured run (motors, camera, reference, read from
    its start); ``result``: its :class:`~identification.paper.IdentificationResult`; ``law``: the
    control law the run used (the paper identified under law 1); ``trajectory``: the reference if
    known exactly (default: spline of /neck/reference); ``damping``: the identified simulator's
    cable damping (N s/m).
    """
    from controllers.closed_loop import run_closed_loop
    from controllers.computed_torque import ComputedTorqueController
    from neck_sim.plant import Plant

    if log.camera is None:
        raise ValueError("simulator comparison: the log has no /neck/camera frames to compare joint angles with")
    if log.motors is None:
        raise ValueError("simulator comparison: the log has no /neck/motors samples to compare forces with")
    if trajectory is None:
        if log.reference is None:
            raise ValueError("simulator comparison: the log has no /neck/reference topic; pass the trajectory")
        trajectory = SampledTrajectory.from_samples(log.reference.t, log.reference.alpha_d)
    nominal = log.params
    t_meas, f_meas, th_meas = log.motors.t - log.motors.t[0], log.motors.force, log.motors.theta
    plants = {
        "rigid, no friction": Plant(nominal.replace(**{"friction.f_s": (0.0,) * nominal.n_cables}), seed=seed,
                                    rigid_cables=True),
        "identified": Plant(identified_params(nominal, result, damping), seed=seed),
    }
    rows, series = {}, {"measured": (t_meas, f_meas)}
    cam_t = log.camera.t - log.motors.t[0]
    for name, plant in plants.items():
        try:
            run = run_closed_loop(plant, ComputedTorqueController(nominal, law=law), trajectory, progress=progress)
        except RuntimeError as exc:      # the closed loop lost the neck: a result, not a crash
            rows[name] = {"force": float("nan"), "theta": float("nan"), "alpha_deg": float("nan"),
                          "mean_force": float("nan"), "failed": str(exc)}
            continue
        n = min(run.t.size, t_meas.size)
        in_run = (cam_t >= run.t[0]) & (cam_t <= run.t[n - 1])
        a_sim = np.stack([np.interp(cam_t[in_run], run.t[:n], run.alpha[:n, j]) for j in range(run.alpha.shape[1])], 1)
        rows[name] = {"force": float(np.mean(np.abs(run.force[:n] - f_meas[:n]))),
                      "theta": float(np.mean(np.abs(run.theta[:n] - th_meas[:n]))),
                      "alpha_deg": float(np.degrees(np.mean(np.abs(a_sim - log.camera.alpha[in_run])))),
                      "mean_force": float(np.mean(run.force[:n]))}
        series[name] = (run.t[:n], run.force[:n])
    return SimulatorComparison(rows, float(np.mean(f_meas)), series)
