"""Where the cables run in the MuJoCo neck: the straight-pose layout, each cable's path as sites
and pulley wraps, and the wrap arcs at any pose (closed-form geometry of
:mod:`neck_sim.analytic.geometry`, the routing of :mod:`neck_sim.routing`).

:mod:`neck_sim.mjcf.build` turns these paths into spatial tendons; the frame and the names
(``c{j}_...`` sites, ``j{i}_...`` bodies) are those of :mod:`neck_sim.mjcf`.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from neck_sim.analytic.geometry import _joint_local, check_alpha, forward_kinematics
from neck_sim.params import NeckParams
from neck_sim.routing import SEG_LEFT_END, SEG_LEFT_SIDE, SEG_LEFT_STRUT, SEG_RIGHT_SIDE, SEG_RIGHT_STRUT

__all__ = ["Layout", "layout", "helper_joints", "helper_name", "Site", "Wrap", "base_body", "cable_paths",
           "tangent_arc", "wrap_arcs", "world_transform", "SIDESITE_RADIUS"]

_MOTOR_DISTANCE = 0.25      # m, motor site to the first pulley's tangent point
_ROW_PITCH = 0.004          # m, z distance between cable rows
SIDESITE_RADIUS = 2.0       # x r: sidesites at 2r from the pulley axis
_TURN_RADIUS = 2.5          # x r: site splitting the full turn on C_i (shadow 2 acos(1/2.5))


class Layout(NamedTuple):
    """Where everything is at the straight pose, in world coordinates (x, y); z rows per cable."""

    corners: np.ndarray       # (N, 4, 2) A, B, C, D of every joint
    mid_top: np.ndarray       # (N, 2) middle of C_i D_i (origin of the top-bar body)
    row_z: np.ndarray         # (m,) z of each cable row
    motor_site: np.ndarray    # (m, 2) first site of each cable (on the motor body)
    motor_axis: np.ndarray    # (m, 2) slide axis: the direction that winds the cable up


def layout(params: NeckParams) -> Layout:
    """The straight-pose :class:`Layout` of ``params``' neck."""
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


def helper_name(i: int, side: str) -> str:
    """Body and hinge name of the helper of joint ``i`` (1-based) on ``side``."""
    return f"j{i}_helper" if side == "left" else f"j{i}_helper_right"


# Cable paths as (kind, ...) items; "site" items are points, "wrap" items are pulleys.

class Site(NamedTuple):
    """A point of a cable path on ``body``."""

    name: str
    body: str
    point: np.ndarray          # world (x, y) at the straight pose


class Wrap(NamedTuple):
    """A pulley a cable path wraps, with the sidesite that picks the side it wraps."""

    pulley: str                # geom name
    body: str
    centre: np.ndarray         # world (x, y) at the straight pose
    sense: int                 # +1 counter-clockwise, -1 clockwise
    sidesite: str


def base_body(i: int) -> str:
    """Body carrying the base bar of joint i (1-based)."""
    return "world" if i == 1 else f"j{i - 1}_top"


def cable_paths(params: NeckParams, lay: Layout) -> list[list]:
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
        items: list = [Site(f"{tag}_motor", f"motor{j}", lay.motor_site[j - 1])]
        if left:
            items.append(Wrap(f"{tag}_pulley_A1", "world", c[0, 0], -1, f"{tag}_side_A1"))
        else:
            items.append(Wrap(f"{tag}_pulley_B1", "world", c[0, 1], +1, f"{tag}_side_B1"))
        for i, kind in enumerate(cable.kinds, start=1):
            A, B, C, D = c[i - 1]
            if i < len(c):
                D = c[i, 1]                         # D_i as B_{i+1}, the base corner of the next joint
            top = f"j{i}_top"
            if kind == SEG_RIGHT_STRUT:
                items += [Site(f"{tag}_mid_bc{i}", f"j{i}_bc", 0.5 * (B + C)),
                          Wrap(f"{tag}_pulley_C{i}", top, C, -1, f"{tag}_side_C{i}"),
                          Site(f"{tag}_mid_top{i}", top, 0.5 * (C + D)),
                          Wrap(f"{tag}_pulley_B{i + 1}", top, D, +1, f"{tag}_side_B{i + 1}")]
            elif kind == SEG_LEFT_STRUT:
                items += [Site(f"{tag}_mid_ad{i}", f"j{i}_ad", 0.5 * (A + D)),
                          Wrap(f"{tag}_pulley_D{i}", top, D, +1, f"{tag}_side_D{i}"),
                          Site(f"{tag}_mid_top{i}", top, 0.5 * (C + D)),
                          Wrap(f"{tag}_pulley_C{i}", top, C, -1, f"{tag}_side_C{i}")]
            elif kind == SEG_LEFT_SIDE:
                pul, side = f"{tag}_pulley_C{i}", f"{tag}_side_C{i}"
                items += [Site(f"{tag}_helper{i}", helper_name(i, "left"), A + np.array([-r, rise])),
                          Wrap(pul, top, C, -1, side + "a"),
                          Site(f"{tag}_turn{i}", top, C + np.array([_TURN_RADIUS * r, 0.0])),
                          Wrap(pul, top, C, -1, side + "b")]
            elif kind == SEG_RIGHT_SIDE:
                pul, side = f"{tag}_pulley_B{i + 1}", f"{tag}_side_B{i + 1}"
                items += [Site(f"{tag}_helper_right{i}", helper_name(i, "right"), B + np.array([r, rise])),
                          Wrap(pul, top, D, +1, side + "a"),
                          Site(f"{tag}_turn{i}", top, D - np.array([_TURN_RADIUS * r, 0.0])),
                          Wrap(pul, top, D, +1, side + "b")]
            else:                                   # case (a): attached at C_i; (b): at D_i
                items.append(Site(f"{tag}_end", top, C if kind == SEG_LEFT_END else D))
        paths.append(items)
    return paths


def _angle(v) -> float:
    """Direction of the 2-D vector ``v`` (rad)."""
    return math.atan2(v[1], v[0])


def tangent_arc(centre, r: float, p, q, sense: int) -> tuple[float, float]:
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
    lay = layout(params)
    world = world_transform(params, a, lay)
    out = {}
    r = params.geometry.r
    for path in cable_paths(params, lay):
        for k, item in enumerate(path):
            if isinstance(item, Wrap):
                p = world(path[k - 1].body, path[k - 1].point)
                q = world(path[k + 1].body, path[k + 1].point)
                _, arc = tangent_arc(world(item.body, item.centre), r, p, q, item.sense)
                out[item.sidesite] = arc
    return out


def world_transform(params: NeckParams, alpha: np.ndarray, lay: Layout):
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
