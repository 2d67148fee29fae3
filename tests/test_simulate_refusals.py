"""`neck-sim simulate` refuses at the edges and leaves nothing half-done: several runs are all or
nothing, a log path any run would refuse is refused before the first run, a live run that leaves
the joint range stops with the same one line and closes its server; and `neck-sim diagnose` does
not print a comparison when no model was extended."""

import os
import re
import time

import numpy as np
import pytest

from neck_sim.cli import main
from neck_sim.params import example_params, save


def _files(directory) -> dict:
    """Every file in ``directory`` with its bytes."""
    return {p.name: p.read_bytes() for p in sorted(directory.iterdir())}


def test_a_later_law_refused_in_its_run_discards_the_earlier_logs(tmp_path, capsys):
    """The 8-joint neck on elastic cables, moves at 0.7 of their duration: law 2 runs to the end,
    law 1 diverges at 6.7 s.  Exit 2, one line naming law 1 and law 2; law 2's log is not kept, and
    the file that was at its path before the command is untouched."""
    (tmp_path / "run-law2.mcap").write_bytes(b"a file that was here before")
    before = _files(tmp_path)
    code = main(["simulate", "--n-joints", "8", "--law", "2", "1", "--duration-scale", "0.7", "--no-progress",
                 "-o", str(tmp_path / "run.mcap"), "--json", str(tmp_path / "m.json")])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1, err
    assert re.search(r"error: law 1, run after law 2: closed loop stopped at t = [\d.]+ s: ", err), err
    assert "the log of law 2 is discarded too" in err
    assert _files(tmp_path) == before


def test_table3_refused_in_its_second_run_writes_nothing(tmp_path, capsys):
    """Table 3 with 1.5 kg at the head and fast moves: the rigid-cable run with pulleys ends, the
    identified-cable one loses its estimate at 2.05 s.  Exit 2, one line naming both runs, no log."""
    code = main(["simulate", "--table3", "--effect", "payload=1.5", "--duration-scale", "0.1", "--no-progress",
                 "-o", str(tmp_path / "t3.mcap")])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1, err
    assert "error: the identified-cable run with pulleys, run after the rigid-cable run with pulleys: " in err, err
    assert "the log of the rigid-cable run with pulleys is discarded too" in err
    assert os.listdir(tmp_path) == []


def test_every_runs_log_path_is_checked_before_the_first_run(tmp_path, capsys):
    """Law 1's log path read-only, or law 2's the --json output: refused before law 2 (the first)
    runs, naming the run's path; a law given twice is refused."""
    locked = tmp_path / "run-law1.mcap"
    locked.write_bytes(b"read-only")
    locked.chmod(0o444)
    before = _files(tmp_path)
    out = str(tmp_path / "run.mcap")
    for extra, words in ((["--law", "2", "1"], f"-o (law1) {locked}: the file is read-only"),
                         (["--law", "2", "1", "--json", str(tmp_path / "run-law2.mcap")], "is also the output of --json"),
                         (["--law", "2", "1", "2"], "--law 2 1 2: law 2 given twice")):
        code = main(["simulate", *extra, "--duration-scale", "0.1", "--no-progress", "-o", out])
        err = capsys.readouterr().err
        assert code == 2 and err.count("\n") == 1 and words in err, (extra, err)
        assert _files(tmp_path) == before, extra


def test_several_runs_publish_every_log_under_its_name(tmp_path, capsys):
    """The staged logs reach their names (the printed ones, the JSON's) and nothing else is left."""
    import json

    from neck_sim.logs.reader import read_log

    assert main(["simulate", "--law", "1", "2", "--duration-scale", "0.1", "--no-progress",
                 "-o", str(tmp_path / "run.mcap"), "--json", str(tmp_path / "m.json")]) == 0
    out = capsys.readouterr().out
    assert sorted(os.listdir(tmp_path)) == ["m.json", "run-law1.mcap", "run-law2.mcap"]
    logs = {label: res["log"] for label, res in json.loads((tmp_path / "m.json").read_text()).items()}
    assert logs == {"law 1": str(tmp_path / "run-law1.mcap"), "law 2": str(tmp_path / "run-law2.mcap")}
    for label, path in logs.items():
        assert f"log ({label}): {path}" in out
        assert read_log(path, topics=["motors"]).run_value("law") == int(label[-1])


