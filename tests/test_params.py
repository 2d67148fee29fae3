
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
