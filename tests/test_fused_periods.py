"""The closed loop's compiled chunks (``controllers.closed_loop._run_periods``: the periods between
events in one call) against the period-by-period Python loop: bit-identical runs.

The reference is the same runner with ``FUSE_PERIODS = False`` (every period through Python:
``advance``, ``PlantBatch.step``).  The batch holds what ends a chunk -- camera frames (30 Hz, one
plant with a camera delay), a controller that leaves its workspace mid-run (too stiff a loop on a
narrow workspace), a plant that diverges (forces of 10 kN) -- and an actuation delay, whose delay
line the chunks run too.
"""

from __future__ import annotations

import numpy as np
import pytest

import controllers.closed_loop as closed_loop
from controllers.computed_torque import ComputedTorqueController
from controllers.trajectories import cycloidal_path
from neck_sim.effects import ActuationDelay, CameraDelay, Effects
from neck_sim.params import default_params
from neck_sim.plant import Plant, PlantBatch, native_available

pytestmark = pytest.mark.skipif(not native_available(), reason="the compiled chunks step the native plant")

FIELDS = ("t", "theta", "force", "requested", "saturated", "alpha_hat", "elongation_hat", "gamma", "alpha",
          "alpha_dot", "tension", "elongation", "loop_gap", "camera_t", "camera_alpha")


def batch_runs(fused: bool, monkeypatch, stepped: list) -> list:
    """Four runs of 0.5 s in one lockstep batch, with or without the compiled chunks."""
    monkeypatch.setattr(closed_loop, "FUSE_PERIODS", fused)
    p = default_params(3)
    narrow = p.replace(**{"geometry.alpha_max": np.radians(30.0)})
    strong = p.replace(**{"actuation.f_max": 1e4})
    traj = cycloidal_path(np.radians([[0.0] * 3, [25.0, -15.0, 20.0]]), 0.3, 0.1)
    plants = [Plant(p, effects=Effects(camera_delay=CameraDelay(delay=0.017)), seed=5), Plant(p, seed=6),
              Plant(strong, seed=7), Plant(p, effects=Effects(actuation_delay=ActuationDelay(0.0053)), seed=8)]
    controllers = [ComputedTorqueController(p, 2), ComputedTorqueController(narrow, 2, omega=400.0),
                   ComputedTorqueController(strong, 2, omega=1500.0), ComputedTorqueController(p, 2)]
    ran = PlantBatch.ran_periods
    monkeypatch.setattr(PlantBatch, "ran_periods", lambda self, count: (stepped.append(count), ran(self, count)))
    return closed_loop.run_lockstep(plants, controllers, [traj] * 4, progress=False)


def test_compiled_chunks_equal_the_python_loop(monkeypatch):
    fused_steps, python_steps = [], []
    fused = batch_runs(True, monkeypatch, fused_steps)
    python = batch_runs(False, monkeypatch, python_steps)
    # the chunks stepped every period but the camera frames' (two schedules: with and without the
    # delay) and the last
    frames = fused[0].metrics.camera_frames
    assert python_steps == [] and sum(fused_steps) >= len(fused[0].t) - 2 * frames - 1
    assert "outside the workspace" in str(fused[1]) and "diverged" in str(fused[2])
    assert str(fused[1]) == str(python[1]) and str(fused[2]) == str(python[2])
    assert fused[0].metrics.camera_frames == 15
    for a, b in ((fused[0], python[0]), (fused[3], python[3])):
        for name in FIELDS:
            x, y = getattr(a, name), getattr(b, name)
            assert x.dtype == y.dtype and x.shape == y.shape and x.tobytes() == y.tobytes(), name
        assert a.metrics == b.metrics
