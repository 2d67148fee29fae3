"""Which plant: the one value that says it, builds it, goes into a log's ``run`` record and back.

    from neck_sim.plant_spec import PlantSpec
    spec = PlantSpec(params, effects, seed=3, rigid_cables=True)
    plant = spec.build()                                    # a neck_sim.plant.Plant
    LogWriter(path, params, run_info=spec.to_record())      # what `neck-sim replay` rebuilds from
    same = PlantSpec.from_record(read_log(path).run_info)   # steps bit-identically to ``plant``

A :class:`PlantSpec` is a frozen, picklable value (parameters, effects, camera seed, physics
timestep, cable model, backend, integrator): it travels to campaign workers
(:mod:`controllers.parallel`) and every loop that drives a plant builds it from one.  The ``run``
record keeps the keys and values it has always had (``seed``, ``effects``, ``plant_params``,
``timestep``, ``rigid_cables``), so logs written before this module still replay.  The backend
is not recorded: the native and Python backends give the same run (``tests/test_plant.py``).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Mapping

from neck_sim.effects import Effects
from neck_sim.logs.contract import record_value
from neck_sim.params import NeckParams, default_params, from_dict, to_dict

if TYPE_CHECKING:
    from neck_sim.plant import Plant

__all__ = ["PlantSpec", "RECORD_KEYS"]

RECORD_KEYS = ("seed", "effects", "plant_params", "timestep", "rigid_cables", "integrator")
"""Keys of the ``run`` record a PlantSpec writes (``integrator`` only when one was chosen)."""


@dataclass(frozen=True)
class PlantSpec:
    """One simulated plant, as a value.

    ``params``: the plant's constants (default ``default_params(3)``); ``effects``: its hidden
    effects (default none); ``seed``: the camera-noise seed; ``timestep``: the physics step, s
    (None: :data:`neck_sim.mjcf.DEFAULT_TIMESTEP`; must divide the control period);
    ``rigid_cables``: the paper's rigid cable model (eq 25/32, x_c = 0) instead of the elastic one
    (eq 54); ``backend``: "native", "python" or None (the process default); ``integrator``: None
    for the plant's default choice.
    """

    params: NeckParams = field(default_factory=lambda: default_params(3))
    effects: Effects = field(default_factory=Effects)
    seed: int = 0
    timestep: float | None = None
    rigid_cables: bool = False
    backend: str | None = None
    integrator: str | None = None

    def __post_init__(self):
        params = default_params(3) if self.params is None else self.params
        if not isinstance(params, NeckParams):
            raise ValueError(f"params: expected NeckParams, got {type(params).__name__}")
        effects = Effects() if self.effects is None else self.effects
        if not isinstance(effects, Effects):
            raise ValueError(f"effects: expected neck_sim.effects.Effects, got {type(effects).__name__}")
        if isinstance(self.seed, bool) or not isinstance(self.seed, (int, float)) or self.seed != int(self.seed):
            raise ValueError(f"seed: expected an integer, got {self.seed!r}")
        timestep = self.timestep
        if timestep is not None:
            if isinstance(timestep, bool) or not isinstance(timestep, (int, float)) or not math.isfinite(timestep):
                raise ValueError(f"timestep: expected a finite number of seconds or None, got {timestep!r}")
            timestep = float(timestep)
        for name in ("backend", "integrator"):
            value = getattr(self, name)
            if value is not None and not isinstance(value, str):
                raise ValueError(f"{name}: expected a name or None, got {value!r}")
        object.__setattr__(self, "params", params)
        object.__setattr__(self, "effects", effects)
        object.__setattr__(self, "seed", int(self.seed))
        object.__setattr__(self, "timestep", timestep)
        object.__setattr__(self, "rigid_cables", bool(self.rigid_cables))

    # -- plants --------------------------------------------------------------------------------
    def build(self) -> "Plant":
        """A fresh :class:`neck_sim.plant.Plant` of this spec (at rest, straight, time 0)."""
        from neck_sim.plant import Plant

        extra = {} if self.integrator is None else {"integrator": self.integrator}
        return Plant(self.params, self.effects, seed=self.seed, timestep=self.timestep,
                     rigid_cables=self.rigid_cables, backend=self.backend, **extra)

    @classmethod
    def of(cls, plant: "Plant") -> "PlantSpec":
        """The spec of a built plant (its timestep resolved, its backend as it runs, its
        integrator as it was asked for: None when the plant chose it from c_a)."""
        return cls(plant.params, plant.effects, seed=plant.seed, timestep=plant.timestep,
                   rigid_cables=plant.rigid_cables, backend=getattr(plant, "backend", None),
                   integrator=getattr(plant, "integrator", None))

    def replace(self, **changes: Any) -> "PlantSpec":
        """A copy with fields replaced (``spec.replace(seed=2)``)."""
        return dataclasses.replace(self, **changes)

    # -- the run record ------------------------------------------------------------------------
    def to_record(self) -> dict[str, Any]:
        """The ``run`` record entries of this plant (pass them in LogWriter's ``run_info``): seed,
        effects (``Effects.to_dict``), plant_params (``params.to_dict``), timestep (s, resolved),
        rigid_cables, and integrator when one was chosen."""
        from neck_sim.mjcf import DEFAULT_TIMESTEP

        record = {"seed": self.seed, "effects": self.effects.to_dict(), "plant_params": to_dict(self.params),
                  "timestep": DEFAULT_TIMESTEP if self.timestep is None else self.timestep,
                  "rigid_cables": self.rigid_cables}
        if self.integrator is not None:
            record["integrator"] = self.integrator
        return record

    @classmethod
    def from_record(cls, record: Mapping[str, Any], *, nominal: NeckParams | None = None) -> "PlantSpec":
        """The spec a ``run`` record describes: the record as read (``Log.run_info``, values as
        JSON text) or as written (:meth:`to_record`).  Entries a record lacks take their defaults
        (``nominal`` for the parameters); :meth:`read_record` also says which."""
        return cls.read_record(record, nominal=nominal)[0]

    @classmethod
    def read_record(cls, record: Mapping[str, Any], *,
                    nominal: NeckParams | None = None) -> tuple["PlantSpec", dict[str, str]]:
        """(spec, assumptions) of a ``run`` record: ``assumptions`` maps each field the record
        did not give ("params", "effects", "seed") to a sentence saying what was assumed.  A record
        without ``plant_params`` needs ``nominal`` (the ``neck`` record's constants); a value of
        the wrong kind raises ValueError naming the key."""
        if not isinstance(record, Mapping):
            raise ValueError(f"run record: expected a mapping, got {type(record).__name__}")
        value = {key: record_value(record.get(key)) for key in RECORD_KEYS}
        notes = {}
        params = value["plant_params"]
        if params is None:
            if nominal is None:
                raise ValueError("run record has no plant_params and no nominal parameters were given")
            params = nominal
            notes["params"] = "run record has no plant_params: using the nominal constants of the neck record"
        elif isinstance(params, Mapping):
            params = from_dict(params)
        else:
            raise ValueError(f"run record plant_params: expected a mapping of parameter groups, got {params!r:.60}")
        effects = value["effects"]
        if effects is None:
            effects = Effects()
            notes["effects"] = "run record has no effects: assuming none"
        elif isinstance(effects, Mapping):
            effects = Effects.from_dict(effects)
        else:
            raise ValueError(f"run record effects: expected a mapping of effect settings (Effects.to_dict), "
                             f"got {effects!r:.60}")
        seed = value["seed"]
        if isinstance(seed, (int, float)) and not isinstance(seed, bool):
            seed = int(seed)
        else:
            notes["seed"] = f"run record seed = {seed!r}: using seed 0 (it only changes the camera noise)"
            seed = 0
        timestep = value["timestep"]
        if timestep is not None and (isinstance(timestep, bool) or not isinstance(timestep, (int, float))):
            raise ValueError(f"run record timestep: expected seconds, got {timestep!r}")
        return cls(params, effects, seed=seed, timestep=timestep, rigid_cables=bool(value["rigid_cables"] or False),
                   integrator=value["integrator"]), notes

