"""``Plant(..., integrator=...)``: None keeps :func:`neck_sim.mjcf.integrator_for`'s choice from
the cable damping c_a; a name fixes MuJoCo's integrator whatever c_a is, so that the simulated
response is continuous in c_a (an output-error fit over c_a chooses the integrator once)."""

import mujoco
import numpy as np
import pytest

from neck_sim.mjcf import DEFAULT_TIMESTEP, IMPLICITFAST_DAMPING_LIMIT, integrator_for
from neck_sim.params import default_params
from neck_sim.plant import INTEGRATORS, Plant

F = np.array([25.0, 22.0, 20.0, 30.0])
A0 = np.radians([20.0, -10.0, 15.0])
PERIODS = 25
P0 = default_params(3)
# the c_a (N s/m) at which integrator_for switches from implicitfast to discrete
C_SWITCH = IMPLICITFAST_DAMPING_LIMIT * min(P0.inertia.bar_mass, P0.inertia.diagonal_mass) / DEFAULT_TIMESTEP


def compiled_integrator(plant):
    """The integrator of the plant's compiled model, by MuJoCo's name."""
    return mujoco.mjtIntegrator(plant.model.opt.integrator).name.removeprefix("mjINT_").lower()


def damped(c_a):
    return P0.replace(**{"cables.c_a": (c_a,) * 4})


def response(params, integrator):
    plant = Plant(params, integrator=integrator)
    plant.reset(A0)
    rows = []
    for _ in range(PERIODS):
        plant.step(F)
        tr = plant.truth()
        rows.append(np.concatenate([tr.alpha, tr.tension]))
    return plant, np.array(rows)


@pytest.mark.parametrize("c_a", [50.0, 3000.0])
def test_none_keeps_the_choice_from_c_a(c_a):
    auto, a = response(damped(c_a), None)
    named, b = response(damped(c_a), integrator_for(damped(c_a)))
    assert auto.integrator is None and named.integrator == integrator_for(damped(c_a))
    assert compiled_integrator(auto) == compiled_integrator(named) == named.integrator
    np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("name", INTEGRATORS)
def test_a_name_fixes_the_compiled_integrator_and_the_xml(name):
    plant = Plant(damped(3000.0) if name == "implicitfast" else P0, integrator=name)
    assert plant.integrator == compiled_integrator(plant) == name
    assert f'integrator="{name}"' in plant.xml


def test_a_fixed_integrator_makes_the_response_continuous_in_c_a():
    # across the switch, the automatic choice jumps (implicitfast -> discrete); a fixed one moves
    # only as much as the 0.2 % change of c_a: measured 5.3e-5 rad and 9.4e-3 N at most against
    # 1.1e-3 rad and 1.1 N with the switch
    below, above = C_SWITCH * 0.999, C_SWITCH * 1.001
    jump = {}
    for name in (None, "implicitfast", "discrete"):
        (p_lo, lo), (p_hi, hi) = response(damped(below), name), response(damped(above), name)
        if name is not None:
            assert compiled_integrator(p_lo) == compiled_integrator(p_hi) == name
        else:
            assert (compiled_integrator(p_lo), compiled_integrator(p_hi)) == ("implicitfast", "discrete")
        jump[name] = np.abs(hi - lo).max(axis=0)
    for name in ("implicitfast", "discrete"):
        assert jump[name][:3].max() < 1e-4 and jump[name][3:].max() < 0.015
        assert jump[None][:3].max() > 10 * jump[name][:3].max()


@pytest.mark.parametrize("bad", ["rk4", "euler", "Discrete", 3, ""])
def test_a_bad_name_is_refused_in_one_line(bad):
    with pytest.raises(ValueError, match=r"^integrator: expected None or one of .*got") as err:
        Plant(P0, integrator=bad)
    assert "\n" not in str(err.value)
