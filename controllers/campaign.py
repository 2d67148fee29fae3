"""Campaigns: many independent jobs on a standard ``concurrent.futures`` executor.

Where the jobs run is one small, picklable choice, :class:`ExecutorSpec`:

* ``ExecutorSpec()``: local worker processes, one per core (``ProcessPoolExecutor``);
* ``ExecutorSpec(workers=1)``: serially in this process (per-step progress, easiest to debug);
* ``ExecutorSpec(cluster="tcp://HOST:PORT")``: a Dask distributed cluster
  (``distributed.Client(address).get_executor()``); start it with ``dask scheduler`` and
  ``dask worker tcp://HOST:PORT --nthreads 1`` on each machine that has neck-sim installed, or
  through dask-jobqueue on SLURM/PBS.

:func:`open_executor` turns the choice into an executor (None for serial), :func:`map_jobs` runs a
module-level function over a list of jobs on it with a progress bar and returns the results in job
order, naming the job that failed.  Jobs that write a file run through :func:`run_in_scratch` so
that a worker on another machine sends the file's bytes back instead of writing into a directory
the caller cannot see; :func:`write_shipped` puts them in place (atomically).

Faults end the campaign loudly and leave nothing behind (docs/campaigns.md):

* a local worker process that dies (killed, out of memory, a crash in compiled code) breaks the
  ``ProcessPoolExecutor`` (``BrokenProcessPool``); :func:`map_jobs` starts a fresh pool and
  reruns the unfinished jobs, each job whose worker died under it at most ``ExecutorSpec.retries``
  times, then fails naming it;
* Ctrl-C or SIGTERM in the caller terminates the local workers at once (they ignore Ctrl-C
  themselves and, on Linux, die with the process that started them even if it is killed hard);
* on Dask, a worker that dies is retried by the scheduler (``distributed.scheduler.allowed-failures``,
  3 by default, then ``KilledWorker`` naming the job); a cluster left without workers for
  ``ExecutorSpec.worker_timeout`` s, or a lost scheduler, fails every unfinished job with a
  one-line :class:`ClusterError`.
"""

from __future__ import annotations

import concurrent.futures as cf
import logging
import multiprocessing
import os
import re
import signal
import sys
import tempfile
import threading
import time
from concurrent.futures.process import BrokenProcessPool
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any, Callable, Iterator, Sequence

from neck_sim.atomic import atomic_write_bytes

__all__ = ["ExecutorSpec", "default_workers", "open_executor", "map_jobs", "run_campaign", "run_in_scratch",
           "write_shipped", "ClusterError", "WorkerDied", "LocalPool", "ClusterPool"]

# tcp://, tls:// (or ucx://, inproc://) + host + port: what distributed.Client accepts as a scheduler address
_ADDRESS = re.compile(r"^(tcp|tls|ucx|inproc)://[^\s:/]+(:\d+)?/?$")


class ClusterError(RuntimeError):
    """The Dask cluster could not be reached, has no workers, or is not installed."""


class WorkerDied(BrokenProcessPool):
    """A local worker process died (killed, out of memory, a crash in compiled code) under a job."""


