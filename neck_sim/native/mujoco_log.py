"""MuJoCo's warnings routed to the ``neck_sim.mujoco`` logger, and which of them end a simulation.

MuJoCo's default handler prints to stdout and appends to ``./MUJOCO_LOG.TXT``; a library should
log.  The texts after which a plant raises :class:`neck_sim.batch.PlantDivergedError` (which quotes
the last one, :func:`last_warning`) are logged at DEBUG only, so a diverging candidate model in a
fit does not flood the terminal.
"""

from __future__ import annotations

import logging

import mujoco

__all__ = ["route_mujoco_warnings", "log_warning", "last_warning", "FATAL_WARNINGS"]

_MUJOCO_LOG = logging.getLogger("neck_sim.mujoco")
_FATAL_TEXTS = ("Nan, Inf or huge value", "Inertia matrix is too close to singular")
_last_mujoco_warning = ""

#: mjtWarning codes after which MuJoCo's state is no longer a valid neck (it resets itself on some
#: of them); ``neck_step_batch`` in the C file tests the same four.
FATAL_WARNINGS = tuple(int(getattr(mujoco.mjtWarning, w)) for w in
                       ("mjWARN_INERTIA", "mjWARN_BADQPOS", "mjWARN_BADQVEL", "mjWARN_BADQACC"))


def log_warning(message: str) -> None:
    """MuJoCo's warning handler of this package: ``message`` to the ``neck_sim.mujoco`` logger."""
    global _last_mujoco_warning
    _last_mujoco_warning = message.strip()
    level = logging.DEBUG if _last_mujoco_warning.startswith(_FATAL_TEXTS) else logging.WARNING
    _MUJOCO_LOG.log(level, "MuJoCo: %s", _last_mujoco_warning)


def route_mujoco_warnings() -> None:
    """Send MuJoCo's warnings to the ``neck_sim.mujoco`` logger unless someone installed a handler."""
    if mujoco.get_mju_user_warning() is None:
        mujoco.set_mju_user_warning(log_warning)


def last_warning() -> str:
    """The text of the last MuJoCo warning this process logged ("" before any)."""
    return _last_mujoco_warning