def test_a_live_run_that_leaves_the_joint_range_is_refused_and_closes_its_server(tmp_path, capsys, monkeypatch):
    """The 10x4 neck with 50 g at the head, fast identification run (it leaves the range at about
    5 s of simulated time), served live: exit 2 with the range refusal in one line, no log; the
    client, connected while the run went on, sees the server close at once, its port is free again
    and no thread of the command is left."""
    pytest.importorskip("foxglove")
    pytest.importorskip("websockets")
    import socket
    import threading

    from neck_sim.live import LiveView
    from test_live import receive

    save(example_params("neck10x4"), tmp_path / "p10.toml")
    def lasting():         # the threads that keep a process alive (tqdm's monitor is a daemon)
        return {t for t in threading.enumerate() if not t.daemon}

    threads = lasting()
    box: dict = {}
    wait = LiveView.wait_for_client

    def connect_then_wait(view, poll=0.2):            # a viewer connects as the command starts waiting
        box["port"] = int(view.url.rsplit(":", 1)[1])
        box["client"] = threading.Thread(target=lambda: box.update(got=receive(view.url, seconds=90)[1],
                                                                   closed=time.monotonic()))
        box["client"].start()
        wait(view, poll)

    monkeypatch.setattr(LiveView, "wait_for_client", connect_then_wait)
    code = main(["simulate", "--live", "--live-port", "0", "--live-pace", "fast", "--params", str(tmp_path / "p10.toml"),
                 "--trajectory", "identification", "--effect", "payload=0.05", "--duration-scale", "0.1",
                 "--no-progress", "-o", str(tmp_path / "run.mcap")])
    returned = time.monotonic()
    err = capsys.readouterr().err
    box["client"].join(90)
    assert code == 2 and err.count("\n") == 1, err
    assert "the neck left its joint range" in err and "no log written" in err, err
    assert box["closed"] - returned < 5.0                # the server closed the connection, no time-out
    truth = np.array([m["t"] for _, _, m in box["got"]["/neck/truth"]])
    assert truth.size > 100 and truth[-1] > 1.0          # the run was served until it was stopped
    with socket.socket() as probe:                        # nothing listens on the view's port any more
        assert probe.connect_ex(("127.0.0.1", box["port"])) != 0
    assert lasting() == threads
    assert sorted(os.listdir(tmp_path)) == ["p10.toml"]


def test_no_finding_gives_the_baselines_resimulation_alone():
    """With no finding the final model is the baseline: its held-out re-simulation is printed
    once, saying that no model was extended, never as a before -> after comparison."""
    from identification.diagnosis.report import resimulation_line
    from identification.diagnosis.resimulation import Resimulation, ResimulationErrors

    def resim(theta, diverged=0):
        errors = ResimulationErrors(theta, (1.0, 2.0), 1.5, 0.3)
        empty = np.zeros(0)
        return Resimulation("ok", errors, errors, empty, empty, empty, empty, n_blocks=6, n_diverged=diverged)

    baseline = resim((0.012, 0.034))
    alone = resimulation_line(baseline, baseline)
    assert "no model was extended" in alone and "->" not in alone and "0.012" in alone, alone
    compared = resimulation_line(baseline, resim((0.012, 0.034)))     # two models, equal errors
    assert "->" in compared and "no model was extended" not in compared, compared
    lost = resim((0.012, 0.034), diverged=6)                           # every block diverged
    alone = resimulation_line(lost, lost)
    assert "the baseline (no model was extended) out of its valid range" in alone and "both" not in alone, alone
    assert "both models out of their" in resimulation_line(lost, resim((0.012, 0.034), diverged=6))
