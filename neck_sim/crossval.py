"""Cross-validation: the MuJoCo model of :mod:`neck_sim.mjcf` against the analytic model.

For random poses alpha in [-range, range]^N the bars are placed exactly on the closed-form pose
(every hinge set from :func:`neck_sim.mjcf.pose_qpos`), and MuJoCo's own quantities are mapped
to alpha-space with the velocity map J = dq/dalpha computed *from MuJoCo*: the null space of the
loop-closure (``connect``) and helper (tendon equality) constraint Jacobians with the motors held
and alpha_i = q_A,i + q_D,i.  Then

* lengths: ``ten_length(alpha) - ten_length(0)`` of the cable tendons vs
  :func:`~neck_sim.analytic.cable_lengths` (absolute error, m);
* Z: ``-(ten_J J)^T`` vs :func:`~neck_sim.analytic.transmission_matrix`;
* M: ``J^T M_q J`` (bar bodies only: helper and motor bodies are given zero mass) vs
  :func:`~neck_sim.analytic.mass_matrix` (``motors=False``);
* g: ``J^T (qfrc_bias - qfrc_spring)`` at rest vs :func:`~neck_sim.analytic.gravity_spring_torque`;
* dq/dalpha: MuJoCo's J vs the closed-form derivative of :func:`~neck_sim.mjcf.pose_qpos`;
* loop gap at the placed pose (m).

Relative errors are max |mujoco - analytic| / max |analytic| per pose (a matrix-norm ratio, so
that structurally zero entries do not divide), and the table reports the worst pose.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from neck_sim.analytic.cables import cable_lengths, transmission_matrix
from neck_sim.analytic.dynamics import gravity_spring_torque, mass_matrix
from neck_sim.mjcf import build_model, model_index, pose_qpos
from neck_sim.atomic import atomic_write_json
from neck_sim.params import NeckParams

__all__ = ["THRESHOLDS", "Row", "CrossvalReport", "crossval", "format_table"]

THRESHOLDS = {           # quantity -> (kind, threshold) of the MuJoCo vs analytic table
    "lengths": ("abs", 1e-9),
    "Z": ("rel", 1e-6),
    "M": ("rel", 1e-6),
    "g": ("rel", 1e-6),
    "dq/dalpha": ("rel", 1e-6),
    "loop gap": ("abs", 1e-12),
}


class Row(NamedTuple):
    quantity: str
    max_abs: float
    max_rel: float
    kind: str          # which error the threshold applies to: "abs" or "rel"
    threshold: float
    ok: bool


class CrossvalReport(NamedTuple):
    n_joints: int
    samples: int
    alpha_range: float   # rad
    seed: int
    rows: list
    n_cables: int = 0
    routing: str = ""    # Routing.describe() of the model's routing

    @property
    def ok(self) -> bool:
        return all(r.ok for r in self.rows)

    def to_dict(self) -> dict:
        return {"n_joints": self.n_joints, "n_cables": self.n_cables, "routing": self.routing.splitlines(),
                "samples": self.samples, "alpha_range_deg": math.degrees(self.alpha_range),
                "seed": self.seed, "ok": self.ok, "rows": [r._asdict() for r in self.rows]}


def _dense_ten_J(model, data, rows) -> np.ndarray:
    out = np.zeros((len(rows), model.nv))
    for k, t in enumerate(rows):
        a, nnz = model.ten_J_rowadr[t], model.ten_J_rownnz[t]
        out[k, model.ten_J_colind[a:a + nnz]] = data.ten_J[a:a + nnz]
    return out


def _velocity_map(model, data, ix) -> np.ndarray:
    """J = dq/dalpha (nv, N) from MuJoCo's constraint Jacobians at the current pose."""
    import mujoco

    n, m = ix.n_joints, ix.n_cables
    nv = model.nv
    rows = []
    jp1, jp2 = np.zeros((3, nv)), np.zeros((3, nv))
    for s1, s2 in ix.loop_sites:
        mujoco.mj_jacSite(model, data, jp1, None, int(s1))
        mujoco.mj_jacSite(model, data, jp2, None, int(s2))
        rows.append(jp1 - jp2)                       # velocity of the gap: must vanish
    rows.append(_dense_ten_J(model, data, ix.helper_tendon))
    sel = np.zeros((n, nv))
    sel[np.arange(n), ix.dof_A] = 1.0
    sel[np.arange(n), ix.dof_D] = 1.0
    held = np.zeros((m, nv))
    held[np.arange(m), ix.dof_motor] = 1.0
    A = np.vstack(rows + [sel, held])
    rhs = np.zeros((A.shape[0], n))
    rhs[A.shape[0] - (n + m): A.shape[0] - m] = np.eye(n)
    J, *_ = np.linalg.lstsq(A, rhs, rcond=None)
    return J


