"""Local worker processes that a campaign can restart after a death and stop at once
(:class:`LocalPool`, a ``concurrent.futures.Executor``)."""

from __future__ import annotations

import concurrent.futures as cf
import multiprocessing
import os
import signal
import sys
from concurrent.futures.process import BrokenProcessPool

from neck_sim.campaign.spec import WorkerDied

__all__ = ["LocalPool"]


class LocalPool(cf.Executor):
    """``n`` local worker processes: a ``ProcessPoolExecutor`` that can be restarted after a worker
    died (:meth:`restart`) and stopped at once (:meth:`terminate`).

    Workers are forked (start-up without re-importing MuJoCo; jobs build their models inside),
    ignore Ctrl-C (the caller decides) and on Linux receive SIGTERM when the thread that started
    them ends, so that a caller killed hard leaves no worker waiting; submit from the thread that
    opened the pool.  Each worker announces itself and the jobs it starts on a queue, which tells
    :meth:`died_under` whether a job was running when the pool broke.
    """

    def __init__(self, n: int, retries: int = 2):
        self.n, self.retries = n, retries
        self._ctx = multiprocessing.get_context("fork")
        self._pids: set[int] = set()
        self._started: set[int] = set()
        self._count = 0
        self._new_pool()

    def _new_pool(self) -> None:
        self._notes = self._ctx.SimpleQueue()
        self._pool = cf.ProcessPoolExecutor(max_workers=self.n, mp_context=self._ctx, initializer=_worker_init,
                                            initargs=(self._notes, os.getpid()))

    def submit(self, fn, /, *args, **kwargs) -> cf.Future:
        """``fn(*args, **kwargs)`` on a worker; if the pool breaks under it, the future fails with
        :class:`WorkerDied` naming ``fn`` (a ``BrokenProcessPool``)."""
        self._count += 1
        inner = self._pool.submit(_announced, self._count, fn, *args, **kwargs)
        outer = cf.Future()
        outer.job_key = self._count
        name = getattr(fn, "__qualname__", repr(fn))

        def settle(done: cf.Future) -> None:
            try:
                if done.cancelled():
                    outer.cancel()
                elif isinstance(done.exception(), BrokenProcessPool):
                    outer.set_exception(WorkerDied(f"the worker process running {name} died (killed by a signal "
                                                   "or out of memory)"))
                elif done.exception() is not None:
                    outer.set_exception(done.exception())
                else:
                    outer.set_result(done.result())
            except cf.InvalidStateError:      # cancelled by its caller meanwhile
                pass

        inner.add_done_callback(settle)
        outer.add_done_callback(lambda f: f.cancelled() and inner.cancel())
        return outer

    def _drain(self) -> None:
        while not self._notes.empty():
            kind, value = self._notes.get()
            (self._pids if kind == "pid" else self._started).add(value)

    def died_under(self, fut: cf.Future) -> bool:
        """True if ``fut`` failed with ``BrokenProcessPool`` after its job had started: a worker
        died while it ran (False for jobs that were only queued)."""
        if not (fut.done() and not fut.cancelled() and isinstance(fut.exception(), BrokenProcessPool)):
            return False
        self._drain()
        return getattr(fut, "job_key", None) in self._started

    def restart(self) -> None:
        """A fresh pool after this one broke (the dead pool's workers are already gone)."""
        self._pool.shutdown(wait=True, cancel_futures=True)
        self._pids.clear()
        self._new_pool()

    def terminate(self) -> None:
        """Cancel what is queued and kill the workers now (not after their running jobs)."""
        self._pool.shutdown(wait=False, cancel_futures=True)
        self._drain()
        for pid in self._pids:
            try:
                os.kill(pid, signal.SIGKILL)
            except (ProcessLookupError, PermissionError):
                pass
        self._pids.clear()

    def shutdown(self, wait: bool = True, *, cancel_futures: bool = False) -> None:
        self._pool.shutdown(wait=wait, cancel_futures=cancel_futures)


def _worker_init(notes, parent: int) -> None:
    """In each local worker: Ctrl-C is the caller's to handle, SIGTERM ends the worker (not the
    caller's Python handler inherited through fork), and the worker dies with its parent."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    if sys.platform.startswith("linux"):
        import ctypes

        try:
            ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGTERM)    # PR_SET_PDEATHSIG
        except (OSError, AttributeError):
            pass
        if os.getppid() != parent:                                         # the parent died first
            os._exit(1)
    global _NOTES
    _NOTES = notes
    notes.put(("pid", os.getpid()))


_NOTES = None       # in a local worker: the pool's queue of announcements


def _announced(key: int, fn, *args, **kwargs):
    _NOTES.put(("job", key))
    return fn(*args, **kwargs)
