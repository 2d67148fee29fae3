"""Compile ``plant_callback.c`` with the system C compiler against MuJoCo's headers and library,
and load it with ctypes.

The library is built once per source text, MuJoCo version and include path into a cache directory
(:func:`neck_sim.cache.cache_dir`); :func:`build` raises :class:`NativeBuildError` when no
compiler is available (the plants then fall back to the Python reference backend,
:mod:`neck_sim.native.reference`).
"""

from __future__ import annotations

import ctypes
import hashlib
import os
import shutil
import subprocess

import mujoco

from neck_sim.cache import cache_dir
from neck_sim.native.source import SOURCE_PATH, PlantStruct, source

__all__ = ["NativeBuildError", "build", "mujoco_include_dir", "mujoco_library", "link_flags", "compiler"]


class NativeBuildError(RuntimeError):
    """The C callback could not be compiled or loaded."""


def mujoco_include_dir() -> str:
    """MuJoCo's C headers shipped with the Python package."""
    include = os.path.join(os.path.dirname(mujoco.__file__), "include")
    if not os.path.exists(os.path.join(include, "mujoco", "mjdata.h")):
        raise NativeBuildError(f"MuJoCo headers not found under {include}")
    return include


def compiler() -> str:
    """The C compiler: ``$CC``, else cc, gcc or clang on PATH."""
    cc = os.environ.get("CC") or shutil.which("cc") or shutil.which("gcc") or shutil.which("clang")
    if not cc:
        raise NativeBuildError("no C compiler (cc, gcc or clang) on PATH")
    return cc


def mujoco_library() -> str:
    """The MuJoCo shared library the Python package loads (``neck_step_batch`` calls its ``mj_step``)."""
    names = sorted(f for f in os.listdir(os.path.dirname(mujoco.__file__))
                   if f.startswith("libmujoco") and (".so" in f or f.endswith(".dylib")))
    if not names:
        raise NativeBuildError(f"no libmujoco shared library beside {mujoco.__file__}")
    return os.path.join(os.path.dirname(mujoco.__file__), names[-1])


def link_flags() -> list[str]:
    """Compiler flags that link against :func:`mujoco_library` (by its file name, with an rpath: the
    loader then reuses the copy the mujoco package has loaded, so there is one mjcb_control)."""
    mjlib = mujoco_library()
    folder = os.path.dirname(mjlib)
    return ["-L", folder, f"-l:{os.path.basename(mjlib)}", f"-Wl,-rpath,{folder}", "-lm"]


def _compile(lib_path: str, include: str, cache: str) -> None:
    cc = compiler()
    tmp = lib_path + f".tmp{os.getpid()}"
    try:
        res = subprocess.run([cc, "-O2", "-shared", "-fPIC", "-I", include, SOURCE_PATH, "-o", tmp, *link_flags()],
                             capture_output=True, text=True, timeout=120)
        if res.returncode != 0:
            raise NativeBuildError(f"{cc} failed: {res.stderr.strip()[:2000]}")
        os.replace(tmp, lib_path)
        for old in os.listdir(cache):           # libraries of earlier sources or MuJoCo versions
            if old.startswith("neck_plant_") and old.endswith(".so") and old != os.path.basename(lib_path):
                try:
                    os.unlink(os.path.join(cache, old))
                except OSError:
                    pass
    except (OSError, subprocess.SubprocessError) as exc:
        raise NativeBuildError(f"cannot compile the plant callback: {exc}") from None
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


def build() -> ctypes.CDLL:
    """Compile (once, cached by source + MuJoCo version) and load the callback library, with the
    argument types of its functions set."""
    include = mujoco_include_dir()
    key = hashlib.sha256((source() + mujoco.__version__ + include).encode()).hexdigest()[:16]
    cache = cache_dir()
    lib_path = os.path.join(cache, f"neck_plant_{key}.so")
    if not os.path.exists(lib_path):
        _compile(lib_path, include, cache)
    try:
        lib = ctypes.CDLL(lib_path)
    except OSError as exc:
        raise NativeBuildError(f"cannot load {lib_path}: {exc}") from None
    plant_p = ctypes.POINTER(PlantStruct)
    lib.neck_register.argtypes = [ctypes.c_void_p, plant_p]
    lib.neck_register.restype = ctypes.c_int
    lib.neck_unregister.argtypes = [ctypes.c_void_p]
    lib.neck_unregister.restype = ctypes.c_int
    lib.neck_registered.restype = ctypes.c_int
    for fn in (lib.neck_tension, lib.neck_friction):
        fn.argtypes = [plant_p, ctypes.c_int, ctypes.c_double, ctypes.c_double, ctypes.POINTER(ctypes.c_double)]
        fn.restype = None
    lib.neck_sense.argtypes = [plant_p, ctypes.c_void_p]
    lib.neck_sense.restype = None
    lib.neck_control.argtypes = [ctypes.c_void_p, ctypes.c_void_p]
    lib.neck_control.restype = None
    # a PyDLL handle on the same library: neck_step_batch keeps the GIL, since MuJoCo may call the
    # Python warning handler (neck_sim.native.mujoco_log routes its warnings to logging) from inside mj_step
    step = ctypes.PyDLL(lib_path).neck_step_batch
    ptr = ctypes.c_void_p
    step.argtypes = [ctypes.c_int, ptr, ptr, ptr, ptr, ctypes.c_int, ctypes.c_int, ctypes.c_int,
                     ptr, ctypes.c_int, ptr, ptr, ptr, ptr, ptr, ptr]
    step.restype = ctypes.c_int
    lib.step_batch = step
    return lib
