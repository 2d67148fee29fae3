"""Open the executor an :class:`ExecutorSpec` names and map jobs over it, in job order, with a
progress bar, naming the job that failed; rerun the jobs whose local worker died."""

from __future__ import annotations

import concurrent.futures as cf
import os
import sys
import tempfile
from concurrent.futures.process import BrokenProcessPool
from contextlib import contextmanager
from typing import Any, Callable, Iterator, Sequence

from neck_sim.atomic import atomic_write_bytes
from neck_sim.campaign.cluster import dask_executor
from neck_sim.campaign.local import LocalPool
from neck_sim.campaign.spec import ClusterError, ExecutorSpec, default_workers

__all__ = ["open_executor", "map_jobs", "run_campaign", "run_in_scratch", "write_shipped"]


@contextmanager
def open_executor(spec: ExecutorSpec = ExecutorSpec(), max_jobs: int | None = None) -> Iterator[cf.Executor | None]:
    """The executor of ``spec`` for the duration of the ``with`` block; None means serial.

    ``max_jobs`` caps the number of local processes (no idle workers for a short campaign).
    """
    if spec.cluster is not None:
        with dask_executor(spec) as ex:
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
