"""Campaigns on a Dask distributed cluster (scheduler and workers on the loopback address only)."""

import re

import numpy as np
import pytest

from neck_sim.campaign import ClusterError, ExecutorSpec, open_executor, run_campaign
from controllers.parallel import RunSpec, run_all
from neck_sim.effects import Effects, ViscousFriction
from neck_sim.logs import read_log
from neck_sim.params import default_params

distributed = pytest.importorskip("distributed")


@pytest.fixture(scope="module")
def cluster():
    # everything on the loopback address, the scheduler's HTTP server included (on a free port)
    with distributed.LocalCluster(host="127.0.0.1", n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address="127.0.0.1:0", silence_logs=40) as c:
        yield c


def test_a_campaign_on_a_dask_cluster_equals_the_serial_runs(cluster, tmp_path):
    p = default_params()
    specs = [RunSpec("law 2", p, law=2, duration_scale=0.1, seed=3, log_path=str(tmp_path / "law2.mcap")),
             RunSpec("viscous", p, law=3, duration_scale=0.1, seed=4, effects=Effects.of(ViscousFriction(0.1)))]
    on_dask = run_all(specs, ExecutorSpec(cluster=cluster.scheduler_address), progress=False)
    log = read_log(tmp_path / "law2.mcap", topics=("motors", "truth"))    # written by a worker, sent back
    serial = run_all(specs, None, progress=False)
    for a, b in zip(on_dask, serial):
        for name in ("theta", "force", "alpha", "tension", "alpha_hat"):
            np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
        assert a.metrics.as_dict() == b.metrics.as_dict()
    assert not np.array_equal(on_dask[0].alpha, on_dask[1].alpha)
    np.testing.assert_array_equal(log.motors.force, serial[0].force)
    np.testing.assert_array_equal(log.truth.alpha, serial[0].alpha)


def test_an_unreachable_cluster_is_named():
    with pytest.raises(ClusterError, match=r"tcp://127.0.0.1:9.*no Dask scheduler"):
        with open_executor(ExecutorSpec(cluster="tcp://127.0.0.1:9", connect_timeout=1.0)):
            pass


def test_blind_logs_generated_on_the_cluster_equal_local_ones(cluster, tmp_path):
    from identification.diagnosis.blind import make_case, make_cases

    [(case, path)] = make_cases([("viscous_friction", 5, 0.5)], tmp_path / "dask",
                                ExecutorSpec(cluster=cluster.scheduler_address), progress=False)
    here, _ = make_case("viscous_friction", 5, tmp_path / "here.mcap", level=0.5)
    assert case == here and path == str(tmp_path / "dask" / "viscous_friction_5_0.5.mcap")
    a, b = read_log(path, topics=("motors", "camera")), read_log(tmp_path / "here.mcap", topics=("motors", "camera"))
    np.testing.assert_array_equal(a.motors.theta, b.motors.theta)
    np.testing.assert_array_equal(a.camera.alpha, b.camera.alpha)


# --- faults: the scheduler and its workers are separate processes started as docs/campaigns.md
# says, so that the test can kill them; everything binds to 127.0.0.1 ------------------------------

SCHEDULER = "dask scheduler --host 127.0.0.1 --port {port} --dashboard-address 127.0.0.1:{dash}"
WORKER = "dask worker tcp://127.0.0.1:{port} --host 127.0.0.1 --dashboard-address 127.0.0.1:0 --nthreads 1"


def _free_port() -> int:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _dask(command: str, env=None, log=None, **fmt):
    """``command`` (``dask ...``) as a process of its own group; ``env``: extra variables; its
    output (Dask's log) goes to the file ``log``, or nowhere."""
    import os
    import subprocess
    import sys

    argv = command.format(**fmt).split()
    module = {"scheduler": "distributed.cli.dask_scheduler", "worker": "distributed.cli.dask_worker"}[argv[1]]
    out = subprocess.DEVNULL if log is None else open(log, "w")
    try:
        return subprocess.Popen([sys.executable, "-m", module, *argv[2:]], start_new_session=True,
                                stdout=out, stderr=subprocess.STDOUT, env={**os.environ, **(env or {})})
    finally:
        if log is not None:
            out.close()


def _log_tails(*logs, lines: int = 25) -> str:
    """The last ``lines`` lines of each log file, headed by its name (for a failure message)."""
    out = []
    for log in logs:
        text = log.read_text(errors="replace").splitlines() if log.exists() else ["(no log)"]
        out.append(f"--- {log.name} (last {lines} lines) ---\n" + "\n".join(text[-lines:]))
    return "\n".join(out)


