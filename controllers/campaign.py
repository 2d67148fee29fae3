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
"""

from __future__ import annotations

import concurrent.futures as cf
import multiprocessing
import os
import re
import tempfile
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any, Callable, Iterator, Sequence

from neck_sim.atomic import atomic_write_bytes

__all__ = ["ExecutorSpec", "default_workers", "open_executor", "map_jobs", "run_campaign", "run_in_scratch",
           "write_shipped", "ClusterError"]

# tcp://, tls:// (or ucx://, inproc://) + host + port: what distributed.Client accepts as a scheduler address
_ADDRESS = re.compile(r"^(tcp|tls|ucx|inproc)://[^\s:/]+(:\d+)?/?$")


class ClusterError(RuntimeError):
    """The Dask cluster could not be reached, has no workers, or is not installed."""


def default_workers() -> int:
    """One worker per available core (at least 1)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on Linux
        return max(1, os.cpu_count() or 1)


@dataclass(frozen=True)
class ExecutorSpec:
    """Where a campaign runs: ``cluster`` (a Dask scheduler address) if given, else ``workers``
    local processes (None: one per core; 1: serially in this process).  ``connect_timeout`` s to
    reach the scheduler and see at least one worker."""

    workers: int | None = None
    cluster: str | None = None
    connect_timeout: float = 30.0

    def __post_init__(self):
        if self.workers is not None and (not isinstance(self.workers, int) or self.workers < 1):
            raise ValueError(f"workers: expected a whole number >= 1, got {self.workers!r}")
        if self.cluster is not None and not _ADDRESS.match(str(self.cluster)):
            raise ValueError(f"cluster: expected a Dask scheduler address such as tcp://HOST:8786, "
                             f"got {self.cluster!r}")
        if not self.connect_timeout > 0:
            raise ValueError(f"connect_timeout: expected a positive number of seconds, got {self.connect_timeout!r}")

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
    # fork keeps start-up cheap (no re-import of MuJoCo per worker); jobs build their models inside
    with cf.ProcessPoolExecutor(max_workers=n, mp_context=multiprocessing.get_context("fork")) as ex:
        yield ex


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
    try:
        try:
            client.wait_for_workers(1, timeout=spec.connect_timeout)
        except (TimeoutError, OSError):
            raise ClusterError(f"cluster {spec.cluster}: the scheduler has no workers after "
                               f"{spec.connect_timeout:g} s; start some with `dask worker {spec.cluster} "
                               "--nthreads 1` on machines where neck-sim is installed") from None
        # pure=False: every job runs (two equal jobs are not merged into one result)
        ex = client.get_executor(pure=False)
        try:
            yield ex
        finally:
            ex.shutdown(wait=False)
    finally:
        client.close()


def map_jobs(fn: Callable[[Any], Any], jobs: Sequence[Any], executor: cf.Executor | None, *,
             labels: Sequence[str] | None = None, progress: bool = True, desc: str = "jobs") -> list:
    """``[fn(job) for job in jobs]`` on ``executor`` (None: here, in order), with a progress bar.

    ``fn`` must be a module-level function and the jobs picklable (they travel to the workers).
    A failing job raises ``RuntimeError`` naming its label (default: its index); the other jobs
    are cancelled.
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
        futures = {executor.submit(fn, job): i for i, job in enumerate(jobs)}
        try:
            for fut in cf.as_completed(futures):
                i = futures[fut]
                try:
                    results[i] = fut.result()
                except Exception as exc:
                    raise RuntimeError(f"job {labels[i]!r} failed: {type(exc).__name__}: {exc}") from exc
                bar.set_postfix_str(labels[i])
                bar.update()
        except BaseException:
            for other in futures:
                other.cancel()
            raise
    return results


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
