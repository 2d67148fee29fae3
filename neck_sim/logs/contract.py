"""The MCAP log contract of ``docs/data-contract.md``, written down once.

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
from typing import Any

import numpy as np

from neck_sim.params import NeckParams, ParameterError, default_params, to_dict
from neck_sim.routing import Routing, paper_routing

__all__ = ["LogError", "TopicSpec", "TOPICS", "TOPIC_BY_NAME", "NECK_RECORD", "RUN_RECORD",
           "topic_schema", "neck_metadata", "params_from_metadata", "resolve_topic", "check_plausible",
           "record_value"]


class LogError(ValueError):
    """A log that does not follow the contract, or cannot be read; the message names the problem."""


NECK_RECORD = "neck"
RUN_RECORD = "run"


def record_value(raw: Any) -> Any:
    """A ``run`` record value as the log holds it: JSON text decoded, the raw string when it is not
    JSON, anything that is not text (None for an absent key) as it is."""
    if not isinstance(raw, str):
        return raw
    try:
        return json.loads(raw)
    except json.JSONDecodeError:
        return raw

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
    m: Any = n + 1                 # whatever the record holds, until checked below
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
    values: dict[str, Any] = {}
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


# -- plausibility of measured data against the ``neck`` record ------------------------------------
# A unit mistake (ms for s, degrees for rad, mN for N) passes every structural check and gives a
# confident wrong answer downstream, so measured topics are compared with the record's constants.

RATE_FACTOR = 1.5            # median sample rate within [1/1.5, 1.5] x the declared rate
ANGLE_MARGIN = 0.1           # rad beyond alpha_max tolerated (camera noise at the joint limit)
_RATE_KEYS = {"motors": ("control_rate_hz", "control", "rate_hz"),
              "camera": ("camera_rate_hz", "sensors", "camera_rate_hz")}
_ANGLE_FIELDS = {"camera": "alpha", "reference": "alpha_d"}
_TIME_UNITS = ((1e-3, "milliseconds"), (1e-6, "microseconds"), (1e-9, "nanoseconds"))


def _rate_problem(spec: TopicSpec, t: np.ndarray, params: NeckParams) -> str | None:
    key, group, name = _RATE_KEYS[spec.name]
    if len(t) < 2:
        return None
    declared = float(getattr(getattr(params, group), name))
    dt = float(np.median(np.diff(t)))
    measured = 1.0 / dt
    ratio = measured / declared
    if 1 / RATE_FACTOR <= ratio <= RATE_FACTOR:
        return None
    cause = next((f"times look like {unit} (the contract wants seconds)" for scale, unit in _TIME_UNITS
                  if scale / 3 <= ratio <= scale * 3), None)
    if cause is None:
        cause = (f"the record's {key} is wrong, or the topic's samples are "
                 + ("missing (gaps)" if ratio < 1 else "duplicated or in a finer time unit"))
    return (f"{spec.topic}: samples 0-{len(t) - 1} (t = {float(t[0]):.6g} .. {float(t[-1]):.6g}) are {dt:.4g} s apart "
            f"(median), a rate of {measured:.4g} Hz, but the {NECK_RECORD!r} record declares {key} = "
            f"{declared:g} Hz: {cause}")


def _angle_problem(spec: TopicSpec, t: np.ndarray, alpha: np.ndarray, params: NeckParams) -> str | None:
    field_name = _ANGLE_FIELDS[spec.name]
    alpha_max = params.geometry.alpha_max
    limit = alpha_max + ANGLE_MARGIN
    bad = np.abs(alpha) > limit
    if not bad.any():
        return None
    i, j = (int(v) for v in np.argwhere(bad)[0])
    worst = float(np.abs(alpha).max())
    # up to a half turn a joint angle in radians is still possible (a neck bent past its range);
    # beyond it, values that would fit the range in degrees are most likely degrees
    cause = ("the neck bent past its joint range (did the run leave the workspace?)" if worst <= math.pi
             else "angles look like degrees (the contract wants radians)" if worst <= math.degrees(limit)
             else "these are not joint angles in radians (wrong column or units?)")
    return (f"{spec.topic}: sample {i} (t = {float(t[i]):.6g} s): {field_name}{j + 1} = {float(alpha[i, j]):.6g} rad "
            f"is outside the joint range |alpha| <= alpha_max = {alpha_max:.4g} rad (largest |value| {worst:.4g}): "
            f"{cause}")


def max_motor_angle(params: NeckParams) -> float:
    """Largest plausible |theta| (rad at the motor shaft): the motor winding a whole neck's height of
    cable, R / r_d x N (L + b + pi r).  Beyond it no cable exists to wind."""
    g, a = params.geometry, params.actuation
    return a.R / a.r_d * g.n_joints * (g.L + g.b + math.pi * g.r)


def _encoder_problem(spec: TopicSpec, t: np.ndarray, theta: np.ndarray, params: NeckParams) -> str | None:
    """Encoders in degrees or counts: a motor angle winding more cable than the neck holds."""
    limit = max_motor_angle(params)
    worst = np.abs(theta).max(axis=0) if theta.size else np.zeros(0)
    if not (worst > limit).any():
        return None
    j = int(np.argmax(worst))
    i = int(np.argmax(np.abs(theta[:, j])))
    value = float(worst[j])
    counts = params.sensors.encoder_counts_per_turn
    integers = bool(np.all(theta == np.round(theta)))       # raw encoder counts are whole numbers
    if integers and value * 2 * math.pi / counts <= limit:
        cause = f"looks like encoder counts ({counts} per turn: {value * 2 * math.pi / counts:.4g} rad), expected rad"
    elif value / math.degrees(1.0) <= limit:
        cause = f"looks like degrees ({value:.6g} deg = {math.radians(value):.4g} rad), expected rad"
    else:
        cause = "these are not motor-shaft angles in radians (wrong column or units?)"
    return (f"{spec.topic}: encoder theta{j + 1} reaches {float(theta[i, j]):.6g} at sample {i} "
            f"(t = {float(t[i]):.6g} s): {cause}; R/r_d x N (L + b + pi r) = {limit:.4g} rad would wind a whole "
            "neck's height of cable")


def _force_unit_problem(spec: TopicSpec, t: np.ndarray, force: np.ndarray, params: NeckParams) -> str | None:
    """Forces in kN: every commanded force below f_max / 1000 (and not all zero)."""
    a = params.actuation
    if not force.size:
        return None
    top = float(np.abs(force).max())
    if not 0 < top <= a.f_max / 1000:
        return None
    return (f"{spec.topic}: every commanded force is at most {top:.4g} N ({len(t)} samples) while the record's "
            f"f_max = {a.f_max:g} N and t_min = {a.t_min:g} N: forces look like kilonewtons, expected N")


def _force_problem(spec: TopicSpec, t: np.ndarray, force: np.ndarray, params: NeckParams) -> str | None:
    f_max = params.actuation.f_max
    tol = 1e-9 * f_max
    bad = (force < -tol) | (force > f_max + tol)
    if not bad.any():
        return None
    i, j = (int(v) for v in np.argwhere(bad)[0])
    value = float(force[i, j])
    if value < 0:
        cause = "a cable can only pull (sign convention or a force-sensor offset?)"
    elif float(np.median(force)) > f_max:
        cause = "forces look like they are in another unit (mN?) (the contract wants newtons)"
    else:
        cause = "spikes beyond the actuators' limit f_max"
    return (f"{spec.topic}: sample {i} (t = {float(t[i]):.6g} s): force{j + 1} = {value:.6g} N is outside "
            f"[0, f_max] = [0, {f_max:g}] N ({int(bad.any(axis=1).sum())} of {len(t)} samples): {cause}")


STALE_SECONDS = 1.0          # a commanded force bit-identical this long while its motor turns is stale
STALE_MOTION_COUNTS = 20     # encoder counts its motor must move meanwhile
MIN_CAMERA_FRAMES = 8        # what identification's camera filter and resampling need


def _stale_force_problem(spec: TopicSpec, t: np.ndarray, theta: np.ndarray, force: np.ndarray,
                         params: NeckParams) -> str | None:
    """A force channel that never changes (bit-identical, away from 0 and the limits) over at
    least ``STALE_SECONDS`` while its motor turns: a stale force logger, not a command."""
    a = params.actuation
    if len(t) < 2 or float(t[-1] - t[0]) < STALE_SECONDS:
        return None
    moved = np.ptp(theta, axis=0) > STALE_MOTION_COUNTS * params.sensors.encoder_resolution
    first = force[0]
    at_limit = (np.abs(first) <= 1e-9 * a.f_max) | (np.abs(first - a.f_min) <= 1e-9 * a.f_max) | (
        np.abs(first - a.f_max) <= 1e-9 * a.f_max)
    stuck = np.all(force == first, axis=0) & moved & ~at_limit
    if not stuck.any():
        return None
    j = int(np.flatnonzero(stuck)[0])
    return (f"{spec.topic}: force{j + 1} = {float(first[j]):.6g} N in all {len(t)} samples "
            f"(t = {float(t[0]):.6g} .. {float(t[-1]):.6g} s) while theta{j + 1} moves over "
            f"{float(np.ptp(theta[:, j])):.4g} rad: a stale force logger (a commanded force never stays "
            "bit-identical while its motor turns); fix the force logging and record again")


def _stuck_camera_problem(spec: TopicSpec, t: np.ndarray, alpha: np.ndarray, params: NeckParams) -> str | None:
    """A camera whose frames are all bit-identical although it has noise (``camera_noise`` > 0)."""
    if len(t) < MIN_CAMERA_FRAMES or params.sensors.camera_noise <= 0 or not np.all(alpha == alpha[0]):
        return None
    values = ", ".join(f"{v:.4g}" for v in alpha[0])
    return (f"{spec.topic}: the camera is stuck: every one of its {len(t)} frames (t = {float(t[0]):.6g} .. "
            f"{float(t[-1]):.6g} s) reads alpha = [{values}] rad, while a working camera has noise of "
            f"about camera_noise = {math.degrees(params.sensors.camera_noise):.3g} deg; check the camera and "
            "its tracking, and record again")


def check_plausible(spec: TopicSpec, fields: dict, params: NeckParams, *,
                    accept_out_of_range_forces: bool = False, simulated: bool = False) -> tuple[str, ...]:
    """Compare a measured topic with the ``neck`` record: sample rates (motors, camera), joint
    angles within |alpha| <= alpha_max + 0.1 rad (camera, reference), commanded forces in
    [0, f_max] (motors); units (encoders in degrees or counts, forces in kN); stuck sensors (a
    force channel bit-identical for a second while its motor turns, a camera whose frames are
    all identical).

    ``fields``: ``t`` (T,) s and the topic's (T, n) arrays.  Raises LogError naming the topic, the
    sample and the likely cause (times in ms, angles in degrees, ...).  ``simulated`` (the log has
    /neck/truth): no stuck-sensor checks, its forces are what neck-sim commanded (an environment
    may hold an action constant), not a logger's record.  With
    ``accept_out_of_range_forces`` an out-of-range force is returned as a warning instead.
    """
    t = fields["t"]
    problems = []
    if spec.name in _RATE_KEYS:
        problems.append(_rate_problem(spec, t, params))
    if spec.name in _ANGLE_FIELDS:
        problems.append(_angle_problem(spec, t, fields[_ANGLE_FIELDS[spec.name]], params))
    if spec.name == "camera" and not simulated:
        problems.append(_stuck_camera_problem(spec, t, fields["alpha"], params))
    if spec.name == "motors" and not simulated:
        problems.append(_stale_force_problem(spec, t, fields["theta"], fields["force"], params))
        problems.append(_encoder_problem(spec, t, fields["theta"], params))
        problems.append(_force_unit_problem(spec, t, fields["force"], params))
    problems = [p for p in problems if p]
    if problems:
        raise LogError(problems[0])
    if spec.name == "motors":
        force = _force_problem(spec, t, fields["force"], params)
        if force:
            if not accept_out_of_range_forces:
                raise LogError(force + " (an explicit option accepts them, e.g. --accept-out-of-range-forces)")
            return (f"accepted out-of-range forces: {force}",)
    return ()
