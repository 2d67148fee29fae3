"""The Python reference backend: the physics of ``plant_callback.c`` written from the definitions
in :mod:`neck_sim.analytic` and the effects, 6-8x slower per control period.

It takes over when no C compiler is available (``set_backend("python")`` chooses it) and is what
the C file is checked against (``tests/test_plant.py``, ``tests/test_effect_contract.py``).
:func:`python_forces` is the control callback of one plant (its
:class:`neck_sim.native.NativePlant`); :func:`step_period` is ``neck_step_batch``'s loop over K
plants.
"""

from __future__ import annotations

import mujoco
import numpy as np

from neck_sim.analytic.dynamics import cable_tension, cap_elongation, motor_friction

__all__ = ["friction", "python_forces", "constraint_tensions", "step_period"]


def friction(record, theta_dot, tension) -> np.ndarray:
    """Motor friction (m,) N at motor speeds ``theta_dot`` (m,) rad/s and cable tensions (m,) N:
    eq (37) plus every motor-side effect's force."""
    f = motor_friction(theta_dot, record.true_params)
    for eff in record.motor_effects:
        f = f + eff.motor_force(theta_dot, tension)
    return f


def python_forces(record) -> None:
    """The control callback of one plant: the affine actuator biases (eq 54 tension, eq 37
    friction, as the top of ``plant_callback.c`` explains) into the model and the truth into the
    struct's outputs."""
    m, d, ix, out = record.model, record.data, record.index, record.outputs
    tp = record.true_params
    x = d.ten_length[ix.cable_tendon] - record.rest + record.x_pre
    xd = d.ten_velocity[ix.cable_tendon].copy()
    bias = m.actuator_biasprm
    if record.rigid_cables:
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
    out.tension[:] = t
    out.elongation[:] = x
    ratio = record.ratio
    sd = d.qvel[ix.dof_motor]
    w = ratio * sd
    hw = 1e-6
    fr = friction(record, w, t)
    dfr = (friction(record, w + hw, t) - friction(record, w - hw, t)) / (2 * hw)
    bias[ix.drive_actuator, 0] = -fr + dfr * ratio * sd
    bias[ix.drive_actuator, 1] = 0.0
    bias[ix.drive_actuator, 2] = -dfr * ratio
    out.theta[:] = ratio * d.qpos[ix.qpos_motor]
    out.theta_dot[:] = w
    out.alpha[:] = d.qpos[ix.qpos_A] + d.qpos[ix.qpos_D]
    out.alpha_dot[:] = d.qvel[ix.dof_A] + d.qvel[ix.dof_D]
    gaps = d.site_xpos[ix.loop_sites[:, 0]] - d.site_xpos[ix.loop_sites[:, 1]]
    record.struct.loop_gap = float(np.sqrt((gaps * gaps).sum(axis=1)).max())
    record.struct.calls += 1


def constraint_tensions(record) -> np.ndarray:
    """Rigid cables: the tension (m,) N of each cable, the force of its equality constraint."""
    d, ix = record.data, record.index
    out = np.zeros(record.n_cables)
    rows = np.nonzero(d.efc_type[: d.nefc] == mujoco.mjtConstraint.mjCNSTR_EQUALITY)[0]
    ids = d.efc_id[rows]
    for j, eq in enumerate(ix.rigid_equality):
        sel = rows[ids == eq]
        if sel.size:
            out[j] = -d.efc_force[sel[0]]
    return out


def step_period(records, rows, nsub: int, commands, per_substep: bool, capture, frame_alpha) -> None:
    """One control period of the plants ``records[i]`` for i in ``rows``: the loop of
    ``neck_step_batch`` with the Python callback (which the caller installs).

    commands: (K, n_sub, m) N per sub-step if ``per_substep``, else (K, m) N for the whole
    period; capture (K, n_sub) or None: camera frames due at the end of each sub-step, whose joint
    angles go into frame_alpha (K, n_sub, N) rad.  The truth is left in each record's outputs.
    """
    for i in rows:
        record = records[i]
        m, d, ix = record.model, record.data, record.index
        ncable = record.n_cables
        for s in range(nsub):
            d.ctrl[:ncable] = commands[i, s] if per_substep else commands[i]
            (mujoco.mj_step2 if s == 0 else mujoco.mj_step)(m, d)
            if capture is not None and capture[i, s]:
                frame_alpha[i, s] = d.qpos[ix.qpos_A] + d.qpos[ix.qpos_D]
        rigid = constraint_tensions(record) if record.rigid_cables else None
        mujoco.mj_step1(m, d)
        if rigid is not None:
            record.outputs.tension[:] = rigid
