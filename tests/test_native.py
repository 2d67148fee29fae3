"""The native path's public face: a batch steps plants through their one public record
(``Plant.native``), the record holds the plant's C registration, and ``neck_sim.native`` (which
``neck_sim.params`` imports for MAX_CABLES) stays light."""

import gc
import subprocess
import sys
from types import SimpleNamespace

import numpy as np
import pytest

import neck_sim.native as native
from neck_sim.batch import PlantBatch
from neck_sim.effects import ActuationDelay, CameraDelay, Effects
from neck_sim.params import default_params
from neck_sim.plant import Plant

A0 = np.radians([12.0, -8.0, 5.0])


def plants():
    p = default_params(3)
    return [Plant(p, effects=Effects(actuation_delay=ActuationDelay(0.0041)), seed=3),
            Plant(p, effects=Effects(camera_delay=CameraDelay(0.011)), seed=4)]


def forces(k):
    return 20.0 + 6.0 * np.sin(0.05 * k + np.arange(4))[None, :] * np.array([[1.0], [-1.0]])


def test_a_batch_reads_nothing_of_a_plant_but_its_record():
    """Stand-ins that carry only ``native`` step bit-identically to the plants stepping alone."""
    alone, inner = plants(), plants()
    for pl in alone + inner:
        pl.reset(A0)
    stand_ins = [SimpleNamespace(native=pl.native) for pl in inner]
    frames = 0
    with PlantBatch(stand_ins) as batch:
        for k in range(40):
            f = forces(k)
            assert batch.step(f) == []
            for i, pl in enumerate(alone):
                pl.step(f[i])
                np.testing.assert_array_equal(batch.encoders()[i], pl.encoders())
                assert batch.out[i].tobytes() == np.concatenate(
                    [pl.truth().theta, pl.truth().alpha, pl.truth().alpha_dot, pl.truth().tension,
                     pl.truth().elongation, [pl.truth().loop_gap]]).tobytes()
                if pl.camera_frame() is not None:
                    frames += 1
                    assert batch.frames[i][0] == pl.camera_frame()[0]
                    assert batch.frames[i][1].tobytes() == pl.camera_frame()[1].tobytes()
                else:
                    assert batch.frames[i] is None
    assert frames >= 2
    # the state came back to the plants: they go on alone from where the batch left them
    for a, b in zip(alone, inner):
        assert a.time == b.time
        a.step([20.0] * 4)
        b.step([20.0] * 4)
        assert a.truth().alpha.tobytes() == b.truth().alpha.tobytes()


@pytest.mark.skipif(not native.native_available(), reason="no C compiler")
def test_the_record_holds_the_registration():
    """A batch that outlives its plant still steps a registered model; the record's end frees it."""
    lib = native.DISPATCH.lib
    before = lib.neck_registered()
    pl = Plant(backend="native")
    pl.reset(A0)
    batch = PlantBatch([pl.native])
    del pl
    gc.collect()
    assert lib.neck_registered() == before + 1
    calls = batch.records[0].struct.calls
    assert batch.step(np.full((1, 4), 20.0)) == []
    assert batch.records[0].struct.calls == calls + batch.nsub      # the C callback saw every sub-step
    del batch
    gc.collect()
    assert lib.neck_registered() == before


def test_the_public_face_resolves_and_stays_light():
    for name in native.__all__:
        assert getattr(native, name) is not None, name
    code = "import sys, neck_sim.native; print(sorted({'numba', 'neck_sim.params'} & set(sys.modules)))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"