def crossval(params: NeckParams, samples: int = 200, seed: int = 0, alpha_range: float = math.radians(60),
             progress: bool = False, analytic_params: NeckParams | None = None) -> CrossvalReport:
    """Compare MuJoCo and the analytic model at ``samples`` random poses (see module docstring).

    The MuJoCo model is built from ``params``; the analytic side uses ``analytic_params``
    (default the same), e.g. to see how far a mis-specified analytic model lands.
    """
    import mujoco

    if int(samples) != samples or samples < 1:
        raise ValueError(f"samples: must be a positive integer, got {samples!r}")
    if not (0 < alpha_range < params.geometry.alpha_max):
        raise ValueError(f"alpha_range: must be in (0, alpha_max = {params.geometry.alpha_max:.4g}) rad, "
                         f"got {alpha_range!r}")
    n = params.n_joints
    ap = params if analytic_params is None else analytic_params
    if ap.n_joints != n:
        raise ValueError(f"analytic_params: {ap.n_joints} joints, the model has {n}")
    if ap.n_cables != params.n_cables:
        raise ValueError(f"analytic_params: {ap.n_cables} cables, the model has {params.n_cables}")
    model, _ = build_model(params)
    ix = model_index(model)
    # Bar bodies only: helpers and motors get no mass; the helpers keep their small rotary
    # inertia (a zero one would make M_q singular) and its exact share is removed below.
    model.body_mass[ix.other_bodies] = 0.0
    helper_bodies = ix.other_bodies[: len(ix.helper_joint)]
    data = mujoco.MjData(model)

    def place(alpha):
        pq = pose_qpos(alpha, params)
        data.qpos[:] = 0.0
        data.qvel[:] = 0.0
        data.qpos[ix.qpos_A], data.qpos[ix.qpos_B], data.qpos[ix.qpos_D] = pq.q_A, pq.q_B, pq.q_D
        data.qpos[ix.qpos_helper] = pq.q_helper
        mujoco.mj_fwdPosition(model, data)
        mujoco.mj_fwdVelocity(model, data)
        return pq

    place(np.zeros(n))
    l0 = data.ten_length[ix.cable_tendon].copy()
    rng = np.random.default_rng(seed)
    alphas = rng.uniform(-alpha_range, alpha_range, (int(samples), n))
    errs = {q: [0.0, 0.0] for q in THRESHOLDS}

    def record(q, mj, an):
        ab = float(np.max(np.abs(mj - an)))
        scale = float(np.max(np.abs(an)))
        rel = ab / scale if scale > 0 else (0.0 if ab == 0 else math.inf)
        errs[q][0] = max(errs[q][0], ab)
        errs[q][1] = max(errs[q][1], rel)

    it = alphas
    if progress:
        from tqdm import tqdm
        it = tqdm(alphas, desc=f"crossval N={n}", unit="pose")
    Mq = np.zeros((model.nv, model.nv))
    jr = np.zeros((3, model.nv))
    for alpha in it:
        pq = place(alpha)
        record("lengths", data.ten_length[ix.cable_tendon] - l0, cable_lengths(alpha, ap))
        gaps = data.site_xpos[ix.loop_sites[:, 0]] - data.site_xpos[ix.loop_sites[:, 1]]
        record("loop gap", np.linalg.norm(gaps, axis=1), np.zeros(n))
        J = _velocity_map(model, data, ix)
        closed = np.zeros_like(J)
        closed[ix.dof_A, np.arange(n)] = pq.dq_A
        closed[ix.dof_B, np.arange(n)] = pq.dq_B
        closed[ix.dof_D, np.arange(n)] = pq.dq_D
        closed[ix.dof_helper, ix.helper_joint] = pq.dq_helper
        record("dq/dalpha", J, closed)
        tenJ = _dense_ten_J(model, data, ix.cable_tendon)
        record("Z", -(tenJ @ J).T, transmission_matrix(alpha, ap))
        mujoco.mj_fullM(model, data, Mq)
        M_mj = J.T @ Mq @ J
        for b in helper_bodies:
            mujoco.mj_jacBody(model, data, None, jr, int(b))
            w = jr[2] @ J                                # helper's angular velocity per alpha_dot
            M_mj -= model.body_inertia[b, 2] * np.outer(w, w)
        record("M", M_mj, mass_matrix(alpha, ap, motors=False))
        record("g", J.T @ (data.qfrc_bias - data.qfrc_spring), gravity_spring_torque(alpha, ap))
    rows = []
    for q, (kind, thr) in THRESHOLDS.items():
        ab, rel = errs[q]
        val = ab if kind == "abs" else rel
        rows.append(Row(q, ab, rel, kind, thr, bool(val <= thr)))
    return CrossvalReport(n, int(samples), float(alpha_range), int(seed), rows, params.n_cables,
                          params.routing.describe())


