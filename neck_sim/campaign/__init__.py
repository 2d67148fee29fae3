"""Campaigns: many independent jobs on a standard ``concurrent.futures`` executor.

The generic executor that closed-loop runs (:mod:`controllers.parallel`), blind-log generation
(:mod:`identification.diagnosis.blind`) and the benchmarks share; it knows nothing of what the jobs do.

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
  3 by default, then ``KilledWorker`` naming the job), but only once its nanny has finished
  starting: a worker registers with the scheduler a moment before its nanny is up, and a worker
  that dies in that moment ends its nanny too (distributed 2026.8); a cluster left without workers
  for ``ExecutorSpec.worker_timeout`` s, or a lost scheduler, fails every unfinished job with a
  one-line :class:`ClusterError`.

Modules: :mod:`~neck_sim.campaign.spec` (where: :class:`ExecutorSpec` and the errors),
:mod:`~neck_sim.campaign.executor` (opening it, mapping jobs), :mod:`~neck_sim.campaign.local`
(:class:`LocalPool`), :mod:`~neck_sim.campaign.cluster` (:class:`ClusterPool`, Dask).

Example::

    from neck_sim.campaign import ExecutorSpec, run_campaign

    def square(x):                      # module-level: jobs travel to the workers by pickle
        return x * x

    run_campaign(square, [1, 2, 3], ExecutorSpec(workers=2), labels=["a", "b", "c"])   # [1, 4, 9]
"""

from neck_sim.campaign.cluster import ClusterPool
from neck_sim.campaign.executor import map_jobs, open_executor, run_campaign, run_in_scratch, write_shipped
from neck_sim.campaign.local import LocalPool
from neck_sim.campaign.spec import ClusterError, ExecutorSpec, WorkerDied, default_workers

__all__ = ["ExecutorSpec", "default_workers", "open_executor", "map_jobs", "run_campaign", "run_in_scratch",
           "write_shipped", "ClusterError", "WorkerDied", "LocalPool", "ClusterPool"]
