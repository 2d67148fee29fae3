"""Every foxglove.* message of a produced log validates against Foxglove's published JSON schemas.

``tests/data/foxglove/*.json`` are the JSON schemas of the npm package ``@foxglove/schemas`` 2.1.0
(MIT, ``dist/jsonschema``), the ones Foxglove publishes; they are read here from disk, never through
``neck_sim.logs.foxglove``.  To refresh them: ``npm pack @foxglove/schemas``, then in node
``JSON.stringify(require("./package/dist/jsonschema").SceneUpdate, null, 2)`` (and FrameTransforms).
"""

from __future__ import annotations

import json
import pathlib

import jsonschema
import numpy as np
import pytest
from mcap.reader import make_reader

from neck_sim.logs import LogWriter
from neck_sim.params import default_params

SCHEMAS = pathlib.Path(__file__).parent / "data" / "foxglove"
PUBLISHED = {"foxglove.SceneUpdate": "SceneUpdate.json", "foxglove.FrameTransforms": "FrameTransforms.json"}


def _validator(schema_name: str) -> jsonschema.protocols.Validator:
    schema = json.loads((SCHEMAS / PUBLISHED[schema_name]).read_text())
    cls = jsonschema.validators.validator_for(schema, default=jsonschema.Draft202012Validator)
    cls.check_schema(schema)
    return cls(schema)


def _produced_log(path, n_joints: int, seed: int):
    """A log with truth, camera and estimate poses (all three drawn in /neck/scene), 0.3 s."""
    rng = np.random.default_rng(seed)
    params = default_params(n_joints)
    n = n_joints
    with LogWriter(path, params) as w:
        for k in range(150):
            t = k / 500.0
            alpha = 0.8 * np.sin(2 * np.pi * (t + rng.uniform(0, 1, n)))
            w.motors(t, rng.uniform(-1, 1, n + 1), rng.uniform(2, 50, n + 1))
            w.truth(t, alpha, np.zeros(n), rng.uniform(2, 50, n + 1), rng.uniform(0, 1e-3, n + 1))
            w.estimate(t, alpha + 0.01)
            if k % 17 == 0:
                w.camera(t, alpha - 0.01)


@pytest.mark.parametrize("n_joints, seed", [(1, 0), (3, 1), (6, 2)])
def test_tf_and_scene_validate_against_foxglove_schemas(tmp_path, n_joints, seed):
    path = tmp_path / "run.mcap"
    _produced_log(path, n_joints, seed)
    validators = {name: _validator(name) for name in PUBLISHED}
    counted = {"/tf": 0, "/neck/scene": 0}
    sources = set()
    with open(path, "rb") as fh:
        for schema, channel, message in make_reader(fh).iter_messages():
            if not schema.name.startswith("foxglove."):
                continue
            assert schema.name in PUBLISHED, f"{channel.topic}: {schema.name} has no published schema here"
            msg = json.loads(message.data)
            errors = sorted(validators[schema.name].iter_errors(msg), key=lambda e: list(e.path))
            assert not errors, (f"{channel.topic} at {message.log_time} ns: {errors[0].message} "
                                f"at {list(errors[0].path)}")
            counted[channel.topic] += 1
            sources.update(e["id"] for e in msg.get("entities", []))
    assert counted["/tf"] >= 9 and counted["/neck/scene"] >= 27, counted     # 30 Hz over 0.3 s, 3 sources
    assert sources == {"neck/truth", "neck/estimate", "neck/camera"}


def test_the_published_schemas_catch_what_was_missing():
    """The validator is not vacuous: the fields an earlier writer left out each make a message invalid."""
    from neck_sim.logs.foxglove import scene_update

    validator = _validator("foxglove.SceneUpdate")
    corners = np.zeros((2, 4, 2))
    good = scene_update(1_000_000_000, corners, "truth")
    assert validator.is_valid(good)
    for drop in (("deletions",), ("entities", 0, "metadata"), ("entities", 0, "models"),
                 ("entities", 0, "lines", 0, "colors"), ("entities", 0, "lines", 0, "indices")):
        bad = json.loads(json.dumps(good))
        parent = bad
        for key in drop[:-1]:
            parent = parent[key]
        del parent[drop[-1]]
        assert not validator.is_valid(bad), drop