def format_table(report: CrossvalReport) -> str:
    """The report as a fixed-width table (one line per quantity)."""
    head = (f"cross-validation MuJoCo vs analytic: N = {report.n_joints}, m = {report.n_cables} cables, "
            f"{report.samples} random poses in [-{math.degrees(report.alpha_range):g}, "
            f"{math.degrees(report.alpha_range):g}] deg^N, seed {report.seed}")
    lines = [head] + [f"  {line}" for line in report.routing.splitlines()]
    lines.append(f"{'quantity':<10} {'max abs':>11} {'max rel':>11}  {'threshold':<14} result")
    for r in report.rows:
        rel = "-" if r.quantity in ("lengths", "loop gap") else f"{r.max_rel:.3e}"
        lines.append(f"{r.quantity:<10} {r.max_abs:>11.3e} {rel:>11}  {r.kind + ' ' + format(r.threshold, '.0e'):<14} "
                     f"{'ok' if r.ok else 'FAIL'}")
    lines.append("all within thresholds" if report.ok else "SOME QUANTITIES EXCEED THEIR THRESHOLDS")
    return "\n".join(lines)


def write_json(report: CrossvalReport, path) -> None:
    atomic_write_json(path, report.to_dict())


# ----------------------------------------------------------------------------- dynamics

DYNAMICS_ALPHA0_DEG = (20.0, -10.0, 15.0)
DYNAMICS_FORCES = (25.0, 22.0, 20.0, 30.0)
FREE_RESPONSE_TOLERANCE_DEG = 0.3
"""Stated tolerance of the free response (max |alpha_mujoco - alpha_analytic| over the first
second) at the default timestep: first-order convergence was measured as 0.48, 0.22, 0.07,
0.013 deg for timesteps 1e-3, 5e-4, 2.5e-4, 1e-4 s (the error lives in the first 10 ms, where the
light bars snap onto suddenly tensioned cables)."""
LOOP_GAP_LIMIT = 1e-4


class DynamicsReport(NamedTuple):
    timestep: float
    hold_duration: float
    max_loop_gap: float          # m, over the hold
    max_tension: float           # N, over the hold
    tensions_finite: bool
    free_duration: float
    max_alpha_error_deg: float   # max |alpha_mujoco - alpha_analytic| over the free response
    rms_alpha_error_deg: float
    max_theta_error: float       # rad at the motor shaft
    tolerance_deg: float
    gap_limit: float

    @property
    def ok(self) -> bool:
        return (self.tensions_finite and self.max_loop_gap < self.gap_limit
                and self.max_alpha_error_deg <= self.tolerance_deg)


