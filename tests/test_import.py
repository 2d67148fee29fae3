"""`neck-sim import`: prototype CSV files -> contract log, with errors naming file, line, column."""

from __future__ import annotations

import numpy as np
import pytest
from test_logs_fixtures import synthetic_arrays

from neck_sim import params as P
from neck_sim.cli import main
from neck_sim.csv_import import import_csv
from neck_sim.logs import read_log


def write_csv(path, header, rows):
    lines = [",".join(header)] + [",".join(repr(float(v)) if not isinstance(v, str) else v for v in row)
                                  for row in rows]
    path.write_text("\n".join(lines) + "\n")


def motors_csv(path, arr, n, order=None):
    cols = ["t"] + [f"theta{j}" for j in range(1, n + 2)] + [f"force{j}" for j in range(1, n + 2)]
    table = np.column_stack([arr["t"], arr["theta"], arr["force"]])
    order = list(range(len(cols))) if order is None else order
    write_csv(path, [cols[i] for i in order], table[:, order])


def camera_csv(path, arr, n, order=None):
    cols = ["t"] + [f"alpha{i}" for i in range(1, n + 1)]
    table = np.column_stack([arr["t"], arr["alpha"]])
    order = list(range(len(cols))) if order is None else order
    write_csv(path, [cols[i] for i in order], table[:, order])


@pytest.fixture
def csvs(tmp_path):
    params = P.default_params(3)
    arr = synthetic_arrays(params, seconds=0.5, seed=3)
    rng = np.random.default_rng(0)
    motors_csv(tmp_path / "motors.csv", arr["motors"], 3, order=list(rng.permutation(9)))
    camera_csv(tmp_path / "camera.csv", arr["camera"], 3, order=[2, 0, 3, 1])
    return tmp_path, params, arr


def test_import_round_trip_any_column_order(csvs):
    tmp, params, arr = csvs
    res = import_csv(tmp / "motors.csv", tmp / "run.mcap", camera=tmp / "camera.csv", params=params)
    assert res.counts == {"motors": len(arr["motors"]["t"]), "camera": len(arr["camera"]["t"])}
    log = read_log(tmp / "run.mcap", require=("motors", "camera"))
    for topic in ("motors", "camera"):
        for name, values in arr[topic].items():
            np.testing.assert_array_equal(getattr(getattr(log, topic), name), values, err_msg=f"{topic}.{name}")
    assert log.truth is None and log.reference is None
    assert log.run_info["source"] == "csv import"
    assert log.params == params


def test_import_uses_the_parameter_file(tmp_path):
    p2 = P.default_params(2).replace(**{"geometry.b": 0.055})
    P.save(p2, tmp_path / "p.json")
    arr = synthetic_arrays(p2, seconds=0.1)
    motors_csv(tmp_path / "m.csv", arr["motors"], 2)
    camera_csv(tmp_path / "c.csv", arr["camera"], 2)
    rc = main(["import", "--motors", str(tmp_path / "m.csv"), "--camera", str(tmp_path / "c.csv"),
               "--params", str(tmp_path / "p.json"), "-o", str(tmp_path / "run.mcap")])
    assert rc == 0
    log = read_log(tmp_path / "run.mcap")
    assert log.n_joints == 2 and log.params.geometry.b == 0.055
    assert log.motors.theta.shape == (len(arr["motors"]["t"]), 3)
    assert log.metadata["b"] == "0.055"


def test_import_optional_reference_and_estimate_and_shift(tmp_path):
    p = P.default_params(3)
    t = 1000.0 + np.arange(5) * 0.002
    write_csv(tmp_path / "m.csv", ["t"] + [f"theta{j}" for j in range(1, 5)] + [f"force{j}" for j in range(1, 5)],
              np.column_stack([t, np.ones((5, 8))]))
    write_csv(tmp_path / "r.csv", ["t", "alpha_d1", "alpha_d2", "alpha_d3"], np.column_stack([t, np.zeros((5, 3))]))
    write_csv(tmp_path / "e.csv", ["T", " ALPHA_HAT1", "alpha_hat2 ", "alpha_hat3"],
              np.column_stack([t[1:], np.ones((4, 3))]))
    res = import_csv(tmp_path / "m.csv", tmp_path / "run.mcap", reference=tmp_path / "r.csv",
                     estimate=tmp_path / "e.csv", params=p, shift_time=True)
    assert res.time_shift == 1000.0
    log = read_log(tmp_path / "run.mcap")
    np.testing.assert_allclose(log.motors.t, t - 1000.0)
    np.testing.assert_allclose(log.estimate.t, t[1:] - 1000.0)
    assert log.reference.alpha_d.shape == (5, 3) and log.camera is None


def run_import(tmp_path, *extra):
    return main(["import", "--motors", str(tmp_path / "m.csv"), *extra, "-o", str(tmp_path / "out.mcap")])


