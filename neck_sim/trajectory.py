"""Joint-space reference trajectories: cycloidal segments and the paper's two trajectories.

They live in the model core (not in ``controllers``) because the dm_control environment
(:mod:`neck_sim.env`) needs them and ``neck_sim`` may not import ``controllers``;
``controllers.trajectories`` re-exports them and adds the force-limited
:func:`~controllers.trajectories.make_trajectory`.

A :class:`Trajectory` is a list of knot poses at knot times; between two knots the reference
follows a cycloidal profile (zero velocity and acceleration at both ends), and two equal
consecutive poses are a hold.  The paper connects "all desired joint configurations with
cycloidal functions" (§5.2.2, §7).

Cycloidal profile over a segment of duration T from q0 to q1, tau = (t - t0) / T in [0, 1]:

    q = q0 + (q1 - q0) (tau - sin(2 pi tau) / (2 pi))
    q' = (q1 - q0) (1 - cos(2 pi tau)) / T
    q'' = (q1 - q0) 2 pi sin(2 pi tau) / T^2

Shapes: poses (K+1, N) rad; ``sample(t)`` accepts any shape of times and returns arrays of shape
t.shape + (N,).  Before the first knot and after the last the reference holds the end pose.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple, Sequence

import numpy as np
import numpy.typing as npt

from neck_sim.params import NeckParams

# Design notes ("Closed-loop facts"): 2.5 s cycloidal moves, 1 s holds keep forces in the paper's range.
MOVE_TIME = 2.5
HOLD_TIME = 1.0

__all__ = ["MOVE_TIME", "HOLD_TIME", "TrajectorySample", "Trajectory", "cycloidal_path",
           "control_test_trajectory", "identification_trajectory", "TRAJECTORIES", "scaled_trajectory"]


class TrajectorySample(NamedTuple):
    """Desired joint angles (rad), velocities (rad/s) and accelerations (rad/s^2), t.shape + (N,)."""

    alpha: np.ndarray
    alpha_dot: np.ndarray
    alpha_ddot: np.ndarray


@dataclass(frozen=True, eq=False)
class Trajectory:
    """Piecewise cycloidal joint-space path through ``poses`` (K+1, N) at ``times`` (K+1,) s."""

    times: np.ndarray
    poses: np.ndarray
    name: str = "trajectory"

    def __post_init__(self):
        times = np.array(self.times, dtype=float)
        poses = np.array(self.poses, dtype=float)
        if times.ndim != 1 or times.size < 2:
            raise ValueError(f"times: expected at least two knot times, got shape {times.shape}")
        if poses.ndim != 2 or poses.shape[0] != times.size:
            raise ValueError(f"poses: expected shape ({times.size}, N) (one pose per knot time), got {poses.shape}")
        if not (np.all(np.isfinite(times)) and np.all(np.isfinite(poses))):
            raise ValueError("times/poses: contain NaN or infinity")
        if times[0] != 0.0:
            raise ValueError(f"times: the first knot must be at t = 0, got {times[0]}")
        if np.any(np.diff(times) <= 0):
            raise ValueError("times: knot times must be strictly increasing (every segment needs a duration > 0)")
        times.setflags(write=False)
        poses.setflags(write=False)
        object.__setattr__(self, "times", times)
        object.__setattr__(self, "poses", poses)

    @property
    def duration(self) -> float:
        """Time of the last knot (s)."""
        return float(self.times[-1])

    @property
    def n_joints(self) -> int:
        return int(self.poses.shape[1])

    def sample(self, t: npt.ArrayLike) -> TrajectorySample:
        """alpha_d, alpha_d_dot, alpha_d_ddot at times ``t`` (any shape, s)."""
        t = np.asarray(t, dtype=float)
        if not np.all(np.isfinite(t)):
            raise ValueError("t: contains NaN or infinity")
        tc = np.clip(t, 0.0, self.duration)
        seg = np.clip(np.searchsorted(self.times, tc, side="right") - 1, 0, self.times.size - 2)
        t0 = self.times[seg]
        T = (self.times[seg + 1] - t0)[..., None]
        tau = ((tc - t0)[..., None]) / T
        dq = self.poses[seg + 1] - self.poses[seg]
        two_pi_tau = 2 * np.pi * tau
        alpha = self.poses[seg] + dq * (tau - np.sin(two_pi_tau) / (2 * np.pi))
        alpha_dot = dq * (1 - np.cos(two_pi_tau)) / T
        alpha_ddot = dq * 2 * np.pi * np.sin(two_pi_tau) / T ** 2
        outside = ((t < 0) | (t > self.duration))[..., None]
        alpha_dot = np.where(outside, 0.0, alpha_dot)
        alpha_ddot = np.where(outside, 0.0, alpha_ddot)
        return TrajectorySample(alpha, alpha_dot, alpha_ddot)

    def check_workspace(self, params: NeckParams) -> None:
        """Raise ValueError if the joint count differs or a knot pose leaves |alpha| <= alpha_max."""
        if self.n_joints != params.n_joints:
            raise ValueError(f"{self.name}: trajectory has {self.n_joints} joints, the neck has {params.n_joints}")
        amax = params.geometry.alpha_max
        worst = np.abs(self.poses).max()
        if worst > amax:
            k, j = np.unravel_index(np.abs(self.poses).argmax(), self.poses.shape)
            raise ValueError(f"{self.name}: knot {k} puts joint {j + 1} at {np.degrees(self.poses[k, j]):.1f} deg, "
                             f"outside the workspace |alpha| <= {np.degrees(amax):.1f} deg")


def cycloidal_path(poses: Sequence, move_time: float, hold_time: float = 0.0, *,
                   start_hold: float | None = None, end_hold: float | None = None,
                   name: str = "cycloidal path") -> Trajectory:
    """Cycloidal moves through ``poses`` (K+1, N) rad, each lasting ``move_time`` s.

    Each pose is held ``hold_time`` s after it is reached; the first pose is held ``start_hold``
    (default ``hold_time``) before the first move and the last one ``end_hold`` (default
    ``hold_time``).  Zero holds are left out.
    """
    knots = np.asarray(poses, dtype=float)
    if knots.ndim != 2 or knots.shape[0] < 2:
        raise ValueError(f"poses: expected shape (K+1, N) with K >= 1 moves, got {knots.shape}")
    for nm, val in (("move_time", move_time), ("hold_time", hold_time)):
        if not np.isfinite(val) or val < 0 or (nm == "move_time" and val == 0):
            raise ValueError(f"{nm}: must be finite and {'positive' if nm == 'move_time' else '>= 0'}, got {val}")
    start_hold = hold_time if start_hold is None else start_hold
    end_hold = hold_time if end_hold is None else end_hold
    if start_hold < 0 or end_hold < 0:
        raise ValueError("start_hold/end_hold: must be >= 0")
    knots_t, knots_q = [0.0], [knots[0]]

    def add(duration, pose):
        if duration > 0:
            knots_t.append(knots_t[-1] + duration)
            knots_q.append(pose)

    add(start_hold, knots[0])
    for k in range(1, knots.shape[0]):
        add(move_time, knots[k])
        add(end_hold if k == knots.shape[0] - 1 else hold_time, knots[k])
    return Trajectory(np.array(knots_t), np.array(knots_q), name)


def _joint_profile(n: int, first_deg: float, last_deg: float) -> np.ndarray:
    """The paper's 3-joint amplitudes spread linearly over N joints (rad)."""
    return np.radians(np.linspace(first_deg, last_deg, n))


