"""Offscreen pictures of the neck rendered by MuJoCo: the four configurations of the paper's Fig. 10.

    from neck_sim.render import render_figure10
    render_figure10("fig10.png")                  # picks an OpenGL backend (EGL, then OSMesa)

Poses are put exactly as the plant puts them (:meth:`neck_sim.plant.Plant.reset`: every hinge
from the closed-form pose, motors at zero elongation); the picture uses the plant's own MJCF
with a few visual additions (white background, an orthographic camera looking along -z at the
plane of the neck, thicker cables).  All panels share one camera, so sizes and positions compare.

OpenGL backends.  MuJoCo chooses its OpenGL platform once per process, from ``MUJOCO_GL``, when
``mujoco`` is first imported.  :func:`render_figure10` therefore renders in a child process
(``python -m neck_sim.render``) and tries the backends in turn: ``MUJOCO_GL`` if set, else EGL
then OSMesa (and GLFW when a display exists).  When none works it raises :class:`RenderError`
naming, for each backend, what is missing (Debian/Ubuntu: ``apt-get install libegl1
libgl1-mesa-dri`` for EGL, ``apt-get install libosmesa6`` for OSMesa).  :func:`render_poses`
renders in the current process, with the backend this process already has.
"""

from __future__ import annotations

import argparse
import ctypes.util
import io
import os
import subprocess
import sys
import tempfile
import xml.etree.ElementTree as ET
from typing import TYPE_CHECKING, NamedTuple, Sequence

import numpy as np

from neck_sim.atomic import atomic_write_bytes
from neck_sim.params import NeckParams, default_params

if TYPE_CHECKING:
    import mujoco

__all__ = ["RenderError", "Framing", "cable_colours", "figure10_poses", "posed_data", "framing", "render_poses",
           "compose_figure", "render_figure10", "BACKENDS", "FIGURE10_TIMES"]

BACKENDS = ("egl", "osmesa", "glfw")
FIGURE10_TIMES = (0.0, 4.0, 7.0, 10.0)
"""s: the instants of the paper's Fig. 10 (straight, [50, 50, 50] deg, straight, [-30, -40, -50] deg)."""

_GL_UNAVAILABLE = 3          # exit code of the worker when its OpenGL backend cannot be used
_MARGIN = 0.08               # fraction of the framed extent added on every side
_CABLE_WIDTH = 0.0011        # m, cable radius in the picture (the model's 0.5 mm is sub-pixel)
_BAR_SCALE = 1.4             # bars drawn thicker than the model's 2 mm capsules (visual only)
_BACKGROUND = (1.0, 1.0, 1.0)
# Paper's cable colours (Fig. 2): right cables blue, yellow, red (more from a palette for N > 3),
# left cable green; yellow darkened to stay visible on white.  Bars neutral so only cables are coloured.
_RIGHT_CABLES = ((0.12, 0.35, 0.85), (0.93, 0.68, 0.0), (0.85, 0.1, 0.1), (0.55, 0.25, 0.75), (0.0, 0.6, 0.65),
                 (0.65, 0.4, 0.15))
_LEFT_CABLE = (0.1, 0.62, 0.2)
_DIAGONAL = (0.4, 0.43, 0.48)
_BAR = (0.2, 0.2, 0.22)
_SPRING = (0.7, 0.7, 0.7)
_PACKAGES = {"egl": "libegl1 libgl1-mesa-dri", "osmesa": "libosmesa6", "glfw": "libglfw3 and a display"}


class RenderError(RuntimeError):
    """Offscreen rendering is not possible here (no usable OpenGL backend) or failed."""


class Framing(NamedTuple):
    """An orthographic view of the x-y plane: centre (x, y) m, visible height and width (m)."""

    center: np.ndarray
    height: float
    width: float


# ----------------------------------------------------------------------------------- the poses

def figure10_poses(params: NeckParams) -> list[np.ndarray]:
    """The four main configurations of the control-test trajectory (Fig. 10), (N,) rad each.

    Taken from :func:`neck_sim.trajectory.control_test_trajectory`: straight, [50, 50, 50] deg,
    straight, [-30, -40, -50] deg (for N joints, that trajectory's profiles).
    """
    from neck_sim.trajectory import control_test_trajectory
    poses = control_test_trajectory(params).poses
    distinct = [poses[0]] + [q for p, q in zip(poses[:-1], poses[1:]) if not np.array_equal(p, q)]
    return [np.array(q) for q in distinct[:4]]


