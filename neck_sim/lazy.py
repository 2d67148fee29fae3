"""Names of a package loaded on first use (PEP 562), so that importing the package loads nothing heavy.

Usage, in a package's ``__init__.py``::

    from neck_sim.lazy import lazy_attributes

    _SOURCES = {"Plant": "neck_sim.plant", "load_params": ("neck_sim.params", "load"),
                "analytic": ("neck_sim.analytic", None)}          # None: the module itself
    __getattr__, __dir__ = lazy_attributes(__name__, _SOURCES, __all__)
"""

from __future__ import annotations

import importlib
import sys
from typing import Any, Callable, Iterable, Mapping

__all__ = ["lazy_attributes"]


def lazy_attributes(package: str, sources: Mapping[str, str | tuple[str, str | None]],
                    exported: Iterable[str]) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """The module-level ``__getattr__`` and ``__dir__`` of ``package``: an exported name maps to the
    module that defines it (same name there) or to (module, its name there; None: the module
    itself).  A loaded value is stored in the package, so the next access skips ``__getattr__``."""
    names = sorted(set(exported))

    def __getattr__(name: str) -> Any:
        source = sources.get(name)
        if source is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        module_name, attr = (source, name) if isinstance(source, str) else source
        module = importlib.import_module(module_name)
        value = module if attr is None else getattr(module, attr)
        setattr(sys.modules[package], name, value)
        return value

    def __dir__() -> list[str]:
        return sorted(set(vars(sys.modules[package])) | set(names))

    return __getattr__, __dir__
