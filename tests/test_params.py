
import pytest

from neck_sim import params as P


def test_defaults_match_sources():
    p = P.default_params()
    assert p.n_joints == 3 and p.n_cables == 4
    assert p.springs.stiffness == (600.0, 200.0, 200.0)
    assert p.friction.f_s == (14.42, 17.65, 18.77, 16.18)
    assert p.cables.lam == (103.3, 88.7, 53.2, 120.9)
    assert p.actuation.reflected_inertia == pytest.approx(15.625)
    assert p.control.gains == (363.0, 33.0, 1331.0)
    for line in P.describe(p).splitlines():
        assert len(line.split()) >= 3, line


@pytest.mark.parametrize("n", [1, 5, 10])
def test_array_lengths_follow_n(n):
    p = P.default_params(n)
    assert len(p.springs.stiffness) == n
    assert len(p.friction.f_s) == len(p.cables.k) == n + 1


@pytest.mark.parametrize("change, field", [
    ({"geometry.L": 0.05}, "geometry.L"),
    ({"geometry.r": -0.001}, "geometry.r"),
    ({"springs.stiffness": (600.0, 200.0)}, "springs.stiffness"),
    ({"cables.k": (1.0, 2.0, 3.0)}, "cables"),
    ({"springs.rest_length": 0.2}, "springs.rest_length"),
    ({"friction.f_s": (1.0, float("nan"), 1.0, 1.0)}, "friction.f_s"),
    ({"geometry.n_joints": 0}, "geometry.n_joints"),
    ({"actuation.f_min": 200.0}, "actuation.f_min"),
])
def test_invalid_values_name_the_field(change, field):
    with pytest.raises(P.ParameterError, match=field.replace(".", r"\.")):
        P.default_params().replace(**change)


@pytest.mark.parametrize("ext", ["json", "toml"])
def test_save_load_round_trip(tmp_path, ext):
    p = P.default_params(4).replace(**{"geometry.r": 0.005, "cables.c_a": (1.0, 2.0, 3.0, 4.0, 5.0)})
    path = tmp_path / f"p.{ext}"
    P.save(p, path)
    assert P.load(path) == p
    assert not [f for f in tmp_path.iterdir() if f.name.startswith(".tmp")]


def test_partial_file_takes_defaults_and_unknown_keys_fail(tmp_path):
    path = tmp_path / "p.toml"
    path.write_text("[geometry]\nr = 0.0\n")
    assert P.load(path) == P.default_params().replace(**{"geometry.r": 0.0})
    path.write_text("[geometry]\nradius = 0.0\n")
    with pytest.raises(P.ParameterError, match="geometry.radius"):
        P.load(path)
    path.write_text("[geometry\n")
    with pytest.raises(P.ParameterError, match="malformed"):
        P.load(path)


# -- messages that name the right thing, in one line, never a raw traceback ----------------------

@pytest.mark.parametrize("field, value, kind", [
    ("b", '"abc"', "number"), ("b", "true", "number"), ("b", "[0.05]", "number"),
    ("alpha_max", '"1.5"', "number"), ("n_joints", '"abc"', "integer"), ("n_joints", "2.5", "integer"),
])
def test_scalar_of_the_wrong_type_names_the_field(tmp_path, field, value, kind):
    path = tmp_path / "p.toml"
    path.write_text(f"[geometry]\n{field} = {value}\n")
    with pytest.raises(P.ParameterError, match=rf"geometry\.{field}: must be an? {kind}"):
        P.load(path)


@pytest.mark.parametrize("group, field, value", [
    ("control", "rate_hz", '"fast"'), ("sensors", "encoder_counts_per_turn", '"2048"'),
    ("cables", "t_cap", "false"), ("inertia", "gravity", '"9.81"')])
def test_every_group_refuses_non_numbers(tmp_path, group, field, value):
    path = tmp_path / "p.toml"
    path.write_text(f"[{group}]\n{field} = {value}\n")
    with pytest.raises(P.ParameterError, match=rf"{group}\.{field}: must be"):
        P.load(path)


@pytest.mark.parametrize("field", ["k", "lam", "c_a", "k_linear"])
def test_cable_array_of_the_wrong_length_is_named(field):
    with pytest.raises(P.ParameterError) as info:
        P.from_dict({"cables": {field: [1.0, 2.0]}})
    assert str(info.value).startswith(f"cables.{field}: expected 4 values"), str(info.value)


