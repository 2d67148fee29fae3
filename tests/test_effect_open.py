"""The vocabulary is open: an effect defined and registered here, in the test file only, is hidden
in the plant, found, fitted, reported and written to the extended model with no edit to any other
file; and an effect can act on the camera timing.

The toy effect is a constant force bias along one cable, registered for its three audiences: its
physics (:mod:`neck_sim.effects`), its columns (:mod:`identification.diagnosis.columns`) and a
blind form (:mod:`identification.diagnosis.blind_forms`).  The plant hides it MuJoCo-natively (a
generalised force on the motor slide, ``qfrc_applied``, set by the effect's ``setup_mujoco``); the
diagnosis finds it through its regressor column (a constant per cable) -- two mechanisms.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import pytest

from identification.diagnosis import blind_forms
from identification.diagnosis import columns as IC
from neck_sim import effects as E
from neck_sim.effects.base import MotorEffect
from neck_sim.params import default_params
from neck_sim.validation import indices, per_item


@dataclass(frozen=True)
class CableBias(MotorEffect):
    """A constant force ``bias`` (N) along the cable, resisting the winding motor when positive (a
    spring-loaded guide, a cable rubbing on a fixed edge).  Hidden in the plant as a MuJoCo
    generalised force on the motor slide; fitted as a constant column per cable."""

    name: ClassVar[str] = "cable_bias"
    description: ClassVar[str] = "a constant force along a cable"
    kind: ClassVar[str] = "mujoco"              # not a callback force: MuJoCo applies it
    magnitude_field: ClassVar[str] = "bias"
    bias: tuple | float = 3.0
    cables: tuple | None = None

    def __post_init__(self):
        object.__setattr__(self, "bias", per_item("cable_bias.bias", self.bias))
        object.__setattr__(self, "cables", indices("cable_bias.cables", self.cables))

    def regressor(self, theta_dot, tension=None):
        return np.ones_like(np.asarray(theta_dot, dtype=float))

    def setup_mujoco(self, model, data, index):
        # the motor slide is in cable-length units: its generalised force is N along the cable
        data.qfrc_applied[index.dof_motor] = -self.per_cable(len(index.dof_motor))


class CableBiasColumns(IC.MotorColumns):
    """One column per cable: the bias (N), either sign."""

    effect: ClassVar[str] = "cable_bias"
    columns: ClassVar[tuple] = (IC.Column("bias", "N", signed=False),)


def hide_bias(params, rng, magnitude, cable, joint):
    """The blind form: a bias of either sign on one cable."""
    bias = float(rng.choice([-1, 1]) * magnitude)
    return blind_forms.Hidden(params, (CableBias(bias=bias, cables=(cable,)),), (cable,), (), f"bias {bias:+.1f} N",
                              CableBias.name)


@dataclass(frozen=True)
class CameraLag(E.Effect):
    """The camera frame stamped t shows the neck at t - ``lag`` (s)."""

    name: ClassVar[str] = "toy_camera_lag"
    description: ClassVar[str] = "camera frames older than their time stamps"
    kind: ClassVar[str] = "camera"
    lag: float = 0.004

    @property
    def camera_delay(self) -> float:
        return self.lag


@pytest.fixture(scope="module")
def registered():
    for cls in (CableBias, CameraLag):
        E.register(cls)
    IC.register(CableBiasColumns)
    blind_forms.register(CableBias.name, CableBias.name, 4.0, "N")(hide_bias)
    yield
    blind_forms.unregister(CableBias.name)
    IC.unregister(CableBias.name)
    for cls in (CableBias, CameraLag):
        E.unregister(cls.name)
    assert "cable_bias" not in E.names() + IC.names() + tuple(blind_forms.forms())


@pytest.fixture(scope="module")
def bias_logs(registered, tmp_path_factory):
    """seed -> (cable, bias N, log path): the bias on a right cable and with a sign drawn from the seed
    (the long left cable is soft and stiffens strongly: its law absorbs offsets, as for the pretension)."""
    from identification.diagnosis.blind import run_log

    out = {}
    for seed in (1, 2):
        rng = np.random.default_rng(seed)
        cable = int(rng.integers(3))
        bias = float(rng.choice([-1, 1]) * rng.uniform(3.0, 5.0))
        path = tmp_path_factory.mktemp("open") / f"bias{seed}.mcap"
        run_log(path, default_params(3), E.Effects(cable_bias=CableBias(bias=bias, cables=(cable,))), seed=seed,
                write_truth=False)
        out[seed] = (cable, bias, path)
    return out


def test_registry_refuses_bad_effects(registered):
    with pytest.raises(ValueError, match="exists"):
        E.register(type("Other", (CableBias,), {"name": "dry_friction"}))
    with pytest.raises(ValueError, match="requires unregistered"):
        E.register(type("Needy", (CableBias,), {"name": "needy", "requires": ("gear_creep",)}))
    with pytest.raises(ValueError, match="built-in"):
        E.unregister("payload")
    with pytest.raises(ValueError, match="unknown effect 'gear_creep'"):
        E.Effects(gear_creep=CableBias())
    with pytest.raises(ValueError, match="'check' is an attribute of Effects"):
        E.register(type("Check", (CableBias,), {"name": "check"}))


def test_a_new_effect_is_a_blind_case(registered):
    """Its blind form is a case of the generator: drawn from a seed, expecting the new effect."""
    from identification.diagnosis.blind import hidden_effect

    assert "cable_bias" in blind_forms.forms()
    case = hidden_effect("cable_bias", 1)
    assert case.expect == "cable_bias" and case.effects.cable_bias is not None
    assert abs(case.effects.cable_bias.bias) == pytest.approx(case.magnitude)
    assert case.model == E.paper_model()


def _leader(verdict) -> str:
    """The effect a verdict names first (a name, or a list of look-alikes that tie)."""
    return verdict if isinstance(verdict, str) else verdict[0]


def test_a_new_effect_is_found_fitted_reported_and_written(bias_logs, tmp_path, capsys):
    from identification.diagnosis.candidates import plant_model
    from identification.diagnosis import DiagnosisSettings, diagnose_log, parse_model
    from neck_sim.cli import main

    # seed 1 through the command line: verdict, JSON, report and the extended model
    cable, bias, path = bias_logs[1]
    js, rep, ext = tmp_path / "d.json", tmp_path / "report", tmp_path / "model.json"
    assert main(["diagnose", str(path), "--steps", "1", "--json", str(js), "--report", str(rep),
                 "--extended", str(ext), "--quiet"]) == 0
    # the leader of the verdict: since the open-world diagnosis spring_error is listed
    # beside it (each adds to the other: a torque on the cable's joint) and leftover structure as
    # 'unexplained'; the finding's fit and the extended model are the bias's
    line = next(x for x in capsys.readouterr().out.splitlines() if x.startswith("verdict: "))
    assert line.startswith(("verdict: cable_bias", "verdict: ['cable_bias'"))
    finding = json.loads(js.read_text())["findings"][0]
    assert _leader(finding["effect"]) == "cable_bias" and finding["cables"] == [cable + 1]
    fitted = finding["parameters"][f"bias({cable + 1})"]
    # achieved: +11 % (seed 1), -19 % (seed 2): about +0.6 N on every seed tried (not understood yet;
    # the leftover structure follows the sign of that cable's speed, so probably a trade-off with its
    # dry friction)
    assert fitted["unit"] == "N" and fitted["value"] == pytest.approx(bias, rel=0.25)
    assert "cable_bias" in (rep / "report.md").read_text()
    gain = finding["gain"]["resimulation_holdout"]          # the extended plant (with the bias) re-simulates better
    assert gain["after"]["alpha_mean_abs_deg"] < 0.5 * gain["before"]["alpha_mean_abs_deg"]
    written = json.loads(ext.read_text())
    eff = E.Effects.from_dict(written["effects"])
    assert eff.cable_bias.per_cable(4)[cable] == pytest.approx(fitted["value"], rel=1e-12)
    assert parse_model(str(ext)).names[-1] == "cable_bias"
    # another seed through the Python API, with every registered effect a candidate
    cable, bias, path = bias_logs[2]
    diag = diagnose_log(path, settings=DiagnosisSettings(max_steps=1, resimulate=False, alpha_hat=False))
    assert _leader(diag.verdict) == "cable_bias" and diag.findings[0].cables == [cable + 1]
    assert diag.steps[0].chosen.term.name == "cable_bias"
    _, effects, rigid = plant_model(diag.steps[0].chosen.fit, default_params(3))
    assert not rigid and effects.cable_bias.per_cable(4)[cable] == pytest.approx(bias, rel=0.25)


def test_a_camera_timing_effect_reaches_the_plant(registered):
    """Frames of a plant with a camera lag show the neck ``lag`` before their stamps (noise off, a
    25 Hz camera so that frames fall on control periods)."""
    from neck_sim.plant import Plant

    p = default_params(3).replace(**{"sensors.camera_noise": 0.0, "sensors.camera_rate_hz": 25.0})
    lag = 2 / p.control.rate_hz
    forces = np.array([30.0, 10.0, 25.0, 20.0])
    for effects, expect_lag in ((E.Effects(), 0.0), (E.Effects.of(CameraLag(lag)), lag)):
        plant = Plant(p, effects)
        plant.reset(np.zeros(3))
        seen = 0
        for _ in range(120):
            plant.step(forces)
            frame = plant.camera_frame()
            if frame is not None:
                seen += 1
                assert frame[0] == pytest.approx(plant.time + expect_lag, abs=1e-9)
                np.testing.assert_array_equal(frame[1], plant.truth().alpha)
        assert seen == 6


def test_a_motor_effect_without_native_kernel_needs_the_python_backend(registered):
    from neck_sim import plant as P

    @dataclass(frozen=True)
    class PythonBias(CableBias):
        """The cable bias as a callback force (no native kernel): the Python callback applies it."""

        name: ClassVar[str] = "python_bias"
        kind: ClassVar[str] = "motor"

        def setup_mujoco(self, model, data, index):
            pass

    E.register(PythonBias)
    previous = P.get_backend()
    try:
        effects = E.Effects.of(PythonBias(bias=4.0, cables=(0,)))
        if P.native_available():
            with pytest.raises(ValueError, match=r"python_bias.*no native kernel.*backend='python'"):
                P.Plant(default_params(3), effects, backend="native")
        alpha = {}
        for name, eff in (("python", effects), ("mujoco", E.Effects.of(CableBias(bias=4.0, cables=(0,))))):
            plant = P.Plant(default_params(3), eff, backend="python")
            plant.reset(np.zeros(3))
            for _ in range(50):
                plant.step(np.full(4, 20.0))
            alpha[name] = plant.truth().alpha
        # the same force applied by the callback and by MuJoCo (implicit vs explicit: close, not equal)
        np.testing.assert_allclose(alpha["python"], alpha["mujoco"], atol=1e-9)
        assert np.abs(alpha["python"]).max() > 1e-3
    finally:
        P.set_backend(previous or "auto")
        E.unregister(PythonBias.name)


def test_the_command_line_lists_registered_effects(registered, capsys):
    from neck_sim.cli import main

    assert main(["effects", "--markdown"]) == 0
    out = capsys.readouterr().out
    for cls in E.registered():
        assert f"| {cls.name} | {cls.description} |" in out
    assert "bias [N] per cable" in out
