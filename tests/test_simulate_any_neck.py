"""`neck-sim simulate` on any routing: the controller choice, paths through reachable poses, the
identification experiment of a neck the paper's laws cannot move, and `--effect`."""

import json

import numpy as np
import pytest

from controllers import reachable_paths as rp
from controllers.selection import CONTROLLERS, choose_controller, make_run_trajectory
from neck_sim.analytic.statics import equilibrium_for_motor_angles, motor_angles_for
from neck_sim.effect_option import parse_effect, parse_effects
from neck_sim.params import default_params, example_params, save


@pytest.fixture(scope="module")
def neck10():
    return example_params("neck10x4")


@pytest.fixture(scope="module")
def tour10(neck10):
    return rp.shapes_tour(neck10)


def test_the_controller_is_chosen_from_the_routing(neck10):
    assert choose_controller(default_params(3)).name == "computed-torque"
    assert choose_controller(default_params(10)).name == "elastic-lqr"
    assert choose_controller(default_params(10), laws=[2]).name == "computed-torque"
    assert choose_controller(neck10).name == "inverse-statics"
    assert choose_controller(example_params("mirrored3")).name == "inverse-statics"
    line = choose_controller(neck10).line
    assert "\n" not in line and "4 cables on 10 joints" in line
    with pytest.raises(ValueError, match="use --controller inverse-statics"):
        choose_controller(neck10, "computed-torque")
    with pytest.raises(ValueError, match="use --controller inverse-statics"):
        choose_controller(neck10, "elastic-lqr")
    with pytest.raises(ValueError) as err:
        choose_controller(neck10, "pid")
    assert all(name in str(err.value) for name in CONTROLLERS) and "\n" not in str(err.value)


def test_the_shapes_tour_is_held_by_its_motor_angles(neck10, tour10):
    """Every grid pose of the tour is a force equilibrium (how the path is built); held here by
    another computation: the equilibrium of the motor angles that hold it, solved from a pose 3 deg
    away, comes back to it (stable with held motors).  C and S curves and a head reach are there."""
    p = neck10
    labels = tour10.labels
    assert {"C+", "C-", "S+", "S-", "reach+"} <= set(labels)
    alpha, tension = tour10.grid_alpha[::10], tour10.forces_at(tour10.grid_t[::10])
    theta = motor_angles_for(alpha, tension, p)
    kick = np.radians(3.0) * np.where(np.arange(p.n_joints) % 2, 1.0, -1.0)
    eq = equilibrium_for_motor_angles(theta, p, alpha + kick)
    assert eq.converged.all() and eq.stable.all()
    assert np.degrees(np.abs(eq.alpha - alpha)).max() < 0.01
    assert np.all(tension >= p.actuation.t_min) and np.all(tension <= rp.FORCE_MARGIN * p.actuation.f_max)
    w = dict(zip(labels, tour10.waypoints))
    bend = {k: np.degrees(tour10.sample(tour10.knots[2 * labels.index(k)]).alpha) for k in ("C+", "C-", "S+", "S-")}
    # C: the upper neck bends one way, and the other way in C-; S: the upper neck bends against C+
    assert bend["C+"][-5:].min() > 1 and bend["C-"][-5:].max() < -1
    assert np.sign(bend["S+"][5:].sum()) != np.sign(bend["S+"][:5].sum())
    assert np.abs(np.concatenate(list(bend.values()))).max() <= rp.BEND_DEG + 1e-9
    assert not np.allclose(w["C+"], w["S+"])


def test_a_trajectory_the_neck_cannot_hold_is_refused_naming_pose_and_cable(neck10):
    with pytest.raises(ValueError) as err:
        make_run_trajectory("control-test", neck10, "inverse-statics", 0.2)
    text = str(err.value)
    assert "\n" not in text and "t = " in text and "deg" in text and "out of this neck's reach" in text
    assert " c1 " in text or " c2 " in text or " c3 " in text or " c4 " in text
    with pytest.raises(ValueError, match="unknown"):
        make_run_trajectory("zigzag", neck10, "inverse-statics")
    with pytest.raises(ValueError, match="--controller inverse-statics"):
        make_run_trajectory("shapes", default_params(3), "computed-torque")