def _default_case(params: NeckParams):
    n = params.n_joints
    a0 = np.radians([DYNAMICS_ALPHA0_DEG[i % 3] for i in range(n)])
    # the k-th right cable takes DYNAMICS_FORCES[k] (the third beyond), left cables the fourth
    sides = params.routing.sides
    right = np.cumsum([s == "right" for s in sides]) - 1
    f = np.array([DYNAMICS_FORCES[min(k, 2)] if s == "right" else DYNAMICS_FORCES[3] for s, k in zip(sides, right)])
    return a0, f


def dynamics_check(params: NeckParams, *, timestep: float | None = None, hold_duration: float = 10.0,
                   free_duration: float = 1.0, alpha0=None, forces=None,
                   tolerance_deg: float = FREE_RESPONSE_TOLERANCE_DEG, gap_limit: float = LOOP_GAP_LIMIT,
                   progress: bool = False) -> DynamicsReport:
    """The plant under constant antagonistic forces (default (25, 22, 20, 30) N
    from alpha0 = (20, -10, 15) deg) for ``hold_duration`` s -- loop gaps and tensions -- and
    its free response against :func:`neck_sim.analytic.simulate_elastic` (eqs 29-30, same
    parameters and forces, friction on) over the first ``free_duration`` s."""
    from neck_sim.analytic.cables import motor_angles_rigid
    from neck_sim.analytic.dynamics import simulate_elastic
    from neck_sim.plant_spec import PlantSpec
    from neck_sim.recorder import Recorder

    a_def, f_def = _default_case(params)
    a0 = a_def if alpha0 is None else np.asarray(alpha0, dtype=float)
    f = f_def if forces is None else np.asarray(forces, dtype=float)
    plant = PlantSpec(params, timestep=timestep).build()
    plant.reset(a0)
    rate = params.control.rate_hz
    steps = int(round(max(hold_duration, free_duration) * rate))
    free_steps = int(round(free_duration * rate))
    # row k: the state after k periods (row 0 the start)
    rec = Recorder(params.n_joints, params.n_cables, steps + 1)
    rec.sample(0, 0.0, plant.encoders(), f, plant.truth())
    it = range(steps)
    if progress:
        from tqdm import tqdm
        it = tqdm(it, desc="dynamics check", unit="step", mininterval=0.5)
    for k in it:
        plant.step(f)
        rec.sample(k + 1, (k + 1) / rate, plant.encoders(), f, plant.truth())
    alpha = rec.truth_column("alpha")[:free_steps + 1]
    theta = rec.truth_column("theta")[:free_steps + 1]
    held = np.flatnonzero(np.arange(1, steps + 1) / rate <= hold_duration + 1e-12) + 1     # rows over the hold
    tension = rec.truth_column("tension")[held]
    max_gap = max(0.0, float(rec.truth_column("loop_gap")[held].max(initial=0.0)))
    finite = bool(np.all(np.isfinite(tension)))
    max_t = max(0.0, float(tension.max(initial=0.0)))
    ts, ref = simulate_elastic(a0, motor_angles_rigid(a0, params), lambda t: f, free_duration, params,
                               sample_dt=1.0 / params.control.rate_hz, rtol=1e-8, atol=1e-10)
    err = np.abs(np.array(alpha) - ref.alpha)
    return DynamicsReport(plant.timestep, hold_duration, max_gap, max_t, finite, free_duration,
                          float(np.degrees(err.max())), float(np.degrees(np.sqrt((err ** 2).mean()))),
                          float(np.abs(np.array(theta) - ref.theta).max()), tolerance_deg, gap_limit)


def format_dynamics(rep: DynamicsReport) -> str:
    return "\n".join([
        f"dynamics check (timestep {rep.timestep:g} s): constant antagonistic forces",
        f"  hold {rep.hold_duration:g} s: max loop gap {rep.max_loop_gap:.2e} m (limit {rep.gap_limit:.0e}), "
        f"max tension {rep.max_tension:.1f} N, tensions finite: {rep.tensions_finite}",
        f"  free response vs simulate_elastic over {rep.free_duration:g} s: max |d alpha| "
        f"{rep.max_alpha_error_deg:.3f} deg (tolerance {rep.tolerance_deg:g}), rms {rep.rms_alpha_error_deg:.3f} deg, "
        f"max |d theta| {rep.max_theta_error:.3f} rad",
        "  ok" if rep.ok else "  FAIL"])
