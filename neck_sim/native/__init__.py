"""The native path of the plant, in one package: the C callback, its ctypes mirror, the backend
dispatch, the Python reference backend, the raw-pointer call of compiled kernels, and MuJoCo's
warnings.

* :mod:`~neck_sim.native.source`: ``plant_callback.c`` (the physics kernel and the ``neck_plant``
  struct, explained at its top), :class:`PlantStruct` generated from it, :data:`MAX_CABLES`;
* :mod:`~neck_sim.native.build`: compiles and loads it (:func:`build`, :class:`NativeBuildError`);
* :mod:`~neck_sim.native.dispatch`: the process-wide owner of MuJoCo's ``mjcb_control``
  (:data:`DISPATCH`, :func:`set_backend`, :func:`get_backend`, :func:`native_available`);
* :mod:`~neck_sim.native.record`: :class:`NativePlant`, the one public value through which a batch
  steps a plant, and its :class:`StepState`;
* :mod:`~neck_sim.native.reference`: the same physics in Python (the fallback backend);
* :mod:`~neck_sim.native.fused` and :mod:`~neck_sim.native.rawcall`: the interface of a batch to a
  compiled caller (:class:`FusedStep`) and :func:`call_c`, which calls a C pointer from numba;
* :mod:`~neck_sim.native.mujoco_log`: MuJoCo's warnings to the ``neck_sim.mujoco`` logger.

Usage::

    from neck_sim import native
    from neck_sim.plant import Plant

    if native.native_available():           # a C compiler found; else the Python backend runs
        native.set_backend("native")
    plant = Plant()
    record = plant.native                   # a NativePlant: model, data, struct, limits, state
    lib = native.DISPATCH.lib                # the loaded library (neck_tension, neck_friction, ...)
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from neck_sim.lazy import lazy_attributes

from neck_sim.native.source import MAX_CABLES, SOURCE_PATH, PlantStruct, source, struct_fields

if TYPE_CHECKING:
    from neck_sim.cache import cache_dir
    from neck_sim.native.build import (NativeBuildError, build, compiler, link_flags, mujoco_include_dir,
                                       mujoco_library)
    from neck_sim.native.dispatch import BACKENDS, DISPATCH, Dispatch, get_backend, native_available, set_backend
    from neck_sim.native.fused import FusedStep
    from neck_sim.native.mujoco_log import FATAL_WARNINGS, last_warning, log_warning, route_mujoco_warnings
    from neck_sim.native.rawcall import call_c
    from neck_sim.native.record import NativePlant, Outputs, StepState

# Loaded on first use (PEP 562): neck_sim.params reads MAX_CABLES from the source module, and a
# command's --help should load neither MuJoCo (build, dispatch) nor numba (rawcall).
_LAZY = {"cache_dir": "neck_sim.cache",
         **dict.fromkeys(("NativeBuildError", "build", "compiler", "link_flags", "mujoco_include_dir",
                          "mujoco_library"), "neck_sim.native.build"),
         **dict.fromkeys(("BACKENDS", "DISPATCH", "Dispatch", "get_backend", "native_available", "set_backend"),
                         "neck_sim.native.dispatch"),
         "FusedStep": "neck_sim.native.fused",
         **dict.fromkeys(("FATAL_WARNINGS", "last_warning", "log_warning", "route_mujoco_warnings"),
                         "neck_sim.native.mujoco_log"),
         "call_c": "neck_sim.native.rawcall",
         **dict.fromkeys(("NativePlant", "Outputs", "StepState"), "neck_sim.native.record")}



__all__ = ["SOURCE_PATH", "source", "MAX_CABLES", "PlantStruct", "struct_fields", "build", "NativeBuildError",
           "mujoco_include_dir", "mujoco_library", "link_flags", "compiler", "cache_dir",
           "FATAL_WARNINGS", "last_warning", "log_warning", "route_mujoco_warnings",
           "BACKENDS", "DISPATCH", "Dispatch", "get_backend", "native_available", "set_backend",
           "NativePlant", "Outputs", "StepState", "FusedStep", "call_c"]

__getattr__, __dir__ = lazy_attributes(__name__, _LAZY, __all__)