def test_the_identification_path_sweeps_every_cable(neck10):
    """Predicted from the path (no plant): every cable's motor reverses many times and its tension
    sweeps a range comparable to the paper's §5.2.2 run on its own neck (predicted by the inverse
    model of identification.excitation, another computation: 31-59 N there)."""
    from controllers.trajectories import make_trajectory
    from identification.excitation import cable_excitation, predict_run

    path = rp.excitation_path(neck10)
    t = np.arange(0.0, path.duration, 0.01)
    ref = path.sample(t)
    ours = cable_excitation(t, motor_angles_for(ref.alpha, ref.tension, neck10), ref.tension)
    p3 = default_params(3)
    paper = make_trajectory("identification", p3)
    t3 = np.arange(0.0, paper.duration, 0.01)
    s3 = paper.sample(t3)
    run3 = predict_run(s3.alpha, s3.alpha_dot, s3.alpha_ddot, t3, p3)
    theirs = cable_excitation(t3, run3.theta, run3.tension)
    span, span3 = ours.tension_max - ours.tension_min, theirs.tension_max - theirs.tension_min
    assert span.min() > 0.75 * span3.min(), (span, span3)
    assert ours.reversals.min() >= 10, ours.reversals
    assert np.all(ours.speed_min < -1.0) and np.all(ours.speed_max > 1.0), (ours.speed_min, ours.speed_max)


@pytest.mark.parametrize("text, params, message", [
    ("nothing=1", None, "unknown effect 'nothing'"),
    ("payload", None, "expected NAME=VALUE"),
    ("payload=heavy", None, "is not a number"),
    ("payload=-1", None, "must be >= 0"),
    ("payload=0.1@2", None, "takes no @INDEX"),
    ("dry_friction=20@5", "neck10x4", "cable 5 does not exist (this neck has 4 cables"),
    ("joint_friction=0.01@11", "neck10x4", "joint 11 does not exist"),
    ("dry_friction=20@two", None, "not a cable number"),
])
def test_bad_effects_are_refused_in_one_line(text, params, message):
    p = default_params(3) if params is None else example_params(params)
    with pytest.raises(ValueError) as err:
        parse_effect(text, p)
    assert message in str(err.value) and "\n" not in str(err.value) and str(err.value).startswith(f"--effect {text}")


def test_effects_map_to_the_plant(neck10):
    e = parse_effect("dry_friction=25@2", neck10)
    assert e.resolved(neck10)[0].tolist() == [14.42, 25.0, 17.65, 16.18]
    s = parse_effect("spring_error=0.5@3", neck10)
    assert s.apply(neck10).springs.stiffness[2] == pytest.approx(100.0)
    assert parse_effect("actuation_delay=0.01", neck10).command_delay == 0.01
    with pytest.raises(ValueError, match="given twice"):
        parse_effects(["payload=0.1", "payload=0.2"], neck10)


def test_simulate_with_an_effect_records_it_in_the_run_record_only(tmp_path, capsys):
    """A payload on the paper's neck: the run record lists it, the neck record stays nominal, and
    the plant really carried it (the tension the cables hold differs from a run without it)."""
    from neck_sim.cli import main
    from neck_sim.logs.reader import read_log

    runs = {}
    for tag, extra in (("plain", []), ("payload", ["--effect", "payload=0.1"])):
        log = tmp_path / f"{tag}.mcap"
        assert main(["simulate", "--duration-scale", "0.1", "--no-progress", "-o", str(log), *extra]) == 0
        runs[tag] = read_log(log, topics=["motors", "truth"])
    out = capsys.readouterr().out
    assert "plant effects: payload" in out
    with_p, without = runs["payload"], runs["plain"]
    assert with_p.run_value("effects") == {"payload": {"name": "payload", "mass": 0.1}}
    assert without.run_value("effects") == {}
    assert with_p.params.inertia.payload_mass == 0.0
    # 0.1 kg at the head of a 0.2 m neck: the cables carry more on average
    assert with_p.truth.tension.mean() > without.truth.tension.mean() + 0.5