def _render_xml(xml: str) -> str:
    """The plant's MJCF plus visual additions only (the kinematic tree is unchanged)."""
    root = ET.fromstring(xml)
    visual = root.find("visual")
    if visual is None:
        visual = ET.SubElement(root, "visual")
    for el in visual.findall("headlight"):
        visual.remove(el)
    ET.SubElement(visual, "headlight", ambient="0.45 0.45 0.45", diffuse="0.55 0.55 0.55", specular="0.1 0.1 0.1")
    ET.SubElement(visual, "quality", offsamples="8")
    asset = root.find("asset")
    if asset is None:
        asset = ET.Element("asset")
        root.insert(1, asset)
    for tex in asset.findall("texture"):          # the model's own sky (for the viewer) would win
        if tex.get("type") == "skybox":
            asset.remove(tex)
    rgb = " ".join(str(c) for c in _BACKGROUND)
    ET.SubElement(asset, "texture", type="skybox", builtin="flat", rgb1=rgb, rgb2=rgb, width="16", height="16")
    world = root.find("worldbody")
    if world is None:
        raise RenderError("render model: the plant's MJCF has no worldbody")
    ET.SubElement(world, "camera", name="neck_sim_figure", pos="0 0 1", xyaxes="1 0 0 0 1 0",
                  projection="orthographic", fovy="0.3")
    return ET.tostring(root, encoding="unicode")


def posed_data(alphas: Sequence, params: NeckParams | None = None) -> tuple[mujoco.MjModel, list[mujoco.MjData]]:
    """(model, [data per pose]) of the neck at each pose of ``alphas`` (K, N) rad, for rendering.

    Each pose is put by :meth:`Plant.reset` (the plant's own placement) and copied into a model
    compiled from the plant's MJCF plus visual additions; positions are then computed by
    ``mj_forward`` (tendon wrap points included).
    """
    import mujoco

    from neck_sim.plant import Plant

    params = default_params(3) if params is None else params
    plant = Plant(params)
    model = mujoco.MjModel.from_xml_string(_render_xml(plant.xml))
    if model.nq != plant.model.nq or model.nbody != plant.model.nbody:
        raise RuntimeError("render model: the visual additions changed the kinematic tree")
    _restyle(model, params)
    out = []
    for alpha in np.atleast_2d(np.asarray(alphas, dtype=float)):
        plant.reset(alpha)
        data = mujoco.MjData(model)
        data.qpos[:] = plant.data.qpos
        mujoco.mj_forward(model, data)
        out.append(data)
    return model, out


def cable_colours(sides: Sequence[str]) -> list[tuple[float, ...]]:
    """One RGB colour per cable, all different, for the cables' ``sides`` ("left"/"right", in
    motor order): the paper's colours first (right cables blue, yellow, red, the first left cable
    green), then the rest of ``_RIGHT_CABLES`` and matplotlib's tab20b and tab20c maps (43 more:
    enough for the 32 cables the plant allows)."""
    from matplotlib import colormaps
    # tab20b/c come in groups of four shades of one hue: take one shade of every hue first
    shades = [(name, k) for shade in range(4) for name in ("tab20b", "tab20c") for k in range(shade, 20, 4)]
    spare = list(_RIGHT_CABLES[3:]) + [tuple(float(v) for v in colormaps[name](k)[:3]) for name, k in shades]
    right, left = list(_RIGHT_CABLES[:3]), [_LEFT_CABLE]
    out = []
    for side in sides:
        pool = left if side == "left" else right
        out.append(pool.pop(0) if pool else spare.pop(0))
    if len(out) > len(set(out)):  # only if a palette entry were repeated
        raise RenderError("cable colours: two cables would share a colour")
    return out


def _restyle(model, params: NeckParams) -> None:
    """Picture colours and widths (visual fields only)."""
    import mujoco
    T, G = mujoco.mjtObj.mjOBJ_TENDON, mujoco.mjtObj.mjOBJ_GEOM
    n = params.n_joints
    for j, rgb in enumerate(cable_colours(params.routing.sides), start=1):
        t = mujoco.mj_name2id(model, T, f"c{j}")
        model.tendon_rgba[t] = (*rgb, 1.0)
        model.tendon_width[t] = _CABLE_WIDTH
    for i in range(1, n + 1):
        for side in ("left", "right"):
            model.tendon_rgba[mujoco.mj_name2id(model, T, f"j{i}_spring_{side}")] = (*_SPRING, 1.0)
        for name, rgb in ((f"j{i}_ad_geom", _DIAGONAL), (f"j{i}_bc_geom", _DIAGONAL), (f"j{i}_top_geom", _BAR)):
            g = mujoco.mj_name2id(model, G, name)
            model.geom_rgba[g] = (*rgb, 1.0)
            model.geom_size[g, 0] *= _BAR_SCALE
    g = mujoco.mj_name2id(model, G, "base_bar")
    model.geom_rgba[g] = (*_BAR, 1.0)
    model.geom_size[g, 0] *= _BAR_SCALE


