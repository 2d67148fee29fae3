"""Jobs on a Dask distributed cluster (:class:`ClusterPool`, a ``concurrent.futures.Executor``
over ``distributed.Client``) with a watchdog that fails the campaign in one line when the
scheduler or every worker is gone."""

from __future__ import annotations

import concurrent.futures as cf
import logging
import threading
import time
from contextlib import contextmanager
from typing import Any, Iterator

from neck_sim.campaign.spec import ClusterError, ExecutorSpec

__all__ = ["ClusterPool", "dask_executor"]


@contextmanager
def dask_executor(spec: ExecutorSpec) -> Iterator[cf.Executor]:
    """A :class:`ClusterPool` on the scheduler at ``spec.cluster`` for the ``with`` block, once
    it has at least one worker; :class:`ClusterError` in one line if there is none or no scheduler
    answers within ``spec.connect_timeout`` s."""
    try:
        from distributed import Client
    except ImportError as exc:       # a dependency of neck-sim; only a broken install lacks it
        raise ClusterError(f"--cluster needs dask.distributed ({exc}); pip install 'dask[distributed]'") from None
    try:
        client = Client(spec.cluster, timeout=spec.connect_timeout, set_as_default=False)
    except (OSError, TimeoutError) as exc:
        raise ClusterError(f"cluster {spec.cluster}: no Dask scheduler answered within {spec.connect_timeout:g} s "
                           f"({exc}); start one with `dask scheduler` and workers with "
                           f"`dask worker {spec.cluster} --nthreads 1`") from None
    pool = ClusterPool(client, spec.cluster, spec.worker_timeout)
    # a lost scheduler: our one line, not the tracebacks Dask logs while the client's comms close
    quiet = _DropOnceLost(pool.lost)
    handlers = logging.getLogger("distributed").handlers + logging.getLogger().handlers
    for h in handlers:
        h.addFilter(quiet)
    try:
        try:
            client.wait_for_workers(1, timeout=spec.connect_timeout)
        except (TimeoutError, OSError):
            raise ClusterError(f"cluster {spec.cluster}: the scheduler has no workers after "
                               f"{spec.connect_timeout:g} s; start some with `dask worker {spec.cluster} "
                               "--nthreads 1` on machines where neck-sim is installed") from None
        yield pool
    finally:
        pool.shutdown(wait=False)
        client.close(timeout=spec.connect_timeout)
        for h in handlers:
            h.removeFilter(quiet)


class ClusterPool(cf.Executor):
    """Jobs on a Dask cluster through ``client`` (each job runs, ``pure=False``), with a watchdog.

    The watchdog (a thread polling every ``poll`` s) fails every unfinished future with a one-line
    :class:`ClusterError` when the client has lost its scheduler, or when the scheduler has had
    no worker for ``worker_timeout`` s while jobs wait (Dask itself would wait forever).  A worker
    that dies while a job runs is the scheduler's to retry (``allowed-failures``).
    """

    def __init__(self, client, address: str, worker_timeout: float, poll: float = 1.0):
        self._client, self.address, self.worker_timeout, self._poll = client, address, worker_timeout, poll
        self._lock = threading.Lock()
        self._pending: dict[cf.Future, Any] = {}
        self.error: ClusterError | None = None
        self.lost = threading.Event()          # the client lost its scheduler
        self._stop = threading.Event()
        self._watchdog = threading.Thread(target=self._watch, name="neck-sim cluster watchdog", daemon=True)
        self._watchdog.start()

    def submit(self, fn, /, *args, **kwargs) -> cf.Future:
        if self.error is not None:
            raise self.error
        inner = self._client.submit(fn, *args, pure=False, **kwargs)
        outer = cf.Future()
        with self._lock:
            self._pending[outer] = inner
        outer.add_done_callback(lambda f: f.cancelled() and self._cancel(inner))
        inner.add_done_callback(lambda f: self._settle(outer, f))
        return outer

    def _cancel(self, inner) -> None:
        if not self.lost.is_set() and inner.status == "pending":      # no call to a scheduler that is gone
            inner.cancel()

    def _settle(self, outer: cf.Future, inner) -> None:
        with self._lock:
            self._pending.pop(outer, None)
            if outer.done():
                return
            if inner.status == "finished":
                outer.set_result(inner.result())
            elif inner.status == "cancelled":      # the client cancels everything when its scheduler is gone
                self.lost.set()
                outer.set_exception(self._lost())
            else:
                outer.set_exception(inner.exception())

    def _lost(self) -> ClusterError:
        return ClusterError(f"cluster {self.address}: lost the connection to the Dask scheduler (it stopped or "
                            "the network failed); the unfinished jobs were abandoned")

    def _fail_all(self, error: ClusterError) -> None:
        with self._lock:
            self.error = error
            pending, self._pending = self._pending, {}
        for outer, inner in pending.items():
            if not outer.done():
                outer.set_exception(error)
            self._cancel(inner)

    def _watch(self) -> None:
        since = None                       # when the cluster was last seen without workers
        while not self._stop.wait(self._poll):
            if self._client.status not in ("running", "newly-created"):
                self.lost.set()
                self._fail_all(self._lost())
                return
            try:
                n = len(self._client.nthreads())
            except Exception:              # the scheduler went away between the check and the call
                continue
            if n or not self._pending:
                since = None
                continue
            since = time.monotonic() if since is None else since
            if time.monotonic() - since >= self.worker_timeout:
                self._fail_all(ClusterError(
                    f"cluster {self.address}: no Dask worker for {self.worker_timeout:g} s while "
                    f"{len(self._pending)} job(s) waited; start workers with `dask worker {self.address} "
                    "--nthreads 1` (ExecutorSpec.worker_timeout sets this wait)"))
                return

    def shutdown(self, wait: bool = True, *, cancel_futures: bool = False) -> None:
        self._stop.set()
        if cancel_futures:
            with self._lock:
                pending = list(self._pending)
            for outer in pending:
                outer.cancel()


class _DropOnceLost(logging.Filter):
    """While a campaign runs on Dask: drops Dask's INFO records (connection chatter) and, once the
    scheduler is lost, everything (the tracebacks of the client's comms closing).  Installed on the
    handlers of the ``distributed`` and root loggers, which every ``distributed.*`` record reaches."""

    def __init__(self, lost: threading.Event):
        super().__init__()
        self._lost = lost

    def filter(self, record: logging.LogRecord) -> bool:
        if not record.name.startswith("distributed"):
            return True
        return record.levelno >= logging.WARNING and not self._lost.is_set()
