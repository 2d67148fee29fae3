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
"""

from __future__ import annotations

import math
import os
import xml.etree.ElementTree as ET
from typing import NamedTuple

import numpy as np

from neck_sim.analytic.geometry import _joint_local, check_alpha, forward_kinematics
from neck_sim.atomic import atomic_write_bytes
from neck_sim.params import NeckParams
from neck_sim.routing import SEG_LEFT_END, SEG_LEFT_SIDE, SEG_LEFT_STRUT, SEG_RIGHT_SIDE, SEG_RIGHT_STRUT

__all__ = ["DEFAULT_TIMESTEP", "Layout", "build_xml", "build_model", "write_xml", "ModelIndex",
           "model_index", "pose_qpos", "wrap_arcs", "committed_xml_path", "helper_joints",
           "integrator_for", "IMPLICITFAST_DAMPING_LIMIT"]

DEFAULT_TIMESTEP = 5e-4
"""Physics timestep (s): the largest that keeps the issue-3 dynamics check true (see plant)."""

_MOTOR_DISTANCE = 0.25      # m, motor site to the first pulley's tangent point
_ROW_PITCH = 0.004          # m, z distance between cable rows
_SIDESITE_RADIUS = 2.0      # x r: sidesites at 2r from the pulley axis
_TURN_RADIUS = 2.5          # x r: site splitting the full turn on C_i (shadow 2 acos(1/2.5))
_HELPER_MASS = 1e-6         # kg, helper body (point mass on the hinge axis)
_HELPER_INERTIA = 1e-7      # kg m^2 about the hinge; keeps its cable-driven mode stable
_MOTOR_BODY_MASS = 1e-3     # kg; the reflected inertia is the slide's armature
_PULLEY_HALF_HEIGHT = 0.0015


class Layout(NamedTuple):
    """Where everything is at the straight pose, in world coordinates (x, y); z rows per cable."""

    corners: np.ndarray       # (N, 4, 2) A, B, C, D of every joint
    mid_top: np.ndarray       # (N, 2) middle of C_i D_i (origin of the top-bar body)
    row_z: np.ndarray         # (m,) z of each cable row
    motor_site: np.ndarray    # (m, 2) first site of each cable (on the motor body)
    motor_axis: np.ndarray    # (m, 2) slide axis: the direction that winds the cable up


def _layout(params: NeckParams) -> Layout:
    g = params.geometry
    n = g.n_joints
    kin = forward_kinematics(np.zeros(n), params)
    corners = kin.corners
    mid_top = 0.5 * (corners[:, 2] + corners[:, 3])
    cables = params.routing.cables
    row_z = np.array([_ROW_PITCH * c.row for c in cables])
    A1, B1 = corners[0, 0], corners[0, 1]
    # Right cables arrive under the base bar travelling +x and wrap B_1 counter-clockwise; left
    # cables arrive travelling -x and wrap A_1 clockwise: both lines are y = -r.
    right = np.array([B1[0] - _MOTOR_DISTANCE, -g.r])
    left = np.array([A1[0] + _MOTOR_DISTANCE, -g.r])
    motor_site = np.array([left if c.side == "left" else right for c in cables])
    motor_axis = np.array([[1.0, 0.0] if c.side == "left" else [-1.0, 0.0] for c in cables])
    return Layout(corners, mid_top, row_z, motor_site, motor_axis)


def helper_joints(params: NeckParams) -> list[tuple[int, str]]:
    """(joint i, side) of every helper body, by joint then left before right.

    A side-routed cable runs on the external tangent of a side, where no bar lies: a light helper
    body hinged at A_i (left, ``j{i}_helper``) or B_i (right, ``j{i}_helper_right``), held at
    alpha_i / 2 by a fixed-tendon equality, carries a site on that tangent.
    """
    kinds = params.routing.segment_cases(params.n_joints)
    out = []
    for i in range(params.n_joints):
        for side, kind in (("left", SEG_LEFT_SIDE), ("right", SEG_RIGHT_SIDE)):
            if np.any(kinds[:, i] == kind):
                out.append((i + 1, side))
    return out


def _helper_name(i: int, side: str) -> str:
    return f"j{i}_helper" if side == "left" else f"j{i}_helper_right"


# --------------------------------------------------------------------------------------------
# Cable paths as (kind, ...) items; "site" items are points, "wrap" items are pulleys.

class _Site(NamedTuple):
    name: str
    body: str
    point: np.ndarray          # world (x, y) at the straight pose


class _Wrap(NamedTuple):
    pulley: str                # geom name
    body: str
    centre: np.ndarray         # world (x, y) at the straight pose
    sense: int                 # +1 counter-clockwise, -1 clockwise
    sidesite: str


def _base_body(i: int) -> str:
    """Body carrying the base bar of joint i (1-based)."""
    return "world" if i == 1 else f"j{i - 1}_top"


def _cable_paths(params: NeckParams, lay: Layout) -> list[list]:
    """Path items of each cable (index 0..m-1), alternating sites and wraps, sites at both ends.

    Per joint i (corners A, B, C, D): case (d) crosses through the midpoints of the diagonal B->C
    and of the top bar, wrapping C_i clockwise and D_i = B_{i+1} counter-clockwise; its mirror
    (d') crosses A->D and the top bar, wrapping D_i ccw and C_i = A_{i+1} cw; a side-routed pass
    (c, c') touches a helper site on the external tangent, then turns once more round the top
    pulley, split in two arcs by a site at 2.5 r towards the inside; an end (a, b) is a site at
    C_i or D_i.
    """
    g = params.geometry
    c = lay.corners
    r = g.r
    rise = 0.5 * (g.L - g.b)
    paths = []
    for j, cable in enumerate(params.routing.cables, start=1):
        tag = f"c{j}"
        left = cable.side == "left"
        items: list = [_Site(f"{tag}_motor", f"motor{j}", lay.motor_site[j - 1])]
        if left:
            items.append(_Wrap(f"{tag}_pulley_A1", "world", c[0, 0], -1, f"{tag}_side_A1"))
        else:
            items.append(_Wrap(f"{tag}_pulley_B1", "world", c[0, 1], +1, f"{tag}_side_B1"))
        for i, kind in enumerate(cable.kinds, start=1):
            A, B, C, D = c[i - 1]
            if i < len(c):
                D = c[i, 1]                         # D_i as B_{i+1}, the base corner of the next joint
            top = f"j{i}_top"
            if kind == SEG_RIGHT_STRUT:
                items += [_Site(f"{tag}_mid_bc{i}", f"j{i}_bc", 0.5 * (B + C)),
                          _Wrap(f"{tag}_pulley_C{i}", top, C, -1, f"{tag}_side_C{i}"),
                          _Site(f"{tag}_mid_top{i}", top, 0.5 * (C + D)),
                          _Wrap(f"{tag}_pulley_B{i + 1}", top, D, +1, f"{tag}_side_B{i + 1}")]
            elif kind == SEG_LEFT_STRUT:
                items += [_Site(f"{tag}_mid_ad{i}", f"j{i}_ad", 0.5 * (A + D)),
                          _Wrap(f"{tag}_pulley_D{i}", top, D, +1, f"{tag}_side_D{i}"),
                          _Site(f"{tag}_mid_top{i}", top, 0.5 * (C + D)),
                          _Wrap(f"{tag}_pulley_C{i}", top, C, -1, f"{tag}_side_C{i}")]
            elif kind == SEG_LEFT_SIDE:
                pul, side = f"{tag}_pulley_C{i}", f"{tag}_side_C{i}"
                items += [_Site(f"{tag}_helper{i}", _helper_name(i, "left"), A + np.array([-r, rise])),
                          _Wrap(pul, top, C, -1, side + "a"),
                          _Site(f"{tag}_turn{i}", top, C + np.array([_TURN_RADIUS * r, 0.0])),
                          _Wrap(pul, top, C, -1, side + "b")]
            elif kind == SEG_RIGHT_SIDE:
                pul, side = f"{tag}_pulley_B{i + 1}", f"{tag}_side_B{i + 1}"
                items += [_Site(f"{tag}_helper_right{i}", _helper_name(i, "right"), B + np.array([r, rise])),
                          _Wrap(pul, top, D, +1, side + "a"),
                          _Site(f"{tag}_turn{i}", top, D - np.array([_TURN_RADIUS * r, 0.0])),
                          _Wrap(pul, top, D, +1, side + "b")]
            else:                                   # case (a): attached at C_i; (b): at D_i
                items.append(_Site(f"{tag}_end", top, C if kind == SEG_LEFT_END else D))
        paths.append(items)
    return paths


def _angle(v) -> float:
    return math.atan2(v[1], v[0])


def _arc(centre, r: float, p, q, sense: int) -> tuple[float, float]:
    """Contact angle where the cable from p meets the pulley, and the wrap angle to leave for q.

    A cable wrapping with ``sense`` (+1 ccw) touches the pulley at angle phi with travel
    direction phi + sense*90 deg; the tangent from an outside point at distance d touches at
    beta -/+ acos(r/d).  Returns (phi_in, arc) with arc in [0, 2 pi).
    """
    dp, dq = np.asarray(p) - centre, np.asarray(q) - centre
    phi_in = _angle(dp) + sense * math.acos(r / math.hypot(*dp))
    phi_out = _angle(dq) - sense * math.acos(r / math.hypot(*dq))
    return phi_in, (sense * (phi_out - phi_in)) % (2 * math.pi)


def wrap_arcs(params: NeckParams, alpha=None) -> dict[str, float]:
    """Wrap angle (rad) of every pulley wrap of every cable at pose ``alpha`` (default straight).

    Computed from the closed-form geometry with the builder's own routing; the routing is valid
    while every arc stays in (0, pi) (the sidesites pick the side from the straight pose).
    Keys are the sidesite names.
    """
    n = params.n_joints
    a = np.zeros(n) if alpha is None else check_alpha(alpha, n)
    lay = _layout(params)
    world = _world_transform(params, a, lay)
    out = {}
    r = params.geometry.r
    for path in _cable_paths(params, lay):
        for k, item in enumerate(path):
            if isinstance(item, _Wrap):
                p = world(path[k - 1].body, path[k - 1].point)
                q = world(path[k + 1].body, path[k + 1].point)
                _, arc = _arc(world(item.body, item.centre), r, p, q, item.sense)
                out[item.sidesite] = arc
    return out


def _world_transform(params: NeckParams, alpha: np.ndarray, lay: Layout):
    """Map (body, straight-pose world point) to the world point at pose alpha (bars only)."""
    g = params.geometry
    n = g.n_joints
    kin = forward_kinematics(alpha, params)
    jl = _joint_local(alpha, g.b, g.L)
    j0 = _joint_local(np.zeros(n), g.b, g.L)
    A0 = np.array([-g.b / 2, 0.0])
    B0 = np.array([g.b / 2, 0.0])
    frames = {"world": (np.zeros(2), 0.0, np.zeros(2))}   # body -> (origin now, angle, origin straight)
    base_angle = 0.0
    for i in range(1, n + 1):
        A_now, B_now, C_now, D_now = kin.corners[i - 1]
        A_st, B_st = lay.corners[i - 1, 0], lay.corners[i - 1, 1]
        C_loc, D_loc = jl.C[i - 1], jl.D[i - 1]
        C0, D0 = j0.C[i - 1], j0.D[i - 1]
        ang_ad = _angle(D_loc - A0) - _angle(D0 - A0)
        ang_bc = _angle(C_loc - B0) - _angle(C0 - B0)
        frames[f"j{i}_ad"] = (A_now, base_angle + ang_ad, A_st)
        frames[f"j{i}_bc"] = (B_now, base_angle + ang_bc, B_st)
        frames[f"j{i}_helper"] = (A_now, base_angle + alpha[i - 1] / 2, A_st)
        frames[f"j{i}_helper_right"] = (B_now, base_angle + alpha[i - 1] / 2, B_st)
        frames[f"j{i}_top"] = (0.5 * (C_now + D_now), base_angle + alpha[i - 1], lay.mid_top[i - 1])
        base_angle += alpha[i - 1]

    def world(body: str, point) -> np.ndarray:
        if body.startswith("motor"):
            return np.asarray(point)
        origin_now, ang, origin_st = frames[body]
        c, s = math.cos(ang), math.sin(ang)
        v = np.asarray(point) - origin_st
        return origin_now + np.array([c * v[0] - s * v[1], s * v[0] + c * v[1]])

    return world


# --------------------------------------------------------------------------------------------
# XML generation

def _fmt(x: float) -> str:
    x = float(x)
    if x == 0.0:
        return "0"
    return repr(x)


def _vec(*xs) -> str:
    return " ".join(_fmt(x) for x in xs)


def _rod_inertial(parent: ET.Element, p0, p1, mass: float, length: float) -> None:
    """Slender rod between p0 and p1 (body-local 2-D points): I = m l^2 / 12 about its centre."""
    centre = 0.5 * (np.asarray(p0) + np.asarray(p1))
    d = np.asarray(p1) - np.asarray(p0)
    half = 0.5 * _angle(d)
    inertia = mass * length ** 2 / 12.0
    # Principal axes: x along the rod (tiny), y and z across it.
    ET.SubElement(parent, "inertial", pos=_vec(centre[0], centre[1], 0.0),
                  quat=_vec(math.cos(half), 0.0, 0.0, math.sin(half)), mass=_fmt(mass),
                  diaginertia=_vec(inertia * 1e-3, inertia, inertia))


def _capsule(parent: ET.Element, name: str, p0, p1, rgba: str, radius: float = 0.002) -> None:
    ET.SubElement(parent, "geom", name=name, type="capsule", size=_fmt(radius),
                  fromto=_vec(p0[0], p0[1], 0.0, p1[0], p1[1], 0.0), rgba=rgba, group="1")


#: Largest c_a dt / m_bar (cable damping N s/m x timestep s / lightest bar kg) at which MuJoCo's
#: ``implicitfast`` integrator keeps the tension-only cables stable.  Measured (issue 13): with 20 g
#: bars at dt = 0.5 ms, 100 N s/m (2.5) runs the control tests and 300 N s/m (7.5) diverges within
#: 20 ms; 1.5 (60 N s/m) keeps a margin.  The default 50 N s/m (1.25) stays on implicitfast.
IMPLICITFAST_DAMPING_LIMIT = 1.5


def integrator_for(params: NeckParams, timestep: float = DEFAULT_TIMESTEP, rigid_cables: bool = False) -> str:
    """MuJoCo integrator for the plant's cables: ``implicitfast`` while the cable damping is light
    for the bars at this timestep (fastest), else ``discrete``.

    Why: ``implicitfast`` treats the eq (54) damping implicitly through the actuator's velocity
    derivative, but MuJoCo solves the loop-closure constraints in the plain mass metric first; when
    dt c_a is large against the bars' mass the two disagree and the loops blow up (the paper's
    c_a = 3000 N s/m diverged within 2 ms).  ``discrete`` (MuJoCo >= 3.13) solves constraints and
    implicit damping in one metric, M + dt D, and is stable and accurate up to c_a = 3000 N s/m at
    0.5 ms, at about twice the cost per step.
    """
    if rigid_cables:
        return "implicitfast"
    bars = min(params.inertia.bar_mass, params.inertia.diagonal_mass)
    stiff = bars <= 0 or max(params.cables.c_a) * timestep / bars > IMPLICITFAST_DAMPING_LIMIT
    return "discrete" if stiff else "implicitfast"


def build_xml(params: NeckParams, *, timestep: float = DEFAULT_TIMESTEP, rigid_cables: bool = False,
              rest_lengths=None) -> str:
    """The MJCF text of the neck described by ``params`` (see the module docstring).

    ``rest_lengths`` (N+1,) m: tendon lengths of the cables at the straight pose with the motors
    at zero, used for the static linear stand-in of the cables; computed by compiling once when
    omitted.
    """
    if not (math.isfinite(timestep) and timestep > 0):
        raise ValueError(f"timestep: must be finite and positive, got {timestep!r}")
    if params.actuation.reflected_inertia <= 10 * _MOTOR_BODY_MASS:
        raise ValueError(f"actuation.I_a: reflected inertia I_a (R/r_d)^2 = {params.actuation.reflected_inertia} kg "
                         f"is too small for the motor model (must exceed {10 * _MOTOR_BODY_MASS} kg)")
    if rest_lengths is None:
        import mujoco
        model = mujoco.MjModel.from_xml_string(
            build_xml(params, timestep=timestep, rigid_cables=rigid_cables, rest_lengths=np.zeros(params.n_cables)))
        data = mujoco.MjData(model)
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        mujoco.mj_tendon(model, data)
        rest_lengths = data.ten_length[:params.n_cables].copy()
    rest_lengths = np.asarray(rest_lengths, dtype=float)
    g, act, inert = params.geometry, params.actuation, params.inertia
    n, m = g.n_joints, params.n_cables
    helpers = helper_joints(params)
    lay = _layout(params)
    c = lay.corners
    paths = _cable_paths(params, lay)
    r = g.r

    root = ET.Element("mujoco", model=f"neck{n}x")
    ET.SubElement(root, "compiler", angle="radian", autolimits="true")
    opt = ET.SubElement(root, "option", timestep=_fmt(timestep),
                        integrator=integrator_for(params, timestep, rigid_cables),
                        gravity=_vec(0.0, -inert.gravity, 0.0), solver="Newton", iterations="50",
                        tolerance="1e-10")
    ET.SubElement(opt, "flag", contact="disable")
    vis = ET.SubElement(root, "visual")
    ET.SubElement(vis, "global", offwidth="1280", offheight="720", azimuth="90", elevation="0")
    ET.SubElement(vis, "scale", framelength="0.02", framewidth="0.002", jointlength="0.01",
                  jointwidth="0.002")
    ET.SubElement(vis, "headlight", ambient="0.5 0.5 0.5", diffuse="0.6 0.6 0.6")
    asset = ET.SubElement(root, "asset")
    ET.SubElement(asset, "texture", name="sky", type="skybox", builtin="gradient", rgb1="1 1 1",
                  rgb2="0.75 0.8 0.88", width="64", height="64")
    ET.SubElement(root, "statistic", center=_vec(0.0, 0.12, 0.0), extent="0.35")
    default = ET.SubElement(root, "default")
    ET.SubElement(default, "geom", contype="0", conaffinity="0", density="0")
    ET.SubElement(default, "joint", type="hinge", axis="0 0 1", limited="false")
    ET.SubElement(default, "site", size="0.0006", group="3", rgba="0.9 0.9 0.2 1")
    ET.SubElement(default, "tendon", limited="false")

    world = ET.SubElement(root, "worldbody")
    ET.SubElement(world, "light", pos="0 0.15 1", dir="0 0 -1", directional="true")
    ET.SubElement(world, "camera", name="front", pos=_vec(0.0, 0.12, 0.6), xyaxes="1 0 0 0 1 0")
    _capsule(world, "base_bar", c[0, 0], c[0, 1], "0.3 0.3 0.3 1")

    bodies: dict[str, ET.Element] = {"world": world}
    origins: dict[str, np.ndarray] = {"world": np.zeros(2)}   # straight-pose world origin of each body

    def local(body: str, point) -> np.ndarray:
        return np.asarray(point) - origins[body]

    def add_body(name: str, parent: str, origin) -> ET.Element:
        el = ET.SubElement(bodies[parent], "body", name=name,
                           pos=_vec(*(np.asarray(origin) - origins[parent]), 0.0))
        bodies[name] = el
        origins[name] = np.asarray(origin, dtype=float)
        return el

    for i in range(1, n + 1):
        A, B, C, D = c[i - 1]
        base = _base_body(i)
        ad = add_body(f"j{i}_ad", base, A)
        ET.SubElement(ad, "joint", name=f"j{i}_A")
        _rod_inertial(ad, local(f"j{i}_ad", A), local(f"j{i}_ad", D), inert.diagonal_mass, g.L)
        _capsule(ad, f"j{i}_ad_geom", local(f"j{i}_ad", A), local(f"j{i}_ad", D), "0.2 0.4 0.8 1")
        top = add_body(f"j{i}_top", f"j{i}_ad", lay.mid_top[i - 1])
        ET.SubElement(top, "joint", name=f"j{i}_D", pos=_vec(*local(f"j{i}_top", D), 0.0))
        top_mass = inert.bar_mass + (inert.payload_mass if i == n else 0.0)
        # The payload is a point mass at the head bar's centre: same centre, same rotary inertia.
        ET.SubElement(top, "inertial", pos="0 0 0", mass=_fmt(top_mass),
                      diaginertia=_vec(inert.bar_mass * g.b ** 2 / 12e3, inert.bar_mass * g.b ** 2 / 12,
                                       inert.bar_mass * g.b ** 2 / 12))
        _capsule(top, f"j{i}_top_geom", local(f"j{i}_top", C), local(f"j{i}_top", D), "0.3 0.3 0.3 1")
        ET.SubElement(top, "site", name=f"j{i}_C_top", pos=_vec(*local(f"j{i}_top", C), 0.0))
        ET.SubElement(top, "site", name=f"j{i}_D_top", pos=_vec(*local(f"j{i}_top", D), 0.0))
        bc = add_body(f"j{i}_bc", base, B)
        ET.SubElement(bc, "joint", name=f"j{i}_B")
        _rod_inertial(bc, local(f"j{i}_bc", B), local(f"j{i}_bc", C), inert.diagonal_mass, g.L)
        _capsule(bc, f"j{i}_bc_geom", local(f"j{i}_bc", B), local(f"j{i}_bc", C), "0.8 0.4 0.2 1")
        ET.SubElement(bc, "site", name=f"j{i}_C_bc", pos=_vec(*local(f"j{i}_bc", C), 0.0))
        ET.SubElement(bodies[base], "site", name=f"j{i}_A_base", pos=_vec(*local(base, A), 0.0))
        ET.SubElement(bodies[base], "site", name=f"j{i}_B_base", pos=_vec(*local(base, B), 0.0))
        for hi, side in helpers:
            if hi == i:
                name = _helper_name(i, side)
                helper = add_body(name, base, A if side == "left" else B)
                ET.SubElement(helper, "joint", name=name)
                ET.SubElement(helper, "inertial", pos="0 0 0", mass=_fmt(_HELPER_MASS),
                              diaginertia=_vec(_HELPER_INERTIA, _HELPER_INERTIA, _HELPER_INERTIA))

    fric = params.friction
    for j in range(m):
        name = f"motor{j + 1}"
        mb = add_body(name, "world", lay.motor_site[j])
        ax = lay.motor_axis[j]
        # Static stand-in for eq (37): its slope at rest, (2/pi) f_s c_s R/r_d (N s/m along the
        # cable); the plant sets this damping to zero and applies eq (37) itself.
        ET.SubElement(mb, "joint", name=name, type="slide", axis=_vec(ax[0], ax[1], 0.0),
                      armature=_fmt(act.reflected_inertia - _MOTOR_BODY_MASS),   # total = I_a (R/r_d)^2
                      damping=_fmt(2 / math.pi * fric.f_s[j] * fric.c_s * act.R / act.r_d))
        ET.SubElement(mb, "inertial", pos="0 0 0", mass=_fmt(_MOTOR_BODY_MASS),
                      diaginertia="1e-9 1e-9 1e-9")
        ET.SubElement(mb, "geom", name=f"{name}_geom", type="box", size="0.006 0.004 0.0015",
                      pos=_vec(*(-0.006 * ax), lay.row_z[j]), rgba="0.1 0.1 0.1 1", group="1")

    # Cable sites, pulleys and sidesites.
    colours = ["0.1 0.3 0.9 1", "0.9 0.8 0.1 1", "0.9 0.1 0.1 1", "0.6 0.2 0.8 1", "0.2 0.7 0.7 1"]
    made_pulleys = set()
    for j, path in enumerate(paths):
        z = lay.row_z[j]
        for k, item in enumerate(path):
            if isinstance(item, _Site):
                ET.SubElement(bodies[item.body], "site", name=item.name, pos=_vec(*local(item.body, item.point), z))
                continue
            if item.pulley not in made_pulleys:
                made_pulleys.add(item.pulley)
                ctr = local(item.body, item.centre)
                ET.SubElement(bodies[item.body], "geom", name=item.pulley, type="cylinder",
                              size=_vec(r, _PULLEY_HALF_HEIGHT), pos=_vec(ctr[0], ctr[1], z),
                              rgba="0.7 0.7 0.7 0.6", group="2")
            phi_in, arc = _arc(item.centre, r, path[k - 1].point, path[k + 1].point, item.sense)
            mid = phi_in + item.sense * arc / 2
            side = item.centre + _SIDESITE_RADIUS * r * np.array([math.cos(mid), math.sin(mid)])
            ET.SubElement(bodies[item.body], "site", name=item.sidesite, pos=_vec(*local(item.body, side), z))

    tendon = ET.SubElement(root, "tendon")
    for j, path in enumerate(paths):
        left = params.routing.cables[j].side == "left"
        sp = ET.SubElement(tendon, "spatial", name=f"c{j + 1}", width="0.0005",
                           rgba=(colours[3] if left else colours[j]) if m <= 4 else colours[j % len(colours)])
        for item in path:
            if isinstance(item, _Site):
                ET.SubElement(sp, "site", site=item.name)
            else:
                ET.SubElement(sp, "geom", geom=item.pulley, sidesite=item.sidesite)
    k_spring = params.springs.stiffness
    for i in range(1, n + 1):
        base = _base_body(i)
        for side, (s0, s1) in (("left", (f"j{i}_A_base", f"j{i}_C_top")), ("right", (f"j{i}_B_base", f"j{i}_D_top"))):
            sp = ET.SubElement(tendon, "spatial", name=f"j{i}_spring_{side}", stiffness=_fmt(k_spring[i - 1]),
                               springlength=_fmt(params.springs.rest_length), width="0.001",
                               rgba="0.5 0.8 0.5 1")
            ET.SubElement(sp, "site", site=s0)
            ET.SubElement(sp, "site", site=s1)
    for i, side in helpers:
        name = _helper_name(i, side)
        fx = ET.SubElement(tendon, "fixed", name=f"{name}_lock")
        ET.SubElement(fx, "joint", joint=name, coef="1")
        ET.SubElement(fx, "joint", joint=f"j{i}_A", coef="-0.5")
        ET.SubElement(fx, "joint", joint=f"j{i}_D", coef="-0.5")

    # Loop closure: solref = 2 timestep (the refsafe minimum), critically damped.  The default
    # solref gives cm-level gaps on this light linkage (geometry-and-errata.md); impedance 0.9999
    # (instead of the notes' 0.99-0.999) cuts the static gap under load 100x (1.7e-5 -> 1.6e-7 m
    # at 20 N) without changing the transient gaps, which scale with timestep^2.
    solref = _vec(2 * timestep, 1.0)
    solimp = "0.9999 0.9999 0.001 0.5 2"
    eq = ET.SubElement(root, "equality")
    for i in range(1, n + 1):
        ET.SubElement(eq, "connect", name=f"j{i}_loop", site1=f"j{i}_C_top", site2=f"j{i}_C_bc",
                      solref=solref, solimp=solimp)
    for i, side in helpers:
        name = _helper_name(i, side)
        ET.SubElement(eq, "tendon", name=f"{name}_eq", tendon1=f"{name}_lock", solref=solref, solimp=solimp)
    if rigid_cables:
        for j in range(m):
            ET.SubElement(eq, "tendon", name=f"c{j + 1}_rigid", tendon1=f"c{j + 1}",
                          solref=solref, solimp=solimp)

    actuator = ET.SubElement(root, "actuator")
    for j in range(m):
        ET.SubElement(actuator, "general", name=f"drive{j + 1}", joint=f"motor{j + 1}", gaintype="fixed",
                      gainprm="1", biastype="affine", biasprm="0 0 0", ctrlrange=_vec(0.0, act.f_max))
    cab = params.cables
    for j in range(m):
        k, ca = (0.0, 0.0) if rigid_cables else (cab.k[j], cab.c_a[j])
        ET.SubElement(actuator, "general", name=f"tension{j + 1}", tendon=f"c{j + 1}", gaintype="fixed",
                      gainprm="0", biastype="affine", biasprm=_vec(k * rest_lengths[j], -k, -ca),
                      ctrllimited="false")
    custom = ET.SubElement(root, "custom")
    ET.SubElement(custom, "text", name="generator",
                  data="neck_sim.mjcf.build_xml; cable tensions and motor friction are rewritten by "
                       "neck_sim.plant at every step (static file: linear bilateral cables, no friction)")
    ET.indent(root, space="  ")
    return ET.tostring(root, encoding="unicode") + "\n"


def build_model(params: NeckParams, *, timestep: float = DEFAULT_TIMESTEP, rigid_cables: bool = False):
    """Compiled :class:`mujoco.MjModel` of :func:`build_xml` (returns (model, xml))."""
    import mujoco
    xml = build_xml(params, timestep=timestep, rigid_cables=rigid_cables)
    return mujoco.MjModel.from_xml_string(xml), xml


def committed_xml_path() -> str:
    """Path of the committed ``mjcf/neck3x.xml``."""
    return os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "mjcf", "neck3x.xml")


def write_xml(params: NeckParams, path: str | os.PathLike, **kwargs) -> str:
    """Write :func:`build_xml` atomically to ``path``; returns the text."""
    xml = build_xml(params, **kwargs)
    atomic_write_bytes(path, xml.encode())
    return xml


# --------------------------------------------------------------------------------------------
# Reading a compiled model

class ModelIndex(NamedTuple):
    """Addresses in a compiled neck model (0-based arrays over joints i or cables j)."""

    n_joints: int
    qpos_A: np.ndarray        # (N,) qpos address of hinge j{i}_A
    qpos_B: np.ndarray
    qpos_D: np.ndarray
    qpos_helper: np.ndarray   # (H,) helpers in the order of helper_joints (N-1 for the paper's routing)
    qpos_motor: np.ndarray    # (m,)
    dof_A: np.ndarray
    dof_B: np.ndarray
    dof_D: np.ndarray
    dof_helper: np.ndarray
    dof_motor: np.ndarray
    cable_tendon: np.ndarray  # (m,) tendon ids of c1..c{m}
    drive_actuator: np.ndarray    # (m,)
    tension_actuator: np.ndarray  # (m,)
    loop_sites: np.ndarray    # (N, 2) site ids of j{i}_C_top, j{i}_C_bc
    bar_bodies: np.ndarray    # (3N,) body ids of the bars
    other_bodies: np.ndarray  # helpers (first H) and motors
    rigid_equality: np.ndarray    # (m,) equality ids of c{j}_rigid, or empty
    helper_joint: np.ndarray  # (H,) 0-based X-joint of each helper
    helper_tendon: np.ndarray     # (H,) tendon ids of the helpers' fixed-tendon locks
    spring_tendon: np.ndarray     # (N, 2) tendon ids of j{i}_spring_left, j{i}_spring_right
    spring_stiffness: np.ndarray  # (N, 2) their stiffness as compiled (N/m), before any effect edits it
    spring_length: np.ndarray     # (N, 2) their rest length as compiled (m)

    @property
    def n_cables(self) -> int:
        return len(self.cable_tendon)


def model_index(model) -> ModelIndex:
    """Look up every address the plant and the cross-validation need, by name."""
    import mujoco

    def ids(kind, names):
        out = []
        for nm in names:
            i = mujoco.mj_name2id(model, kind, nm)
            if i < 0:
                raise ValueError(f"model: no {kind.name.removeprefix('mjOBJ_').lower()} named {nm!r} "
                                 "(not a neck_sim model?)")
            out.append(i)
        return np.array(out, dtype=int)

    J = mujoco.mjtObj.mjOBJ_JOINT
    n = 0
    while mujoco.mj_name2id(model, J, f"j{n + 1}_A") >= 0:
        n += 1
    if n == 0:
        raise ValueError("model: no joint named 'j1_A' (not a neck_sim model?)")
    m = 0
    while mujoco.mj_name2id(model, J, f"motor{m + 1}") >= 0:
        m += 1
    jn = range(1, n + 1)
    cn = range(1, m + 1)
    helpers = [(i, side) for i in jn for side in ("left", "right")
               if mujoco.mj_name2id(model, J, _helper_name(i, side)) >= 0]
    hnames = [_helper_name(i, side) for i, side in helpers]
    jA, jB, jD = (ids(J, [f"j{i}_{h}" for i in jn]) for h in "ABD")
    jH = ids(J, hnames)
    jM = ids(J, [f"motor{j}" for j in cn])
    q = model.jnt_qposadr
    v = model.jnt_dofadr
    B = mujoco.mjtObj.mjOBJ_BODY
    T = mujoco.mjtObj.mjOBJ_TENDON
    bars = ids(B, [f"j{i}_{p}" for i in jn for p in ("ad", "bc", "top")])
    others = np.concatenate([ids(B, hnames), ids(B, [f"motor{j}" for j in cn])])
    rigid = np.array([mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_EQUALITY, f"c{j}_rigid") for j in cn], dtype=int)
    rigid = rigid if np.all(rigid >= 0) else np.zeros(0, dtype=int)
    S = mujoco.mjtObj.mjOBJ_SITE
    loops = np.stack([ids(S, [f"j{i}_C_top" for i in jn]), ids(S, [f"j{i}_C_bc" for i in jn])], axis=1)
    springs = ids(T, [f"j{i}_spring_{side}" for i in jn for side in ("left", "right")]).reshape(n, 2)
    return ModelIndex(n, q[jA], q[jB], q[jD], q[jH], q[jM], v[jA], v[jB], v[jD], v[jH], v[jM],
                      ids(T, [f"c{j}" for j in cn]),
                      ids(mujoco.mjtObj.mjOBJ_ACTUATOR, [f"drive{j}" for j in cn]),
                      ids(mujoco.mjtObj.mjOBJ_ACTUATOR, [f"tension{j}" for j in cn]),
                      loops, bars, others, rigid, np.array([i - 1 for i, _ in helpers], dtype=int),
                      ids(T, [f"{h}_lock" for h in hnames]), springs,
                      model.tendon_stiffness[springs].copy(), model.tendon_lengthspring[springs, 0].copy())


class PoseQpos(NamedTuple):
    """Hinge angles of the closed-form pose and their derivatives d q / d alpha_i (per joint)."""

    q_A: np.ndarray
    q_B: np.ndarray
    q_D: np.ndarray
    q_helper: np.ndarray
    dq_A: np.ndarray
    dq_B: np.ndarray
    dq_D: np.ndarray
    dq_helper: np.ndarray


def pose_qpos(alpha, params: NeckParams) -> PoseQpos:
    """Hinge angles (relative to the straight pose) that put the bars on the closed-form pose.

    q_A = angle(D - A) - its straight value, q_B = psi - psi(0), q_D = alpha - q_A, helpers
    alpha/2; shapes (..., N) (helpers (..., H), in the order of :func:`helper_joints`).  The derivatives are those of the closed form
    (eqs 1, 2, 7 differentiated), i.e. the analytic model's own kinematics.
    """
    g = params.geometry
    n = g.n_joints
    a = check_alpha(alpha, n)
    A = np.array([-g.b / 2, 0.0])
    B = np.array([g.b / 2, 0.0])
    jl = _joint_local(a, g.b, g.L)
    j0 = _joint_local(np.zeros(n), g.b, g.L)

    def ang(v):
        return np.arctan2(v[..., 1], v[..., 0])

    def cross(u, w):
        return u[..., 0] * w[..., 1] - u[..., 1] * w[..., 0]

    q_A = ang(jl.D - A) - ang(j0.D - A)
    q_B = ang(jl.C - B) - ang(j0.C - B)
    dq_A = cross(jl.D - A, jl.dD) / g.L ** 2
    dq_B = cross(jl.C - B, jl.dC) / g.L ** 2
    at = np.array([i - 1 for i, _ in helper_joints(params)], dtype=int)
    return PoseQpos(q_A, q_B, a - q_A, a[..., at] / 2, dq_A, dq_B, 1.0 - dq_A, np.full(a[..., at].shape, 0.5))


if __name__ == "__main__":      # regenerate the committed file: python -m neck_sim.mjcf
    from neck_sim.params import default_params
    write_xml(default_params(3), committed_xml_path())
    print(f"wrote {committed_xml_path()}")