def _wait_for_nannies(address: str, n: int, timeout: float) -> None:
    """Return once the scheduler at ``address`` has ``n`` workers whose nannies have finished
    starting.  A worker registers with the scheduler before its nanny has finished starting (the
    nanny waits for the worker's first message); a worker that dies in between is not restarted:
    its nanny fails to start and closes (``nanny-start-failed``), and the cluster has no worker."""
    import time

    with distributed.Client(address, timeout=timeout, set_as_default=False) as client:
        client.wait_for_workers(n, timeout=timeout)
        deadline = time.monotonic() + timeout
        while True:
            status = client.run(lambda dask_worker: dask_worker.status.name, nanny=True)   # nanny address -> status
            if len(status) >= n and all(s == "running" for s in status.values()):
                return
            assert time.monotonic() < deadline, f"nannies not running after {timeout:g} s: {status}"
            time.sleep(0.05)


def _kill_group(proc) -> None:
    import os
    import signal

    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except ProcessLookupError:
        pass
    proc.wait(timeout=10)


@pytest.fixture
def separate_cluster():
    """(address, scheduler process, worker process); both killed at the end whatever happens."""
    port = _free_port()
    sched = _dask(SCHEDULER, port=port, dash=_free_port())
    worker = _dask(WORKER, port=port)
    try:
        yield f"tcp://127.0.0.1:{port}", sched, worker
    finally:
        for p in (worker, sched):
            _kill_group(p)


def _kill_after(proc, seconds: float):
    import threading

    t = threading.Timer(seconds, _kill_group, args=(proc,))
    t.start()
    return t


def _bounded(fn, *args, seconds: float = 30, context=lambda: ""):
    """The exception ``fn(*args)`` raises, run in a thread; fails the test if it is still waiting
    after ``seconds`` (the fixture then kills the cluster, which ends the thread).  ``context()``:
    what a failure message adds (the cluster's logs)."""
    import threading

    box = []

    def target():
        try:
            fn(*args)
        except BaseException as exc:
            box.append(exc)

    t = threading.Thread(target=target, daemon=True)
    t.start()
    t.join(seconds)
    assert not t.is_alive(), f"still waiting after {seconds} s\n{context()}"
    assert box, f"no error raised\n{context()}"
    return box[0]


def test_a_cluster_whose_workers_all_died_fails_after_the_worker_timeout(separate_cluster):
    import time

    address, _, worker = separate_cluster
    spec = ExecutorSpec(cluster=address, connect_timeout=30, worker_timeout=3)
    with open_executor(spec) as ex:             # connected, one worker seen
        t0 = time.monotonic()
        _kill_after(worker, 1.0)                # the worker and its nanny, while the jobs run
        exc = _bounded(lambda: run_campaign(time.sleep, [30] * 3, ex, progress=False), seconds=20)
        waited = time.monotonic() - t0
    assert isinstance(exc, ClusterError) and re.search(r"no Dask worker for 3 s while \d job\(s\) waited", str(exc))
    assert 1.0 + 3 <= waited < 1.0 + 3 + 5, waited


# a caller that turns SIGTERM into an exception as `neck-sim` does, then runs long jobs on the cluster
_CALLER = """
import signal, sys, time
sys.path.insert(0, {root!r})
from neck_sim.campaign import ExecutorSpec, open_executor, run_campaign

def stop(signum, frame):
    raise KeyboardInterrupt
signal.signal(signal.SIGTERM, stop)
try:
    with open_executor(ExecutorSpec(cluster={address!r})) as ex:
        print("connected", flush=True)
        run_campaign(time.sleep, [30] * 3, ex, progress=False)
except KeyboardInterrupt:
    sys.exit(143)
except Exception as exc:
    print(f"{{type(exc).__name__}}: {{exc}}", file=sys.stderr)
"""


