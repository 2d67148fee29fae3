"""The simulated prototype: the MuJoCo neck of :mod:`neck_sim.mjcf` with tension-only elastic
cables (eq 54), geared motors with friction (eqs 29, 37), the optional effects of
:mod:`neck_sim.effects`, stepped at the control rate and read through the prototype's sensors.

Forces (sign convention of :mod:`neck_sim.analytic.cables`)
    Each motor is a slide s = (r_d/R) theta in cable-length units inside its cable's tendon, so
    the tendon length minus its rest length is the elongation x_c (plus the ``pretension``
    offset) and its rate is x_c_dot.  At every physics step a control callback sets, per cable,

    * tension t = :func:`neck_sim.analytic.cable_tension` (x_c, x_c_dot) (eq 54 solved for t,
      zero when slack, linear above ``cables.t_cap``) as the bias of actuator ``tension{j}``:
      force -t along the tendon, i.e. tau = Z t on the bars and -t on the motor;
    * motor friction (eq 37 plus the motor-side effects) as the bias of ``drive{j}``, whose gain
      applies the commanded force f:  I_a (R/r_d)^2 s_ddot = f - t - f_friction.

    Both biases are written in MuJoCo's *affine* form b0 + b2 * velocity with b2 the exact
    velocity derivative, so the implicit integrator treats cable damping and friction implicitly
    (a user-type bias would be explicit: with c_a = 50 N s/m on bars of 1e-5 kg m^2 that is
    unstable at dt = 5e-4 s).  Light damping runs on ``implicitfast``; stiff cables (up to the
    paper's c_a = 3000 N s/m) on ``discrete``, which solves the loop constraints in the same
    implicit metric (:func:`neck_sim.mjcf.integrator_for`; ``integrator=`` fixes one instead).

    The per-step state this writes into the model (``actuator_biasprm``) is explained once, at the
    top of ``neck_sim/native/plant_callback.c``.

The callback is the C file ``neck_sim/native/plant_callback.c``, compiled at first use by
:mod:`neck_sim.native` into a cache (``$NECK_SIM_CACHE`` or ``~/.cache/neck_sim``); when no
compiler is available the Python reference backend with the same physics takes over
(:func:`neck_sim.native.set_backend`), 6-8x slower per control period.  MuJoCo's callback is
process-global: :mod:`neck_sim.native.dispatch` dispatches it by model, and each plant keeps the
backend it was made with.

Stepping: :class:`neck_sim.batch.PlantBatch` runs control periods for K plants at once;
:meth:`Plant.step` is its K = 1 case (the plant's own batch), so there is one stepping path.  A
batch reads a plant through one public value, :attr:`Plant.native` (a
:class:`neck_sim.native.NativePlant`).

Rigid cables (the paper's rigid cable model, eq 25/32 with x_c = 0): ``Plant(...,
rigid_cables=True)`` holds each cable tendon at its rest length with an equality constraint
(bilateral, as in that model); tensions are then the constraint forces of the last sub-step.

Usage::

    from neck_sim.plant import Plant

    plant = Plant(seed=1)                   # default_params(3), no effects
    plant.reset(alpha0=[0.2, -0.1, 0.15])   # rad
    for _ in range(100):
        plant.step([25.0, 22.0, 20.0, 30.0])   # N, one control period
    theta, frame, truth = plant.encoders(), plant.camera_frame(), plant.truth()
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping, Set as AbstractSet
from typing import Any, NamedTuple, cast

import mujoco
import numpy as np
import numpy.typing as npt

from neck_sim.analytic.cables import motor_angles_rigid
from neck_sim.batch import PlantBatch, PlantDivergedError, clip_forces, delayed_controls, quantise, truth_columns
from neck_sim.effects import Effects
from neck_sim.effects.backlash import lead_step
from neck_sim.mjcf import DEFAULT_TIMESTEP, build_xml, model_index, pose_qpos
from neck_sim.native import (DISPATCH, FATAL_WARNINGS, MAX_CABLES, NativeBuildError, NativePlant, Outputs,
                             PlantStruct, StepState, get_backend, native_available, route_mujoco_warnings,
                             set_backend)
from neck_sim.params import NeckParams, default_params

# PlantBatch, PlantDivergedError, truth_columns, clip_forces, delayed_controls and the backend
# functions are defined in neck_sim.batch and neck_sim.native; they are named here too because
# code written against this module imports them from it.
__all__ = ["Plant", "Truth", "INTEGRATORS", "PlantBatch", "PlantDivergedError", "truth_columns", "clip_forces",
           "delayed_controls", "set_backend", "get_backend", "native_available", "NativeBuildError", "MAX_CABLES"]


class Truth(NamedTuple):
    """What only a simulation knows, at the current instant (SI units).

    alpha, alpha_dot (N,); theta, theta_dot (m,) motor-shaft angles (rad, rad/s); tension
    (m,) N; elongation (m,) m (x_c, positive = stretched), m = ``params.n_cables``; loop_gap: largest distance (m)
    between the two sides of a loop-closure ``connect``.
    """

    alpha: np.ndarray
    alpha_dot: np.ndarray
    theta: np.ndarray
    theta_dot: np.ndarray
    tension: np.ndarray
    elongation: np.ndarray
    loop_gap: float


#: MuJoCo integrators a plant may be fixed to: those that treat the cable damping (the velocity
#: derivative of the actuator biases) implicitly; ``euler`` would take it explicitly (unstable for
#: c_a = 50 N s/m on 20 g bars at dt = 0.5 ms) and ``rk4`` has no split mj_step1/mj_step2.
INTEGRATORS = ("implicitfast", "implicit", "discrete")


def _check_integrator(integrator) -> str:
    if not isinstance(integrator, str) or integrator not in INTEGRATORS:
        raise ValueError(f"integrator: expected None or one of {', '.join(map(repr, INTEGRATORS))} "
                         f"(integrators that treat the cable damping implicitly), got {integrator!r}")
    return integrator


def _with_integrator(xml: str, integrator: str) -> str:
    """The MJCF ``xml`` with its ``<option integrator=...>`` replaced (one definition of the model
    text: the plant's ``xml`` is what it compiled)."""
    out, count = re.subn(r'(<option\b[^>]*\bintegrator=")[a-z0-9]+(")', rf"\g<1>{integrator}\g<2>", xml, count=1)
    if count != 1:
        raise RuntimeError("plant: the MJCF has no <option integrator=...> to set")
    return out


class Plant:
    """The simulated neck.

    ``Plant(params=None, effects=None, seed=0, timestep=None, *, rigid_cables=False,
    backend=None, integrator=None)``: ``params`` are the plant's constants (default
    ``default_params(3)``), ``effects`` the hidden extra effects (off by default), ``seed`` seeds
    the camera noise, ``timestep`` the physics step (default
    :data:`neck_sim.mjcf.DEFAULT_TIMESTEP`; must divide the control period).  ``integrator``:
    None lets :func:`neck_sim.mjcf.integrator_for` choose from the cable damping c_a; one of
    :data:`INTEGRATORS` fixes MuJoCo's integrator whatever c_a is (a fit over c_a needs the
    simulated response continuous in c_a, so it chooses once per fit).
    """

    def __init__(self, params: NeckParams | None = None, effects: Effects | None = None, seed: int = 0,
                 timestep: float | None = None, *, rigid_cables: bool = False, backend: str | None = None,
                 integrator: str | None = None) -> None:
        self.params = default_params(3) if params is None else params
        if not isinstance(self.params, NeckParams):
            raise ValueError(f"params: expected NeckParams, got {type(self.params).__name__}")
        self.effects = Effects() if effects is None else effects
        if not isinstance(self.effects, Effects):
            raise ValueError(f"effects: expected neck_sim.effects.Effects, got {type(self.effects).__name__}")
        n, m = self.params.n_joints, self.params.n_cables      # NeckParams holds both <= MAX_CABLES
        self.true_params = self.effects.true_params(self.params)
        self.seed = int(seed)
        self.rigid_cables = bool(rigid_cables)
        self.integrator = integrator
        """The fixed MuJoCo integrator (one of :data:`INTEGRATORS`), or None: chosen from c_a."""
        route_mujoco_warnings()
        if self.rigid_cables:
            moot = [e.name for e in self.effects.active() if e.acts_on_cable_law]
            if moot:
                raise ValueError(f"effects {moot}: act on the cable elongation or tension law, which rigid "
                                 "cables do not have")
        if integrator is not None:
            _check_integrator(integrator)
        dt = DEFAULT_TIMESTEP if timestep is None else float(timestep)
        period = 1.0 / self.params.control.rate_hz
        nsub = int(round(period / dt)) if (math.isfinite(dt) and dt > 0) else 0
        if nsub < 1 or abs(nsub * dt - period) > 1e-9 * period:
            raise ValueError(f"control.rate_hz = {self.params.control.rate_hz:g} Hz: its period {period:.6g} s is "
                             f"not a whole number of physics steps of {dt:g} s (timestep"
                             f"{' default' if timestep is None else ''}); choose a rate that divides {1 / dt:g} Hz")
        self.timestep = dt
        self.period = period
        self.substeps = nsub
        self.xml = build_xml(self.true_params, timestep=dt, rigid_cables=self.rigid_cables)
        if integrator is not None:
            self.xml = _with_integrator(self.xml, integrator)
        self.model = mujoco.MjModel.from_xml_string(self.xml)
        self.data = mujoco.MjData(self.model)
        self._ix = ix = model_index(self.model)
        self._address = self.model._address
        self.model.dof_damping[ix.dof_motor] = 0.0      # the static stand-in for eq (37); the callback applies it

        act, tp = self.params.actuation, self.true_params
        self._ratio = act.R / act.r_d                      # theta = ratio * s
        self._res = self.params.sensors.encoder_resolution
        self._inv_res = 1.0 / self._res
        mujoco.mj_kinematics(self.model, self.data)
        mujoco.mj_comPos(self.model, self.data)
        mujoco.mj_tendon(self.model, self.data)
        self._rest = self.data.ten_length[ix.cable_tendon].copy()
        self._x_pre = self.effects.elongation_offset(m)
        # a dead band between motor (encoder) and drum: the motor's lead over the drum, rad
        band = self.effects.encoder_band(m) * self._ratio
        self._band = band if np.any(band > 0) else None
        self._lead = np.zeros(m)
        self._drum = np.zeros(m)
        motor_effects = self.effects.motor_effects()
        self._c = self._make_struct(tp, motor_effects)
        c = self._c
        view = np.ctypeslib.as_array
        outputs = Outputs(tension=view(c.tension)[:m], elongation=view(c.elongation)[:m], theta=view(c.theta)[:m],
                          theta_dot=view(c.theta_dot)[:m], alpha=view(c.alpha)[:n], alpha_dot=view(c.alpha_dot)[:n])
        self._out_tension, self._out_theta = outputs.tension, outputs.theta
        self._n1 = m
        if not np.array_equal(ix.drive_actuator, np.arange(m)):
            raise RuntimeError("model: the drive actuators must be the first m actuators (one per cable)")
        python_only = [e.name for e in motor_effects if e.native_fields(m) is None]
        if python_only and DISPATCH.choose(backend) == "native":
            raise ValueError(f"effects {python_only}: no native kernel (native_fields) for the C callback; "
                             "use Plant(..., backend='python')")
        self.native = NativePlant(
            model=self.model, data=self.data, struct=c, index=ix, params=self.params, true_params=tp,
            rigid_cables=self.rigid_cables, timestep=dt, period=period, substeps=nsub, f_max=act.f_max,
            delay=self.effects.command_delay(), camera_delay=self.effects.camera_lag(), ratio=self._ratio,
            rest=self._rest, x_pre=self._x_pre, motor_effects=tuple(motor_effects),
            fatal_warnings=tuple(self.data.warning[w] for w in FATAL_WARNINGS),    # live views, cheap to poll
            outputs=outputs, state=StepState(0, 1, 0, np.zeros((1, m)), None, np.random.default_rng(self.seed)))
        """What a :class:`neck_sim.batch.PlantBatch` steps: a :class:`neck_sim.native.NativePlant`."""
        DISPATCH.register(self.native, backend)
        self._solo: PlantBatch | None = None
        self.reset()

    # -- construction helpers
    def _make_struct(self, tp: NeckParams, motor_effects) -> PlantStruct:
        n1 = tp.n_cables
        ix = self._ix
        c = PlantStruct()
        c.ncable, c.rigid, c.njoint = n1, int(self.rigid_cables), tp.n_joints
        c.ratio, c.t_cap, c.res, c.inv_res = self._ratio, tp.cables.t_cap, self._res, self._inv_res

        def put(name, values):
            arr = getattr(c, name)
            for j, v in enumerate(np.broadcast_to(np.asarray(values), (n1,))):
                arr[j] = v

        put("tendon", ix.cable_tendon)
        put("dof", ix.dof_motor)
        put("qmotor", ix.qpos_motor)
        for name, vals in (("qA", ix.qpos_A), ("qD", ix.qpos_D), ("vA", ix.dof_A), ("vD", ix.dof_D),
                           ("site1", ix.loop_sites[:, 0]), ("site2", ix.loop_sites[:, 1])):
            arr = getattr(c, name)
            for i, v in enumerate(vals):
                arr[i] = int(v)
        put("act_drive", ix.drive_actuator)
        if self.rigid_cables:
            put("eq_rigid", ix.rigid_equality)
        put("act_tension", ix.tension_actuator)
        put("rest", self._rest)
        put("x_pre", self._x_pre)
        put("k", tp.cables.k)
        put("lam", tp.cables.lam)
        put("c_a", tp.cables.c_a)
        put("f_s", tp.friction.f_s)
        put("c_s", tp.friction.c_s)
        put("st_speed", 1.0)
        put("st_smooth", 1.0)
        put("pf_c", 1.0)
        for e in motor_effects:
            for name, values in (e.native_fields(n1) or {}).items():
                put(name, values)
        return c

    # -- public API
    @property
    def n_joints(self) -> int:
        return self.params.n_joints

    @property
    def time(self) -> float:
        """s since the last reset (the state a PlantBatch holds while it is open)."""
        return self._k * self.timestep

    @property
    def _k(self) -> int:
        """Physics sub-steps since the last reset."""
        state = self.native.state
        holder = state.holder()
        return state.k if holder is None else int(holder.k[state.row])


    @property
    def backend(self) -> str:
        """This plant's callback: "native" (C) or "python"."""
        return cast(str, DISPATCH.backend_of(self._address))     # registered for the plant's lifetime

    def reset(self, alpha0: npt.ArrayLike | None = None) -> None:
        """Put the neck at pose ``alpha0`` (N,) rad (default straight) at rest, motors at zero
        elongation (plus ``pretension``), time 0, camera noise reseeded."""
        n = self.n_joints
        a0 = np.zeros(n) if alpha0 is None else np.asarray(alpha0, dtype=float)
        if a0.shape != (n,):
            raise ValueError(f"alpha0: expected shape ({n},) (one angle per X-joint), got {a0.shape}")
        if not np.all(np.isfinite(a0)):
            raise ValueError("alpha0: contains NaN or infinity")
        amax = self.params.geometry.alpha_max
        if np.any(np.abs(a0) >= amax):
            raise ValueError(f"alpha0: {np.degrees(a0).round(2).tolist()} deg outside the joint range "
                             f"(|alpha| < {math.degrees(amax):g} deg)")
        m, d, ix = self.model, self.data, self._ix
        mujoco.mj_resetData(m, d)
        pq = pose_qpos(a0, self.params)
        d.qpos[ix.qpos_A], d.qpos[ix.qpos_B], d.qpos[ix.qpos_D] = pq.q_A, pq.q_B, pq.q_D
        d.qpos[ix.qpos_helper] = pq.q_helper
        d.qpos[ix.qpos_motor] = motor_angles_rigid(a0, self.params) / self._ratio
        for e in self.effects.active():
            e.setup_mujoco(m, d, ix)
        self.native.reset_state(self.seed)
        self._solo = None                                 # this plant's own batch, opened at its first step
        previous = DISPATCH.enter(self.backend)
        try:
            mujoco.mj_step1(m, d)
        finally:
            DISPATCH.leave(previous)
        self._lead = np.zeros(self._n1)                   # encoders zeroed in the middle of the band
        self._drum = self._out_theta.copy()

    def checked_forces(self, forces: Any) -> list[float]:
        """Commanded forces (m,) N as a list of floats clipped to [0, f_max] N, as :meth:`step` applies
        them; wrong shapes, non-numbers, NaN or infinity raise a one-line ValueError."""
        n1 = self._n1
        try:
            if isinstance(forces, (Mapping, AbstractSet, str, bytes)):   # iterating would read keys, not forces
                raise TypeError
            vals = [float(v) for v in forces]
        except (TypeError, ValueError):
            raise ValueError(f"forces: expected {n1} numbers (one per cable), got {np.shape(forces)} "
                             f"{type(forces).__name__}") from None
        if len(vals) != n1:
            raise ValueError(f"forces: expected shape ({n1},) (one per cable), got ({len(vals)},)")
        fmax = self.native.f_max
        out = []
        for v in vals:
            if not math.isfinite(v):
                raise ValueError(f"forces: contains NaN or infinity: {vals}")
            out.append(0.0 if v < 0.0 else (fmax if v > fmax else v))
        return out

    def step(self, forces: npt.ArrayLike) -> None:
        """Apply commanded cable forces (m,) N (clipped to [0, f_max]) for one control period."""
        solo, holder = self._solo, self.native.state.holder()
        if holder is None or holder is not solo:
            if holder is not None:
                raise RuntimeError("plant: it is stepping in an open PlantBatch; step the batch (or close it) instead")
            solo = self._solo = PlantBatch([self.native], yields=True)
        solo.forces[0] = self.checked_forces(forces)
        if solo.step_checked():
            raise solo.diverged(0)
        if self._band is not None:
            self._lead = lead_step(self._lead, self._out_theta - self._drum, self._band)
            self._drum = self._out_theta.copy()

    def encoders(self) -> np.ndarray:
        """Motor angles theta (m,) rad, quantised to the encoder resolution (nearest count); with a
        dead band (``backlash``) the motor leads the drum the cable winds on."""
        theta = self._out_theta if self._band is None else self._out_theta + self._lead
        return quantise(theta, self._inv_res, self._res, np.empty(self._n1))

    @property
    def steps_alone(self) -> bool:
        """This plant must step through its own :meth:`step` (a dead band keeps state between
        periods that the compiled batch does not)."""
        return self._band is not None

    def camera_frame(self) -> tuple[float, np.ndarray] | None:
        """(t, alpha (N,)) of the camera frame taken during the last step (30 Hz, Gaussian noise
        of ``sensors.camera_noise`` per joint, seeded), or None."""
        state = self.native.state
        holder = state.holder()
        return state.frame if holder is None else holder.frames[state.row]

    def truth(self) -> Truth:
        """Simulation truth at the current instant (computed by the callback after each period)."""
        out = self.native.outputs
        return Truth(out.alpha.copy(), out.alpha_dot.copy(), out.theta.copy(), out.theta_dot.copy(),
                     out.tension.copy(), out.elongation.copy(), self._c.loop_gap)

    def __repr__(self) -> str:
        return (f"Plant(n_joints={self.n_joints}, effects={self.effects.names()}, timestep={self.timestep}, "
                f"rigid_cables={self.rigid_cables}, backend={self.backend!r})")