def _check_amplitude(amplitude: float) -> float:
    if not (np.isfinite(amplitude) and amplitude > 0):
        raise ValueError(f"amplitude: must be a positive scale of the joint angles, got {amplitude}")
    return float(amplitude)


def control_test_trajectory(params: NeckParams, move_time: float = MOVE_TIME,
                            hold_time: float = HOLD_TIME, amplitude: float = 1.0) -> Trajectory:
    """The control-test trajectory of §7: straight -> [50, 50, 50] deg -> straight ->
    [-30, -40, -50] deg -> straight (for N joints: 50 deg each, then -30 .. -50 deg linearly),
    every angle times ``amplitude``.

    Defaults (2.5 s moves, 1 s holds, 15 s in all) are those of the design notes.
    """
    n = params.n_joints
    straight = np.zeros(n)
    s = _check_amplitude(amplitude)
    poses = [straight, np.full(n, s * np.radians(50.0)), straight, -s * _joint_profile(n, 30.0, 50.0), straight]
    traj = cycloidal_path(poses, move_time, hold_time, name="control-test")
    traj.check_workspace(params)
    return traj


def identification_trajectory(params: NeckParams, move_time: float = MOVE_TIME,
                              hold_time: float = HOLD_TIME, amplitude: float = 1.0) -> Trajectory:
    """The identification trajectory of §5.2.2: N + 1 sequences of six cycloidal motions.

    Each sequence goes straight -> a -> -a -> straight -> -a -> a -> straight.  Sequence 1 uses
    a = [40, 30, 20] deg (N joints: 40 .. 20 deg linearly); sequence j + 1 flips the sign of joint
    j's amplitude.  For N = 3 that is the paper's four sequences (24 motions, 84 s with the
    defaults).  Every angle is multiplied by ``amplitude``.
    """
    n = params.n_joints
    base = _check_amplitude(amplitude) * _joint_profile(n, 40.0, 20.0)
    straight = np.zeros(n)
    poses = [straight]
    for seq in range(n + 1):
        a = base.copy()
        if seq > 0:
            a[seq - 1] = -a[seq - 1]
        poses += [a, -a, straight, -a, a, straight]
    traj = cycloidal_path(poses, move_time, hold_time, name="identification")
    traj.check_workspace(params)
    return traj


TRAJECTORIES = {"control-test": control_test_trajectory, "identification": identification_trajectory}


def scaled_trajectory(name: str, params: NeckParams, duration_scale: float = 1.0,
                      amplitude: float = 1.0) -> Trajectory:
    """One of :data:`TRAJECTORIES` by name with its move and hold times scaled by ``duration_scale``
    and its joint angles by ``amplitude``, exactly as given.

    A scaled trajectory (``amplitude`` != 1) is named ``"<name> x<amplitude>"`` so that logs and
    tables say so.  :func:`controllers.trajectories.make_trajectory` is the one that chooses the
    amplitude keeping a long neck's cable forces within f_max.
    """
    if name not in TRAJECTORIES:
        raise ValueError(f"trajectory: unknown name {name!r} (known: {', '.join(TRAJECTORIES)})")
    if not np.isfinite(duration_scale) or duration_scale <= 0:
        raise ValueError(f"duration_scale: must be positive, got {duration_scale}")
    traj = TRAJECTORIES[name](params, move_time=MOVE_TIME * duration_scale,
                              hold_time=HOLD_TIME * duration_scale, amplitude=amplitude)
    if amplitude != 1.0:
        traj = Trajectory(traj.times, traj.poses, f"{name} x{amplitude:.2f}")
    return traj
