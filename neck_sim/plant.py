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
    implicit metric (:func:`neck_sim.mjcf.integrator_for`).

    The per-step state this writes into the model (``actuator_biasprm``) is explained once, at the
    top of ``neck_sim/native/plant_callback.c``.

Callbacks are process-global in MuJoCo.  The callback is registered once and dispatches by
``mjModel`` address: models that belong to no live :class:`Plant` are left untouched (a plain
MuJoCo model keeps working), and each plant sees only its own parameters.  Each plant keeps the
backend it was made with: a Python-backend plant in the process leaves native plants
bit-identical.  The callback is the C
file ``neck_sim/native/plant_callback.c``, compiled at first use by :mod:`neck_sim.native` into a
cache (``$NECK_SIM_CACHE`` or ``~/.cache/neck_sim``); when no compiler is available a pure-Python
callback with the same physics takes over (``set_backend``), 6-8x slower per control period.

Stepping: a control period (1/``control.rate_hz``) is ``mj_step2`` + ``mj_step`` x (n-1) +
``mj_step1``, so that after every period the position/velocity stages (tendon lengths, loop gaps,
tensions) describe the current state; ``ctrl`` is set before each sub-step to the command then in
force (actuation delay) and the joint angles are read where a camera frame is due.
:class:`PlantBatch` runs such periods for K plants at once, with the native callback in one C
call (``neck_step_batch``, which calls MuJoCo's ``mj_step*`` from C); :meth:`Plant.step` is its
K = 1 case, so there is one stepping path.

Rigid cables (the paper's rigid cable model, eq 25/32 with x_c = 0): ``Plant(...,
rigid_cables=True)`` holds each cable tendon at its rest length with an equality constraint
(bilateral, as in that model); tensions are then the constraint forces of the last sub-step.
"""

from __future__ import annotations

import ctypes
import logging
import math
import os
import re
import warnings
import weakref
from collections.abc import Mapping, Set as AbstractSet
from typing import NamedTuple

import mujoco
import numpy as np

from neck_sim.analytic.cables import motor_angles_rigid
from neck_sim.analytic.dynamics import cable_tension, cap_elongation, motor_friction
from neck_sim import native
from neck_sim.effects import Effects
from neck_sim.effects.backlash import lead_step
from neck_sim.jit import kernel
from neck_sim.mjcf import DEFAULT_TIMESTEP, build_xml, model_index, pose_qpos
from neck_sim.native import MAX_CABLES, NativeBuildError, PlantStruct
from neck_sim.params import NeckParams, default_params

__all__ = ["Plant", "PlantBatch", "INTEGRATORS", "truth_columns", "clip_forces", "Truth", "PlantDivergedError", "set_backend", "get_backend",
           "native_available", "NativeBuildError", "MAX_CABLES"]


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


class PlantDivergedError(RuntimeError):
    """The simulation blew up: MuJoCo saw a singular inertia or a NaN/huge state (and may have reset it)."""


_MUJOCO_LOG = logging.getLogger("neck_sim.mujoco")
# Texts of MuJoCo's warnings after which the plant raises PlantDivergedError (which quotes them):
# logged at DEBUG only, so a diverging candidate model does not flood the terminal.
_FATAL_TEXTS = ("Nan, Inf or huge value", "Inertia matrix is too close to singular")
_last_mujoco_warning = ""


def _mujoco_warning(message: str) -> None:
    # MuJoCo's default prints to stdout and appends to ./MUJOCO_LOG.TXT; a library should log.
    global _last_mujoco_warning
    _last_mujoco_warning = message.strip()
    level = logging.DEBUG if _last_mujoco_warning.startswith(_FATAL_TEXTS) else logging.WARNING
    _MUJOCO_LOG.log(level, "MuJoCo: %s", _last_mujoco_warning)


def _route_mujoco_warnings() -> None:
    """Send MuJoCo's warnings to the ``neck_sim.mujoco`` logger unless someone installed a handler."""
    if mujoco.get_mju_user_warning() is None:
        mujoco.set_mju_user_warning(_mujoco_warning)


class _Dispatch:
    """Process-wide owner of MuJoCo's mjcb_control: the default backend and the plants.

    Each plant keeps the backend it was made with, so a Python-backend plant alive in the process
    changes nothing for native plants (their results stay bit-identical).  Native: the C callback
    stays installed; it looks the model up among the registered plants and returns at once for any
    other model (a plain model keeps working).  Python: a Python mjcb_control breaks compiling any
    model (MuJoCo runs it on a temporary mjData), so it is installed only while a Python-backend
    plant steps (``enter``/``leave``, which put back whatever callback was installed before).
    """

    def __init__(self):
        self.lib: ctypes.CDLL | None = None
        self.native_error: str | None = None
        self.backend: str | None = None           # the default of plants made without a backend
        self.native_cb = None                     # the C callback object handed to set_mjcb_control
        self.plants: dict[int, weakref.ref] = {}  # model address -> plant

    def native(self) -> ctypes.CDLL | None:
        if self.lib is None and self.native_error is None:
            try:
                self.lib = native.build()
                self.native_cb = self.lib.neck_control
            except NativeBuildError as exc:
                self.native_error = str(exc)
        return self.lib

    def choose(self, backend: str | None) -> str:
        if backend is None:
            backend = self.backend or os.environ.get("NECK_SIM_CALLBACK", "auto")
        if backend not in ("auto", "native", "python"):
            raise ValueError(f"backend: expected 'auto', 'native' or 'python', got {backend!r}")
        if backend in ("auto", "native") and self.native() is None:
            if backend == "native":
                raise NativeBuildError(self.native_error)
            warnings.warn(f"neck_sim.plant: native callback unavailable ({self.native_error}); "
                          "using the slower Python callback", RuntimeWarning, stacklevel=3)
            backend = "python"
        return "native" if backend == "auto" else backend

    def set_backend(self, backend: str) -> str:
        """The default for new plants; live plants are moved to it."""
        chosen = self.choose(backend)
        self.backend = chosen
        for p in [p for ref in list(self.plants.values()) if (p := ref()) is not None]:
            if p._backend != chosen:
                self._unregister_raw(p._address, p._backend)
                p._backend = chosen
                self._register_raw(p)
        return chosen

    def _callback(self, backend: str):
        return self.native_cb if backend == "native" else _python_control

    @staticmethod
    def _refuse(current) -> None:
        raise RuntimeError("the process-global MuJoCo control callback (mjcb_control) is set to "
                           f"{current!r}; neck_sim plants need it: call mujoco.set_mjcb_control(None) first")

    def enter(self, backend: str):
        """Before a plant of ``backend`` steps: make its callback the installed one; returns what
        ``leave`` restores (the native callback stays installed once there)."""
        want = self._callback(backend)
        current = mujoco.get_mjcb_control()
        if current is want:
            return current
        if current is not None and current is not self.native_cb and current is not _python_control:
            self._refuse(current)
        mujoco.set_mjcb_control(want)
        return want if current is None and backend == "native" else current

    def leave(self, previous) -> None:
        if mujoco.get_mjcb_control() is not previous:
            mujoco.set_mjcb_control(previous)

    def _register_raw(self, plant: "Plant") -> None:
        if plant._backend == "native":
            if self.lib.neck_register(plant._address, ctypes.byref(plant._c)) < 0:
                raise RuntimeError("too many live plants in this process (256)")

    def _unregister_raw(self, address: int, backend: str | None) -> None:
        if backend == "native" and self.lib is not None:
            self.lib.neck_unregister(address)

    def register(self, plant: "Plant", backend: str | None) -> None:
        plant._backend = self.choose(backend)
        if self.backend is None:
            self.backend = plant._backend
        self.plants[plant._address] = weakref.ref(plant)
        self._register_raw(plant)

    def unregister(self, address: int, backend: str | None) -> None:
        self.plants.pop(address, None)
        self._unregister_raw(address, backend)


_DISPATCH = _Dispatch()


def _finalize(address: int, _keepalive, backend_cell) -> None:
    _DISPATCH.unregister(address, backend_cell[0])


def _python_control(m, d) -> None:
    ref = _DISPATCH.plants.get(m._address)
    plant = ref() if ref is not None else None
    if plant is not None and plant.model is m and plant._backend == "python":
        plant._python_forces()


def set_backend(backend: str) -> str:
    """Choose the default callback of plants: ``"native"`` (C), ``"python"`` or ``"auto"``.

    Live plants are moved to the new backend.  Returns the backend in use.  A plant made with an
    explicit ``backend=`` keeps it and changes nothing for the others.
    """
    return _DISPATCH.set_backend(backend)


def get_backend() -> str | None:
    """The default backend of plants (None before the first plant or ``set_backend``)."""
    return _DISPATCH.backend


def native_available() -> bool:
    """True when the C callback compiles and loads on this machine."""
    return _DISPATCH.native() is not None


# ----------------------------------------------------------------------------------------- plant

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


# Warnings after which MuJoCo's state is no longer a valid neck (it resets itself on some of them).
_FATAL_WARNINGS = tuple(int(getattr(mujoco.mjtWarning, w)) for w in
                        ("mjWARN_INERTIA", "mjWARN_BADQPOS", "mjWARN_BADQVEL", "mjWARN_BADQACC"))


class Plant:
    """The simulated neck (interfaces.md, ``neck_sim.plant``).

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
                 integrator: str | None = None):
        self.params = default_params(3) if params is None else params
        if not isinstance(self.params, NeckParams):
            raise ValueError(f"params: expected NeckParams, got {type(self.params).__name__}")
        self.effects = Effects() if effects is None else effects
        if not isinstance(self.effects, Effects):
            raise ValueError(f"effects: expected neck_sim.effects.Effects, got {type(self.effects).__name__}")
        n, m = self.params.n_joints, self.params.n_cables
        if max(n, m) > MAX_CABLES:
            raise ValueError(f"params: at most {MAX_CABLES} joints and {MAX_CABLES} cables supported, "
                             f"got {n} and {m}")
        self.true_params = self.effects.true_params(self.params)
        self.seed = int(seed)
        self.rigid_cables = bool(rigid_cables)
        _route_mujoco_warnings()
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
        self._fatal_warnings = tuple(self.data.warning[w] for w in _FATAL_WARNINGS)   # live views, cheap to poll
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
        self._motor_effects = self.effects.motor_effects()
        self._c = self._make_struct(tp)
        self._out_tension = np.ctypeslib.as_array(self._c.tension)[:m]
        self._out_elong = np.ctypeslib.as_array(self._c.elongation)[:m]
        self._out_theta = np.ctypeslib.as_array(self._c.theta)[:m]
        self._out_theta_dot = np.ctypeslib.as_array(self._c.theta_dot)[:m]
        self._out_alpha = np.ctypeslib.as_array(self._c.alpha)[:n]
        self._out_alpha_dot = np.ctypeslib.as_array(self._c.alpha_dot)[:n]
        self._delay = self.effects.command_delay()
        self._camera_delay = self.effects.camera_lag()    # a frame stamped t shows the neck at t - delay
        self._n1 = m
        if not np.array_equal(ix.drive_actuator, np.arange(m)):
            raise RuntimeError("model: the drive actuators must be the first m actuators (one per cable)")
        self._fmax = act.f_max
        python_only = [e.name for e in self._motor_effects if e.native_fields(m) is None]
        if python_only and _DISPATCH.choose(backend) == "native":
            raise ValueError(f"effects {python_only}: no native kernel (native_fields) for the C callback; "
                             "use Plant(..., backend='python')")
        self._backend_cell = [None]             # shared with the finalizer, which must not hold the plant
        _DISPATCH.register(self, backend)
        self._finalizer = weakref.finalize(self, _finalize, self._address, self._c, self._backend_cell)
        self.reset()

    # -- construction helpers
    def _make_struct(self, tp: NeckParams) -> PlantStruct:
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
        for e in self._motor_effects:
            for name, values in (e.native_fields(n1) or {}).items():
                put(name, values)
        return c

    # -- the Python backend: same physics from the definitions in analytic/ and effects
    def _friction(self, theta_dot, tension):
        f = motor_friction(theta_dot, self.true_params)
        for eff in self._motor_effects:
            f = f + eff.motor_force(theta_dot, tension)
        return f

    def _python_forces(self) -> None:
        m, d, ix = self.model, self.data, self._ix
        tp = self.true_params
        x = d.ten_length[ix.cable_tendon] - self._rest + self._x_pre
        xd = d.ten_velocity[ix.cable_tendon].copy()
        bias = m.actuator_biasprm
        if self.rigid_cables:
            t = np.zeros_like(x)
        else:
            t = cable_tension(x, xd, tp)
            # d t / d x_dot of eq (54) on its taut branch (a finite difference would halve it at
            # the slack/taut kink, where the C callback takes the taut branch)
            cab = tp.cables
            k, lam = np.asarray(cab.k), np.asarray(cab.lam)
            xs = cap_elongation(k, lam, cab.t_cap)
            dt = np.where((x > 0) & (t > 0), np.asarray(cab.c_a) / (1.0 - lam * np.minimum(x, xs)), 0.0)
            bias[ix.tension_actuator, 0] = -t + dt * xd
            bias[ix.tension_actuator, 1] = 0.0
            bias[ix.tension_actuator, 2] = -dt
        self._out_tension[:] = t
        self._out_elong[:] = x
        sd = d.qvel[ix.dof_motor]
        w = self._ratio * sd
        hw = 1e-6
        fr = self._friction(w, t)
        dfr = (self._friction(w + hw, t) - self._friction(w - hw, t)) / (2 * hw)
        bias[ix.drive_actuator, 0] = -fr + dfr * self._ratio * sd
        bias[ix.drive_actuator, 1] = 0.0
        bias[ix.drive_actuator, 2] = -dfr * self._ratio
        self._out_theta[:] = self._ratio * d.qpos[ix.qpos_motor]
        self._out_theta_dot[:] = w
        self._out_alpha[:] = d.qpos[ix.qpos_A] + d.qpos[ix.qpos_D]
        self._out_alpha_dot[:] = d.qvel[ix.dof_A] + d.qvel[ix.dof_D]
        gaps = d.site_xpos[ix.loop_sites[:, 0]] - d.site_xpos[ix.loop_sites[:, 1]]
        self._c.loop_gap = float(np.sqrt((gaps * gaps).sum(axis=1)).max())
        self._c.calls += 1

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
        if self._batch is None:
            return int(self._solo.k[0])
        return int(self._batch.k[self._batch.plants.index(self)])

    @property
    def integrator(self) -> str:
        """MuJoCo's integrator of this plant, as the compiled model has it: ``implicitfast``,
        ``implicit`` or ``discrete``."""
        return mujoco.mjtIntegrator(self.model.opt.integrator).name.removeprefix("mjINT_").lower()

    @property
    def backend(self) -> str:
        """This plant's callback: "native" (C) or "python"."""
        return self._backend_cell[0]

    @property
    def _backend(self) -> str:
        return self._backend_cell[0]

    @_backend.setter
    def _backend(self, value: str) -> None:
        self._backend_cell[0] = value

    def reset(self, alpha0=None) -> None:
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
        self._rng = np.random.default_rng(self.seed)
        self._batch = None
        self._solo = PlantBatch([self], fresh=True)       # this plant's stepping state
        previous = _DISPATCH.enter(self._backend)
        try:
            mujoco.mj_step1(m, d)
        finally:
            _DISPATCH.leave(previous)
        self._lead = np.zeros(self._n1)                   # encoders zeroed in the middle of the band
        self._drum = self._out_theta.copy()

    def _check_forces(self, forces) -> list:
        """Commanded forces as a list of floats clipped to [0, f_max]; bad input raises ValueError."""
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
        fmax = self._fmax
        out = []
        for v in vals:
            if not math.isfinite(v):
                raise ValueError(f"forces: contains NaN or infinity: {vals}")
            out.append(0.0 if v < 0.0 else (fmax if v > fmax else v))
        return out

    def step(self, forces) -> None:
        """Apply commanded cable forces (m,) N (clipped to [0, f_max]) for one control period."""
        if self._batch is not None:
            raise RuntimeError("plant: it is stepping in an open PlantBatch; step the batch (or close it) instead")
        solo = self._solo
        solo.forces[0] = self._check_forces(forces)
        if solo.step_checked():
            raise solo.diverged(0)
        if self._band is not None:
            self._lead = lead_step(self._lead, self._out_theta - self._drum, self._band)
            self._drum = self._out_theta.copy()

    def _camera_step(self, k: int) -> int:
        """Sub-step index at whose end camera frame k (due at k / camera_rate_hz) is taken."""
        return math.ceil((k / self.params.sensors.camera_rate_hz - self._camera_delay) / self.timestep - 1e-6)

    def _constraint_tensions(self) -> np.ndarray:
        d, ix = self.data, self._ix
        out = np.zeros(self._n1)
        rows = np.nonzero(d.efc_type[: d.nefc] == mujoco.mjtConstraint.mjCNSTR_EQUALITY)[0]
        ids = d.efc_id[rows]
        for j, eq in enumerate(ix.rigid_equality):
            sel = rows[ids == eq]
            if sel.size:
                out[j] = -d.efc_force[sel[0]]
        return out

    def encoders(self) -> np.ndarray:
        """Motor angles theta (m,) rad, quantised to the encoder resolution (nearest count); with a
        dead band (``backlash``) the motor leads the drum the cable winds on."""
        theta = self._out_theta if self._band is None else self._out_theta + self._lead
        return _quantise(theta, self._inv_res, self._res, np.empty(self._n1))

    @property
    def steps_alone(self) -> bool:
        """This plant must step through its own :meth:`step` (a dead band keeps state between
        periods that the compiled batch does not)."""
        return self._band is not None

    def camera_frame(self):
        """(t, alpha (N,)) of the camera frame taken during the last step (30 Hz, Gaussian noise
        of ``sensors.camera_noise`` per joint, seeded), or None."""
        return self._solo.frames[0]

    def truth(self) -> Truth:
        """Simulation truth at the current instant (computed by the callback after each period)."""
        return Truth(self._out_alpha.copy(), self._out_alpha_dot.copy(), self._out_theta.copy(),
                     self._out_theta_dot.copy(), self._out_tension.copy(), self._out_elong.copy(), self._c.loop_gap)

    def __repr__(self) -> str:
        return (f"Plant(n_joints={self.n_joints}, effects={self.effects.names()}, timestep={self.timestep}, "
                f"rigid_cables={self.rigid_cables}, backend={self.backend!r})")


# ----------------------------------------------------------------------------------------- batch

def _quantise(theta: np.ndarray, inv_res, res, out: np.ndarray) -> np.ndarray:
    """Encoder reading of motor angles theta (rad): the nearest count of resolution ``res`` (rad), into ``out``."""
    np.multiply(theta, inv_res, out=out)
    return np.multiply(np.rint(out, out=out), res, out=out)


@kernel
def clip_forces(requested, fmax, out) -> None:
    """out (K, m) N: ``requested`` (K, m) N clipped to [0, f_max] with f_max (K, 1) N per plant, as
    ``np.minimum(np.maximum(requested, 0), fmax)`` (a -0.0 becomes 0.0); rows must be finite."""
    K, m = out.shape
    for r in range(K):
        for c in range(m):
            f = requested[r, c]
            f = f if f > 0.0 else 0.0
            out[r, c] = f if f < fmax[r, 0] else fmax[r, 0]


@kernel
def delayed_controls(k, forces, hist, R, delay, dt, period, ctrl) -> None:
    """ctrl (K, n_sub, m) N: the command in force at each sub-step of the period that starts at
    sub-step k (K,), for commands ``forces`` (K, m) N issued now and actuation delays ``delay`` (K,)
    s (sub-step dt, control period ``period``, s).  The command of period p is issued at p T and
    acts from p T + delay; before the first one takes effect the delay line holds the first
    command.  hist (K, R_max, m): each plant's ring buffer of commands (period q's at q % R (K,),
    enough for every period a delay reaches back to); this period's forces are written into it.
    """
    K, nsub, m = ctrl.shape
    for r in range(K):
        cur = k[r] // nsub
        q = cur % R[r]
        for c in range(m):
            hist[r, q, c] = forces[r, c]
        for s in range(nsub):
            row = q
            if delay[r] > 0.0:
                p = math.floor(((k[r] + s) * dt - delay[r]) / period + 1e-9)
                row = min(cur, max(0, p)) % R[r]
            for c in range(m):
                ctrl[r, s, c] = hist[r, row, c]


def truth_columns(n: int, m: int) -> dict[str, slice]:
    """Columns of :attr:`PlantBatch.out` (width 3m + 2n + 1) for N = n joints and m cables; the C
    function ``neck_step_batch`` writes the same layout."""
    widths = (("theta", m), ("alpha", n), ("alpha_dot", n), ("tension", m), ("elongation", m), ("loop_gap", 1))
    out, start = {}, 0
    for name, width in widths:
        out[name] = slice(start, start + width)
        start += width
    return out


class PlantBatch:
    """K plants advanced together one control period at a time: the plant's one stepping path
    (:meth:`Plant.step` is the K = 1 case, on the plant's own batch).

    ``PlantBatch(plants)`` takes over the plants' stepping state (sub-step counter, camera
    schedule, actuation-delay line) until :meth:`close` (or the end of a ``with`` block) hands it
    back; meanwhile the plants cannot step alone.  The plants are distinct :class:`Plant` objects
    with the same N, m, timestep and control period.

    ``step(forces)`` runs one period, forces (K, m) N: each row is clipped to [0, f_max] (a row
    with NaN or infinity stops that plant with ValueError), the delayed commands in force at each
    sub-step and the camera frames due are worked out for all K, and each plant runs
    ``mj_step2`` + ``mj_step`` x (n_sub - 1) + ``mj_step1`` with ``ctrl`` set per sub-step and its
    joint angles copied where a frame is due: for all K in one C call (native backend,
    ``neck_step_batch``) or in Python (Python backend).  Then

    * ``out`` (K, 3m + 2N + 1): theta (m,) rad, alpha, alpha_dot (N,), tension (m,) N, elongation
      (m,) m, loop_gap m of each plant (its :meth:`Plant.truth`); ``encoders()`` (K, m) rad;
    * ``frames[i]``: the last camera frame (t, alpha (N,)) of the period, or None;
    * a plant whose simulation diverged is stopped, its PlantDivergedError in ``errors[i]``.
    """

    def __init__(self, plants, *, fresh: bool = False):
        plants = list(plants)
        if not plants or not all(isinstance(p, Plant) for p in plants):
            raise ValueError("PlantBatch: expected one or more neck_sim.plant.Plant objects")
        if len({id(p) for p in plants}) != len(plants):
            raise ValueError("PlantBatch: the same plant twice (each run needs its own plant)")
        p0 = plants[0]
        for i, p in enumerate(plants):
            if (p.substeps, p.timestep, p.n_joints, p._n1) != (p0.substeps, p0.timestep, p0.n_joints, p0._n1):
                raise ValueError(f"PlantBatch: plant {i} has (sub-steps, timestep, N, m) = "
                                 f"{(p.substeps, p.timestep, p.n_joints, p._n1)}, plant 0 "
                                 f"{(p0.substeps, p0.timestep, p0.n_joints, p0._n1)}")
            if not fresh and p._batch is not None:
                raise ValueError(f"PlantBatch: plant {i} is already in an open batch")
            if p._backend != p0._backend:
                raise ValueError(f"PlantBatch: plant {i} runs on the {p._backend} backend, plant 0 on the "
                                 f"{p0._backend} one; a batch steps with one callback")
        K, n, m, nsub = len(plants), p0.n_joints, p0._n1, p0.substeps
        # a plant's own batch refers to it weakly: no reference cycle, so a dropped plant leaves the
        # C registry at once (not at the next cyclic garbage collection)
        self.plants = [weakref.proxy(p) for p in plants] if fresh else plants
        self.K, self.n, self.m, self.nsub = K, n, m, nsub
        self.dt, self.period = p0.timestep, p0.period
        col = lambda values: np.array(values, dtype=float)[:, None]   # noqa: E731  (K, 1) for broadcasting
        self._fmax = col([p._fmax for p in plants])
        self._delay = np.array([p._delay for p in plants], dtype=float)
        self._delayed = np.flatnonzero(self._delay > 0.0)
        # ring buffer of commands: period q's at q % R, enough for every period a delay reaches back to
        self._R = np.array([int(math.ceil(d / self.period)) + 2 if d > 0 else 1 for d in self._delay])
        self.hist = np.zeros((K, int(self._R.max()), m))
        if fresh:
            self.k = np.zeros(K, dtype=np.int64)
            self.frame_index = np.ones(K, dtype=np.int64)     # camera frame j is due at j / camera_rate_hz
            self.next_cam = np.array([p._camera_step(1) for p in plants], dtype=np.int64)
            self.frames: list = [None] * K
        else:
            solos = [p._solo for p in plants]
            self.k = np.array([s.k[0] for s in solos], dtype=np.int64)
            self.frame_index = np.array([s.frame_index[0] for s in solos], dtype=np.int64)
            self.next_cam = np.array([s.next_cam[0] for s in solos], dtype=np.int64)
            self.frames = [s.frames[0] for s in solos]
            for i, s in enumerate(solos):
                self.hist[i, : self._R[i]] = s.hist[0]
            for p in plants:
                p._batch = self
        self._framed = any(f is not None for f in self.frames)
        self.forces = np.zeros((K, m))
        self.ctrl = np.zeros((K, nsub, m))
        self.capture = np.zeros((K, nsub), dtype=np.int32)
        self.frame_alpha = np.zeros((K, nsub, n))
        self._cols = truth_columns(n, m)
        self.out = np.zeros((K, self._cols["loop_gap"].stop))
        self.fatal = np.zeros(K, dtype=np.int32)
        self._encoders = np.zeros((K, m))
        self.active = np.ones(K, dtype=np.uint8)
        self.errors: list = [None] * K
        for i, p in enumerate(plants):
            self._copy_outputs(i)
        ptrs = lambda values: (ctypes.c_void_p * K)(*values)   # noqa: E731
        self._c_args = (K, ptrs([ctypes.addressof(p._c) for p in plants]), ptrs([p.model._address for p in plants]),
                        ptrs([p.data._address for p in plants]), self.active.ctypes.data, nsub, m, n)
        self._c_out = (self.frame_alpha.ctypes.data, self.k.ctypes.data, self.out.ctypes.data,
                       self._encoders.ctypes.data, self.fatal.ctypes.data)
        self._c_forces, self._c_ctrl = self.forces.ctypes.data, self.ctrl.ctypes.data
        self._c_capture = self.capture.ctypes.data
        self._cam_lead = self._camera_lead()

    # -- state
    @property
    def time(self) -> np.ndarray:
        """(K,) s since each plant's reset."""
        return self.k * self.dt

    def encoders(self) -> np.ndarray:
        """Motor angles theta (K, m) rad, quantised to each plant's encoder resolution (nearest count);
        a buffer the next step overwrites."""
        return self._encoders

    def stop(self, i: int, error: BaseException) -> None:
        """Plant i steps no more; ``errors[i]`` says why."""
        self.errors[i] = error
        self.active[i] = 0
        self.fatal[i] = 0

    def close(self) -> None:
        """Hand the stepping state back to the plants (they can step alone again)."""
        for i, p in enumerate(self.plants):
            if p._batch is not self:
                continue
            solo = p._solo
            solo.k[0], solo.frame_index[0], solo.next_cam[0] = self.k[i], self.frame_index[i], self.next_cam[i]
            solo.hist[0] = self.hist[i, : self._R[i]]
            solo.frames[0] = self.frames[i]
            solo._framed = True
            solo._cam_lead = solo._camera_lead()
            p._batch = None

    def __enter__(self) -> "PlantBatch":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # -- stepping
    def step(self, forces) -> list:
        """One control period for the active plants (forces (K, m) N); returns the indices of the
        plants stopped in it (bad forces, diverged simulation), whose errors are in ``errors``."""
        try:
            f = forces if type(forces) is np.ndarray and forces.dtype == np.float64 else np.asarray(forces, dtype=float)
        except (TypeError, ValueError):
            f = None
        if f is None or f.shape != (self.K, self.m):
            raise ValueError(f"forces: expected shape ({self.K}, {self.m}) (one row of cable forces per plant), "
                             f"got {np.shape(forces)}")
        stopped = []
        if not math.isfinite(f.sum()):              # one reduction; the rows only when something is off
            ok = np.isfinite(f).all(axis=1)
            for i in np.flatnonzero(~ok & (self.active > 0)):
                self.stop(i, ValueError(f"forces: contains NaN or infinity: {f[i].tolist()}"))
                stopped.append(int(i))
            f = np.where(ok[:, None], f, 0.0)
        clip_forces(f, self._fmax, self.forces)
        if self.step_checked():
            stopped += self.stop_diverged()
        return stopped

    def stop_diverged(self) -> list:
        """Stop the active plants whose ``fatal`` is set (their simulation diverged in the period
        just run); returns their indices."""
        stopped = [int(i) for i in np.flatnonzero(self.fatal * self.active)]
        for i in stopped:
            self.stop(i, self.diverged(i))
        return stopped

    # -- periods stepped by a compiled caller (controllers.closed_loop runs the periods between
    #    events in one numba kernel that calls neck_step_batch itself)
    def quiet_periods(self) -> int:
        """How many control periods from now need none of :meth:`step_checked`'s Python: native
        backend, no camera frame due (the delay line is :func:`delayed_controls`, a kernel).
        The caller steps them through :meth:`native_step` and then calls :meth:`ran_periods`."""
        if not self._native:
            return 0
        return max(0, (self._cam_lead - 1) // self.nsub)     # periods whose _cam_lead stays > nsub

    def native_step(self) -> tuple:
        """(address of ``neck_step_batch``, its arguments) for one period with no camera capture,
        commanding ``self.forces`` or, with an actuation delay, ``self.ctrl`` (which the caller fills
        with :func:`delayed_controls`): pointers as integers, C ints as np.int32.  The address is 0
        off the native backend (where :meth:`quiet_periods` is 0)."""
        K, plants, models, datas, active, nsub, m, n = self._c_args
        i32, addr = np.int32, ctypes.addressof
        per_substep = self._delayed.size > 0
        args = (i32(K), addr(plants), addr(models), addr(datas), int(active), i32(nsub), i32(m), i32(n),
                int(self._c_ctrl if per_substep else self._c_forces), i32(per_substep), 0,
                *(int(a) for a in self._c_out))
        native = self._native
        return ctypes.cast(_DISPATCH.lib.step_batch, ctypes.c_void_p).value if native else 0, args

    def delay_line(self) -> tuple:
        """The arguments of :func:`delayed_controls` but the forces (needed when some delay > 0)."""
        return self.k, self.hist, self._R, self._delay, self.dt, self.period, self.ctrl

    def ran_periods(self, count: int) -> None:
        """Bookkeeping of :meth:`step_checked` after ``count`` periods stepped through
        :meth:`native_step` (at most :meth:`quiet_periods`)."""
        if count > 0 and self._framed:
            self.frames = [None] * self.K
            self._framed = False
        self._cam_lead -= count * self.nsub

    def step_checked(self) -> int:
        """One control period with ``self.forces`` (K, m) already clipped; returns how many plants
        have ``fatal`` set (their simulation diverged)."""
        nsub, k0 = self.nsub, self.k
        per_substep = self._delayed.size > 0
        if per_substep:
            delayed_controls(k0, self.forces, self.hist, self._R, self._delay, self.dt, self.period, self.ctrl)
        if self._framed:
            self.frames = [None] * self.K
            self._framed = False
        due = None
        if self._cam_lead <= nsub:               # some plant may take a camera frame in this period
            due = np.flatnonzero((self.next_cam <= k0 + nsub) & (self.active > 0))
            start = k0.copy()
            self._schedule_frames(due, start)
        if self._native:
            previous = _DISPATCH.enter("native")
            try:
                fatal = _DISPATCH.lib.step_batch(*self._c_args, self._c_ctrl if per_substep else self._c_forces,
                                                 int(per_substep), self._c_capture if due is not None else None,
                                                 *self._c_out)
            finally:
                _DISPATCH.leave(previous)
            if fatal < 0:
                raise RuntimeError("PlantBatch: a plant's sizes changed (C struct disagrees with N, m)")
        else:
            fatal = self._step_python(per_substep, due is not None)
        if due is None:
            self._cam_lead -= nsub
        else:
            self._take_frames(due, start)
            self._cam_lead = self._camera_lead()
        return fatal

    @property
    def _native(self) -> bool:
        """The batch's plants step with the C callback (``set_backend`` may move them)."""
        return self.plants[0]._backend == "native"

    def _camera_lead(self) -> int:
        """Sub-steps until the first active plant's next camera frame."""
        lead = (self.next_cam - self.k)[self.active > 0]
        return int(lead.min()) if lead.size else 1 << 62

    def _schedule_frames(self, due: np.ndarray, k0: np.ndarray) -> None:
        """capture (K, n_sub): frames due at the end of each sub-step (a frame already late is taken
        at the end of the first one); advances the camera schedule of the plants in ``due``."""
        self.capture[:] = 0
        for i in due:
            plant, start = self.plants[i], int(k0[i])
            while self.next_cam[i] <= start + self.nsub:
                self.capture[i, max(int(self.next_cam[i]) - start, 1) - 1] += 1
                self.frame_index[i] += 1
                self.next_cam[i] = plant._camera_step(int(self.frame_index[i]))

    def _take_frames(self, due: np.ndarray, start: np.ndarray) -> None:
        """Camera frames of this period, each with its own draw of the plant's seeded noise."""
        for i in due:
            plant = self.plants[i]
            frame = None
            for s in np.flatnonzero(self.capture[i]):
                t = (int(start[i]) + int(s) + 1) * self.dt + plant._camera_delay
                alpha = self.frame_alpha[i, s]
                for _ in range(int(self.capture[i, s])):
                    frame = (t, alpha + plant._rng.normal(0.0, plant.params.sensors.camera_noise, alpha.shape))
            self.frames[i] = frame
        self._framed = True

    def _step_python(self, per_substep: bool, capture: bool) -> int:
        """The C loop of ``neck_step_batch`` with the Python callback."""
        previous = _DISPATCH.enter("python")
        try:
            for i in np.flatnonzero(self.active):
                plant = self.plants[i]
                m, d = plant.model, plant.data
                for s in range(self.nsub):
                    d.ctrl[: self.m] = self.ctrl[i, s] if per_substep else self.forces[i]
                    (mujoco.mj_step2 if s == 0 else mujoco.mj_step)(m, d)
                    if capture and self.capture[i, s]:
                        self.frame_alpha[i, s] = d.qpos[plant._ix.qpos_A] + d.qpos[plant._ix.qpos_D]
                rigid = plant._constraint_tensions() if plant.rigid_cables else None
                mujoco.mj_step1(m, d)
                if rigid is not None:
                    plant._out_tension[:] = rigid
                self.k[i] += self.nsub
                self._copy_outputs(i)
                self.fatal[i] = any(w.number for w in plant._fatal_warnings)
        finally:
            _DISPATCH.leave(previous)
        return int(self.fatal[self.active > 0].sum())

    def _copy_outputs(self, i: int) -> None:
        """Plant i's outputs (its struct's) into row i of ``out`` and its encoder reading (the C loop's own copy)."""
        p, o, c = self.plants[i], self.out[i], self._cols
        _quantise(p._out_theta, p._inv_res, p._res, self._encoders[i])
        o[c["theta"]], o[c["alpha"]], o[c["alpha_dot"]] = p._out_theta, p._out_alpha, p._out_alpha_dot
        o[c["tension"]], o[c["elongation"]], o[c["loop_gap"]] = p._out_tension, p._out_elong, p._c.loop_gap

    def diverged(self, i: int) -> PlantDivergedError:
        """The error of plant i, whose simulation diverged in the period just run."""
        p = self.plants[i]
        return PlantDivergedError(
            f"plant: the simulation diverged during the control period ending at t = {self.k[i] * self.dt:.4f} s "
            f"(MuJoCo reported a singular inertia or a NaN/huge state or acceleration); the commanded "
            f"forces {np.array2string(self.forces[i], precision=1)} N or the parameters drive the neck out of its "
            f"valid range (|alpha| < {p.params.geometry.alpha_max:.3g} rad). Call reset() to go on."
            + (f" MuJoCo said: {_last_mujoco_warning}" if _last_mujoco_warning else ""))