def framing(model: mujoco.MjModel, datas: Sequence[mujoco.MjData], margin: float = _MARGIN) -> Framing:
    """One view that holds every pose: the bars, pulleys and cable sites (motors excluded)."""
    import mujoco
    names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_SITE, i) or "" for i in range(model.nsite)]
    keep = np.array([not nm.endswith("_motor") for nm in names])
    pts = np.concatenate([d.site_xpos[keep, :2] for d in datas])
    lo, hi = pts.min(0), pts.max(0)
    ext = hi - lo
    pad = margin * max(ext)
    lo, hi = lo - pad, hi + pad
    return Framing((lo + hi) / 2, float(hi[1] - lo[1]), float(hi[0] - lo[0]))


# ------------------------------------------------------------------------------- in-process GL

def _gl_failure(exc: BaseException) -> RenderError:
    gl = os.environ.get("MUJOCO_GL", "") or "glfw (default)"
    return RenderError(f"MuJoCo cannot create an OpenGL context with MUJOCO_GL={gl}: {exc}. "
                       "Set MUJOCO_GL=egl or MUJOCO_GL=osmesa before importing mujoco (Debian/Ubuntu packages: "
                       f"{_PACKAGES['egl']} for EGL, {_PACKAGES['osmesa']} for OSMesa), or use "
                       "neck_sim.render.render_figure10 / `neck-sim render`, which pick a backend themselves")


def render_poses(alphas: Sequence, params: NeckParams | None = None, *, width: int = 400,
                 view: Framing | None = None) -> tuple[list[np.ndarray], Framing]:
    """RGB images (H, W, 3) uint8 of the neck at each pose of ``alphas`` (K, N) rad.

    Renders in this process with the OpenGL backend it already has (``MUJOCO_GL``); raises
    :class:`RenderError` naming the problem when there is none.  All images share one view
    (``view``, default: :func:`framing` of all poses); returns (images, view).
    """
    import mujoco

    width = int(width)
    if width < 32:
        raise ValueError(f"width: at least 32 pixels per image, got {width}")
    params = default_params(3) if params is None else params
    model, datas = posed_data(alphas, params)
    view = framing(model, datas) if view is None else view
    height = int(round(width * view.height / view.width))
    model.vis.global_.offwidth, model.vis.global_.offheight = width, height
    cam = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_CAMERA, "neck_sim_figure")
    model.cam_pos[cam] = (view.center[0], view.center[1], 1.0)
    model.cam_fovy[cam] = view.height            # orthographic: the visible height in metres
    for data in datas:
        mujoco.mj_camlight(model, data)          # camera moved after the poses were computed
    Renderer = getattr(mujoco, "Renderer", None)
    if Renderer is None:
        raise _gl_failure(ImportError("mujoco.Renderer is unavailable (its OpenGL platform failed to load)"))
    try:
        renderer = Renderer(model, height=height, width=width)
    except Exception as exc:                     # mujoco.FatalError, GLError, RuntimeError, ImportError
        raise _gl_failure(exc) from None
    try:
        images = []
        opt = mujoco.MjvOption()
        opt.sitegroup[:] = 0                     # no site markers
        for data in datas:
            renderer.update_scene(data, camera=cam, scene_option=opt)
            # no ground to cast on: the shadow map (4096^2, software GL) would cost ~0.5 s per image
            renderer.scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = False
            renderer.scene.flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = False
            images.append(renderer.render().copy())
    finally:
        renderer.close()
    return images, view


