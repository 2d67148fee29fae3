"""The C source of the plant callback (``plant_callback.c``) and its ctypes mirror.

The C file is the one declaration of the ``neck_plant`` struct (parameters in, truth out):
:class:`PlantStruct` is generated from that declaration's text, so the two cannot drift
(``tests/test_plant.py`` checks every offset against the C compiler's ``offsetof``), and
:data:`MAX_CABLES` is read from its ``#define NECK_MAXC``.
"""

from __future__ import annotations

import ctypes
import functools
import os
import re

__all__ = ["SOURCE_PATH", "source", "MAX_CABLES", "struct_fields", "PlantStruct"]

SOURCE_PATH = os.path.join(os.path.dirname(os.path.abspath(__file__)), "plant_callback.c")

_C_TYPES = {"int": ctypes.c_int, "double": ctypes.c_double}


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
