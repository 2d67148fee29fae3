"""The interface of a :class:`neck_sim.batch.PlantBatch` to a compiled caller that steps it itself.

``controllers.closed_loop`` runs the control periods between events (camera frames, failures) in
one numba kernel, which calls ``neck_step_batch`` of ``plant_callback.c`` directly (through
:func:`neck_sim.native.call_c`).  The batch gives such a caller four things, and nothing else:

* ``batch.fused_step()``: a :class:`FusedStep` (the C function's address and its arguments, and
  the buffers the arguments point at);
* ``batch.quiet_periods()``: how many control periods from now need none of the batch's Python
  (native backend, no camera frame due); 0 off the native backend;
* ``batch.ran_periods(count)``: the batch's bookkeeping after ``count`` periods stepped that way;
* ``batch.framed``: some plant took a camera frame in the last period (``batch.frames``).

Usage (the kernel side, numba)::

    step = batch.fused_step()                    # once per batch
    count = batch.quiet_periods()
    previous = DISPATCH.enter("native")
    try:
        kernel(count, step.address, step.args, step.f_max, step.forces, step.delay_line, ...)
    finally:
        DISPATCH.leave(previous)
    batch.ran_periods(count)

    # in the kernel, per period: clip_forces(requested, f_max, forces); if delayed:
    # delayed_controls(delay_line[0], forces, *delay_line[1:]); fatal = call_c(address, args)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["FusedStep"]


@dataclass(frozen=True, eq=False)
class FusedStep:
    """One control period of a native batch with no camera capture, for a compiled caller.

    address: of ``neck_step_batch`` (0 off the native backend, where ``quiet_periods`` is 0);
    args: its arguments (pointers as integers, C ints as ``np.int32``), commanding ``forces`` or,
    with an actuation delay, the per-sub-step commands the delay line fills;
    f_max (K, 1) N: each plant's force limit; forces (K, m) N: the buffer to clip the commanded
    forces into (``neck_sim.batch.clip_forces``); delay_line: the arguments of
    ``neck_sim.batch.delayed_controls`` but the forces, needed when some plant's actuation delay
    is > 0 (``delayed``); encoders (K, m) rad and out (K, 3m + 2N + 1): where the C call leaves the
    encoder readings and the truth rows (``neck_sim.batch.truth_columns``).
    """

    address: int
    args: tuple
    f_max: np.ndarray
    forces: np.ndarray
    delay_line: tuple
    delayed: bool
    encoders: np.ndarray
    out: np.ndarray
