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

import math

import numpy as np

from neck_sim.analytic import forward_kinematics
from neck_sim.params import NeckParams, paper_routing

__all__ = ["TF_TOPIC", "SCENE_TOPIC", "FRAME_TRANSFORMS_SCHEMA", "SCENE_UPDATE_SCHEMA",
           "frame_transforms", "scene_update", "visualization_messages"]

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


def _stamp(log_time: int) -> dict:
    return {"sec": log_time // 1_000_000_000, "nsec": log_time % 1_000_000_000}


def frame_transforms(log_time: int, frame_origin, frame_angle) -> dict:
    """``foxglove.FrameTransforms`` of the bar frames: origins (N+1, 2) m and angles (N+1,) rad.

    Frames and angles are those of :class:`neck_sim.analytic.Kinematics` for one pose.
    """
    stamp = _stamp(log_time)
    out = [{"timestamp": stamp, "parent_frame_id": "world", "child_frame_id": "neck",
            "translation": {"x": 0.0, "y": 0.0, "z": 0.0}, "rotation": _PLANE_TO_Z_UP}]
    for i, ((x, y), phi) in enumerate(zip(np.asarray(frame_origin).tolist(), np.asarray(frame_angle).tolist())):
        out.append({"timestamp": stamp, "parent_frame_id": "neck", "child_frame_id": f"bar{i}",
                    "translation": {"x": x, "y": y, "z": 0.0},
                    "rotation": {"x": 0.0, "y": 0.0, "z": math.sin(phi / 2), "w": math.cos(phi / 2)}})
    return {"transforms": out}


def _line(kind: int, points, rgba, thickness: float) -> dict:
    return {"type": kind, "pose": _IDENTITY_POSE, "thickness": thickness, "scale_invariant": False,
            "points": [{"x": x, "y": y, "z": 0.0} for x, y in points],
            "color": dict(zip("rgba", rgba)), "colors": [], "indices": []}


def scene_update(log_time: int, corners, source: str, routing=None) -> dict:
    """``foxglove.SceneUpdate`` drawing the neck from the joint corners (N, 4, 2) (A, B, C, D) m.

    ``source`` is ``"truth"`` (bars, springs and cables), ``"estimate"`` or ``"camera"`` (bars only);
    each source is one entity, replaced by the next update of the same source.  Cables follow
    ``routing`` (default the paper's) through the axes of the pulleys they wrap.
    """
    corners = np.asarray(corners).tolist()
    bars, springs = [], []
    for i, (A, B, C, D) in enumerate(corners):
        if i == 0:
            bars += [A, B]
        bars += [C, D, A, D, B, C]
        springs += [A, C, B, D]
    lines = [_line(2, bars, _SOURCE_COLORS[source], 0.004)]
    if source == "truth":
        lines.append(_line(2, springs, (0.5, 0.5, 0.5, 0.6), 0.0015))
        routing = paper_routing(len(corners)) if routing is None else routing
        index = {"A": 0, "B": 1, "C": 2, "D": 3}
        for j, cable in enumerate(routing.cables):
            end = ("C" if cable.side == "left" else "D", cable.ends_at)
            path = [corners[i - 1][index[corner]] for corner, i in cable.pulleys() + (end,)]
            rgb = _LEFT_COLOR if cable.side == "left" else _CABLE_COLORS[min(j, 2)]
            lines.append(_line(0, path, (*rgb, 1.0), 0.002))
    entity = {"timestamp": _stamp(log_time), "frame_id": "neck", "id": f"neck/{source}",
              "lifetime": {"sec": 0, "nsec": 0}, "frame_locked": False,
              "metadata": [{"key": "source", "value": source}],
              "arrows": [], "cubes": [], "spheres": [], "cylinders": [], "lines": lines,
              "triangles": [], "texts": [], "models": []}
    return {"deletions": [], "entities": [entity]}


def visualization_messages(log_times, alphas, params: NeckParams, source: str, tf: bool):
    """Yield (topic, log_time, message dict) for poses ``alphas`` (K, N) of one source, in time order.

    The forward kinematics of all K poses is computed in one batch.
    """
    alphas = np.asarray(alphas, dtype=float).reshape(len(log_times), params.n_joints)
    kin = forward_kinematics(alphas, params, allow_outside_range=True)   # a diverged estimate is still drawn
    for k, ns in enumerate(log_times):
        if tf:
            yield TF_TOPIC, ns, frame_transforms(ns, kin.frame_origin[k], kin.frame_angle[k])
        yield SCENE_TOPIC, ns, scene_update(ns, kin.corners[k], source, params.routing)
