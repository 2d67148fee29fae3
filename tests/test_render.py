"""Offscreen rendering: exact poses, the Fig. 10 picture, and a clear message without OpenGL.

Rendering needs an OpenGL backend on the machine (EGL: Debian packages libegl1 libgl1-mesa-dri;
OSMesa: libosmesa6); CI installs one (see .ci/run).
"""

import os
import subprocess
import sys

import matplotlib
import numpy as np
import pytest

matplotlib.use("Agg")
import matplotlib.image as mpimg  # noqa: E402

from neck_sim import render  # noqa: E402
from neck_sim.analytic import forward_kinematics  # noqa: E402
from neck_sim.params import default_params  # noqa: E402


def _site(model, name):
    import mujoco
    return mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, name)


def test_poses_are_put_exactly(params, rng):
    alphas = rng.uniform(-1.0, 1.0, (5, 3))
    model, datas = render.posed_data(alphas, params)
    for alpha, data in zip(alphas, datas):
        corners = forward_kinematics(alpha, params).corners          # closed form, (N, 4, 2)
        for i in range(3):
            np.testing.assert_allclose(data.site_xpos[_site(model, f"j{i + 1}_C_top"), :2], corners[i, 2], atol=1e-9)
            np.testing.assert_allclose(data.site_xpos[_site(model, f"j{i + 1}_D_top"), :2], corners[i, 3], atol=1e-9)
            np.testing.assert_allclose(data.site_xpos[_site(model, f"j{i + 1}_C_bc"), :2], corners[i, 2], atol=1e-9)


def test_figure10_poses_and_framing(params):
    poses = render.figure10_poses(params)
    np.testing.assert_allclose(np.degrees(poses), [[0, 0, 0], [50, 50, 50], [0, 0, 0], [-30, -40, -50]], atol=1e-12)
    model, datas = render.posed_data(poses, params)
    view = render.framing(model, datas)
    lo, hi = view.center - [view.width / 2, view.height / 2], view.center + [view.width / 2, view.height / 2]
    for alpha in poses:                              # every corner of every pose is in the picture
        c = forward_kinematics(alpha, params).corners.reshape(-1, 2)
        assert np.all(c > lo) and np.all(c < hi)
    assert view.height > 0.26                        # the straight neck: 3 sqrt(L^2 - b^2) = 0.26 m


def test_figure10_picture(tmp_path):
    out = tmp_path / "fig10.png"
    res = render.render_figure10(out, width=800, panels_dir=tmp_path / "panels")
    assert res.backend in render.BACKENDS and os.path.getsize(out) > 10_000
    img = mpimg.imread(out)[..., :3]
    assert img.shape[1] == 800
    assert np.median(img) > 0.95                     # light background
    panels = [mpimg.imread(tmp_path / "panels" / f"panel{k}.png")[..., :3] for k in range(4)]
    assert all(p.shape == panels[0].shape for p in panels) and panels[0].shape[1] == 200
    # the bars: dark and grey (the cables are coloured, the background white)
    bars = [(p.mean(-1) < 0.6) & (np.ptp(p, axis=-1) < 0.15) for p in panels]
    assert all(b.sum() > 100 for b in bars)          # the neck is drawn in every panel
    # the two straight panels show the same pose; alpha > 0 bends the neck to the left (-x)
    assert np.abs(panels[0] - panels[2]).mean() < 1e-3
    assert np.abs(panels[0] - panels[1]).mean() > 0.01
    cx = [np.nonzero(b)[1].mean() for b in bars]
    assert cx[1] < cx[0] - 10 and cx[3] > cx[0] + 10
    # the straight neck is upright: its bars span far more rows than columns
    ys, xs = np.nonzero(bars[0])
    assert np.ptp(ys) > 2 * np.ptp(xs[ys < np.percentile(ys, 90)])
    # cable 1 (blue) is visible
    blue = (img[..., 2] > 0.6) & (img[..., 0] < 0.35) & (img[..., 1] < 0.55)
    assert blue.sum() > 30