def compose_figure(images: Sequence[np.ndarray], titles: Sequence[str], path: str | os.PathLike[str], *, view: Framing,
                   suptitle: str | None = None, legend: Sequence[tuple[str, tuple]] = (), dpi: int = 100) -> None:
    """Panels side by side with titles, a 5 cm scale bar and a legend, written atomically as PNG.

    ``images`` share the orthographic ``view`` (for the scale bar); text scales with the panel size.
    """
    from matplotlib.figure import Figure          # the object API: no pyplot, no global backend
    from matplotlib.lines import Line2D

    h, w = images[0].shape[:2]
    k = len(images)
    fs = float(np.clip(w / 32, 6, 12))            # title font (pt) that fits a panel's width
    ncol = min(len(legend or ()), 7)                          # legend columns; more entries wrap
    rows = -(-len(legend or ()) // ncol) if ncol else 1
    head, foot = 2.6 * fs / 72 + 0.1, 1.8 * rows * fs / 72 + 0.05   # inches for the titles and the legend
    H = h / dpi + head + foot
    fig = Figure(figsize=(k * w / dpi, H), dpi=dpi, facecolor="white")
    for i, (img, title) in enumerate(zip(images, titles)):
        ax = fig.add_axes((i / k, foot / H, 1 / k, h / dpi / H))
        ax.imshow(img, interpolation="antialiased")
        ax.set_axis_off()
        ax.set_title(title, fontsize=fs, pad=2)
        if i == 0:
            px = 0.05 / view.width * w            # 5 cm in pixels
            x0, y0 = 0.05 * w, 0.08 * h
            ax.plot([x0, x0 + px], [y0, y0], color="0.15", lw=max(1.5, fs / 4), solid_capstyle="butt")
            ax.text(x0 + px / 2, y0 + 0.02 * h, "5 cm", ha="center", va="top", fontsize=0.8 * fs, color="0.15")
            ax.set_xlim(-0.5, w - 0.5)
            ax.set_ylim(h - 0.5, -0.5)
    if suptitle:
        fig.suptitle(suptitle, fontsize=fs * 1.05, y=1 - 0.05 / H, va="top")
    if legend:
        handles = [Line2D([], [], color=c, lw=3) for _, c in legend]
        fig.legend(handles, [name for name, _ in legend], loc="lower center", ncol=ncol, frameon=False,
                   fontsize=0.85 * fs, bbox_to_anchor=(0.5, 0.0), handlelength=1.5, columnspacing=1.2)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi, facecolor="white")
    atomic_write_bytes(path, buf.getvalue())


def _write_png(path, image: np.ndarray) -> None:
    import matplotlib.image
    buf = io.BytesIO()
    matplotlib.image.imsave(buf, image, format="png")
    atomic_write_bytes(path, buf.getvalue())


def _fmt_pose(alpha: np.ndarray) -> str:
    deg = np.degrees(alpha)
    if np.allclose(deg, 0):
        return "straight"
    if deg.size > 4:  # a long neck's list would overrun its panel's title
        return f"α = [{deg[0]:.0f} .. {deg[-1]:.0f}]° ({deg.size} joints)"
    return "α = [" + ", ".join(f"{d:.0f}" for d in deg) + "]°"


def _legend(model, params: NeckParams) -> list[tuple[str, tuple]]:
    import mujoco
    out = []
    for j, side in enumerate(params.routing.sides, start=1):
        t = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_TENDON, f"c{j}")
        out.append((f"cable {j} ({side})", tuple(model.tendon_rgba[t][:3])))
    t = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_TENDON, "j1_spring_left")
    out.append(("side springs", tuple(model.tendon_rgba[t][:3])))
    return out


