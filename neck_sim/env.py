"""A dm_control environment of the simulated neck: track a joint-space reference with cable forces.

    from neck_sim import env as neck_env
    env = neck_env.load(n_joints=3, seed=0)                 # random cycloidal targets
    ts = env.reset()
    while not ts.last():
        ts = env.step(my_policy(ts.observation))            # m cable forces (N+1 for the paper) in [0, f_max] N

The environment is a :class:`dm_control.rl.control.Environment` whose physics,
:class:`NeckPhysics`, is a :class:`dm_control.mujoco.Physics` *wrapping* a
:class:`neck_sim.plant.Plant`: it shares the plant's ``MjModel``/``MjData``, so the plant's
callbacks (eq 54 cable tensions, eq 37 motor friction, the hidden effects) act, and one
environment step is one :meth:`Plant.step` -- one control period, 1/``control.rate_hz`` (500 Hz).

Actions: the m commanded cable forces (m = params.n_cables, N+1 for the paper) f (N), ``BoundedArray`` [0, ``actuation.f_max``].

Observations (what the prototype measures; all float64):

* ``encoder_angles`` (m,) rad: motor angles theta, quantised to the encoder resolution;
* ``encoder_speeds`` (m,) rad/s: their backward difference over one control period (zero at
  the first step), as the prototype's controller gets them;
* ``camera_angles`` (N,) rad: the last camera frame (30 Hz, 1 deg noise), held between frames;
  before the first frame, the known start pose;
* ``camera_new`` (1,): 1.0 when a frame arrived during the last control period, else 0.0;
* ``reference``, ``reference_velocity``, ``reference_acceleration`` (N,): alpha_d and its
  derivatives (rad, rad/s, rad/s^2) at the current time.

With ``observe_truth=True`` the observation also holds the simulation truth ``true_alpha``,
``true_alpha_dot`` (N,), ``true_tension``, ``true_elongation`` (m,) -- for debugging; it is
always available as ``env.physics.truth()`` (a :class:`neck_sim.plant.Truth`).

Reward: mean over joints of ``dm_control.utils.rewards.tolerance(|alpha_i - alpha_d,i|,
bounds=(0, reward_tolerance), margin=reward_margin)`` (true alpha; smooth, in [0, 1]).
An episode ends after ``time_limit`` s (discount 1) or when a joint leaves the workspace
|alpha| < ``geometry.alpha_max`` (discount 0: the prototype would break).

Episodes are seeded by the task's ``RandomState`` (``load(seed=...)``; shimmy's
``reset(seed=...)`` replaces it): random targets and the camera noise of each episode come from
it, so the same seed and actions give identical observations.

MuJoCo's control callback is process-global; :mod:`neck_sim.plant` dispatches it by model, so
several environments with different parameters can live and step in one process.
"""

from __future__ import annotations

import collections
import math
import os
from typing import Any

import numpy as np
from dm_control import mujoco as dm_mujoco
from dm_control.mujoco import wrapper
from dm_control.rl import control
from dm_control.suite import base
from dm_control.utils import rewards
from dm_env import specs

from neck_sim.effects import Effects
from neck_sim.params import NeckParams, default_params
from neck_sim.plant import Plant, Truth
from neck_sim.plant_spec import PlantSpec
from neck_sim.recorder import Recorder
from neck_sim.trajectory import HOLD_TIME, MOVE_TIME, Trajectory, cycloidal_path, scaled_trajectory

__all__ = ["load", "NeckPhysics", "TrackingTask", "NeckEnvironment", "OPTIONS", "RANDOM_DURATION",
           "RANDOM_TARGET_RANGE", "REWARD_TOLERANCE", "REWARD_MARGIN"]

RANDOM_DURATION = 10.0                  # s, default episode length with random targets
RANDOM_TARGET_RANGE = math.radians(50.0)  # rad, |alpha_d| of random targets: the paper's test range (§7)
REWARD_TOLERANCE = math.radians(1.0)    # rad, error that still earns the full reward
REWARD_MARGIN = math.radians(10.0)      # rad, error beyond the tolerance where the reward is 0.1

OPTIONS = ("params", "effects", "trajectory", "time_limit", "duration_scale", "move_time", "hold_time",
           "target_range", "observe_truth", "log_path", "reward_tolerance", "reward_margin",
           "rigid_cables", "timestep", "live")
"""Keyword options of :func:`load`."""