def test_simulate_refuses_bad_effects_and_controllers(tmp_path, capsys, monkeypatch):
    from neck_sim.cli import main

    monkeypatch.chdir(tmp_path)
    p10 = tmp_path / "p10.toml"
    save(example_params("neck10x4"), p10)
    for argv, message in ((["--controller", "pid"], "--controller pid: unknown (known: auto, computed-torque"),
                          (["--effect", "payload=0.1@1"], "takes no @INDEX"),
                          (["--params", str(p10), "--effect", "dry_friction=3@9"], "cable 9 does not exist"),
                          (["--params", str(p10), "--controller", "computed-torque"], "use --controller inverse-statics"),
                          (["--params", str(p10), "--law", "2"], "drop --law"),
                          (["--params", str(p10), "--trajectory", "control-test"], "out of this neck's reach")):
        assert main(["simulate", "--no-progress", *argv]) == 2, argv
        err = capsys.readouterr().err
        assert message in err and err.count("\n") == 1, (argv, err)
    assert sorted(x.name for x in tmp_path.iterdir()) == ["p10.toml"]


def test_simulate_moves_the_ten_joint_four_cable_neck(tmp_path, capsys):
    """`neck-sim simulate --params p10.toml`: inverse statics, the shapes tour, a log with every
    joint and cable (Foxglove scene included) and a tracking error near the Python API's."""
    from mcap.reader import make_reader

    from neck_sim.cli import main
    from neck_sim.logs.reader import read_log

    p10 = tmp_path / "p10.toml"
    save(example_params("neck10x4"), p10)
    log, js = tmp_path / "s.mcap", tmp_path / "s.json"
    assert main(["simulate", "--params", str(p10), "--duration-scale", "0.5", "--no-progress", "-o", str(log),
                 "--json", str(js)]) == 0
    out = capsys.readouterr().out
    assert out.splitlines()[0].startswith("controller: inverse statics")
    m = json.loads(js.read_text())["inverse statics"]["metrics"]
    assert m["slack_samples"] == 0
    # 1.78 deg mean achieved with 1.25 s moves (0.87 deg with the full 2.5 s): the N - m joint modes
    # the four cables cannot reach ring after each move, and no motor can damp them
    assert m["tracking_error_true"] < 2.0, m["tracking_error_true"]
    assert m["estimation_error_true"] < 2.0
    lg = read_log(log, topics=["motors", "truth", "camera"])
    assert lg.truth.alpha.shape[1] == 10 and lg.motors.theta.shape[1] == 4 and lg.camera.alpha.shape[1] == 10
    with open(log, "rb") as fh:
        for _, _, message in make_reader(fh).iter_messages(topics=["/neck/scene"]):
            entities = json.loads(message.data)["entities"]
            break
    truth = next(e for e in entities if e["id"].endswith("truth"))
    strips = [ls for ls in truth["lines"] if ls["type"] == 0]            # one line strip per cable
    # c1, c2 end at joint 5 (through 5 pulleys + the end), c3, c4 at the head (15 + the end)
    assert [len(ls["points"]) for ls in strips] == [6, 6, 16, 16]


def test_cable_excitation_on_known_arrays():
    from identification.excitation import cable_excitation

    t = np.arange(0.0, 4.0, 0.001)
    theta = np.stack([np.sin(2 * np.pi * t), 3.0 * t], axis=1)          # 2 Hz sine: reversals; a ramp: none
    tension = np.stack([10 + 5 * np.cos(t), np.full_like(t, 7.0)], axis=1)
    ex = cable_excitation(t, theta, tension, start=1.0)
    assert ex.reversals.tolist() == [6, 0]                              # 1 s .. 4 s: 6 sign changes of cos
    np.testing.assert_allclose(ex.speed_max, [2 * np.pi, 3.0], rtol=1e-4)
    np.testing.assert_allclose(ex.tension_min, [10 + 5 * np.cos(np.pi), 7.0], atol=1e-5)
    np.testing.assert_allclose(ex.tension_max, [10 + 5 * np.cos(1.0), 7.0], atol=1e-5)


