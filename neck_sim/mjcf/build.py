"""The XML assembly: :func:`build_xml` writes the MJCF text of a neck (bodies, hinges, motors,
cable tendons along :mod:`neck_sim.mjcf.paths`, springs, loop-closure equalities, actuators; the
layout is described in :mod:`neck_sim.mjcf`), :func:`integrator_for` picks its integrator."""

from __future__ import annotations

import math
import os
import xml.etree.ElementTree as ET

import numpy as np

from neck_sim.atomic import atomic_write_bytes
from neck_sim.mjcf.paths import (SIDESITE_RADIUS, Site, base_body, cable_paths, helper_joints, helper_name, layout,
                                 tangent_arc)
from neck_sim.params import NeckParams

__all__ = ["DEFAULT_TIMESTEP", "IMPLICITFAST_DAMPING_LIMIT", "integrator_for", "build_xml", "build_model",
           "write_xml", "committed_xml_path"]

DEFAULT_TIMESTEP = 5e-4
"""Physics timestep (s): the largest that keeps the plant's free response on the analytic dynamics
(:func:`neck_sim.crossval.dynamics_check`; see plant)."""

_HELPER_MASS = 1e-6         # kg, helper body (point mass on the hinge axis)
_HELPER_INERTIA = 1e-7      # kg m^2 about the hinge; keeps its cable-driven mode stable
_MOTOR_BODY_MASS = 1e-3     # kg; the reflected inertia is the slide's armature
_PULLEY_HALF_HEIGHT = 0.0015


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
    half = 0.5 * math.atan2(d[1], d[0])
    inertia = mass * length ** 2 / 12.0
    # Principal axes: x along the rod (tiny), y and z across it.
    ET.SubElement(parent, "inertial", pos=_vec(centre[0], centre[1], 0.0),
                  quat=_vec(math.cos(half), 0.0, 0.0, math.sin(half)), mass=_fmt(mass),
                  diaginertia=_vec(inertia * 1e-3, inertia, inertia))


def _capsule(parent: ET.Element, name: str, p0, p1, rgba: str, radius: float = 0.002) -> None:
    ET.SubElement(parent, "geom", name=name, type="capsule", size=_fmt(radius),
                  fromto=_vec(p0[0], p0[1], 0.0, p1[0], p1[1], 0.0), rgba=rgba, group="1")


#: Largest c_a dt / m_bar (cable damping N s/m x timestep s / lightest bar kg) at which MuJoCo's
#: ``implicitfast`` integrator keeps the tension-only cables stable.  Measured: with 20 g
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
    lay = layout(params)
    c = lay.corners
    paths = cable_paths(params, lay)
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
        base = base_body(i)
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
                name = helper_name(i, side)
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
            if isinstance(item, Site):
                ET.SubElement(bodies[item.body], "site", name=item.name, pos=_vec(*local(item.body, item.point), z))
                continue
            if item.pulley not in made_pulleys:
                made_pulleys.add(item.pulley)
                ctr = local(item.body, item.centre)
                ET.SubElement(bodies[item.body], "geom", name=item.pulley, type="cylinder",
                              size=_vec(r, _PULLEY_HALF_HEIGHT), pos=_vec(ctr[0], ctr[1], z),
                              rgba="0.7 0.7 0.7 0.6", group="2")
            phi_in, arc = tangent_arc(item.centre, r, path[k - 1].point, path[k + 1].point, item.sense)
            mid = phi_in + item.sense * arc / 2
            side = item.centre + SIDESITE_RADIUS * r * np.array([math.cos(mid), math.sin(mid)])
            ET.SubElement(bodies[item.body], "site", name=item.sidesite, pos=_vec(*local(item.body, side), z))

    tendon = ET.SubElement(root, "tendon")
    for j, path in enumerate(paths):
        left = params.routing.cables[j].side == "left"
        sp = ET.SubElement(tendon, "spatial", name=f"c{j + 1}", width="0.0005",
                           rgba=(colours[3] if left else colours[j]) if m <= 4 else colours[j % len(colours)])
        for item in path:
            if isinstance(item, Site):
                ET.SubElement(sp, "site", site=item.name)
            else:
                ET.SubElement(sp, "geom", geom=item.pulley, sidesite=item.sidesite)
    k_spring = params.springs.stiffness
    for i in range(1, n + 1):
        base = base_body(i)
        for side, (s0, s1) in (("left", (f"j{i}_A_base", f"j{i}_C_top")), ("right", (f"j{i}_B_base", f"j{i}_D_top"))):
            sp = ET.SubElement(tendon, "spatial", name=f"j{i}_spring_{side}", stiffness=_fmt(k_spring[i - 1]),
                               springlength=_fmt(params.springs.rest_length), width="0.001",
                               rgba="0.5 0.8 0.5 1")
            ET.SubElement(sp, "site", site=s0)
            ET.SubElement(sp, "site", site=s1)
    for i, side in helpers:
        name = helper_name(i, side)
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
        name = helper_name(i, side)
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
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))   # the repository
    return os.path.join(root, "mjcf", "neck3x.xml")


def write_xml(params: NeckParams, path: str | os.PathLike, **kwargs) -> str:
    """Write :func:`build_xml` atomically to ``path``; returns the text."""
    xml = build_xml(params, **kwargs)
    atomic_write_bytes(path, xml.encode())
    return xml