@pytest.mark.parametrize("field", ["bar_mass", "diagonal_mass"])
def test_massless_bars_are_refused_before_mujoco(field):
    with pytest.raises(P.ParameterError, match=rf"inertia\.{field}: must be finite and positive"):
        P.default_params().replace(**{f"inertia.{field}": 0.0})


def test_t_min_above_f_max_is_refused():
    with pytest.raises(P.ParameterError, match=r"actuation\.t_min: 120.0 N exceeds f_max = 100.0 N"):
        P.default_params().replace(**{"actuation.t_min": 120.0})


def test_one_joint_limit_in_the_parameters(tmp_path):
    from neck_sim.cli import main
    from neck_sim.native import MAX_CABLES

    assert P.MAX_CABLES == MAX_CABLES                   # the compiled callback's arrays
    assert P.default_params(P.MAX_CABLES - 1).n_cables == P.MAX_CABLES
    with pytest.raises(P.ParameterError, match=rf"routing: {P.MAX_CABLES + 1} cables .* at most {P.MAX_CABLES}"):
        P.default_params(P.MAX_CABLES)
    with pytest.raises(P.ParameterError, match=rf"geometry\.n_joints: must be an integer between 1 and {P.MAX_CABLES}"):
        P.default_params(40)
    out = tmp_path / "p40.toml"
    assert main(["params", "--n-joints", "40", "-o", str(out)]) == 2
    assert not out.exists()


@pytest.mark.parametrize("name, text", [("p.toml", ""), ("p.toml", "# only a comment\n"), ("p.json", "{}")])
def test_empty_parameter_file_is_refused_naming_it(tmp_path, name, text):
    path = tmp_path / name
    path.write_text(text)
    with pytest.raises(P.ParameterError, match=rf"{path}: the parameter file is empty"):
        P.load(path)


def test_the_printed_table_redirected_into_a_file_is_refused_saying_how_to_write_one(tmp_path):
    path = tmp_path / "p.toml"
    path.write_text(P.describe(P.default_params()))     # what `neck-sim params > p.toml` writes
    with pytest.raises(P.ParameterError, match=rf"{path}: this is the table `neck-sim params` prints.*-o FILE"):
        P.load(path)
    path.write_text("geometry.L = \n")                    # a broken file is still called malformed
    with pytest.raises(P.ParameterError, match=rf"{path}: malformed parameter file"):
        P.load(path)


def test_control_rate_that_the_physics_step_cannot_divide():
    from neck_sim.plant import Plant

    with pytest.raises(ValueError) as info:
        Plant(P.default_params().replace(**{"control.rate_hz": 7.0}))
    msg = str(info.value)
    assert msg.startswith("control.rate_hz = 7 Hz") and "0.0005 s" in msg and "None" not in msg, msg


@pytest.mark.parametrize("forces", [{0: 10.0, 1: 10.0, 2: 10.0, 3: 10.0}, {10.0, 20.0, 30.0, 40.0}, "1234"])
def test_plant_step_refuses_unordered_containers(forces):
    from neck_sim.plant import Plant

    plant = Plant()
    with pytest.raises(ValueError, match="forces: expected 4 numbers"):
        plant.step(forces)
    plant.step([10.0, 10.0, 10.0, 10.0])            # the same values as a list are fine


def test_replay_with_parameters_of_another_n_names_both(tmp_path):
    from test_logs_fixtures import plant_run

    from neck_sim.replay import replay

    log = tmp_path / "run.mcap"
    plant_run(log, seconds=0.1)
    with pytest.raises(P.ParameterError,
                       match=r"N = 2 joints and 3 cables but the log .*run\.mcap was recorded with N = 3 and 4"):
        replay(log, params=P.default_params(2))


@pytest.mark.parametrize("field, value", [("ends_at", "inf"), ("ends_at", "nan"), ("row", "inf")])
def test_routing_integers_that_are_not_finite_are_refused(tmp_path, field, value):
    path = tmp_path / "p.toml"
    path.write_text(f"[[routing.cables]]\nside = \"left\"\npasses = []\nends_at = 1\n{field} = {value}\n"
                    if field != "ends_at" else
                    f"[[routing.cables]]\nside = \"left\"\npasses = []\n{field} = {value}\n")
    with pytest.raises(P.ParameterError, match=rf"routing\.cables\[0\]\.{field}: must be an? (integer|joint number)"):
        P.load(path)
