"""The plant's native control callback: ``plant_callback.c`` compiled with the system C compiler,
loaded with ctypes.

The C file is the one source of the physics kernel and of the ``neck_plant`` struct (parameters
in, truth out); :class:`PlantStruct` is generated from that declaration's text, so the two cannot
drift (``tests/test_plant.py`` checks every offset against the C compiler's ``offsetof``).  What
the callback writes into the ``mjModel`` at each step is explained at the top of the C file.

The library is built once per source text, MuJoCo version and include path into a cache directory
(:func:`neck_sim.cache.cache_dir`); :func:`build` raises :class:`NativeBuildError`
when no compiler is available, and the plant then falls back to its Python callback.
"""

from __future__ import annotations

import ctypes
import functools
import hashlib
import os
import re
import shutil
import subprocess

import mujoco

from neck_sim.cache import cache_dir

__all__ = ["SOURCE_PATH", "source", "MAX_CABLES", "PlantStruct", "struct_fields", "build", "NativeBuildError",
           "mujoco_include_dir", "mujoco_library", "link_flags", "compiler", "cache_dir"]

SOURCE_PATH = os.path.join(os.path.dirname(os.path.abspath(__file__)), "plant_callback.c")

_C_TYPES = {"int": ctypes.c_int, "double": ctypes.c_double}


class NativeBuildError(RuntimeError):
    """The C callback could not be compiled or loaded."""


@functools.lru_cache(maxsize=1)
def source() -> str:
    """Text of ``plant_callback.c``."""
    with open(SOURCE_PATH, encoding="utf-8") as fh:
        return fh.read()


def _define(name: str, text: str) -> int:
    m = re.search(rf"^#define\s+{name}\s+(\d+)", text, re.MULTILINE)
    if m is None:
        raise RuntimeError(f"{SOURCE_PATH}: no '#define {name} <integer>'")
    return int(m.group(1))


MAX_CABLES = _define("NECK_MAXC", source())
"""Cables per plant the C struct holds (``NECK_MAXC``)."""


def struct_fields(text: str | None = None) -> list[tuple[str, type, int]]:
    """Members of the C ``neck_plant`` struct in declaration order: (name, ctypes scalar type,
    array length or 0 for a scalar), parsed from the C source."""
    text = source() if text is None else text
    m = re.search(r"typedef\s+struct\s*\{(.*?)\}\s*neck_plant\s*;", text, re.DOTALL)
    if m is None:
        raise RuntimeError(f"{SOURCE_PATH}: no 'typedef struct {{...}} neck_plant;'")
    body = re.sub(r"/\*.*?\*/|//[^\n]*", " ", m.group(1), flags=re.DOTALL)
    sizes = {"NECK_MAXC": MAX_CABLES}
    out = []
    for decl in filter(None, (d.strip() for d in body.split(";"))):
        ctype, _, names = decl.partition(" ")
        if ctype not in _C_TYPES:
            raise RuntimeError(f"{SOURCE_PATH}: neck_plant member type {ctype!r} in {decl!r}: "
                               f"only {sorted(_C_TYPES)} are mirrored")
        for item in names.split(","):
            im = re.fullmatch(r"\s*(\w+)\s*(?:\[\s*(\w+)\s*\])?\s*", item)
            if im is None:
                raise RuntimeError(f"{SOURCE_PATH}: cannot read neck_plant member {item!r}")
            n = im.group(2)
            length = 0 if n is None else (int(n) if n.isdigit() else sizes[n])
            out.append((im.group(1), _C_TYPES[ctype], length))
    return out


class PlantStruct(ctypes.Structure):
    """ctypes mirror of the C ``neck_plant`` struct, generated from ``plant_callback.c``."""

    _fields_ = [(name, t * n if n else t) for name, t, n in struct_fields()]


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
    # Python warning handler (neck_sim.plant routes MuJoCo's warnings to logging) from inside mj_step
    step = ctypes.PyDLL(lib_path).neck_step_batch
    ptr = ctypes.c_void_p
    step.argtypes = [ctypes.c_int, ptr, ptr, ptr, ptr, ctypes.c_int, ctypes.c_int, ctypes.c_int,
                     ptr, ctypes.c_int, ptr, ptr, ptr, ptr, ptr, ptr]
    step.restype = ctypes.c_int
    lib.step_batch = step
    return lib
