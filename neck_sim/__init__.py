"""neck-sim's model core: the neck's constants, its analytic model, the simulated plant, hidden
effects and the MCAP logs.

A neck is a :class:`NeckParams` (SI units; ``default_params(N)`` the paper's constants for N
joints, ``example_params(name)`` a shipped example, ``load_params(path)`` a TOML file); a
:class:`Plant` simulates it in MuJoCo with optional hidden :class:`Effects`; a :class:`PlantSpec`
names such a plant (params, effects, seed, timestep, cable model) so that it can be rebuilt; a
:class:`PlantBatch` steps K plants per control period; a :class:`Recorder` writes what a loop
recorded to a log that :func:`read_log` reads back.  :mod:`neck_sim.analytic` is the paper's model
(numpy, batched).  The controllers and the identification build on this package
(``controllers``, ``identification``).

Usage::

    import numpy as np
    import neck_sim

    params = neck_sim.default_params(3)                          # the paper's 3-X neck
    spec = neck_sim.PlantSpec(params, neck_sim.Effects.of(neck_sim.effects.Payload(0.05)), seed=0)
    plant = spec.build()                                         # a Plant hiding a 50 g payload
    plant.reset(np.zeros(3))
    for _ in range(10):                                          # 20 ms at the control rate
        plant.step(np.full(params.n_cables, 20.0))               # cable forces, N
    alpha = plant.truth().alpha                                  # joint angles, rad
    Z = neck_sim.analytic.transmission_matrix(alpha, params)     # eq (22), (N, m)

Names are imported when first used (PEP 562), so that ``import neck_sim`` and ``neck-sim --help``
do not load MuJoCo, numba or SciPy.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from neck_sim.lazy import lazy_attributes

if TYPE_CHECKING:
    from neck_sim import analytic, effects
    from neck_sim.batch import PlantBatch
    from neck_sim.effects import Effect, Effects, MotorEffect, register
    from neck_sim.logs import Log, LogError, LogWriter, read_log
    from neck_sim.params import NeckParams, ParameterError, default_params, example_params
    from neck_sim.params import load as load_params
    from neck_sim.params import save as save_params
    from neck_sim.plant import Plant, PlantDivergedError, Truth
    from neck_sim.plant_spec import PlantSpec
    from neck_sim.recorder import Recorder
    from neck_sim.replay import replay
    from neck_sim.trajectory import Trajectory, TrajectorySample, control_test_trajectory, identification_trajectory

__all__ = ["NeckParams", "ParameterError", "default_params", "example_params", "load_params", "save_params",
           "Plant", "PlantDivergedError", "Truth", "PlantBatch", "PlantSpec", "Recorder",
           "Effects", "Effect", "MotorEffect", "register", "effects",
           "read_log", "Log", "LogError", "LogWriter", "replay",
           "Trajectory", "TrajectorySample", "control_test_trajectory", "identification_trajectory",
           "analytic"]

# exported name -> (module, its name there; None: the module itself)
_SOURCES: dict[str, tuple[str, str | None]] = {
    **{n: ("neck_sim.params", n) for n in ("NeckParams", "ParameterError", "default_params", "example_params")},
    "load_params": ("neck_sim.params", "load"), "save_params": ("neck_sim.params", "save"),
    **{n: ("neck_sim.plant", n) for n in ("Plant", "PlantDivergedError", "Truth")},
    "PlantBatch": ("neck_sim.batch", "PlantBatch"), "PlantSpec": ("neck_sim.plant_spec", "PlantSpec"),
    "Recorder": ("neck_sim.recorder", "Recorder"),
    **{n: ("neck_sim.effects", n) for n in ("Effects", "Effect", "MotorEffect", "register")},
    **{n: ("neck_sim.logs", n) for n in ("read_log", "Log", "LogError", "LogWriter")},
    "replay": ("neck_sim.replay", "replay"),
    **{n: ("neck_sim.trajectory", n)
       for n in ("Trajectory", "TrajectorySample", "control_test_trajectory", "identification_trajectory")},
    "effects": ("neck_sim.effects", None), "analytic": ("neck_sim.analytic", None),
}

__getattr__, __dir__ = lazy_attributes(__name__, _SOURCES, __all__)
