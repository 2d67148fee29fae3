"""Identification of a neck from its logs: the paper's section 5 and the diagnosis.

:func:`identify_log` runs the paper's identification (§5.3-5.5: dry friction, cable stiffness,
Tables 1 and 2, the reconstruction errors) on a log's measured topics (motors and camera) and
:func:`format_tables` prints it beside the paper's numbers (:data:`PAPER`).  :func:`diagnose_log`
asks what the model still lacks: it adds candidate physical effects to a baseline model and keeps
those the held-out data support (:class:`Diagnosis`).  :func:`excitation_quality` and
:func:`optimise_identification_trajectory` judge and design the excitation before a run.

Usage::

    import neck_sim
    from controllers import ComputedTorqueController, make_trajectory, run_closed_loop
    from identification import IdentificationSettings, identify_log

    params = neck_sim.default_params(3)
    trajectory = make_trajectory("identification", params, duration_scale=0.2)   # 17 s
    run_closed_loop(neck_sim.Plant(params, seed=0), ComputedTorqueController(params, law=1), trajectory,
                    log_path="ident.mcap", progress=False)      # a measured log, as from a prototype
    log = neck_sim.read_log("ident.mcap", topics=("motors", "camera"))
    result = identify_log(log, IdentificationSettings(bootstrap=0))     # no bootstrap: seconds
    print(result.f_s, params.friction.f_s)                      # dry friction per cable (N) vs the truth

``format_tables(result, truth=params)`` prints Tables 1 and 2 beside the paper's;
``diagnose_log(log)`` names the effects the paper's model lacks (about a minute on this log).

Names are imported when first used (PEP 562): ``import identification`` loads neither SciPy nor
MuJoCo.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from neck_sim.lazy import lazy_attributes

if TYPE_CHECKING:
    from identification.diagnosis import Diagnosis, DiagnosisSettings, diagnose, diagnose_log
    from identification.excitation import excitation_quality, optimise_identification_trajectory
    from identification.paper import (PAPER, IdentificationResult, IdentificationSettings, format_tables, identify,
                                      identify_log)
    from identification.preprocessing import Measurements, prepare
    from identification.simulator import compare_simulators, identified_params

__all__ = ["identify_log", "identify", "IdentificationSettings", "IdentificationResult", "format_tables", "PAPER",
           "Measurements", "prepare", "identified_params", "compare_simulators",
           "diagnose_log", "diagnose", "Diagnosis", "DiagnosisSettings",
           "excitation_quality", "optimise_identification_trajectory"]

# exported name -> the module that defines it
_SOURCES: dict[str, str] = {
    **dict.fromkeys(("identify_log", "identify", "IdentificationSettings", "IdentificationResult", "format_tables",
                     "PAPER"), "identification.paper"),
    "Measurements": "identification.preprocessing", "prepare": "identification.preprocessing",
    "identified_params": "identification.simulator", "compare_simulators": "identification.simulator",
    **dict.fromkeys(("diagnose_log", "diagnose", "Diagnosis", "DiagnosisSettings"), "identification.diagnosis"),
    "excitation_quality": "identification.excitation",
    "optimise_identification_trajectory": "identification.excitation",
}

__getattr__, __dir__ = lazy_attributes(__name__, _SOURCES, __all__)