def test_the_first_excursion_is_the_sample_check_alpha_names():
    """neck_sim.joint_range against the model's own range check (another computation: argwhere
    over the flattened array in check_alpha)."""
    from neck_sim.analytic.geometry import PoseRangeError, check_alpha
    from neck_sim.joint_range import first_excursion

    rng = np.random.default_rng(3)
    alpha = rng.uniform(-1.4, 1.4, (300, 10))
    alpha[170, 7], alpha[171, 2], alpha[250, 0] = -1.6, 1.7, np.nan
    t = np.arange(300) * 0.002
    out = first_excursion(t, alpha, 1.5)
    with pytest.raises(PoseRangeError) as err:
        check_alpha(alpha[:250], 10, alpha_max=1.5)
    assert f"joint {out.joint + 1} at {np.degrees(out.angle):.2f} deg (index ({out.sample}, {out.joint}))" \
        in str(err.value)
    assert out.t == pytest.approx(0.34) and first_excursion(t[:170], alpha[:170], 1.5) is None
    assert first_excursion(t[172:], alpha[172:], 1.5).sample == 250 - 172          # NaN: out of range


def test_a_plant_that_cannot_hold_the_path_is_refused_before_the_run(neck10):
    """The identification path is planned on the nominal model; a heavier payload (measured: the
    run at --duration-scale 0.1 leaves the range at 5.2 s with 0.1 kg) or a pretension the motors
    cannot hold is refused before any simulation, naming the pose and the cable."""
    light = parse_effects(["payload=0.05"], neck10)
    path = make_run_trajectory("identification", neck10, "inverse-statics", 0.1, light)
    assert path.duration > 9
    for effect, words in (("payload=0.1", "unstable on the simulated plant with the motors held there (its unstable "
                                          "mode moves joint "),
                          ("pretension=0.002", "in cable c1 on the simulated plant, more than 90 N")):
        with pytest.raises(ValueError) as err:
            make_run_trajectory("identification", neck10, "inverse-statics", 0.1, parse_effects([effect], neck10))
        text = str(err.value)
        assert "\n" not in text and words in text and "t = 0.00 s" in text and "waypoint 'start" in text, text
        assert "simulate a smaller effect" in text


def test_a_run_that_leaves_the_joint_range_is_refused_and_writes_nothing(tmp_path, capsys, monkeypatch):
    """With 50 g at the head the 10x4 neck's fast identification run swings joint 6 past 90 deg
    (dynamic: the plant's statics along the path stay within 21 deg and 84 N): refused in one
    line, exit 2, no log."""
    import re

    from neck_sim.cli import main

    monkeypatch.chdir(tmp_path)
    save(example_params("neck10x4"), tmp_path / "p10.toml")
    assert main(["simulate", "--params", "p10.toml", "--trajectory", "identification", "--effect", "payload=0.05",
                 "--duration-scale", "0.1", "--no-progress", "-o", "run.mcap", "--json", "m.json"]) == 2
    err = capsys.readouterr().err
    found = re.search(r"stopped at t = ([\d.]+) s: the neck left its joint range: joint (\d+) at (-?[\d.]+) deg, "
                      r"outside the joint range \|alpha\| <= 90.00 deg", err)
    assert found and err.count("\n") == 1, err
    assert abs(float(found.group(3))) > 90 and 1 <= int(found.group(2)) <= 10
    assert "--duration-scale than 0.1" in err and "payload=0.05" in err
    assert sorted(x.name for x in tmp_path.iterdir()) == ["p10.toml"]


def test_the_range_guard_leaves_a_run_in_range_unchanged(tmp_path):
    """The paper's neck, default run: the command's log (guard on) equals, array for array, the log
    the Python API writes for the same run without the guard."""
    from controllers import experiments as ex
    from neck_sim.cli import main
    from neck_sim.logs.reader import read_log

    guarded, plain = tmp_path / "guarded.mcap", tmp_path / "plain.mcap"
    assert main(["simulate", "--duration-scale", "0.1", "--no-progress", "-o", str(guarded)]) == 0
    p = default_params(3)
    ex.control_tests(p, make_run_trajectory(None, p, "computed-torque", 0.1), [2], progress=False,
                     log_path=lambda label: str(plain), stop_outside_range=False)
    from dataclasses import fields

    a, b = read_log(guarded), read_log(plain)
    for topic in ("motors", "camera", "reference", "estimate", "truth"):
        x, y = getattr(a, topic), getattr(b, topic)
        assert x is not None and len(x.t) > 40, topic
        for f in fields(x):
            np.testing.assert_array_equal(getattr(x, f.name), getattr(y, f.name), err_msg=f"{topic}.{f.name}")
