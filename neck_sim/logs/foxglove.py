"""Foxglove well-known messages (JSON) that draw the neck in Foxglove's 3D panel.

``/tf`` carries ``foxglove.FrameTransforms``: ``world`` -> ``neck`` (the neck's vertical plane,
its x to the right and its y up, turned so that y is Foxglove's z-up) and ``neck`` -> ``bar{i}``
(the middle of bar i: 0 the fixed base bar, i the top bar of X-joint i).  ``/neck/scene`` carries
``foxglove.SceneUpdate`` with one entity per source of joint angles (truth, estimate, camera):
bars, diagonals and side springs as line lists and, for the truth, the cables as coloured line
strips through the pulley axes (c1 blue, c2 yellow, c3 red, left cable green, as in the paper).
Geometry comes from :func:`neck_sim.analytic.forward_kinematics`.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import orjson

from neck_sim.analytic import forward_kinematics
from neck_sim.logs import jsonrecords
from neck_sim.params import NeckParams
from neck_sim.routing import paper_routing

__all__ = ["TF_TOPIC", "SCENE_TOPIC", "FRAME_TRANSFORMS_SCHEMA", "SCENE_UPDATE_SCHEMA",
           "Batch", "frame_transforms", "scene_update", "visualization_batches"]

TF_TOPIC = "/tf"
SCENE_TOPIC = "/neck/scene"

_TIME = {"type": "object", "title": "time",
         "properties": {"sec": {"type": "integer", "minimum": 0},
                        "nsec": {"type": "integer", "minimum": 0, "maximum": 999999999}}}
_DURATION = {"type": "object", "title": "duration",
             "properties": {"sec": {"type": "integer"}, "nsec": {"type": "integer", "minimum": 0, "maximum": 999999999}}}


def _record(title: str, **props) -> dict:
    """An object schema whose fields are all required, as in Foxglove's generated schemas."""
    return {"title": title, "type": "object", "properties": props, "required": list(props)}


def _array(items: dict) -> dict:
    return {"type": "array", "items": items}


_NUMBER = {"type": "number"}
_VEC3 = _record("foxglove.Vector3", x=_NUMBER, y=_NUMBER, z=_NUMBER)
_QUAT = _record("foxglove.Quaternion", x=_NUMBER, y=_NUMBER, z=_NUMBER, w=_NUMBER)
_COLOR = _record("foxglove.Color", r=_NUMBER, g=_NUMBER, b=_NUMBER, a=_NUMBER)
_POINT3 = _record("foxglove.Point3", x=_NUMBER, y=_NUMBER, z=_NUMBER)
_POSE = _record("foxglove.Pose", position=_VEC3, orientation=_QUAT)

# The schemas of Foxglove's published JSON schemas (npm @foxglove/schemas, jsonschema/), with the
# names Foxglove recognises.  Every required field is listed; the primitives neck-sim never draws
# (arrows, cubes, ..., models) are declared as arrays and always written empty.
# tests/test_foxglove_schema.py validates produced logs against the published files themselves.
FRAME_TRANSFORMS_SCHEMA = {
    **_record("foxglove.FrameTransforms", transforms=_array(_record(
        "foxglove.FrameTransform", timestamp=_TIME, parent_frame_id={"type": "string"},
        child_frame_id={"type": "string"}, translation=_VEC3, rotation=_QUAT))),
    "description": "An array of FrameTransform messages",
}
_LINE = _record("foxglove.LinePrimitive",
                type={"title": "foxglove.LineType", "oneOf": [
                    {"title": "LINE_STRIP", "const": 0}, {"title": "LINE_LOOP", "const": 1},
                    {"title": "LINE_LIST", "const": 2}]},
                pose=_POSE, thickness=_NUMBER, scale_invariant={"type": "boolean"},
                points=_array(_POINT3), color=_COLOR, colors=_array(_COLOR),
                indices=_array({"type": "integer", "minimum": 0}))