def test_unavailable_backend_is_a_clear_message_not_a_crash(tmp_path):
    """Force a backend that cannot work (GLFW without any display) through the command line."""
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    out = tmp_path / "x.png"
    res = subprocess.run([sys.executable, "-m", "neck_sim.cli", "render", "-o", str(out), "--backend", "glfw",
                          "--width", "400"], env=env, capture_output=True, text=True, timeout=120)
    assert res.returncode == 2, res.stderr
    assert "no OpenGL backend" in res.stderr and "glfw" in res.stderr and "display" in res.stderr
    assert "Traceback" not in res.stderr and not out.exists()


def test_worker_reports_a_failing_platform(tmp_path, monkeypatch):
    """The child process itself fails to get a context: its reason reaches the RenderError."""
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.setattr(render, "_missing_library", lambda backend: None)   # skip the pre-check
    out = tmp_path / "x.png"
    with pytest.raises(render.RenderError, match="glfw: MuJoCo cannot create an OpenGL context"):
        render.render_figure10(out, width=400, backend="glfw")
    assert not out.exists()
    # a platform library that does not load at all (PyOpenGL pinned to another platform)
    env = dict(os.environ, MUJOCO_GL="osmesa", PYOPENGL_PLATFORM="egl")
    res = subprocess.run([sys.executable, "-m", "neck_sim.render", "--out", str(out), "--width", "400"],
                         env=env, capture_output=True, text=True, timeout=120)
    assert res.returncode == render._GL_UNAVAILABLE and "OpenGL platform does not load" in res.stderr
    assert "Traceback" not in res.stderr


def test_bad_arguments():
    with pytest.raises(ValueError, match="backend"):
        render.render_figure10("x.png", backend="vulkan")
    with pytest.raises(ValueError, match="width"):
        render.render_figure10("x.png", width=10)
    assert render.figure10_poses(default_params(5))[1].shape == (5,)


def test_missing_system_library_names_the_package(tmp_path, monkeypatch):
    monkeypatch.setattr(render.ctypes.util, "find_library", lambda name: None)
    monkeypatch.delenv("MUJOCO_GL", raising=False)
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    with pytest.raises(render.RenderError) as err:
        render.render_figure10(tmp_path / "x.png", width=400)
    msg = str(err.value)
    assert "egl: libEGL.so not found" in msg and "libegl1" in msg
    assert "osmesa: libOSMesa.so not found" in msg and "apt-get install libosmesa6" in msg
    assert not (tmp_path / "x.png").exists()


def test_environment_renders_through_dm_control_and_shimmy():
    """env.physics.render (dm_control) and shimmy's rgb_array mode draw the plant's own state."""
    backend = next(b for b in ("egl", "osmesa") if render._missing_library(b) is None)
    code = """
import numpy as np
from shimmy import DmControlCompatibilityV0
from neck_sim import env as neck_env
e = neck_env.load(seed=0)
e.reset()
a = e.physics.render(120, 160, camera_id="front")
for _ in range(200):
    e.step(np.array([100.0, 0.0, 0.0, 0.0]))
b = e.physics.render(120, 160, camera_id="front")
g = DmControlCompatibilityV0(neck_env.load(seed=0), render_mode="rgb_array", render_kwargs=dict(camera_id="front"))
g.reset(seed=1)
c = g.render()
g.close()
assert a.shape == (120, 160, 3) and c.shape == (240, 320, 3) and a.max() > 100
assert np.abs(a.astype(float) - b).mean() > 0.5      # the neck moved in the picture
print("ok")
"""
    env = dict(os.environ, MUJOCO_GL=backend, PYOPENGL_PLATFORM=backend)
    res = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=120)
    assert res.returncode == 0 and res.stdout.strip().endswith("ok"), res.stderr[-2000:]
