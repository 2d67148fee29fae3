"""Campaign faults on local worker processes: a worker that dies, Ctrl-C and SIGTERM in the caller.

The jobs are tiny (sleeps, a self-kill); what is tested is the executor, not the simulation.
"""

import os
import signal
import subprocess
import sys
import textwrap
import time

import pytest

from interrupts import sigint_as_from_a_terminal
from neck_sim.campaign import ExecutorSpec, LocalPool, WorkerDied, open_executor, run_campaign

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")


def _die_first_time(job):
    """Kill this worker the first time job ``(x, flag_path)`` runs, then return x."""
    x, flag = job
    if flag is not None and not os.path.exists(flag):
        open(flag, "w").close()
        os.kill(os.getpid(), signal.SIGKILL)
    time.sleep(0.05)
    return x


def _always_die(x):
    if x == "poison":
        os.kill(os.getpid(), signal.SIGKILL)
    time.sleep(0.05)
    return x


def test_a_job_whose_worker_died_once_is_rerun_and_the_campaign_completes(tmp_path, capfd):
    jobs = [(i, str(tmp_path / "died") if i == 3 else None) for i in range(6)]
    assert run_campaign(_die_first_time, jobs, ExecutorSpec(workers=2), progress=False) == list(range(6))
    assert os.path.exists(tmp_path / "died")              # the worker was killed once, really
    assert "a worker process died while running job" in capfd.readouterr().err


def test_a_job_that_always_kills_its_worker_fails_naming_it_after_the_retries():
    t0 = time.monotonic()
    with pytest.raises(RuntimeError, match=r"job 'poison' failed: its worker process died 3 time\(s\) .*2 retries"):
        run_campaign(_always_die, ["a", "poison", "b"], ExecutorSpec(workers=2), labels=["a", "poison", "b"],
                     progress=False)
    assert time.monotonic() - t0 < 60
    with pytest.raises(RuntimeError, match=r"job 'poison' failed: its worker process died 1 time\(s\)"):
        run_campaign(_always_die, ["poison"] * 2, ExecutorSpec(workers=2, retries=0), labels=["poison", "p2"],
                     progress=False)


def test_a_job_submitted_directly_names_its_function_when_its_worker_dies():
    with open_executor(ExecutorSpec(workers=2)) as pool:
        fut = pool.submit(_always_die, "poison")
        with pytest.raises(WorkerDied, match=r"the worker process running _always_die died"):
            fut.result(timeout=30)
        pool.restart()                                    # and the pool is usable again
        assert pool.submit(_always_die, "fine").result(timeout=30) == "fine"


def _children(pid: int) -> set[int]:
    """Live (not zombie) processes whose parent is ``pid``."""
    out = set()
    for d in os.listdir("/proc"):
        if d.isdigit():
            try:
                with open(f"/proc/{d}/stat") as fh:
                    fields = fh.read().rsplit(")", 1)[1].split()
            except OSError:
                continue
            if int(fields[1]) == pid and fields[0] != "Z":
                out.add(int(d))
    return out


def _alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as fh:
            return fh.read().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


# a caller that turns SIGTERM into an exception as `neck-sim` does (neck_sim.cli), then runs a
# campaign of long jobs on two local workers
_CALLER = textwrap.dedent("""
    import signal, sys, time
    sys.path.insert(0, {root!r})
    from neck_sim.campaign import ExecutorSpec, run_campaign

    def stop(signum, frame):
        raise KeyboardInterrupt
    signal.signal(signal.SIGTERM, stop)
    try:
        run_campaign(time.sleep, [60] * 4, ExecutorSpec(workers=2), progress=False)
    except KeyboardInterrupt:
        sys.exit(143)
""")


def _start_caller(tmp_path):
    script = tmp_path / "caller.py"
    script.write_text(_CALLER.format(root=os.getcwd()))
    proc = subprocess.Popen([sys.executable, str(script)], start_new_session=True,
                            preexec_fn=sigint_as_from_a_terminal)
    deadline = time.monotonic() + 30
    # started and initialised (they ignore SIGINT): a signal at the instant of a fork is lost in
    # CPython's after-fork hooks, which is not what these tests are about
    while len(_children(proc.pid)) < 2 or not all(map(_ignores_sigint, _children(proc.pid))):
        assert time.monotonic() < deadline and proc.poll() is None, "the workers never started"
        time.sleep(0.05)
    return proc, _children(proc.pid)


def _ignores_sigint(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/status") as fh:
            mask = next(line.split()[1] for line in fh if line.startswith("SigIgn:"))
    except (OSError, StopIteration):
        return False
    return bool(int(mask, 16) >> (signal.SIGINT - 1) & 1)


@pytest.mark.parametrize("how", ["SIGTERM", "Ctrl-C"])
def test_sigterm_or_ctrl_c_leaves_no_worker_behind(tmp_path, how):
    proc, workers = _start_caller(tmp_path)
    try:
        if how == "SIGTERM":
            proc.send_signal(signal.SIGTERM)          # to the caller only, as `kill PID` does
        else:
            os.killpg(proc.pid, signal.SIGINT)        # to the whole group, as a terminal does
        assert proc.wait(timeout=20) == 143            # the caller saw KeyboardInterrupt
        deadline = time.monotonic() + 5
        while any(map(_alive, workers)) and time.monotonic() < deadline:
            time.sleep(0.05)
        assert not any(map(_alive, workers)), f"workers {sorted(filter(_alive, workers))} survived"
    finally:
        for pid in [proc.pid, *workers]:
            if _alive(pid):
                os.kill(pid, signal.SIGKILL)


def test_workers_die_with_a_caller_killed_hard(tmp_path):
    proc, workers = _start_caller(tmp_path)
    try:
        proc.kill()                                   # SIGKILL: no Python cleanup runs in the caller
        proc.wait(timeout=10)
        deadline = time.monotonic() + 5
        while any(map(_alive, workers)) and time.monotonic() < deadline:
            time.sleep(0.05)
        assert not any(map(_alive, workers)), f"workers {sorted(filter(_alive, workers))} survived"
    finally:
        for pid in workers:
            if _alive(pid):
                os.kill(pid, signal.SIGKILL)


def test_retry_settings_are_checked():
    with pytest.raises(ValueError, match="retries"):
        ExecutorSpec(retries=-1)
    with pytest.raises(ValueError, match="worker_timeout"):
        ExecutorSpec(worker_timeout=0)
    assert LocalPool(2, retries=5).retries == 5
