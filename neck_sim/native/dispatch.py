"""The process-wide owner of MuJoCo's ``mjcb_control``: the backend of each plant, and the
callback installed while a plant steps.

Callbacks are process-global in MuJoCo.  The callback dispatches by ``mjModel`` address: models
that belong to no live plant are left untouched (a plain MuJoCo model keeps working), and each
plant sees only its own parameters.  Each plant keeps the backend it was made with, so a
Python-backend plant alive in the process changes nothing for native plants (their results stay
bit-identical).  Native: the C callback stays installed once there; it looks the model up among
the registered plants and returns at once for any other model.  Python: a Python
``mjcb_control`` breaks compiling any model (MuJoCo runs it on a temporary mjData), so it is
installed only while a Python-backend plant steps (:meth:`Dispatch.enter` / :meth:`Dispatch.leave`,
which put back whatever callback was installed before).
"""

from __future__ import annotations

import ctypes
import os
import warnings
import weakref

import mujoco

from neck_sim.native.build import NativeBuildError, build

__all__ = ["Dispatch", "DISPATCH", "set_backend", "get_backend", "native_available", "BACKENDS"]

BACKENDS = ("auto", "native", "python")


class Dispatch:
    """The default backend, the live plants (by model address) and the C library.

    A plant is registered through its :class:`neck_sim.native.NativePlant` record (``register``);
    the registration ends when the record is collected (a finalizer on the record).
    """

    def __init__(self):
        self.lib: ctypes.CDLL | None = None
        self.native_error: str | None = None
        self.backend: str | None = None           # the default of plants made without a backend
        self.native_cb = None                     # the C callback object handed to set_mjcb_control
        self.plants: dict[int, list] = {}         # model address -> [weakref to the record, backend]
        self._python_forces = None

    def native(self) -> ctypes.CDLL | None:
        """The loaded C library, built at the first call; None when it cannot be built."""
        if self.lib is None and self.native_error is None:
            try:
                self.lib = build()
                self.native_cb = self.lib.neck_control
            except NativeBuildError as exc:
                self.native_error = str(exc)
        return self.lib

    def choose(self, backend: str | None) -> str:
        """The backend a plant made with ``backend`` gets ("native" or "python")."""
        if backend is None:
            backend = self.backend or os.environ.get("NECK_SIM_CALLBACK", "auto")
        if backend not in BACKENDS:
            raise ValueError(f"backend: expected 'auto', 'native' or 'python', got {backend!r}")
        if backend in ("auto", "native") and self.native() is None:
            if backend == "native":
                raise NativeBuildError(self.native_error)
            warnings.warn(f"neck_sim.plant: native callback unavailable ({self.native_error}); "
                          "using the slower Python callback", RuntimeWarning, stacklevel=3)
            backend = "python"
        return "native" if backend == "auto" else backend

    def backend_of(self, address: int) -> str | None:
        """The backend of the live plant whose model is at ``address`` (None for another model)."""
        entry = self.plants.get(address)
        return None if entry is None else entry[1]

    def set_backend(self, backend: str) -> str:
        """The default for new plants; live plants are moved to it."""
        chosen = self.choose(backend)
        self.backend = chosen
        for address, entry in list(self.plants.items()):
            record = entry[0]()
            if record is not None and entry[1] != chosen:
                self._unregister_raw(address, entry[1])
                entry[1] = chosen
                self._register_raw(record, chosen)
        return chosen

    def _callback(self, backend: str):
        return self.native_cb if backend == "native" else _python_control

    @staticmethod
    def _refuse(current) -> None:
        raise RuntimeError("the process-global MuJoCo control callback (mjcb_control) is set to "
                           f"{current!r}; neck_sim plants need it: call mujoco.set_mjcb_control(None) first")

    def enter(self, backend: str):
        """Before a plant of ``backend`` steps: make its callback the installed one; returns what
        :meth:`leave` restores (the native callback stays installed once there)."""
        want = self._callback(backend)
        current = mujoco.get_mjcb_control()
        if current is want:
            return current
        if current is not None and current is not self.native_cb and current is not _python_control:
            self._refuse(current)
        mujoco.set_mjcb_control(want)
        return want if current is None and backend == "native" else current

    def leave(self, previous) -> None:
        """After stepping: put back what :meth:`enter` returned."""
        if mujoco.get_mjcb_control() is not previous:
            mujoco.set_mjcb_control(previous)

    def _register_raw(self, record, backend: str) -> None:
        if backend == "native":
            if self.lib.neck_register(record.address, ctypes.byref(record.struct)) < 0:
                raise RuntimeError("too many live plants in this process (256)")

    def _unregister_raw(self, address: int, backend: str | None) -> None:
        if backend == "native" and self.lib is not None:
            self.lib.neck_unregister(address)

    def register(self, record, backend: str | None) -> str:
        """Register the plant of ``record`` (a :class:`neck_sim.native.NativePlant`) with the
        backend :meth:`choose` gives ``backend``; returns it.  The registration ends with the record."""
        chosen = self.choose(backend)
        if self.backend is None:
            self.backend = chosen
        self.plants[record.address] = [weakref.ref(record), chosen]
        self._register_raw(record, chosen)
        # the struct rides along so that C never holds a pointer to freed memory
        weakref.finalize(record, _finalize, record.address, record.struct)
        return chosen

    def unregister(self, address: int) -> None:
        """End the registration of the plant whose model was at ``address`` (its record is gone)."""
        entry = self.plants.get(address)
        if entry is not None and entry[0]() is None:
            del self.plants[address]
            self._unregister_raw(address, entry[1])


#: The one dispatch of the process.
DISPATCH = Dispatch()


def _finalize(address: int, _keepalive) -> None:
    DISPATCH.unregister(address)


def _python_control(m, d) -> None:
    entry = DISPATCH.plants.get(m._address)
    record = entry[0]() if entry is not None else None
    if record is not None and record.model is m and entry[1] == "python":
        if DISPATCH._python_forces is None:
            # imported at first use: neck_sim.params imports this package for MAX_CABLES, and the
            # reference physics imports neck_sim.params
            from neck_sim.native.reference import python_forces
            DISPATCH._python_forces = python_forces
        DISPATCH._python_forces(record)


def set_backend(backend: str) -> str:
    """Choose the default callback of plants: ``"native"`` (C), ``"python"`` or ``"auto"``.

    Live plants are moved to the new backend.  Returns the backend in use.  A plant made with an
    explicit ``backend=`` keeps it and changes nothing for the others.
    """
    return DISPATCH.set_backend(backend)


def get_backend() -> str | None:
    """The default backend of plants (None before the first plant or ``set_backend``)."""
    return DISPATCH.backend


def native_available() -> bool:
    """True when the C callback compiles and loads on this machine."""
    return DISPATCH.native() is not None