def test_import_any_routing(tmp_path, capsys):
    """10 joints, 4 cables: theta1..4, force1..4, alpha1..10 (not N + 1 motors); a file of another
    neck is refused naming the expected columns, and nothing is written."""
    p10 = P.example_params("neck10x4")
    P.save(p10, tmp_path / "p10.toml")
    arr = synthetic_arrays(p10, seconds=0.2, seed=1)
    motors_csv(tmp_path / "m.csv", arr["motors"], 3)            # 3 joints on the paper's routing: 4 motors
    camera_csv(tmp_path / "c.csv", arr["camera"], 10)
    args = ["--camera", str(tmp_path / "c.csv"), "--params", str(tmp_path / "p10.toml")]
    assert run_import(tmp_path, *args) == 0
    assert "m = 4 cables" in capsys.readouterr().out
    log = read_log(tmp_path / "out.mcap", require=("motors", "camera"))
    assert log.params.routing == p10.routing and log.camera.alpha.shape[1] == 10
    np.testing.assert_array_equal(log.motors.theta, arr["motors"]["theta"])
    np.testing.assert_array_equal(log.camera.alpha, arr["camera"]["alpha"])
    (tmp_path / "out.mcap").unlink()
    # the paper's routing for 10 joints: 11 motors in the file, 4 cables in the routing
    p_paper = P.default_params(10)
    arr11 = synthetic_arrays(p_paper, seconds=0.2, seed=1)
    motors_csv(tmp_path / "m.csv", arr11["motors"], 10)
    assert run_import(tmp_path, *args) == 2
    err = capsys.readouterr().err
    assert "m.csv: column(s) theta5, theta6" in err and "beyond the routing's 4 cables" in err
    assert "expected 4 per channel (theta1, theta2, theta3, theta4, force1, force2, force3, force4), found 11" in err
    assert len(err.strip().splitlines()) == 1 and not (tmp_path / "out.mcap").exists()
    # too few: the missing columns named with the routing's reason
    motors_csv(tmp_path / "m.csv", arr["motors"], 3)
    camera_csv(tmp_path / "c.csv", {"t": arr["camera"]["t"], "alpha": arr["camera"]["alpha"][:, :3]}, 3)
    assert run_import(tmp_path, *args) == 2
    err = capsys.readouterr().err
    assert "c.csv: missing column(s) alpha4, alpha5" in err and "needed for the neck's 10 joints: t, alpha1" in err
    assert not (tmp_path / "out.mcap").exists()


def test_import_errors_name_the_problem(tmp_path, capsys):
    head = ["t"] + [f"theta{j}" for j in range(1, 5)] + [f"force{j}" for j in range(1, 5)]
    write_csv(tmp_path / "m.csv", head[:-1], np.zeros((2, 8)))
    assert run_import(tmp_path) == 2
    assert "m.csv: missing column(s) force4" in capsys.readouterr().err

    rows = [[0.0] + [0.0] * 8, [0.002, "abc"] + [0.0] * 7]
    write_csv(tmp_path / "m.csv", head, rows)
    assert run_import(tmp_path) == 2
    assert "m.csv:3: column theta1: 'abc' is not a number" in capsys.readouterr().err

    write_csv(tmp_path / "m.csv", head, [[0.0] + [0.0] * 8, [0.004] + [0.0] * 8, [0.002] + [0.0] * 8])
    assert run_import(tmp_path) == 2
    assert "m.csv:4: time not increasing: t = 0.002 s after 0.004 s" in capsys.readouterr().err

    write_csv(tmp_path / "m.csv", head, [[0.0] + [0.0] * 8, [0.002] + [0.0] * 7])
    assert run_import(tmp_path) == 2
    assert "m.csv:3: expected 9 cells (as in the header), got 8" in capsys.readouterr().err

    write_csv(tmp_path / "m.csv", head, [[-0.5] + [0.0] * 8])
    assert run_import(tmp_path) == 2
    assert "negative time t = -0.5 s" in capsys.readouterr().err

    write_csv(tmp_path / "m.csv", head, [[0.0] + [0.0] * 7 + ["nan"]])
    assert run_import(tmp_path) == 2
    assert "column force4: 'nan' is not a finite number" in capsys.readouterr().err

    write_csv(tmp_path / "m.csv", head + ["t"], [[0.0] * 10])
    assert run_import(tmp_path) == 2
    assert "duplicate column(s) t" in capsys.readouterr().err

    (tmp_path / "m.csv").write_text("")
    assert run_import(tmp_path) == 2
    assert "empty CSV file" in capsys.readouterr().err

    assert main(["import", "--motors", str(tmp_path / "nope.csv"), "-o", str(tmp_path / "o.mcap")]) == 2
    assert "nope.csv: cannot read CSV file" in capsys.readouterr().err
    assert not (tmp_path / "out.mcap").exists() and not (tmp_path / "o.mcap").exists()