def default_workers() -> int:
    """One worker per available core (at least 1)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on Linux
        return max(1, os.cpu_count() or 1)


@dataclass(frozen=True)
class ExecutorSpec:
    """Where a campaign runs: ``cluster`` (a Dask scheduler address) if given, else ``workers``
    local processes (None: one per core; 1: serially in this process).

    ``connect_timeout`` s to reach the scheduler and see at least one worker; ``worker_timeout`` s
    a Dask cluster may stay without any worker while jobs wait before they fail; ``retries``: how
    many times a job is rerun after its local worker process died under it (on Dask the
    scheduler's ``allowed-failures`` decides).
    """

    workers: int | None = None
    cluster: str | None = None
    connect_timeout: float = 30.0
    worker_timeout: float = 30.0
    retries: int = 2

    def __post_init__(self):
        if self.workers is not None and (not isinstance(self.workers, int) or self.workers < 1):
            raise ValueError(f"workers: expected a whole number >= 1, got {self.workers!r}")
        if self.cluster is not None and not _ADDRESS.match(str(self.cluster)):
            raise ValueError(f"cluster: expected a Dask scheduler address such as tcp://HOST:8786, "
                             f"got {self.cluster!r}")
        if not self.connect_timeout > 0:
            raise ValueError(f"connect_timeout: expected a positive number of seconds, got {self.connect_timeout!r}")
        if not self.worker_timeout > 0:
            raise ValueError(f"worker_timeout: expected a positive number of seconds, got {self.worker_timeout!r}")
        if not isinstance(self.retries, int) or self.retries < 0:
            raise ValueError(f"retries: expected a whole number >= 0, got {self.retries!r}")

    @property
    def serial(self) -> bool:
        return self.cluster is None and self.workers == 1

    def describe(self) -> str:
        if self.cluster is not None:
            return f"Dask cluster {self.cluster}"
        n = default_workers() if self.workers is None else self.workers
        return "serial (this process)" if n == 1 else f"{n} local worker processes"


@contextmanager
def open_executor(spec: ExecutorSpec = ExecutorSpec(), max_jobs: int | None = None) -> Iterator[cf.Executor | None]:
    """The executor of ``spec`` for the duration of the ``with`` block; None means serial.

    ``max_jobs`` caps the number of local processes (no idle workers for a short campaign).
    """
    if spec.cluster is not None:
        with _dask_executor(spec) as ex:
            yield ex
        return
    n = default_workers() if spec.workers is None else spec.workers
    if max_jobs is not None:
        n = min(n, max(1, max_jobs))
    if n == 1:
        yield None
        return
    pool = LocalPool(n, spec.retries)
    try:
        yield pool
    except BaseException:
        pool.terminate()          # Ctrl-C, SIGTERM or a failed job: no worker outlives the campaign
        raise
    pool.shutdown(wait=True)


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


@contextmanager
def _dask_executor(spec: ExecutorSpec) -> Iterator[cf.Executor]:
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


def map_jobs(fn: Callable[[Any], Any], jobs: Sequence[Any], executor: cf.Executor | None, *,
             labels: Sequence[str] | None = None, progress: bool = True, desc: str = "jobs") -> list:
    """``[fn(job) for job in jobs]`` on ``executor`` (None: here, in order), with a progress bar.

    ``fn`` must be a module-level function and the jobs picklable (they travel to the workers).
    A failing job raises ``RuntimeError`` naming its label (default: its index); the other jobs
    are cancelled.  On a :class:`LocalPool`, a worker that dies breaks the pool: the pool is
    restarted and the unfinished jobs rerun, a job whose worker died under it at most
    ``executor.retries`` times (then ``RuntimeError`` naming it).  A :class:`ClusterError` (the
    Dask cluster lost its scheduler or every worker) is raised as it is.
    """
    from tqdm.auto import tqdm

    jobs = list(jobs)
    labels = [str(i) for i in range(len(jobs))] if labels is None else [str(s) for s in labels]
    if len(labels) != len(jobs):
        raise ValueError(f"labels: expected one per job ({len(jobs)}), got {len(labels)}")
    results: list = [None] * len(jobs)
    with tqdm(total=len(jobs), desc=desc, unit="job", disable=not progress or len(jobs) <= 1) as bar:
        if executor is None:
            for i, job in enumerate(jobs):
                results[i] = _call_labelled(fn, job, labels[i])
                bar.set_postfix_str(labels[i])
                bar.update()
            return results
        deaths = [0] * len(jobs)
        futures = {executor.submit(fn, job): i for i, job in enumerate(jobs)}
        try:
            while futures:
                done, _ = cf.wait(futures, return_when=cf.FIRST_COMPLETED)
                if any(_broken(f) for f in done) and isinstance(executor, LocalPool):
                    futures = _rerun_after_death(fn, jobs, labels, futures, executor, deaths, bar)
                    continue
                for fut in done:
                    i = futures.pop(fut)
                    try:
                        results[i] = fut.result()
                    except ClusterError:
                        raise
                    except Exception as exc:
                        raise RuntimeError(f"job {labels[i]!r} failed: {type(exc).__name__}: {exc}") from exc
                    bar.set_postfix_str(labels[i])
                    bar.update()
        except BaseException:
            for other in futures:
                other.cancel()
            raise
    return results


def _broken(fut: cf.Future) -> bool:
    return not fut.cancelled() and isinstance(fut.exception(), BrokenProcessPool)


def _rerun_after_death(fn, jobs, labels, futures: dict, pool: LocalPool, deaths: list, bar) -> dict:
    """The pool broke under the jobs of ``futures``: rerun the ones that were running, each alone
    on a fresh pool (so that a death names its job), then resubmit the rest together.

    A death is charged to a job when it was the only one running; a job dies at most
    ``pool.retries + 1`` times so (plus once alongside others), the last raising ``RuntimeError``
    naming it.
    """
    cf.wait(futures)                          # a broken pool fails all its futures at once
    kept = {fut: i for fut, i in futures.items() if not _broken(fut)}       # finished before the break
    suspects = [i for fut, i in futures.items() if _broken(fut) and pool.died_under(fut)]
    queued = [i for fut, i in futures.items() if _broken(fut) and i not in suspects]

    def died(i: int) -> None:
        deaths[i] += 1
        if deaths[i] > pool.retries:
            raise RuntimeError(f"job {labels[i]!r} failed: its worker process died {deaths[i]} time(s) while "
                               f"running it (killed by a signal or out of memory; {pool.retries} retries)")
        bar.write(f"a worker process died while running job {labels[i]!r}; rerunning it "
                  f"({deaths[i]} of {pool.retries} retries)", file=sys.stderr)

    if len(suspects) == 1:
        died(suspects[0])
    elif suspects:
        bar.write("a worker process died while running jobs " + ", ".join(repr(labels[i]) for i in suspects)
                  + "; rerunning each alone to find which", file=sys.stderr)
    pool.restart()
    for i in suspects:
        while True:
            fut = pool.submit(fn, jobs[i])
            cf.wait([fut])
            if not _broken(fut):
                kept[fut] = i
                break
            died(i)
            pool.restart()
    kept.update({pool.submit(fn, jobs[i]): i for i in queued})
    return kept


def _call_labelled(fn, job, label: str):
    try:
        return fn(job)
    except Exception as exc:
        raise RuntimeError(f"job {label!r} failed: {type(exc).__name__}: {exc}") from exc


def run_campaign(fn: Callable[[Any], Any], jobs: Sequence[Any],
                 executor: ExecutorSpec | cf.Executor | None = ExecutorSpec(), *,
                 labels: Sequence[str] | None = None, progress: bool = True, desc: str = "jobs") -> list:
    """:func:`map_jobs` on ``executor``: an :class:`ExecutorSpec` (opened for these jobs and closed
    afterwards), an executor already open, or None (serially here)."""
    if isinstance(executor, ExecutorSpec):
        with open_executor(executor, max_jobs=len(jobs)) as ex:
            return map_jobs(fn, jobs, ex, labels=labels, progress=progress, desc=desc)
    return map_jobs(fn, jobs, executor, labels=labels, progress=progress, desc=desc)


def run_in_scratch(fn: Callable[..., Any], filename: str, *args, **kwargs) -> tuple[Any, bytes]:
    """On a worker: ``fn(path, *args, **kwargs)`` with ``path`` a file ``filename`` in a fresh
    scratch directory; returns (fn's value, the file's bytes) and removes the scratch."""
    with tempfile.TemporaryDirectory(prefix="neck-sim-job-") as d:
        path = os.path.join(d, os.path.basename(filename))
        value = fn(path, *args, **kwargs)
        with open(path, "rb") as fh:
            return value, fh.read()


def write_shipped(path: str | os.PathLike, data: bytes) -> str:
    """Put the bytes a worker sent back (:func:`run_in_scratch`) at ``path``, atomically."""
    atomic_write_bytes(path, data)
    return os.fspath(path)