def _caller_outcome(address: str, fault, timeout: float):
    """Start the caller on ``address``; once it runs its jobs, ``fault()``; returns (exit status,
    stderr, seconds from the fault to the caller's exit)."""
    import os
    import subprocess
    import sys
    import time

    caller = subprocess.Popen([sys.executable, "-c", _CALLER.format(root=os.getcwd(), address=address)],
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert caller.stdout.readline() == "connected\n"
        time.sleep(1.0)
        t0 = time.monotonic()
        fault(caller)
        _, err = caller.communicate(timeout=timeout)
        return caller.returncode, err, time.monotonic() - t0
    finally:
        caller.kill()


def test_sigterm_ends_a_dask_campaign_at_once_and_quietly(separate_cluster):
    import signal

    address, _, worker = separate_cluster
    status, err, waited = _caller_outcome(address, lambda caller: caller.send_signal(signal.SIGTERM), 30)
    assert status == 143 and err == "", err
    assert waited < 10, waited
    assert worker.poll() is None                     # the cluster stays up for the next campaign


def test_a_scheduler_that_dies_ends_the_campaign_with_one_line(separate_cluster):
    address, sched, _ = separate_cluster
    _, err, waited = _caller_outcome(address, lambda caller: _kill_group(sched), 25)
    assert err.startswith("ClusterError: cluster tcp://127.0.0.1:") and "lost the connection" in err, err
    assert err.count("\n") == 1, err                     # one line: no traceback, no log record
    assert waited < 5, waited


def test_a_job_that_kills_its_dask_worker_fails_naming_it_after_allowed_failures(tmp_path):
    import os

    # allowed-failures set where the scheduler starts, as docs/campaigns.md says; the nanny
    # restarts the worker after each death, once it has finished starting (_wait_for_nannies)
    port = _free_port()
    logs = (tmp_path / "scheduler.log", tmp_path / "worker.log")
    sched = _dask(SCHEDULER, env={"DASK_DISTRIBUTED__SCHEDULER__ALLOWED_FAILURES": "1"}, log=logs[0], port=port,
                  dash=_free_port())
    worker = _dask(WORKER, log=logs[1], port=port)
    try:
        address = f"tcp://127.0.0.1:{port}"
        _wait_for_nannies(address, 1, timeout=30)
        spec = ExecutorSpec(cluster=address, connect_timeout=30, worker_timeout=30)
        with open_executor(spec) as ex:
            exc = _bounded(lambda: run_campaign(os._exit, [3], ex, labels=["crash"], progress=False), seconds=40,
                           context=lambda: _log_tails(*logs))
        assert isinstance(exc, RuntimeError) and re.match(r"job 'crash' failed: KilledWorker: .* on 2 different workers",
                                                          str(exc)), f"{exc!r}\n{_log_tails(*logs)}"
    finally:
        for p in (worker, sched):
            _kill_group(p)


def _listening(pid: int) -> set[str]:
    """Addresses (``ip:port``) of the TCP sockets ``pid`` listens on (IPv4 and IPv6), from /proc."""
    import os

    inodes = set()
    for fd in os.listdir(f"/proc/{pid}/fd"):
        try:
            link = os.readlink(f"/proc/{pid}/fd/{fd}")
        except OSError:
            continue
        if link.startswith("socket:["):
            inodes.add(link[8:-1])
    out = set()
    for table in ("tcp", "tcp6"):
        with open(f"/proc/{pid}/net/{table}") as fh:
            for line in fh.readlines()[1:]:
                f = line.split()
                if f[3] == "0A" and f[9] in inodes:           # LISTEN
                    ip, port = f[1].split(":")
                    raw = bytes.fromhex(ip)
                    if len(raw) == 4:
                        addr = ".".join(str(b) for b in raw[::-1])
                    else:                                     # four little-endian words
                        words = b"".join(raw[i:i + 4][::-1] for i in range(0, 16, 4))
                        import ipaddress
                        addr = str(ipaddress.IPv6Address(words))
                    out.add(f"{addr}:{int(port, 16)}")
    return out


def test_the_documented_commands_listen_on_loopback_only(separate_cluster):
    import pathlib
    import time

    import psutil

    doc = (pathlib.Path(__file__).parents[1] / "docs" / "campaigns.md").read_text()
    assert SCHEDULER.format(port=8786, dash=8787) in doc and WORKER.format(port=8786) in doc
    address, sched, worker = separate_cluster
    with open_executor(ExecutorSpec(cluster=address, connect_timeout=30)):
        time.sleep(1.0)                          # every server of the worker is up once it registered
        pids = [p.pid for p in (sched, worker)]
        pids += [c.pid for p in pids for c in psutil.Process(p).children(recursive=True)]
        listening = set().union(*(_listening(p) for p in pids))
    assert len(listening) >= 4, listening        # scheduler, its dashboard, nanny, worker (and its dashboard)
    assert all(a.startswith(("127.0.0.1:", "::ffff:127.0.0.1:", "::1:")) for a in listening), listening
