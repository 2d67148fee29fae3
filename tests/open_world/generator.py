"""Blind measured-data logs whose hidden effects share no code with the diagnosis' candidates.

The generator never imports :mod:`neck_sim.effects`, :mod:`identification.diagnosis.candidates` or
:mod:`identification.diagnosis`: it builds a *nominal* :class:`neck_sim.plant.Plant` (no effects)
and hides each effect by another mechanism than the candidate's:

* MuJoCo model fields of the compiled plant (``plant.model``): motor-slide ``dof_damping`` (viscous friction; the plant
  zeroes the motor dofs' damping at construction and applies eq 37 in its callback, so a damping
  set afterwards adds to it), hinge ``dof_frictionloss`` (joint friction), a side spring
  tendon's ``tendon_stiffness`` / ``tendon_lengthspring`` (spring error), the head body's
  ``body_mass`` / ``body_inertia`` / ``body_ipos`` with the payload off the bar's middle;
* formulas written here: a tanh Coulomb law and an exponential Stribeck law on the commanded
  force (MuJoCo's ``dof_frictionloss`` on a motor slide is no Coulomb friction: its soft
  constraint with the slide's 16 kg reflected inertia acts as a damper below about 1 cm/s), a command FIFO
  (actuation delay), camera frames restamped late (camera delay), an encoder offset
  (pretension: the encoders were zeroed with the cables stretched), a smooth play between the
  encoder's motor and the drum (backlash: the lead swings exponentially, not the diagnosis'
  clipped play);
* effects the vocabulary has no name for: cable creep (the cables lengthen in proportion to the
  integral of their tension), a camera scale error, a cable's own hysteresis (a Dahl-like force
  that lags the cable's stretch direction).

Excitations: the §5.2.2 sequences (:func:`trajectory`) or a random multisine in joint space
(:class:`Multisine`, an excitation the tool did not design); :func:`combine` hides several
effects at once.

Runs: :func:`simulate` (the paper's routing: a motor servo around the flat-output feed-forward of
the identification shape) and :func:`simulate_reachable` (any routing, e.g. 10 joints and 4 cables:
the nominal inverse-statics controller through the equilibria of tension waypoints).

Each :class:`Spec` says what a correct diagnosis names (``expect``), where (0-based cable,
joint, spring) and the magnitude to compare with, in the candidate's parameter units.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from typing import Callable

import mujoco
import numpy as np

from identification.excitation import paper_amplitudes, predict_run, sequences_trajectory
from neck_sim.logs import LogWriter
from neck_sim.params import NeckParams, default_params
from neck_sim.plant import Plant
from neck_sim.trajectory import TrajectorySample

UNEXPLAINED = "unexplained"     # the vocabulary's name, written here (no import of neck_sim.effects)


@dataclass
class Hooks:
    """What one hidden effect does to a simulation: ``edit(plant)`` on the compiled model after
    reset; ``force(k, f_cmd, plant) -> f_applied`` (N) on the way to the plant;
    ``encoder(theta_true) -> theta_logged``; ``camera(t, alpha) -> (t_stamp, alpha_logged)``."""

    edit: Callable | None = None
    force: Callable | None = None
    encoder: Callable | None = None
    camera: Callable | None = None


@dataclass(frozen=True)
class Spec:
    """A blind case: ``name`` of the hidden form, ``expect`` the vocabulary name a correct
    diagnosis gives (``unexplained`` for effects outside it), ``model`` the baseline model the
    diagnosis starts from, ``magnitude`` in the candidate's units with ``symbol`` the fitted
    parameter to compare (``None``: no magnitude check), ``where`` the 0-based cable/joint."""

    name: str
    expect: str
    magnitude: float
    hooks: Hooks = field(compare=False, repr=False)
    params: NeckParams = field(compare=False, repr=False)
    model: str = "paper"
    symbol: str | None = None
    cables: tuple = ()
    joints: tuple = ()
    description: str = ""


# --------------------------------------------------------------------------------- mechanisms

def _ratio(p: NeckParams) -> float:
    return p.actuation.R / p.actuation.r_d          # theta (rad) per metre of cable on the drum


def _by_name(model, kind, name) -> int:
    i = mujoco.mj_name2id(model, kind, name)
    if i < 0:
        raise ValueError(f"generator: the plant has no {name!r}")
    return i


def _dof(model, joint: str) -> int:
    return int(model.jnt_dofadr[_by_name(model, mujoco.mjtObj.mjOBJ_JOINT, joint)])


def make_spec(name: str, seed: int, level: float = 1.0, n_joints: int = 3, params: NeckParams | None = None) -> Spec:
    """The blind case ``name`` at ``level`` x its test magnitude (times a factor in [0.8, 1.25]),
    with the affected cable / joint / spring side drawn from ``seed``, on the nominal neck
    ``params`` (default: the paper's routing for ``n_joints``)."""
    rng = np.random.default_rng([seed, sum(map(ord, name))])
    p = default_params(n_joints) if params is None else params
    n_joints = p.n_joints
    factor = level * float(np.exp(rng.uniform(np.log(0.8), np.log(1.25))))
    cable, joint, side = int(rng.integers(p.n_cables)), int(rng.integers(n_joints)), int(rng.integers(2))
    ratio = _ratio(p)
    no_dry = p.replace(**{"friction.f_s": (0.0,) * p.n_cables})
    if name == "none":
        return Spec(name, "none", 0.0, Hooks(), p, description="no hidden effect (noise only)")
    if name in ("dry_friction", "dry_friction_all"):   # tanh Coulomb law on the commanded force, written here
        F, w0 = 10.0 * factor, 0.3
        where = slice(None) if name == "dry_friction_all" else cable

        def force(k, f, pl):
            out = f.copy()
            out[where] -= F * np.tanh(pl.truth().theta_dot[where] / w0)
            return out
        if name == "dry_friction_all":
            return Spec(name, "dry_friction", F, Hooks(force=force), no_dry, "cable_elasticity,tension_stiffening",
                        None, tuple(range(p.n_cables)), (), f"tanh Coulomb friction {F:.1f} N on every cable")
        return Spec(name, "dry_friction", F, Hooks(force=force), no_dry, "cable_elasticity,tension_stiffening",
                    f"f_s({cable + 1})", (cable,), (), f"tanh Coulomb friction {F:.1f} N on cable {cable + 1}")
    if name in ("viscous_friction", "viscous_friction_left"):   # MuJoCo damping on the motor slide
        c_v = 0.15 * factor
        # right cables; the long left one separately (README: a known miss)
        cable = cable % n_joints if name == "viscous_friction" else n_joints

        def edit(pl):
            pl.model.dof_damping[_dof(pl.model, f"motor{cable + 1}")] = c_v * ratio     # N s/m of cable
        return Spec(name, "viscous_friction", c_v, Hooks(edit=edit), p, symbol=f"c_v({cable + 1})", cables=(cable,),
                    description=f"motor-slide damping {c_v * ratio:.0f} N s/m (c_v {c_v:.3f} N s/rad) on cable "
                                f"{cable + 1}")
    if name == "stribeck_friction":                # exponential Stribeck curve, written here
        extra, v_s = 8.0 * factor, 4.0

        def force(k, f, pl):
            w = pl.truth().theta_dot
            out = f.copy()
            out[cable] -= extra * np.exp(-(w[cable] / v_s) ** 2) * np.tanh(w[cable] / 0.3)
            return out
        return Spec(name, "stribeck_friction", extra, Hooks(force=force), p, cables=(cable,),
                    description=f"exponential Stribeck bump {extra:.1f} N (v_s {v_s} rad/s) on cable {cable + 1}")
    if name == "joint_friction":                   # MuJoCo friction on the X-joint's hinges
        tau = 0.04 * factor

        def edit(pl):
            for h in "ABD":
                i = _dof(pl.model, f"j{joint + 1}_{h}")
                pl.model.dof_frictionloss[i] = tau
                # a stiff friction constraint (2 physics steps): MuJoCo's default 20 ms acts as a
                # damper on the light top joint
                pl.model.dof_solref[i] = (2 * pl.model.opt.timestep, 1.0)
        return Spec(name, "joint_friction", tau, Hooks(edit=edit), p, symbol=f"tau_j({joint + 1})", joints=(joint,),
                    description=f"hinge frictionloss {tau:.3f} N m in joint {joint + 1}")
    if name == "spring_error":                     # one side spring's tendon stiffness
        k0 = p.springs.stiffness[joint]
        dk = k0 * 0.5 * factor * (1 if rng.random() < 0.5 else -1)
        tendon = f"j{joint + 1}_spring_{('left', 'right')[side]}"

        def edit(pl):
            i = _by_name(pl.model, mujoco.mjtObj.mjOBJ_TENDON, tendon)
            pl.model.tendon_stiffness[i] = k0 + dk
        return Spec(name, "spring_error", dk, Hooks(edit=edit), p, symbol=f"dk({joint + 1}{'LR'[side]})",
                    joints=(joint,), description=f"{tendon} stiffness {k0:.0f} -> {k0 + dk:.0f} N/m")
    if name == "payload":                          # a body with its own inertia, off the bar's middle
        m = 0.08 * factor
        offset = np.array([0.006, 0.004, 0.0])     # m from the bar's middle (along it, up the neck)

        def edit(pl):
            b = _by_name(pl.model, mujoco.mjtObj.mjOBJ_BODY, f"j{n_joints}_top")
            M0, c0 = float(pl.model.body_mass[b]), pl.model.body_ipos[b].copy()
            c = (M0 * c0 + m * (c0 + offset)) / (M0 + m)
            # parallel axis: the bar's own inertia and the payload's (a 2 cm cube) about the new centre
            d0, d1 = c0 - c, c0 + offset - c
            cube = m * 0.02 ** 2 / 6
            I = pl.model.body_inertia[b] + cube
            I = I + M0 * (d0 @ d0 - d0 ** 2) + m * (d1 @ d1 - d1 ** 2)
            pl.model.body_mass[b], pl.model.body_ipos[b], pl.model.body_inertia[b] = M0 + m, c, I
        return Spec(name, "payload", m, Hooks(edit=edit), p, symbol="payload",
                    description=f"{1e3 * m:.0f} g body 6 mm off the head bar's middle")
    if name in ("actuation_delay", "actuation_delay_one"):     # a FIFO of commands (on one motor only)
        d = 0.010 * factor
        lag = max(int(round(d * p.control.rate_hz)), 1)
        fifo: list = []
        one = name == "actuation_delay_one"

        def force(k, f, pl):
            fifo.append(f.copy())
            late = fifo[max(len(fifo) - 1 - lag, 0)]
            if not one:
                return late
            out = f.copy()
            out[cable] = late[cable]
            return out
        return Spec(name, "actuation_delay", lag / p.control.rate_hz, Hooks(force=force), p,
                    symbol=f"motor_delay({cable + 1})" if one else "delay", cables=(cable,) if one else (),
                    description=f"command FIFO of {lag} periods ({1e3 * lag / p.control.rate_hz:.0f} ms)"
                                + (f" on motor {cable + 1} only" if one else ""))
    if name == "camera_delay":                     # frames restamped late
        d = 0.033 * factor
        return Spec(name, "camera_delay", d, Hooks(camera=lambda t, a: (t + d, a)), p, symbol="delay",
                    description=f"camera frames restamped {1e3 * d:.0f} ms late")
    if name in ("pretension", "pretension_left"):  # encoders zeroed with the cable stretched
        x0 = (0.003 if name == "pretension" else 0.002) * factor
        # a right cable, or the long left one (its limit is in the README's detection table)
        cable = cable % n_joints if name == "pretension" else n_joints
        offset = np.zeros(p.n_cables)
        offset[cable] = x0 * ratio

        def encoder(theta):
            return theta - offset
        return Spec(name, "pretension", x0, Hooks(encoder=encoder), p, symbol=f"x0({cable + 1})", cables=(cable,),
                    description=f"encoder {cable + 1} zeroed {1e3 * x0:.1f} mm of cable early")
    if name in ("backlash", "backlash_all"):      # play between motor (encoder) and drum, a formula of its own
        band = 0.3e-3 * factor                    # m of cable
        cable = cable % n_joints                  # a right cable, or every motor
        where = np.arange(p.n_cables) if name == "backlash_all" else np.array([cable])
        half = 0.5 * band * ratio                 # rad at the motor shaft
        state = {}

        def encoder(theta):
            # the motor leads the drum it turns (the plant's slide: theta): after a reversal the
            # lead swings to the other side, approaching +-half exponentially with a scale of a
            # thirtieth of the half band of drum travel (a smooth play, not the plant's clipped one)
            prev = state.get("drum", theta.copy())
            lead = state.get("lead", np.zeros_like(theta))
            d = theta - prev
            gain = 1.0 - np.exp(-np.abs(d) / (half / 30))
            lead = lead + (np.sign(d) * half - lead) * gain
            lead[np.setdiff1d(np.arange(theta.size), where)] = 0.0
            state["drum"], state["lead"] = theta.copy(), lead
            return theta + lead
        cables = tuple(int(c) for c in where)
        return Spec(name, "backlash", band, Hooks(encoder=encoder), p, symbol=None if name == "backlash_all"
                    else f"band({cable + 1})", cables=cables,
                    description=f"gear backlash {1e3 * band:.2f} mm of cable on "
                                + ("every motor" if name == "backlash_all" else f"motor {cable + 1}"))
    if name == "creep":                            # out of vocabulary: cables lengthen under load
        beta = 4e-6 * factor                        # m of creep per N s of tension (about 2 mm per log)
        state = {"x": np.zeros(p.n_cables)}

        def force(k, f, pl):
            state["x"] += beta * np.maximum(pl.truth().tension, 0.0) * dt_c
            return f

        def encoder(theta):                         # the drum turns that much further for the same stretch
            return theta + state["x"] * ratio
        dt_c = 1.0 / p.control.rate_hz
        return Spec(name, UNEXPLAINED, beta, Hooks(force=force, encoder=encoder), p,
                    description=f"cable creep {beta * 1e6:.0f} um per N s of tension")
    if name == "camera_scale":                     # out of vocabulary: camera calibration error
        s = 1.0 + 0.08 * factor
        return Spec(name, UNEXPLAINED, s - 1, Hooks(camera=lambda t, a: (t, s * a)), p,
                    description=f"camera angles x {s:.3f}")
    if name == "cable_hysteresis":                 # out of vocabulary: a cable whose tension lags its stretch
        h = 6.0 * factor                            # N of hysteresis on a right cable
        cable = cable % n_joints
        state = {}

        def force(k, f, pl):
            # a Dahl-like internal friction of the cable itself, in series with the motor: the
            # force that reaches the cable lags the cable's stretch direction
            x = pl.truth().elongation[cable]
            prev = state.get("x", x)
            z = state.get("z", 0.0)
            z = float(np.clip(z + (x - prev) / 2e-4, -1.0, 1.0))      # saturates over 0.2 mm of stretch
            state["x"], state["z"] = x, z
            out = f.copy()
            out[cable] -= h * z
            return out
        return Spec(name, UNEXPLAINED, h, Hooks(force=force), p, cables=(cable,),
                    description=f"cable {cable + 1} hysteresis {h:.1f} N over 0.2 mm of stretch")
    raise ValueError(f"generator: unknown case {name!r} (known: {', '.join(CASES)})")


def combine(specs) -> Spec:
    """Two or more hidden effects at once (their hooks chained: edits and encoder/camera formulas
    in order, forces one after the other); ``expect`` joins the names with ``+``, the baseline
    model is the first one's.  The cases must not need different nominal parameters (dry
    friction's case removes the plant's own: combine it with effects on the default plant
    only when it comes first)."""
    specs = list(specs)
    hooks = [s.hooks for s in specs]

    def edit(pl):
        for h in hooks:
            if h.edit is not None:
                h.edit(pl)

    def force(k, f, pl):
        for h in hooks:
            if h.force is not None:
                f = h.force(k, f, pl)
        return f

    def encoder(theta):
        for h in hooks:
            if h.encoder is not None:
                theta = h.encoder(theta)
        return theta

    def camera(t, a):
        for h in hooks:
            if h.camera is not None:
                t, a = h.camera(t, a)
        return t, a
    return Spec("+".join(s.name for s in specs), "+".join(s.expect for s in specs), 0.0,
                Hooks(edit, force, encoder, camera), specs[0].params, specs[0].model,
                description=" and ".join(s.description for s in specs))


CASES = ("none", "dry_friction", "dry_friction_all", "viscous_friction", "viscous_friction_left", "stribeck_friction",
         "joint_friction", "spring_error", "payload", "actuation_delay", "actuation_delay_one", "camera_delay",
         "pretension", "pretension_left", "backlash", "backlash_all", "creep", "camera_scale", "cable_hysteresis")
PAIRS = ("viscous_friction+payload", "spring_error+actuation_delay", "joint_friction+camera_delay",
         "payload+pretension", "stribeck_friction+spring_error", "actuation_delay+camera_delay")
"""Two effects hidden at once (:func:`combine`): on different channels or shapes, each at its
test magnitude."""
OUT_OF_VOCABULARY = ("creep", "camera_scale")
"""The out-of-vocabulary effects the blind tests require ``unexplained`` for.  (``cable_hysteresis``,
the third, is in the detection benchmark only: at its test level it gives ``unexplained`` in 1 of 3
seeds and ``pretension`` in 2, docs/diagnosis.md.)"""


# ------------------------------------------------------------------------------------ simulation

def trajectory(params: NeckParams, sequences: int = 2, move_time: float = 0.8, hold_time: float = 0.2):
    """The identification shape (§5.2.2), shortened: ``sequences`` of six cycloidal moves."""
    amps = paper_amplitudes(params.n_joints)[:sequences]
    return sequences_trajectory(amps, move_time, hold_time, name=f"open-world ({sequences} sequences)")


BEND = 0.02
LOW, HIGH = (35.0, 50.0), (65.0, 80.0)


def reachable_waypoints(params: NeckParams, rng: np.random.Generator, moves: int) -> np.ndarray:
    """Tension waypoints (moves + 1, m) N for a neck with fewer cables than N + 1: from 60 N on
    every cable, each waypoint a common pretension alternating low (35-50 N) and high (65-80 N),
    so every cable's tension sweeps about 30-45 N and its motor turns both ways, plus a bend:
    each pair of antagonist cables (same end joint, opposite sides) pulls its side by up to
    4 % of the pretension, the sign alternating, so the neck bends both ways in C and S shapes."""
    m = params.n_cables
    side = np.array([1.0 if c.side == "left" else -1.0 for c in params.routing.cables])
    ends = np.array([c.ends_at for c in params.routing.cables])
    groups = {e: ends == e for e in np.unique(ends)}
    w = [np.full(m, 60.0)]
    for k in range(moves):
        P = rng.uniform(*LOW) if k % 2 == 0 else rng.uniform(*HIGH)
        bend = np.zeros(m)
        for g, sel in groups.items():
            bend[sel] = (-1) ** k * rng.uniform(0.5, 1.0) * rng.choice((-1.0, 1.0)) * BEND * P
        w.append(P + side * bend)
    return np.array(w)


def simulate_reachable(path, spec: Spec, seed: int, *, moves: int = 10, move_time: float = 1.5,
                       hold_time: float = 0.4, write_truth: bool = False) -> str:
    """:func:`simulate` for necks with fewer cables than N + 1: the nominal controller of such a
    neck (``controllers.underactuated``: inverse statics and motor-angle PID on the nominal
    constants, never told of the hidden effect) drives the plant with ``spec``'s hidden effect
    through the equilibria of :func:`reachable_waypoints`; writes the measured topics (atomic).
    The plant runs at that controller's physics timestep (``controllers.selection.plant_timestep``,
    0.25 ms): at the default 0.5 ms a 60 s run of the 10-joint, 4-cable neck with one side spring
    20 % weak diverged 18 s in."""
    from controllers.selection import plant_timestep
    from controllers.underactuated import ReachablePath, UnderactuatedController

    p = nominal = spec.params
    rng = np.random.default_rng([seed, 7])
    traj = ReachablePath(nominal, reachable_waypoints(nominal, rng, moves), move_time=move_time, hold_time=hold_time)
    rate = p.control.rate_hz
    steps = int(round(traj.duration * rate)) + 1
    t = np.arange(steps) / rate
    ctrl = UnderactuatedController(nominal)
    ref = ctrl.motor_reference(traj.sample(t))
    plant = Plant(p, seed=seed, timestep=plant_timestep("inverse-statics"))
    plant.reset(alpha0=ref.alpha[0])
    h = spec.hooks
    if h.edit is not None:
        h.edit(plant)
    read = h.encoder or (lambda th: th)
    ctrl.reset(ref.alpha[0], read(plant.encoders()))
    theta_log, force_log, frames = np.empty((steps, p.n_cables)), np.empty((steps, p.n_cables)), []
    truth = []
    for k in range(steps):
        theta = read(plant.encoders())
        f = ctrl.step(theta, ref.at(k)).forces
        theta_log[k], force_log[k] = theta, f
        plant.step(h.force(k, f, plant) if h.force is not None else f)
        if write_truth:
            truth.append(plant.truth())
        frame = plant.camera_frame()
        if frame is not None:
            frames.append(h.camera(*frame) if h.camera is not None else frame)
    with LogWriter(path, nominal, run_info={"generator": "tests/open_world/generator.py", "hidden": spec.description,
                                            "trajectory": "reachable path"}) as w:
        for k in range(steps):
            w.motors(float(t[k]), theta_log[k], force_log[k])
            if write_truth:
                tr = truth[k]
                w.truth(float(t[k]), tr.alpha, tr.alpha_dot, tr.tension, tr.elongation)
        for tc, ac in frames:
            if tc <= t[-1]:
                w.camera(float(tc), ac)
    return os.fspath(path)


@dataclass(frozen=True)
class Multisine:
    """A random multisine in joint space, the kind of excitation a user records on a prototype
    (not designed by the tool): per joint, ``components`` sines of frequencies drawn in
    [0.1, 0.6] Hz with random phases, scaled so that the largest |alpha_j| is ``fraction`` of the
    paper's amplitude of that joint (40, 30, 20 deg for N = 3), faded in and out over ``ramp`` s
    by a quintic smoothstep (starts and ends at rest, straight).  ``sample(t)`` -> (alpha, alpha_dot,
    alpha_ddot), rad, rad/s, rad/s^2, t.shape + (N,)."""

    duration: float
    freqs: np.ndarray = field(repr=False)       # (N, K) Hz
    phases: np.ndarray = field(repr=False)      # (N, K) rad
    amps: np.ndarray = field(repr=False)        # (N, K) rad
    ramp: float = 1.0
    name: str = "random multisine"

    @classmethod
    def draw(cls, params: NeckParams, seed: int, duration: float = 12.0, components: int = 4,
             fraction: float = 0.8, ramp: float = 1.0) -> "Multisine":
        rng = np.random.default_rng([seed, 7919])
        n = params.n_joints
        freqs = rng.uniform(0.1, 0.6, (n, components))
        phases = rng.uniform(0, 2 * np.pi, (n, components))
        amps = rng.uniform(0.5, 1.0, (n, components))
        probe = cls(duration, freqs, phases, amps, ramp)
        t = np.linspace(0.0, duration, int(duration * 200) + 1)
        peak = np.abs(probe.sample(t)[0]).max(0)
        target = fraction * paper_amplitudes(n)[0]
        return cls(duration, freqs, phases, amps * (target / peak)[:, None], ramp, f"random multisine (seed {seed})")

    def sample(self, t):
        t = np.asarray(t, dtype=float)[..., None, None]
        w = 2 * np.pi * self.freqs
        arg = w * t + self.phases
        s0 = (self.amps * np.sin(arg)).sum(-1)
        s1 = (self.amps * w * np.cos(arg)).sum(-1)
        s2 = (-self.amps * w * w * np.sin(arg)).sum(-1)
        tt = t[..., 0, 0]
        # quintic smoothstep envelope e(t) (C2: no jump in the acceleration), 0 at both ends
        u = np.clip(np.minimum(tt, self.duration - tt) / self.ramp, 0.0, 1.0)
        du = np.where((u > 0) & (u < 1), np.where(tt < self.duration / 2, 1.0, -1.0) / self.ramp, 0.0)
        e0 = u ** 3 * (10 - 15 * u + 6 * u * u)
        e1 = 30 * u * u * (1 - u) ** 2 * du
        e2 = 60 * u * (1 - u) * (1 - 2 * u) * du * du
        e0, e1, e2 = e0[..., None], e1[..., None], e2[..., None]
        return TrajectorySample(e0 * s0, e1 * s0 + e0 * s1, e2 * s0 + 2 * e1 * s1 + e0 * s2)


def simulate(path, spec: Spec, seed: int, *, sequences: int = 2, excitation=None) -> str:
    """Drive a nominal plant with ``spec``'s hidden effect along :func:`trajectory` (or
    ``excitation``, anything with ``duration`` and ``sample(t)``, e.g. a :class:`Multisine`) with a
    motor servo around the nominal feed-forward, write the measured topics (atomic).  Returns ``path``."""
    p = spec.params
    traj = trajectory(p, sequences) if excitation is None else excitation
    rate = p.control.rate_hz
    dt = 1.0 / rate
    steps = int(round(traj.duration * rate)) + 1
    t = np.arange(steps) * dt
    s = traj.sample(t)
    ff = predict_run(s.alpha, s.alpha_dot, s.alpha_ddot, t, default_params(p.n_joints))
    plant = Plant(p, seed=seed)
    plant.reset(alpha0=s.alpha[0])
    h = spec.hooks
    if h.edit is not None:
        h.edit(plant)
    k_p, k_d, tau = 3.0, 0.25, 0.01
    a = dt / (tau + dt)
    read = h.encoder or (lambda th: th)
    theta_prev = read(plant.encoders())
    speed = np.zeros(p.n_cables)
    theta_log, force_log, frames = np.empty((steps, p.n_cables)), np.empty((steps, p.n_cables)), []
    for k in range(steps):
        theta = read(plant.encoders())
        speed += a * ((theta - theta_prev) / dt - speed)
        theta_prev = theta
        f = np.clip(ff.force[k] + k_p * (ff.theta[k] - theta) + k_d * (ff.theta_dot[k] - speed),
                    p.actuation.f_min, p.actuation.f_max)
        theta_log[k], force_log[k] = theta, f
        plant.step(h.force(k, f, plant) if h.force is not None else f)
        frame = plant.camera_frame()
        if frame is not None:
            frames.append(h.camera(*frame) if h.camera is not None else frame)
    with LogWriter(path, p, run_info={"generator": "tests/open_world/generator.py", "hidden": spec.description}) as w:
        for k in range(steps):
            w.motors(float(t[k]), theta_log[k], force_log[k])
        for tc, ac in frames:
            if tc <= t[-1]:
                w.camera(float(tc), ac)
    return os.fspath(path)