def figure10_in_process(path, params: NeckParams | None = None, *, width: int = 2000, panels_dir=None) -> str:
    """Render and write the Fig. 10 picture in this process (its OpenGL backend); returns the path.

    ``panels_dir``: also write each rendered panel as ``panel{k}.png`` there (k = 0..3).
    """
    params = default_params(3) if params is None else params
    if int(width) < 4 * 100:
        raise ValueError(f"width: at least 400 pixels for four panels, got {width}")
    poses = figure10_poses(params)
    images, view = render_poses(poses, params, width=int(width) // len(poses))
    model, _ = posed_data(poses[:1], params)
    titles = [f"t = {t:g} s: {_fmt_pose(a)}" for t, a in zip(FIGURE10_TIMES, poses)]
    if panels_dir is not None:
        os.makedirs(panels_dir, exist_ok=True)
        for k, img in enumerate(images):
            _write_png(os.path.join(panels_dir, f"panel{k}.png"), img)
    compose_figure(images, titles, path, view=view, legend=_legend(model, params),
                   suptitle=f"{params.n_joints}-X neck, main configurations of the control-test trajectory "
                            "(paper Fig. 10), MuJoCo offscreen")
    return os.fspath(path)


# ------------------------------------------------------------------------ backend selection

class RenderResult(NamedTuple):
    path: str
    backend: str


def _candidates(backend: str | None) -> list[str]:
    if backend not in (None, "auto"):
        if backend not in BACKENDS:
            raise ValueError(f"backend: expected 'auto' or one of {', '.join(BACKENDS)}, got {backend!r}")
        return [backend]
    env = os.environ.get("MUJOCO_GL", "").strip().lower()
    if env in BACKENDS:
        return [env]
    out = ["egl", "osmesa"]
    if os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"):
        out.append("glfw")
    return out


def _missing_library(backend: str) -> str | None:
    """The system library a backend needs that the dynamic loader cannot find, or None."""
    if backend == "glfw" and not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        return "no display (DISPLAY and WAYLAND_DISPLAY unset): GLFW needs a window system"
    lib = {"egl": "EGL", "osmesa": "OSMesa", "glfw": None}[backend]
    if lib and ctypes.util.find_library(lib) is None:
        return f"lib{lib}.so not found (Debian/Ubuntu: apt-get install {_PACKAGES[backend]})"
    return None


def render_figure10(path: str | os.PathLike[str], params: NeckParams | None = None, *, width: int = 2000,
                    backend: str | None = "auto",
                    panels_dir: str | os.PathLike[str] | None = None, timeout: float = 300.0) -> RenderResult:
    """Write the Fig. 10 picture (four poses side by side, ``width`` px in all) to ``path`` (PNG).

    ``panels_dir``: also write each rendered panel (no text) as ``panel{k}.png`` there.

    Renders in a child process per OpenGL backend tried (see the module docstring); raises
    :class:`RenderError` listing what each backend lacks when none works.
    """
    path = os.fspath(path)
    if int(width) < 400:
        raise ValueError(f"width: at least 400 pixels for four panels, got {width}")
    params = default_params(3) if params is None else params
    failures = []
    with tempfile.TemporaryDirectory(prefix="neck_sim_render_") as tmp:
        pfile = os.path.join(tmp, "params.json")
        from neck_sim.params import save
        save(params, pfile)
        for b in _candidates(backend):
            missing = _missing_library(b)
            if missing:
                failures.append(f"{b}: {missing}")
                continue
            env = dict(os.environ, MUJOCO_GL=b)
            if b in ("egl", "osmesa"):
                env["PYOPENGL_PLATFORM"] = b
            else:
                env.pop("PYOPENGL_PLATFORM", None)
            cmd = [sys.executable, "-m", "neck_sim.render", "--out", path, "--width", str(int(width)),
                   "--params", pfile]
            if panels_dir is not None:
                cmd += ["--panels-dir", os.fspath(panels_dir)]
            try:
                res = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=timeout)
            except subprocess.TimeoutExpired:
                failures.append(f"{b}: no picture after {timeout:g} s")
                continue
            if res.returncode == 0:
                return RenderResult(path, b)
            last = (res.stderr.strip().splitlines() or ["(no message)"])[-1]
            if res.returncode != _GL_UNAVAILABLE:
                raise RenderError(f"rendering with MUJOCO_GL={b} failed: {last}")
            failures.append(f"{b}: {last}")
    raise RenderError("no OpenGL backend for offscreen rendering works here -- " + "; ".join(failures))


def main(argv=None) -> int:
    """Worker: ``MUJOCO_GL=egl python -m neck_sim.render --out fig.png [--width W] [--params P]``."""
    ap = argparse.ArgumentParser(prog="python -m neck_sim.render", description=main.__doc__)
    ap.add_argument("--out", required=True)
    ap.add_argument("--width", type=int, default=2000)
    ap.add_argument("--params")
    ap.add_argument("--panels-dir")
    args = ap.parse_args(argv)
    from neck_sim import params as P
    params = P.load(args.params) if args.params else default_params(3)
    try:
        # Surface the platform's own import error (mujoco swallows it and drops Renderer).
        from mujoco.rendering.classic import gl_context  # noqa: F401
    except Exception as exc:
        print(f"MuJoCo's OpenGL platform does not load ({type(exc).__name__}: {exc})", file=sys.stderr)
        return _GL_UNAVAILABLE
    try:
        figure10_in_process(args.out, params, width=args.width, panels_dir=args.panels_dir)
    except RenderError as exc:
        print(str(exc).split(". Set MUJOCO_GL")[0], file=sys.stderr)
        return _GL_UNAVAILABLE
    return 0


if __name__ == "__main__":
    sys.exit(main())