class NeckPhysics(dm_mujoco.Physics):
    """A dm_control ``Physics`` sharing the model and data of a :class:`~neck_sim.plant.Plant`.

    Build it with :meth:`from_plant`.  ``set_control(forces)`` takes the N+1 cable forces;
    ``step(nstep)`` runs ``nstep / plant.substeps`` plant control periods (nstep must be a
    multiple of the plant's sub-steps).  Everything dm_control offers on a Physics (``named``,
    ``render``, ``model``, ``data``) reads the plant's state.
    """

    _plant: Plant

    @classmethod
    def from_plant(cls, plant: Plant) -> "NeckPhysics":
        phys = cls.__new__(cls)
        phys._plant = plant
        phys._forces = np.zeros(plant.params.n_cables)
        phys._last_frame = None
        dm_mujoco.Physics.__init__(phys, wrapper.MjData(plant.data))
        return phys

    @property
    def plant(self) -> Plant:
        return self._plant

    def set_control(self, control) -> None:
        """Commanded cable forces (N+1,) N for the next control period (clipped to [0, f_max])."""
        self._forces = np.array(self._plant.checked_forces(control), dtype=float)

    def step(self, nstep: int = 1) -> None:
        n = self._plant.substeps
        if nstep < n or nstep % n:
            raise ValueError(f"nstep: the plant steps whole control periods of {n} physics steps, got {nstep}")
        frame = None
        # records nothing itself: the task records each environment step (one control period,
        # NeckEnvironment's control_timestep) through its Recorder in before_step/after_step
        with self.check_invalid_state():
            for _ in range(nstep // n):
                self._plant.step(self._forces)
                frame = self._plant.camera_frame() or frame
        self._last_frame = frame

    def reset(self, keyframe_id=None, alpha0=None) -> None:
        """Put the neck at rest at ``alpha0`` (N,) rad (default straight); keyframes are not used."""
        if keyframe_id is not None:
            raise ValueError("keyframe_id: the neck model has no keyframes; pass alpha0")
        self._plant.reset(alpha0)
        self._forces = np.zeros(self._plant.params.n_cables)
        self._last_frame = None

    def after_reset(self) -> None:
        # Plant.reset already ran the position/velocity stages (mj_step1): the state is consistent.
        pass

    def copy(self, share_model=False):
        raise NotImplementedError("NeckPhysics is bound to its Plant (callbacks, sensors): "
                                  "make another environment with neck_sim.env.load(...) instead")

    def time(self) -> float:
        return self._plant.time

    def camera_frame(self):
        """(t, alpha (N,)) of the last camera frame taken during the last ``step``, or None."""
        return self._last_frame

    def encoders(self) -> np.ndarray:
        return self._plant.encoders()

    def truth(self) -> Truth:
        return self._plant.truth()

    @property
    def forces(self) -> np.ndarray:
        """The commanded (clipped) forces of the current control period (N+1,) N."""
        return self._forces.copy()


def _random_trajectory(random: np.random.RandomState, n: int, duration: float, target_range: float,
                       move_time: float, hold_time: float, start: np.ndarray) -> Trajectory:
    """Cycloidal moves from ``start`` through uniform random poses in [-target_range, target_range]^N."""
    k = max(1, math.ceil(duration / (move_time + hold_time)))
    poses = np.vstack([start, random.uniform(-target_range, target_range, size=(k, n))])
    return cycloidal_path(poses, move_time, hold_time, start_hold=0.0, name="random targets")


class TrackingTask(base.Task):
    """Track a joint-space reference with the cable forces (see the module docstring)."""

    def __init__(self, params: NeckParams, trajectory="random", *, random=None, duration: float = RANDOM_DURATION,
                 move_time: float = MOVE_TIME, hold_time: float = HOLD_TIME,
                 target_range: float = RANDOM_TARGET_RANGE, observe_truth: bool = False,
                 reward_tolerance: float = REWARD_TOLERANCE, reward_margin: float = REWARD_MARGIN,
                 log_path=None, live=None):
        super().__init__(random=random)
        self.params = params
        n = params.n_joints
        self._n = n
        self._fixed = None if isinstance(trajectory, str) else trajectory
        if self._fixed is not None:
            _check_trajectory(self._fixed, params)
        self._duration = float(duration)
        self._move_time, self._hold_time = float(move_time), float(hold_time)
        self._target_range = float(target_range)
        self._observe_truth = bool(observe_truth)
        self._reward_tolerance, self._reward_margin = float(reward_tolerance), float(reward_margin)
        self._log_path = None if log_path is None else os.fspath(log_path)
        self._writer = None
        self._recorder = None       # the episode's samples, for the log and the live view
        self.live = live            # a neck_sim.live.LiveView fed like the log, or None
        self._episode = -1
        self._rate = params.control.rate_hz
        self.trajectory: Trajectory | Any = self._fixed
        self._prev_theta = np.zeros(params.n_cables)
        self._speed = np.zeros(params.n_cables)
        self._camera = np.zeros(n)
        self._camera_new = 0.0
        self._ref = (np.zeros(n),) * 3

    # -- episode
    def initialize_episode(self, physics: NeckPhysics) -> None:
        plant = physics.plant
        n = self._n
        if self._fixed is None:
            self.trajectory = _random_trajectory(self.random, n, self._duration, self._target_range,
                                                 self._move_time, self._hold_time, np.zeros(n))
        start = np.asarray(self.trajectory.sample(0.0)[0], dtype=float)
        # The camera noise of this episode: drawn from the task's RandomState (seeded episodes).
        plant.seed = int(self.random.randint(2 ** 31 - 1))
        physics.reset(alpha0=start)
        self._prev_theta = plant.encoders()
        self._speed = np.zeros(self.params.n_cables)
        self._camera = start.copy()
        self._camera_new = 0.0
        self._ref = self._reference(physics.time())
        self._episode += 1
        self._open_log(physics)
        if self.live is not None:
            self.live.new_run()

    def before_step(self, action, physics: NeckPhysics) -> None:
        physics.set_control(action)
        rec = self._recorder
        if rec is not None:
            k = rec.append(physics.time(), physics.encoders(), physics.forces, physics.truth(), alpha_d=self._ref[0])
            if self.live is not None:
                rec.write(self.live, rows=slice(k, k + 1), frames=slice(0, 0))

    def after_step(self, physics: NeckPhysics) -> None:
        self._ref = self._reference(physics.time())
        theta = physics.encoders()
        self._speed = (theta - self._prev_theta) * self._rate
        self._prev_theta = theta
        frame = physics.camera_frame()
        if frame is None:
            self._camera_new = 0.0
        else:
            self._camera = np.array(frame[1], dtype=float)
            self._camera_new = 1.0
            rec = self._recorder
            if rec is not None:
                rec.frame(frame)
                if self.live is not None:
                    rec.write(self.live, rows=slice(0, 0), frames=slice(-1, None))

    # -- specs
    def action_spec(self, physics: NeckPhysics) -> specs.BoundedArray:
        n1 = self.params.n_cables
        return specs.BoundedArray((n1,), np.float64, np.zeros(n1), np.full(n1, self.params.actuation.f_max),
                                  name="cable_forces")

    def observation_spec(self, physics: NeckPhysics) -> collections.OrderedDict:
        return collections.OrderedDict((name, specs.Array(shape, np.float64, name=name))
                                       for name, shape in self._shapes())

    def _shapes(self):
        n, n1 = self._n, self.params.n_cables
        out = [("encoder_angles", (n1,)), ("encoder_speeds", (n1,)), ("camera_angles", (n,)), ("camera_new", (1,)),
               ("reference", (n,)), ("reference_velocity", (n,)), ("reference_acceleration", (n,))]
        if self._observe_truth:
            out += [("true_alpha", (n,)), ("true_alpha_dot", (n,)), ("true_tension", (n1,)),
                    ("true_elongation", (n1,))]
        return out

    # -- observation, reward, termination
    def _reference(self, t: float):
        s = self.trajectory.sample(t)
        return tuple(np.array(x, dtype=float).reshape(self._n) for x in s[:3])

    def get_observation(self, physics: NeckPhysics) -> collections.OrderedDict:
        ref, ref_dot, ref_ddot = (x.copy() for x in self._ref)
        obs = collections.OrderedDict()
        obs["encoder_angles"] = physics.encoders()
        obs["encoder_speeds"] = self._speed.copy()
        obs["camera_angles"] = self._camera.copy()
        obs["camera_new"] = np.array([self._camera_new])
        obs["reference"] = ref
        obs["reference_velocity"] = ref_dot
        obs["reference_acceleration"] = ref_ddot
        if self._observe_truth:
            tr = physics.truth()
            obs["true_alpha"] = tr.alpha
            obs["true_alpha_dot"] = tr.alpha_dot
            obs["true_tension"] = tr.tension
            obs["true_elongation"] = tr.elongation
        return obs

    def tracking_error(self, physics: NeckPhysics) -> np.ndarray:
        """|alpha - alpha_d| (N,) rad, true joint angles against the reference at the current time."""
        return np.abs(physics.truth().alpha - self._ref[0])

    def get_reward(self, physics: NeckPhysics) -> float:
        r = rewards.tolerance(self.tracking_error(physics), bounds=(0.0, self._reward_tolerance),
                              margin=self._reward_margin, sigmoid="gaussian", value_at_margin=0.1)
        return float(np.mean(r))

    def get_termination(self, physics: NeckPhysics):
        alpha = physics.truth().alpha
        if not (np.all(np.isfinite(alpha)) and np.all(np.abs(alpha) < self.params.geometry.alpha_max)):
            return 0.0
        return None

    # -- logging
    def log_file(self, episode: int | None = None) -> str | None:
        """The MCAP file of ``episode`` (default: the current one), or None without ``log_path``."""
        if self._log_path is None:
            return None
        ep = self._episode if episode is None else episode
        return self._log_path.format(episode=ep) if "{episode" in self._log_path else self._log_path

    def _open_log(self, physics: NeckPhysics) -> None:
        """A new episode's recorder (for its log and the live view) and its log, opened now (a path
        that cannot be written fails at reset) and written from the recorder when it closes."""
        self.close_log()
        if self._log_path is None and self.live is None:
            return
        plant = physics.plant
        self._recorder = Recorder(self._n, self.params.n_cables, reference=True)
        if self._log_path is None:
            return
        from neck_sim.logs import LogWriter
        # the plant's spec, as every other loop records it, so that `neck-sim replay` rebuilds it
        info = {"source": "neck_sim.env", "episode": self._episode, "trajectory": getattr(self.trajectory, "name", "custom"),
                **PlantSpec.of(plant).to_record()}
        self._writer = LogWriter(self.log_file(), plant.params, mjcf_xml=plant.xml, run_info=info)

    def close_log(self) -> None:
        """Finish the current episode's MCAP file (written atomically on close)."""
        rec, self._recorder = self._recorder, None
        w, self._writer = self._writer, None
        if w is not None:
            rec.write(w)
            w.close()


class NeckEnvironment(control.Environment):
    """``control.Environment`` with an exact step count per episode and the task's MCAP log.

    An episode has ``round(time_limit * control.rate_hz)`` steps; its log (``log_path``) is closed
    when the episode ends, at the next ``reset`` or at ``close()``.
    """

    def __init__(self, physics: NeckPhysics, task: TrackingTask, time_limit: float):
        rate = task.params.control.rate_hz
        super().__init__(physics, task, time_limit=time_limit, control_timestep=1.0 / rate)
        self._step_limit = max(1, int(round(time_limit * rate)))
        self._owns_live = False       # load(live=True) opened the view: close() stops it

    def step(self, action):
        ts = super().step(action)
        if ts.last():
            self._task.close_log()
        return ts

    def close(self) -> None:
        self._task.close_log()
        if self._task.live is not None and self._owns_live:
            self._task.live.close()
        super().close()


def _check_trajectory(traj, params: NeckParams) -> None:
    if not callable(getattr(traj, "sample", None)) or not hasattr(traj, "duration"):
        raise ValueError("trajectory: expected 'random', 'control-test', 'identification' or an object with "
                         f"sample(t) -> (alpha_d, alpha_d_dot, alpha_d_ddot) and duration, got {type(traj).__name__}")
    sample = traj.sample(0.0)
    shape = np.shape(sample[0])
    if shape != (params.n_joints,):
        raise ValueError(f"trajectory: sample(0) gives alpha_d of shape {shape}, the neck has {params.n_joints} joints")
    if callable(getattr(traj, "check_workspace", None)):
        traj.check_workspace(params)


def _positive(name: str, value) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: expected a number, got {value!r}") from None
    if not (math.isfinite(v) and v > 0):
        raise ValueError(f"{name}: must be finite and > 0, got {value!r}")
    return v


def load(n_joints: int = 3, seed: int | None = None, **options) -> NeckEnvironment:
    """The neck tracking environment (see the module docstring).

    Args:
      n_joints: number of X-joints N (ignored in favour of ``params`` when given; must agree).
      seed: seeds random targets and camera noise (None: fresh entropy).
    Options:
      params (NeckParams): plant constants (default ``default_params(n_joints)``); effects
        (:class:`neck_sim.effects.Effects`): hidden effects of the plant; rigid_cables (bool);
        timestep (s, physics step dividing the control period).
      trajectory: ``"random"`` (default: cycloidal moves through random poses),
        ``"control-test"`` (§7), ``"identification"`` (§5.2.2), or an object with
        ``sample(t) -> (alpha_d, alpha_d_dot, alpha_d_ddot)`` and ``duration`` (e.g. a
        :class:`neck_sim.trajectory.Trajectory`).
      time_limit (s): episode length (default: the trajectory's duration, 10 s for random targets).
      duration_scale: scales move and hold times of the paper's trajectories (default 1).
      move_time, hold_time (s), target_range (rad): random targets (defaults 2.5 s, 1 s, 50 deg).
      observe_truth (bool): add the simulation truth to the observation.
      log_path: MCAP file of each episode (``{episode}`` in the path is replaced by the episode
        number; without it each episode overwrites the file).
      reward_tolerance, reward_margin (rad): the reward's tolerance (defaults 1 deg, 10 deg).
      live: True serves every episode to Foxglove at ws://127.0.0.1:8765 in real time (stopped
        by ``close()``), or a :class:`neck_sim.live.LiveView` of your own (its port and pace);
        the same topics as the log (docs/live-view.md; needs foxglove-sdk).
    """
    unknown = sorted(set(options) - set(OPTIONS))
    if unknown:
        raise ValueError(f"load: unknown option(s) {', '.join(map(repr, unknown))} (known: {', '.join(OPTIONS)})")
    params = options.get("params")
    if params is None:
        params = default_params(n_joints)
    elif not isinstance(params, NeckParams):
        raise ValueError(f"params: expected NeckParams, got {type(params).__name__}")
    elif params.n_joints != n_joints and n_joints != 3:
        raise ValueError(f"n_joints: {n_joints} disagrees with params (n_joints = {params.n_joints})")
    effects = options.get("effects") or Effects()
    plant = PlantSpec(params, effects, seed=0, timestep=options.get("timestep"),
                      rigid_cables=bool(options.get("rigid_cables", False))).build()

    trajectory = options.get("trajectory", "random")
    kw = {}
    if isinstance(trajectory, str):
        if trajectory == "random":
            duration = _positive("time_limit", options.get("time_limit", RANDOM_DURATION))
            kw = dict(duration=duration,
                      move_time=_positive("move_time", options.get("move_time", MOVE_TIME)),
                      hold_time=float(options.get("hold_time", HOLD_TIME)),
                      target_range=_positive("target_range", options.get("target_range", RANDOM_TARGET_RANGE)))
            if not 0 <= kw["hold_time"] < math.inf:
                raise ValueError(f"hold_time: must be finite and >= 0, got {kw['hold_time']}")
            if kw["target_range"] >= params.geometry.alpha_max:
                raise ValueError(f"target_range: {math.degrees(kw['target_range']):g} deg reaches the workspace limit "
                                 f"{math.degrees(params.geometry.alpha_max):g} deg")
        else:
            trajectory = scaled_trajectory(trajectory, params, _positive("duration_scale",
                                                                         options.get("duration_scale", 1.0)))
    if not isinstance(trajectory, str):
        _check_trajectory(trajectory, params)
        duration = _positive("time_limit", options.get("time_limit", trajectory.duration))
    live = options.get("live") or None
    if live is not None and live is not True and not callable(getattr(live, "write_batch", None)):
        raise ValueError(f"live: expected True or a neck_sim.live.LiveView, got {live!r}")
    if live is True:
        from neck_sim.live import LiveView
        live = LiveView(params)
    task = TrackingTask(params, trajectory, random=seed, observe_truth=options.get("observe_truth", False),
                        reward_tolerance=_positive("reward_tolerance", options.get("reward_tolerance", REWARD_TOLERANCE)),
                        reward_margin=_positive("reward_margin", options.get("reward_margin", REWARD_MARGIN)),
                        log_path=options.get("log_path"), live=live, **kw)
    env = NeckEnvironment(NeckPhysics.from_plant(plant), task, time_limit=duration)
    env._owns_live = options.get("live") is True
    return env