_UNUSED = _array({"type": "object"})
SCENE_UPDATE_SCHEMA = {
    **_record("foxglove.SceneUpdate",
              deletions=_array(_record("foxglove.SceneEntityDeletion", timestamp=_TIME,
                                       type={"title": "foxglove.SceneEntityDeletionType", "oneOf": [
                                           {"title": "MATCHING_ID", "const": 0}, {"title": "ALL", "const": 1}]},
                                       id={"type": "string"})),
              entities=_array(_record(
                  "foxglove.SceneEntity", timestamp=_TIME, frame_id={"type": "string"}, id={"type": "string"},
                  lifetime=_DURATION, frame_locked={"type": "boolean"},
                  metadata=_array(_record("foxglove.KeyValuePair", key={"type": "string"},
                                          value={"type": "string"})),
                  arrows=_UNUSED, cubes=_UNUSED, spheres=_UNUSED, cylinders=_UNUSED, lines=_array(_LINE),
                  triangles=_UNUSED, texts=_UNUSED, models=_UNUSED))),
    "description": "An update to the entities displayed in a 3D scene",
}

_PLANE_TO_Z_UP = {"x": math.sin(math.pi / 4), "y": 0.0, "z": 0.0, "w": math.cos(math.pi / 4)}  # +90 deg about x
_IDENTITY_POSE = {"position": {"x": 0.0, "y": 0.0, "z": 0.0}, "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}}
_CABLE_COLORS = ((0.1, 0.35, 0.95), (0.95, 0.8, 0.1), (0.9, 0.15, 0.1))   # c1, c2, c3; beyond: repeat
_LEFT_COLOR = (0.1, 0.7, 0.2)
_SOURCE_COLORS = {"truth": (0.85, 0.85, 0.85, 1.0), "estimate": (1.0, 0.55, 0.0, 0.8),
                  "camera": (0.2, 0.8, 1.0, 0.8)}


# Drawn coordinates (m) and quaternion components to 1 um / 1e-6: finer than any screen shows, and
# the shorter numbers halve what the scene costs to write and compress.  The contract topics stay exact.
_DRAWN_DIGITS = 6
_STAMP = {"sec": jsonrecords.SEC, "nsec": jsonrecords.NSEC}


def _point(slot: int) -> dict:
    return {"x": jsonrecords.Slot(slot), "y": jsonrecords.Slot(slot + 1), "z": 0.0}


def _frame_transforms_template(n_joints: int) -> jsonrecords.Template:
    """Values: frame origins (N+1, 2) m flattened, then sin(phi/2) (N+1,), then cos(phi/2) (N+1,)."""
    n = n_joints + 1
    out = [{"timestamp": _STAMP, "parent_frame_id": "world", "child_frame_id": "neck",
            "translation": {"x": 0.0, "y": 0.0, "z": 0.0}, "rotation": _PLANE_TO_Z_UP}]
    for i in range(n):
        out.append({"timestamp": _STAMP, "parent_frame_id": "neck", "child_frame_id": f"bar{i}",
                    "translation": _point(2 * i),
                    "rotation": {"x": 0.0, "y": 0.0, "z": jsonrecords.Slot(2 * n + i),
                                 "w": jsonrecords.Slot(3 * n + i)}})
    return jsonrecords.template({"transforms": out})


def _frame_transform_values(frame_origin, frame_angle) -> np.ndarray:
    """(K, 4 (N+1)) values of :func:`_frame_transforms_template` from origins (K, N+1, 2), angles (K, N+1)."""
    origin = np.asarray(frame_origin, dtype=float)
    half = 0.5 * np.asarray(frame_angle, dtype=float)
    values = np.concatenate([origin.reshape(len(origin), -1), np.sin(half), np.cos(half)], axis=1)
    return np.round(values, _DRAWN_DIGITS)


def _scene_values(corners) -> np.ndarray:
    """(K, 8 N) values of :func:`_scene_template` from joint corners (K, N, 4, 2) m."""
    corners = np.asarray(corners, dtype=float)
    return np.round(corners.reshape(len(corners), -1), _DRAWN_DIGITS)


def _line(kind: int, corner_ids, rgba, thickness: float) -> dict:
    return {"type": kind, "pose": _IDENTITY_POSE, "thickness": thickness, "scale_invariant": False,
            "points": [_point(2 * c) for c in corner_ids],
            "color": dict(zip("rgba", rgba)), "colors": [], "indices": []}


def _scene_template(n_joints: int, source: str, routing=None) -> jsonrecords.Template:
    """Values: the joint corners (N, 4, 2) m flattened (corner c of joint i is point 4 i + c)."""
    A, B, C, D = range(4)
    bars, springs = [], []
    for i in range(n_joints):
        a, b, c, d = (4 * i + k for k in (A, B, C, D))
        if i == 0:
            bars += [a, b]
        bars += [c, d, a, d, b, c]
        springs += [a, c, b, d]
    lines = [_line(2, bars, _SOURCE_COLORS[source], 0.004)]
    if source == "truth":
        lines.append(_line(2, springs, (0.5, 0.5, 0.5, 0.6), 0.0015))
        routing = paper_routing(n_joints) if routing is None else routing
        index = {"A": A, "B": B, "C": C, "D": D}
        for j, cable in enumerate(routing.cables):
            end = ("C" if cable.side == "left" else "D", cable.ends_at)
            path = [4 * (i - 1) + index[corner] for corner, i in cable.pulleys() + (end,)]
            rgb = _LEFT_COLOR if cable.side == "left" else _CABLE_COLORS[min(j, 2)]
            lines.append(_line(0, path, (*rgb, 1.0), 0.002))
    entity = {"timestamp": _STAMP, "frame_id": "neck", "id": f"neck/{source}",
              "lifetime": {"sec": 0, "nsec": 0}, "frame_locked": False,
              "metadata": [{"key": "source", "value": source}],
              "arrows": [], "cubes": [], "spheres": [], "cylinders": [], "lines": lines,
              "triangles": [], "texts": [], "models": []}
    return jsonrecords.template({"deletions": [], "entities": [entity]})


def frame_transforms(log_time: int, frame_origin, frame_angle) -> dict:
    """``foxglove.FrameTransforms`` of the bar frames: origins (N+1, 2) m and angles (N+1,) rad.

    Frames and angles are those of :class:`neck_sim.analytic.Kinematics` for one pose.
    """
    origin = np.asarray(frame_origin, dtype=float)
    values = _frame_transform_values(origin[None], np.asarray(frame_angle, dtype=float)[None])[0]
    return orjson.loads(jsonrecords.render(_frame_transforms_template(len(origin) - 1), values, log_time))


def scene_update(log_time: int, corners, source: str, routing=None) -> dict:
    """``foxglove.SceneUpdate`` drawing the neck from the joint corners (N, 4, 2) (A, B, C, D) m.

    ``source`` is ``"truth"`` (bars, springs and cables), ``"estimate"`` or ``"camera"`` (bars only);
    each source is one entity, replaced by the next update of the same source.  Cables follow
    ``routing`` (default the paper's) through the axes of the pulleys they wrap.
    """
    corners = np.asarray(corners, dtype=float)
    values = _scene_values(corners[None])[0]
    return orjson.loads(jsonrecords.render(_scene_template(len(corners), source, routing), values, log_time))


@dataclasses.dataclass(frozen=True)
class Batch:
    """K messages of one topic: their template, values (K, V) and log times (K,) int64 ns."""
    topic: str
    schema_name: str
    schema: dict
    template: jsonrecords.Template
    values: np.ndarray
    log_ns: np.ndarray


def visualization_batches(log_times, alphas, params: NeckParams, source: str, tf: bool) -> list[Batch]:
    """The ``/neck/scene`` (and, if ``tf``, ``/tf``) messages of poses ``alphas`` (K, N) of one source.

    The forward kinematics of all K poses is computed in one batch.
    """
    log_ns = np.asarray(log_times, dtype=np.int64)
    alphas = np.asarray(alphas, dtype=float).reshape(len(log_ns), params.n_joints)
    kin = forward_kinematics(alphas, params, allow_outside_range=True)   # a diverged estimate is still drawn
    out = [Batch(SCENE_TOPIC, "foxglove.SceneUpdate", SCENE_UPDATE_SCHEMA,
                 _scene_template(params.n_joints, source, params.routing),
                 _scene_values(kin.corners), log_ns)]
    if tf:
        out.append(Batch(TF_TOPIC, "foxglove.FrameTransforms", FRAME_TRANSFORMS_SCHEMA,
                         _frame_transforms_template(params.n_joints),
                         _frame_transform_values(kin.frame_origin, kin.frame_angle), log_ns))
    return out
