"""The MCAP log contract of ``shared/design/measured-data.md``, written down once.

Topics (JSON messages, one jsonschema per topic; ``log_time`` = ``publish_time`` = the sample time
in integer ns since the start of the run; every message also carries ``t`` in float seconds):

=================== ================================================ ==============================
topic               fields (SI)                                      who may read it
=================== ================================================ ==============================
``/neck/motors``    t, theta [m] rad, force [m] N                    measured (required)
``/neck/camera``    t, alpha [N] rad (video, about 30 Hz)            measured
``/neck/reference`` t, alpha_d [N] rad                               measured
``/neck/estimate``  t, alpha_hat [N] rad                             measured
``/neck/truth``     t, alpha [N], alpha_dot [N] rad/s, tension [m]   simulation only
                    N, elongation [m] m
=================== ================================================ ==============================

N joints, m cables (``n_cables`` in the ``neck`` record, default N + 1; ``routing`` says which cable
is which when it is not the paper's).  A metadata record ``neck`` (strings) holds the nominal
constants the experimenter knows; it never holds friction or cable parameters.  ``NeckParams`` <-> ``neck`` record conversion lives here.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass

from neck_sim.params import NeckParams, ParameterError, Routing, default_params, paper_routing, to_dict

__all__ = ["LogError", "TopicSpec", "TOPICS", "TOPIC_BY_NAME", "NECK_RECORD", "RUN_RECORD",
           "topic_schema", "neck_metadata", "params_from_metadata", "resolve_topic"]


class LogError(ValueError):
    """A log that does not follow the contract, or cannot be read; the message names the problem."""


NECK_RECORD = "neck"
RUN_RECORD = "run"

# Per-field length: "joints" = N, "cables" = m (the routing's cable count, N + 1 by default).
_JOINTS, _CABLES = "joints", "cables"


@dataclass(frozen=True)
class TopicSpec:
    """One contract topic: short name (attribute of ``Log``), MCAP topic, schema name and fields."""

    name: str
    topic: str
    schema_name: str
    fields: tuple[tuple[str, str, str, str], ...]   # (field, length kind, unit, description)
    description: str

    def lengths(self, n_joints: int, n_cables: int | None = None) -> tuple[int, ...]:
        m = n_joints + 1 if n_cables is None else n_cables
        return tuple(n_joints if kind == _JOINTS else m for _, kind, _, _ in self.fields)

    @property
    def field_names(self) -> tuple[str, ...]:
        return tuple(f for f, _, _, _ in self.fields)


TOPICS: tuple[TopicSpec, ...] = (
    TopicSpec("motors", "/neck/motors", "neck_sim.Motors",
              (("theta", _CABLES, "rad", "motor-shaft angles, 0 at the straight rest pose, > 0 winds the cable up"),
               ("force", _CABLES, "N", "commanded cable forces f")),
              "encoders and commanded forces at the control rate"),
    TopicSpec("camera", "/neck/camera", "neck_sim.Camera",
              (("alpha", _JOINTS, "rad", "joint angles from image processing"),),
              "joint angles from video (about 30 Hz)"),
    TopicSpec("reference", "/neck/reference", "neck_sim.Reference",
              (("alpha_d", _JOINTS, "rad", "desired joint angles"),),
              "reference trajectory at the control rate"),
    TopicSpec("estimate", "/neck/estimate", "neck_sim.Estimate",
              (("alpha_hat", _JOINTS, "rad", "online estimate of the joint angles"),),
              "online joint-angle estimate at the control rate"),
    TopicSpec("truth", "/neck/truth", "neck_sim.Truth",
              (("alpha", _JOINTS, "rad", "true joint angles"),
               ("alpha_dot", _JOINTS, "rad/s", "true joint speeds"),
               ("tension", _CABLES, "N", "true cable tensions"),
               ("elongation", _CABLES, "m", "true cable elongations x_c (> 0 stretched)")),
              "simulation only: never read by analyses of measured data"),
)
TOPIC_BY_NAME = {spec.name: spec for spec in TOPICS}
_BY_TOPIC = {spec.topic: spec for spec in TOPICS}


def resolve_topic(name: str) -> TopicSpec:
    """A topic spec from its short name (``"motors"``) or MCAP topic (``"/neck/motors"``)."""
    spec = TOPIC_BY_NAME.get(name) or _BY_TOPIC.get(name)
    if spec is None:
        known = ", ".join(TOPIC_BY_NAME)
        raise LogError(f"unknown topic {name!r} (contract topics: {known})")
    return spec


def topic_schema(spec: TopicSpec, n_joints: int, n_cables: int | None = None) -> dict:
    """The jsonschema (draft 2020-12) of one topic for an N-joint neck with m cables (default N + 1)."""
    props = {"t": {"type": "number", "minimum": 0, "description": "sample time since the start of the run (s)"}}
    for (name, kind, unit, desc), n in zip(spec.fields, spec.lengths(n_joints, n_cables)):
        props[name] = {"type": "array", "items": {"type": "number"}, "minItems": n, "maxItems": n,
                       "description": f"{desc} ({unit}); index k is "
                                      f"{'cable/motor' if kind == _CABLES else 'X-joint'} k+1"}
    return {"$schema": "https://json-schema.org/draft/2020-12/schema", "title": spec.schema_name,
            "description": spec.description, "type": "object", "properties": props,
            "required": ["t", *spec.field_names]}


# ``neck`` metadata keys: key -> (params path, required). Lists are JSON arrays.
_METADATA_KEYS: dict[str, tuple[str, bool]] = {
    "n_joints": ("geometry.n_joints", True),
    "b": ("geometry.b", True),
    "L": ("geometry.L", True),
    "r": ("geometry.r", True),
    "r_d": ("actuation.r_d", True),
    "R": ("actuation.R", True),
    "I_a": ("actuation.I_a", True),
    "control_rate_hz": ("control.rate_hz", True),
    "camera_rate_hz": ("sensors.camera_rate_hz", True),
    "encoder_counts_per_turn": ("sensors.encoder_counts_per_turn", False),
    "spring_stiffness": ("springs.stiffness", False),
    "spring_rest_length": ("springs.rest_length", False),
    "bar_mass": ("inertia.bar_mass", False),
    "diagonal_mass": ("inertia.diagonal_mass", False),
    "gravity": ("inertia.gravity", False),
    "f_min": ("actuation.f_min", False),
    "f_max": ("actuation.f_max", False),
}


def _get(params: NeckParams, path: str):
    grp, fld = path.split(".")
    return getattr(getattr(params, grp), fld)


def neck_metadata(params: NeckParams) -> dict[str, str]:
    """The ``neck`` record for nominal ``params``: strings, decimal numbers, JSON lists, SI units.

    ``n_cables`` is always written; ``routing`` (the JSON list of the parameter file's
    ``routing.cables``) only when it is not the paper's routing for N.
    """
    out = {}
    for key, (path, _) in _METADATA_KEYS.items():
        value = _get(params, path)
        out[key] = json.dumps(list(value)) if isinstance(value, tuple) else repr(value)
    out["n_cables"] = repr(params.n_cables)
    if params.routing != paper_routing(params.n_joints):
        out["routing"] = json.dumps(to_dict(params)["routing"]["cables"])
    return out


def _routing_from_metadata(meta: dict[str, str], n: int) -> Routing:
    """The routing of a ``neck`` record: its ``routing`` key, else the paper's (N + 1 cables)."""
    m = n + 1
    if "n_cables" in meta:
        try:
            m = json.loads(meta["n_cables"])
        except (json.JSONDecodeError, TypeError):
            m = None
        if isinstance(m, float) and m.is_integer():
            m = int(m)
        if not isinstance(m, int) or isinstance(m, bool) or m < 1:
            raise LogError(f"metadata record {NECK_RECORD!r}: n_cables = {meta['n_cables']!r} is not an integer >= 1")
    if "routing" not in meta:
        if m != n + 1:
            raise LogError(f"metadata record {NECK_RECORD!r}: n_cables = {m} differs from the paper's N + 1 = {n + 1} "
                           "and there is no 'routing' key saying which cable is which (a JSON list of the "
                           "parameter file's routing.cables tables)")
        return paper_routing(n)
    try:
        routing = Routing(cables=json.loads(meta["routing"]))
        routing.check_joints(n)
    except (json.JSONDecodeError, TypeError) as exc:
        raise LogError(f"metadata record {NECK_RECORD!r}: key 'routing' is not a JSON list of cable tables ({exc})") from None
    except ParameterError as exc:
        raise LogError(f"metadata record {NECK_RECORD!r}: key 'routing': {exc}") from None
    if routing.n_cables != m:
        raise LogError(f"metadata record {NECK_RECORD!r}: n_cables = {m} but the routing has {routing.n_cables} cables")
    return routing


