"""PlantBatch (K plants per control period in one native call) against the stepping sequence of
the plant before it existed, written here from MuJoCo's own Python calls."""

import math

import mujoco
import numpy as np
import pytest

from neck_sim import effects as E
from neck_sim import plant as P
from neck_sim.native import DISPATCH

A0 = np.radians([10.0, -8.0, 5.0])


class ReferenceStepper:
    """One plant stepped as ``Plant.step`` did per plant before PlantBatch: the period cut at camera
    frames and delayed-command switches, ``mj_step2`` / ``mj_step`` segments / ``mj_step1`` called
    from Python, the schedules computed per sub-step in plain Python floats."""

    def __init__(self, plant: P.Plant, alpha0):
        plant.reset(alpha0)
        self.plant, self.k = plant, 0
        self.rate, self.dt, self.n = plant.params.sensors.camera_rate_hz, plant.timestep, plant.substeps
        self.period = self.n * self.dt
        self.delay, self.cam_delay = plant.effects.command_delay(), plant.effects.camera_lag()
        self.rng = np.random.default_rng(plant.seed)
        self.frame_index, self.next_cam = 1, self.camera_step(1)
        self.commands = {}
        self.frame = None

    def camera_step(self, j):
        return math.ceil((j / self.rate - self.cam_delay) / self.dt - 1e-6)

    def command_at(self, step):
        """Command in force during absolute sub-step ``step`` (issued at p T, acting from p T + delay)."""
        p = min(self.k // self.n, max(0, int(math.floor((step * self.dt - self.delay) / self.period + 1e-9))))
        return self.commands[p]

    def step(self, forces):
        pl = self.plant
        m, d = pl.model, pl.data
        f = np.clip(np.asarray(forces, dtype=float), 0.0, pl.params.actuation.f_max)
        self.commands[self.k // self.n] = f
        frames = {}
        while self.next_cam <= self.k + self.n:
            frames.setdefault(max(self.next_cam - self.k, 1), 0)
            frames[max(self.next_cam - self.k, 1)] += 1
            self.frame_index += 1
            self.next_cam = self.camera_step(self.frame_index)
        self.frame = None
        previous = DISPATCH.enter(pl.backend)
        try:
            for s in range(self.n):
                d.ctrl[: len(f)] = self.command_at(self.k + s)
                (mujoco.mj_step2 if s == 0 else mujoco.mj_step)(m, d)
                for _ in range(frames.get(s + 1, 0)):
                    alpha = d.qpos[pl._ix.qpos_A] + d.qpos[pl._ix.qpos_D]
                    noise = self.rng.normal(0.0, pl.params.sensors.camera_noise, alpha.shape)
                    self.frame = ((self.k + s + 1) * self.dt + self.cam_delay, alpha + noise)
            tension = None
            if pl.rigid_cables:                       # the equality constraints' forces, before mj_step1
                rows = np.flatnonzero(d.efc_type[: d.nefc] == mujoco.mjtConstraint.mjCNSTR_EQUALITY)
                tension = np.array([-d.efc_force[rows[d.efc_id[rows] == eq][0]] if np.any(d.efc_id[rows] == eq)
                                    else 0.0 for eq in pl._ix.rigid_equality])
            mujoco.mj_step1(m, d)
        finally:
            DISPATCH.leave(previous)
        self.k += self.n
        ix = pl._ix
        ratio = pl.params.actuation.R / pl.params.actuation.r_d
        res = pl.params.sensors.encoder_resolution
        theta = ratio * d.qpos[ix.qpos_motor]
        alpha = d.qpos[ix.qpos_A] + d.qpos[ix.qpos_D]
        return (np.rint(theta / res) * res, alpha, pl._out_tension.copy() if tension is None else tension,
                self.frame)


def _plants(params, backend=None):
    p = params
    return [P.Plant(p, effects=E.Effects(actuation_delay=E.ActuationDelay(0.0073)), seed=4, backend=backend),
            P.Plant(p, effects=E.Effects(camera_delay=E.CameraDelay(0.013)), seed=5, backend=backend),
            P.Plant(p, effects=E.Effects(actuation_delay=E.ActuationDelay(0.0031),
                                         camera_delay=E.CameraDelay(0.021)), seed=6, backend=backend),
            P.Plant(p, rigid_cables=True, seed=7, backend=backend)]


def _forces(k, K, m):
    """Open-loop forces, different per plant and period (N); every 20th period one cable asks for
    1000 N and another for -5 N (both clipped, to f_max and to 0)."""
    t = k * 0.002
    f = 20.0 + 8.0 * np.sin(2 * np.pi * 1.3 * t + np.arange(K)[:, None] + 0.7 * np.arange(m))
    if k % 20 == 10:
        f[:, 0], f[:, -1] = 1000.0, -5.0
    return f


@pytest.mark.parametrize("backend", ["native", "python"])
def test_batch_equals_the_per_plant_sequence(params, backend):
    """K = 4 (actuation delay, camera delay, both, rigid cables) over 60 periods with 3 or 4 camera
    frames each: encoders, joint angles, tensions and frames bit-identical to the reference."""
    if backend == "native" and not P.native_available():
        pytest.skip("no C compiler")
    previous = P.get_backend()
    try:
        refs = [ReferenceStepper(pl, A0 * (1 + 0.1 * i)) for i, pl in enumerate(_plants(params, backend))]
        plants = _plants(params, backend)
        for i, pl in enumerate(plants):
            pl.reset(A0 * (1 + 0.1 * i))
        K, m, n = len(plants), params.n_cables, params.n_joints
        cols = P.truth_columns(n, m)
        frames = 0
        with P.PlantBatch(plants) as batch:
            for k in range(60):
                f = _forces(k, K, m)
                assert batch.step(f) == []
                for i, ref in enumerate(refs):
                    theta, alpha, tension, frame = ref.step(f[i])
                    np.testing.assert_array_equal(batch.encoders()[i], theta)
                    np.testing.assert_array_equal(batch.out[i, cols["alpha"]], alpha)
                    np.testing.assert_array_equal(batch.out[i, cols["tension"]], tension)
                    assert (batch.frames[i] is None) == (frame is None)
                    if frame is not None:
                        frames += 1
                        assert batch.frames[i][0] == frame[0]
                        np.testing.assert_array_equal(batch.frames[i][1], frame[1])
        assert frames >= 3 * K
        assert all(np.any(batch.out[i, cols["tension"]] > 1.0) for i in range(K))   # the cables carry load
        for pl, ref in zip(plants, refs):               # state handed back: the plants go on alone
            pl.step(np.full(m, 21.0))
            np.testing.assert_array_equal(pl.encoders(), ref.step(np.full(m, 21.0))[0])
            assert pl.time == ref.k * ref.dt
    finally:
        P.set_backend(previous)


def test_batch_stops_only_the_failing_plants(params):
    """A NaN force row and a diverged simulation stop their own plant with the messages of
    Plant.step; the other plant goes on exactly as alone."""
    plants = [P.Plant(params, seed=s) for s in range(3)]
    alone = P.Plant(params, seed=0)
    for pl in plants + [alone]:
        pl.reset(A0)
    m = params.n_cables
    with P.PlantBatch(plants) as batch:
        f = _forces(0, 3, m)
        f[1, 2] = np.nan
        assert batch.step(f) == [1]
        assert isinstance(batch.errors[1], ValueError) and "forces: contains NaN or infinity" in str(batch.errors[1])
        alone.step(f[0])
        plants[2].data.qvel[:] = 1e20                  # MuJoCo refuses this state (bad qvel)
        assert batch.step(_forces(1, 3, m)) == [2]
        assert isinstance(batch.errors[2], P.PlantDivergedError) and "t = 0.0040 s" in str(batch.errors[2])
        alone.step(_forces(1, 3, m)[0])
        assert batch.step(_forces(2, 3, m)) == [] and batch.active.tolist() == [1, 0, 0]
        alone.step(_forces(2, 3, m)[0])
        np.testing.assert_array_equal(batch.encoders()[0], alone.encoders())
        assert plants[0].time == alone.time == 3 * plants[0].period
    with P.PlantBatch([plants[0]]) as one, pytest.raises(ValueError, match="shape"):
        one.step(np.zeros(m))
    with pytest.raises(ValueError, match="same plant twice"):
        P.PlantBatch([plants[0], plants[0]])
    with P.PlantBatch([plants[0]]):
        with pytest.raises(RuntimeError, match="open PlantBatch"):
            plants[0].step(np.zeros(m))


def test_a_dropped_plant_leaves_the_registry_at_once(params):
    """A plant's own batch must not keep it alive (no reference cycle): its C registry slot is
    freed when the last reference goes, without waiting for the cyclic garbage collector."""
    import gc

    if not P.native_available():
        pytest.skip("no C compiler")
    pl = P.Plant(params, backend="native")
    pl.step(np.full(params.n_cables, 20.0))
    before = DISPATCH.lib.neck_registered()
    gc.disable()
    try:
        del pl
        assert DISPATCH.lib.neck_registered() == before - 1
    finally:
        gc.enable()
