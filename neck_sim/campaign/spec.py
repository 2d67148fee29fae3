"""Where a campaign runs (:class:`ExecutorSpec`, a small picklable choice) and the errors a
campaign raises when its workers or its cluster fail."""

from __future__ import annotations

import os
import re
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass

__all__ = ["ExecutorSpec", "default_workers", "ClusterError", "WorkerDied"]

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
