"""Blind tests of the diagnosis: plant logs with a hidden effect drawn from a seed.

A blind test hides one effect of the vocabulary (:mod:`neck_sim.effects`) in the simulated plant,
writes a contract log, and lets :func:`identification.diagnosis.diagnose` find it without being
told.  This module makes those logs quickly:

* :func:`excitation_trajectory` -- the §5.2.2 identification shape (sequences of six cycloidal
  motions, each sequence flipping one joint), shortened: a few sequences, faster moves;
* :func:`run_log` -- drives a :class:`neck_sim.plant.Plant` along it and writes the MCAP log
  (measured topics, reference and the simulation truth).  The controller is a motor-space servo
  around the flat-output feed-forward of the *nominal* model
  (:func:`identification.excitation.predict_run`: the forces and motor angles that would track
  the trajectory exactly on the paper's model),

      f = f_ff + k_p (theta_ff - theta) + k_d (theta_dot_ff - theta_dot_filtered),

  a few vector operations per period instead of the computed-torque law's model evaluation
  (about 50 times faster), so a test can afford a dozen logs.  The data are identification-like:
  every joint sweeps +-20..40 deg, forces span about 5..80 N, holds at every knot;
* :func:`hidden_effect` -- the effect to hide, in a *form that differs from the diagnosis'
  candidate* where the vocabulary allows it (another Stribeck speed and smoothing, a sharper
  dry-friction sign, friction on one cable only, a pulley-friction smoothing other than the
  candidate's), with its magnitude and the affected cable or joint drawn from a seed;
* :data:`CASES` -- per effect, the plant (parameters and effects) and the baseline model the
  diagnosis starts from.  Effects of the paper's own model (``dry_friction``,
  ``cable_elasticity``, ``tension_stiffening``) are hidden against a baseline that lacks them.

Units SI; cables 0-based in code (c1 = 0), 1-based in reports.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field

import numpy as np

from neck_sim import effects as effect_registry
from neck_sim.effects import NONE, Effects
from neck_sim.params import NeckParams, default_params

__all__ = ["excitation_trajectory", "ServoGains", "run_log", "BlindCase", "hidden_effect", "blind_forms", "CASES",
           "MAGNITUDES", "make_case", "make_cases"]


def excitation_trajectory(params: NeckParams, sequences: int = 3, move_time: float = 0.9, hold_time: float = 0.25,
                          scale: float = 1.0):
    """The identification trajectory's shape (§5.2.2), shortened: ``sequences`` of its N + 1
    sequences (first the all-same-direction one, then joint 1 flipped, ...), each of six cycloidal
    motions of ``move_time`` s with ``hold_time`` s holds; amplitudes times ``scale``.

    3 sequences with the defaults last 20.8 s.
    """
    from identification.excitation import paper_amplitudes, sequences_trajectory

    n = params.n_joints
    if not 1 <= sequences <= n + 1:
        raise ValueError(f"sequences: expected 1..{n + 1}, got {sequences}")
    amps = paper_amplitudes(n)[:sequences] * scale
    traj = sequences_trajectory(amps, move_time, hold_time, name=f"excitation ({sequences} sequences)")
    traj.check_workspace(params)
    return traj


@dataclass(frozen=True)
class ServoGains:
    """Motor-space servo gains: k_p N/rad, k_d N s/rad at the motor shaft; speed filter tau s."""

    k_p: float = 3.0
    k_d: float = 0.25
    tau: float = 0.01


def run_log(path, plant_params: NeckParams, effects: Effects | None = None, *, trajectory=None, seed: int = 0,
            model_params: NeckParams | None = None, gains: ServoGains = ServoGains(), rigid_cables: bool = False,
            progress: bool = False, run_info: dict | None = None, write_truth: bool = True) -> str:
    """Simulate ``trajectory`` (default :func:`excitation_trajectory`) on a plant with hidden
    ``effects`` and write the contract log at ``path`` (atomic).  Returns ``path``.

    ``plant_params`` are the plant's constants (its friction and cable values are the truth),
    ``model_params`` the nominal model the feed-forward is computed with (default
    ``default_params(N)``, the paper's model).  The log's ``neck`` record holds the nominal
    constants of ``plant_params``; the ``run`` record holds the hidden effects (simulation only),
    ``/neck/truth`` the true state unless ``write_truth`` is False (it halves the writing time).
    """
    from tqdm.auto import tqdm

    from identification.excitation import predict_run
    from neck_sim.plant_spec import PlantSpec
    from neck_sim.recorder import Recorder

    n = plant_params.n_joints
    model = default_params(n) if model_params is None else model_params
    traj = excitation_trajectory(plant_params) if trajectory is None else trajectory
    rate = plant_params.control.rate_hz
    dt = 1.0 / rate
    steps = int(round(traj.duration * rate)) + 1
    t = np.arange(steps) * dt
    s = traj.sample(t)
    ff = predict_run(s.alpha, s.alpha_dot, s.alpha_ddot, t, model)
    spec = PlantSpec(plant_params, effects, seed=seed, rigid_cables=rigid_cables)
    plant = spec.build()
    plant.reset(alpha0=s.alpha[0])
    act = plant_params.actuation
    f_lo, f_hi = act.f_min, act.f_max
    a = dt / (gains.tau + dt)
    info = {"generator": "identification.blind.run_log", "trajectory": traj.name,
            **PlantSpec.of(plant).to_record(), **(run_info or {})}
    theta_prev = plant.encoders()
    speed = np.zeros(n + 1)
    rec = Recorder(n, plant_params.n_cables, steps, truth=write_truth, reference=True)
    rec.alpha_d[0] = s.alpha
    for k in tqdm(range(steps), desc="blind log", unit="step", disable=not progress, mininterval=0.5):
        theta = plant.encoders()
        speed += a * ((theta - theta_prev) / dt - speed)
        theta_prev = theta
        f = ff.force[k] + gains.k_p * (ff.theta[k] - theta) + gains.k_d * (ff.theta_dot[k] - speed)
        f = np.clip(f, f_lo, f_hi)
        rec.sample(k, t[k], theta, f, plant.truth() if write_truth else None)
        plant.step(f)
        rec.frame(plant.camera_frame())
    rec.write_log(path, plant_params, mjcf_xml=plant.xml, run_info=info)
    return os.fspath(path)


# ------------------------------------------------------------------------------------- hidden effects

def blind_forms() -> dict:
    """Blind case name -> (effect class, test magnitude, hide function) over the registry, in
    report order (an effect may have several forms, e.g. ``dry_friction:tanh``)."""
    return {case: (cls, mag, hide) for cls in effect_registry.registered()
            for case, (mag, hide) in cls.blind_forms().items()}


#: Test magnitudes per blind case (the "medium" level) of the built-in vocabulary; the detection
#: benchmark scales them.  Defined by each effect's module (``blind_magnitude``).
MAGNITUDES = {case: mag for case, (_, mag, _) in blind_forms().items()}


@dataclass(frozen=True)
class BlindCase:
    """A plant with one hidden effect and the model the diagnosis starts from.

    ``params`` the plant's constants, ``effects`` its hidden effects, ``model`` the baseline
    structure for :func:`identification.diagnosis.diagnose` (component names), ``expect`` the
    effect a correct diagnosis names, ``cables``/``joints`` where it was hidden (0-based).
    """

    name: str
    params: NeckParams
    effects: Effects
    model: tuple
    expect: str
    cables: tuple = ()
    joints: tuple = ()
    magnitude: float = 0.0
    description: str = ""
    info: dict = field(default_factory=dict)


def baseline_without(name: str) -> tuple[str, ...]:
    """The paper's model without effect ``name`` and what requires it (the model a blind test of
    an effect of the paper's own model starts from)."""
    drop = {name}
    for cls in effect_registry.registered():
        if drop & set(cls.requires):
            drop.add(cls.name)
    return tuple(n for n in effect_registry.paper_model() if n not in drop)


def hidden_effect(name: str, seed: int, level: float = 1.0, params: NeckParams | None = None) -> BlindCase:
    """The blind case ``name``: magnitude ``level`` x the effect's test magnitude times a factor
    in [0.8, 1.25] and the affected cable/joint, both drawn from ``seed``; the effect's own module
    says how to hide it (:meth:`neck_sim.effects.Effect.hide`).

    The hidden forms differ from the candidates' on purpose (see the module docstring).
    """
    p = default_params(3) if params is None else params
    forms = blind_forms()
    if name != NONE and name not in forms:
        raise ValueError(f"unknown blind case {name!r} (known: {', '.join((NONE,) + tuple(forms))})")
    rng = np.random.default_rng([seed, sum(map(ord, name))])
    nominal = forms[name][1] if name in forms else 0.0
    mag = nominal * level * float(np.exp(rng.uniform(np.log(0.8), np.log(1.25))))
    cable = int(rng.integers(p.n_cables))
    joint = int(rng.integers(p.n_joints))
    if name == NONE:
        return BlindCase(name, p, Effects(), effect_registry.paper_model(), NONE, (), (), 0.0,
                         "no hidden effect (noise only)")
    h = forms[name][2](p, rng, mag, cable, joint)
    return BlindCase(name, h.params, Effects.of(*h.effects), baseline_without(h.expect), h.expect, h.cables, h.joints,
                     mag, h.description)


#: Every blind case: the noise-only control, then one per effect (and per variant form).
CASES = (NONE,) + tuple(MAGNITUDES)


def make_case(name: str, seed: int, path, *, level: float = 1.0, trajectory=None, progress: bool = False,
              write_truth: bool = False):
    """(case, log path): :func:`hidden_effect` simulated by :func:`run_log` with camera seed ``seed``."""
    case = hidden_effect(name, seed, level)
    run_log(path, case.params, case.effects, trajectory=trajectory, seed=seed, progress=progress,
            run_info={"hidden": case.description}, write_truth=write_truth)
    return case, os.fspath(path)


def make_cases(jobs, directory, executor=None, *, progress: bool = True, write_truth: bool = False) -> list:
    """[(case, log path)] of :func:`make_case` for each job ``(name, seed, level)``, generated on a
    campaign executor (:func:`controllers.campaign.run_campaign`: an ``ExecutorSpec``, an open
    executor, or None for serially here); logs land in ``directory`` as ``NAME_SEED_LEVEL.mcap``."""
    from controllers.campaign import run_campaign, write_shipped

    jobs = [(str(name), int(seed), float(level), bool(write_truth)) for name, seed, level in jobs]
    names = [f"{name.replace(':', '_')}_{seed}_{level:g}.mcap" for name, seed, level, _ in jobs]
    made = run_campaign(_make_case_shipped, jobs, executor, labels=names, progress=progress, desc="blind logs")
    return [(case, write_shipped(os.path.join(directory, name), data)) for name, (case, data) in zip(names, made)]


def _make_case_shipped(job):
    """On a worker: (case, log bytes) of one :func:`make_cases` job."""
    from controllers.campaign import run_in_scratch

    name, seed, level, write_truth = job
    return run_in_scratch(_make_case_at, "case.mcap", name, seed, level, write_truth)


def _make_case_at(path, name, seed, level, write_truth) -> BlindCase:
    return make_case(name, seed, path, level=level, write_truth=write_truth)[0]