def params_from_metadata(meta: dict[str, str]) -> NeckParams:
    """NeckParams from a ``neck`` record: its keys where given, the defaults for N otherwise.

    Friction and cable parameters are never in the record: they take the defaults.  Unknown keys
    are ignored.  Raises LogError naming a missing required key or an unparsable value.
    """
    missing = [k for k, (_, req) in _METADATA_KEYS.items() if req and k not in meta]
    if missing:
        raise LogError(f"metadata record {NECK_RECORD!r}: missing required key(s) {', '.join(missing)}")
    values = {}
    for key, (path, _) in _METADATA_KEYS.items():
        if key not in meta:
            continue
        try:
            value = json.loads(meta[key])
        except (json.JSONDecodeError, TypeError):
            raise LogError(f"metadata record {NECK_RECORD!r}: key {key!r} = {meta[key]!r} is not a number "
                           "or a JSON list") from None
        numbers = value if isinstance(value, list) else [value]
        if not all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in numbers):
            raise LogError(f"metadata record {NECK_RECORD!r}: key {key!r} = {meta[key]!r} is not a finite number")
        values[path] = tuple(float(v) for v in value) if isinstance(value, list) else value
    n = values.pop("geometry.n_joints")
    if isinstance(n, float) and n.is_integer():
        n = int(n)
    if not isinstance(n, int) or n < 1:
        raise LogError(f"metadata record {NECK_RECORD!r}: n_joints = {meta['n_joints']!r} is not an integer >= 1")
    if "sensors.encoder_counts_per_turn" in values:
        c = values["sensors.encoder_counts_per_turn"]
        if not float(c).is_integer():
            raise LogError(f"metadata record {NECK_RECORD!r}: encoder_counts_per_turn = {c!r} is not an integer")
        values["sensors.encoder_counts_per_turn"] = int(c)
    routing = _routing_from_metadata(meta, n)
    try:
        return default_params(n, routing).replace(**values)
    except ParameterError as exc:
        raise LogError(f"metadata record {NECK_RECORD!r}: {exc}") from None
