"""MJCF builder: the N-X neck as a MuJoCo model, generated from :class:`~neck_sim.params.NeckParams`.

Frame: the model lives in the analytic frame of :mod:`neck_sim.analytic.geometry` -- the neck
moves in the x-y plane, y up, gravity along -y, every hinge axis along +z (so a positive hinge
angle is counter-clockwise, like alpha).  Nothing is rotated: a point (x, y) of the analytic
model is the MuJoCo point (x, y, z_row).  At ``qpos = 0`` the neck is straight (alpha = 0).

Bodies of X-joint i (``j{i}_...``): diagonal ``ad`` hinged at A_i on the base bar (hinge
``j{i}_A``), diagonal ``bc`` hinged at B_i (``j{i}_B``), top bar ``top`` hinged at D_i on ``ad``
(``j{i}_D``); the loop is closed by an equality ``connect`` between site ``j{i}_C_top`` (on the
top bar) and ``j{i}_C_bc`` (on ``bc``).  The top bar's frame is the analytic frame i+1 (origin at
the middle of CD, x along C->D) and is the base bar of joint i+1; the base bar of joint 1 is the
world.  Hence alpha_i = q(j{i}_A) + q(j{i}_D).

Cables are spatial tendons ``c1``..``c{N+1}`` routed as in ``docs/geometry-and-errata.md``
(one z-row per cable, pulleys of radius r as wrap cylinders on the hinge axes, sidesites at 2r
in the direction of the middle of each arc, a site between any two wraps).  Right cable j: case
(d) on joints 1..j-1 (crossing the diagonal B->C and the top bar C->D through their midpoints),
case (b) on joint j, attached at D_j.  Left cable: case (c) on joints 1..N-1 (external tangent
of the left side, kept by a light helper body ``j{i}_helper`` hinged at A_i whose angle a
fixed-tendon equality holds at alpha_i/2; the extra full turn on C_i is split in two arcs by
site ``c{N+1}_turn{i}``), case (a) on joint N, attached at C_N.

Each motor is a slide joint ``motor{j}`` in cable-length units (s = (r_d/R) theta, armature
I_a (R/r_d)^2) that carries the cable's first site, on the cable's incoming straight line: the
tendon length is then ``l_c(alpha) + s + const``, so ``ten_length - rest = x_c``, the elongation
of :mod:`neck_sim.analytic.cables`, and a force -t on the tendon pulls the bars *and* the motor.

Actuators (``actuator`` order): ``drive{j}`` on ``motor{j}`` (ctrl = commanded force f, N, gain
1, affine bias = minus motor friction) for j = 1..N+1, then ``tension{j}`` on tendon ``c{j}``
(gain 0, affine bias = minus the cable tension).  In the static XML the tension bias is a linear
bilateral spring (k_j, c_a_j) about the rest length and the friction bias is zero, so the file
runs on its own in ``python -m mujoco.viewer``; :mod:`neck_sim.plant` rewrites both biases at
every physics step (eq 54 tension-only cables, eq 37 friction and the plant's effects).

Side springs are spatial tendons ``j{i}_spring_left`` (A_i C_i) and ``j{i}_spring_right``
(B_i D_i) with stiffness and springlength.  Rigid cables (``rigid_cables=True``): each cable
tendon is held at its rest length by an equality constraint ``c{j}_rigid`` instead.

Modules: :mod:`~neck_sim.mjcf.paths` (cable and pulley geometry), :mod:`~neck_sim.mjcf.build`
(the XML assembly), :mod:`~neck_sim.mjcf.index` (reading a compiled model).
``python -m neck_sim.mjcf`` regenerates the committed ``mjcf/neck3x.xml``.

Example::

    import mujoco
    from neck_sim import mjcf
    from neck_sim.params import default_params

    p = default_params(3)
    model, xml = mjcf.build_model(p)                   # compiled MjModel and its MJCF text
    index = mjcf.model_index(model)                    # qpos/dof/tendon/actuator addresses by name
    data = mujoco.MjData(model)
    q = mjcf.pose_qpos([0.3, -0.2, 0.1], p)            # hinge angles of a closed-form pose (rad)
    data.qpos[index.qpos_A], data.qpos[index.qpos_B], data.qpos[index.qpos_D] = q.q_A, q.q_B, q.q_D
"""

from neck_sim.mjcf.build import (DEFAULT_TIMESTEP, IMPLICITFAST_DAMPING_LIMIT, build_model, build_xml,
                                 committed_xml_path, integrator_for, write_xml)
from neck_sim.mjcf.index import ModelIndex, PoseQpos, model_index, pose_qpos
from neck_sim.mjcf.paths import Layout, helper_joints, wrap_arcs

__all__ = ["DEFAULT_TIMESTEP", "Layout", "build_xml", "build_model", "write_xml", "ModelIndex", "PoseQpos",
           "model_index", "pose_qpos", "wrap_arcs", "committed_xml_path", "helper_joints", "integrator_for",
           "IMPLICITFAST_DAMPING_LIMIT"]
