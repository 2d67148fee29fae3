"""What a batch stepper needs of a plant: one public, frozen record (:class:`NativePlant`).

A :class:`neck_sim.plant.Plant` builds it once (``plant.native``) and a
:class:`neck_sim.batch.PlantBatch` steps plants through it alone, never through the plant's
private attributes: the MuJoCo model and data, the C struct the callback reads and writes, the
limits (f_max, actuation delay), the camera schedule and the per-plant stepping state
(:class:`StepState`, the one mutable part, handed between the plant's own batch and others).

The record, not the plant, holds the plant's place in the C registry: the registration ends when
the last record reference goes (a batch that outlives its plant still steps a registered model).
"""

from __future__ import annotations

import math
import weakref
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import numpy as np

__all__ = ["NativePlant", "StepState", "Outputs"]


class Outputs(NamedTuple):
    """Numpy views into the C struct's outputs of the last callback (m cables, N joints): tension
    (m,) N, elongation (m,) m, theta, theta_dot (m,) rad, rad/s, alpha, alpha_dot (N,) rad, rad/s."""

    tension: np.ndarray
    elongation: np.ndarray
    theta: np.ndarray
    theta_dot: np.ndarray
    alpha: np.ndarray
    alpha_dot: np.ndarray


@dataclass(eq=False)
class StepState:
    """A plant's stepping state, which one batch at a time holds (``owner``, its row ``row``).

    k: physics sub-steps since the reset; frame_index: number j of the next camera frame (due at
    j / camera_rate_hz); next_cam: the sub-step at whose end it is taken; hist (R, m) N: the ring
    buffer of commands of the actuation-delay line; frame: the last camera frame (t s, alpha (N,)
    rad) or None; rng: the camera noise generator (seeded at each reset).
    """

    k: int
    frame_index: int
    next_cam: int
    hist: np.ndarray
    frame: Any
    rng: np.random.Generator
    owner: Any = None          # weakref.ref to the batch that holds the state, or None
    row: int = 0

    def holder(self):
        """The batch that holds this state now, or None."""
        return None if self.owner is None else self.owner()


@dataclass(frozen=True, eq=False)
class NativePlant:
    """One plant as a batch steps it (SI units).

    model, data: its MuJoCo ``MjModel``/``MjData`` (not shared with another simulation: the
    callback writes the actuator biases of the model); struct: its
    :class:`neck_sim.native.PlantStruct`; index: :func:`neck_sim.mjcf.model_index` of the model;
    params: the nominal constants (camera rate and noise, encoder resolution, joint range);
    true_params: those the physics uses (with the effects); substeps physics steps of ``timestep``
    s per control period ``period`` s; f_max N: the force limit; delay s: the actuation delay;
    camera_delay s: a frame stamped t shows the neck at t - camera_delay; ratio = R / r_d rad/m
    (theta = ratio s); rest, x_pre (m,) m: cable rest lengths and pretension offsets;
    motor_effects: the effects with a motor force (the Python backend adds them to eq 37);
    fatal_warnings: live views of MuJoCo's fatal warning counters; outputs: :class:`Outputs`.
    """

    model: Any
    data: Any
    struct: Any
    index: Any
    params: Any
    true_params: Any
    rigid_cables: bool
    timestep: float
    period: float
    substeps: int
    f_max: float
    delay: float
    camera_delay: float
    ratio: float
    rest: np.ndarray
    x_pre: np.ndarray
    motor_effects: tuple
    fatal_warnings: tuple
    outputs: Outputs
    state: StepState = field(repr=False)

    @property
    def n_joints(self) -> int:
        return self.params.n_joints

    @property
    def n_cables(self) -> int:
        return self.params.n_cables

    @property
    def address(self) -> int:
        """The ``mjModel`` address, the plant's key in the C registry and the dispatch."""
        return self.model._address

    @property
    def history_length(self) -> int:
        """R: periods of commands the delay line keeps (every period ``delay`` reaches back to)."""
        return int(math.ceil(self.delay / self.period)) + 2 if self.delay > 0 else 1

    def camera_step(self, j: int) -> int:
        """Sub-step index at whose end camera frame j (due at j / camera_rate_hz) is taken."""
        return math.ceil((j / self.params.sensors.camera_rate_hz - self.camera_delay) / self.timestep - 1e-6)

    def reset_state(self, seed: int) -> None:
        """Time 0, the first camera frame next, an empty delay line, the camera noise reseeded; no
        batch holds the state afterwards."""
        s = self.state
        s.k, s.frame_index, s.next_cam = 0, 1, self.camera_step(1)
        s.hist = np.zeros((self.history_length, self.n_cables))
        s.frame, s.rng, s.owner, s.row = None, np.random.default_rng(seed), None, 0

    def hold(self, batch, row: int) -> None:
        """``batch`` holds the stepping state now (as its row ``row``); weakly, so that a plant's own
        batch does not keep its record alive."""
        self.state.owner, self.state.row = weakref.ref(batch), row
