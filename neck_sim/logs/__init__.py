"""MCAP logs of neck runs: the contract, the writer and the reader.

The layout is ``docs/data-contract.md``: measured topics ``/neck/motors``,
``/neck/camera``, ``/neck/reference``, ``/neck/estimate``, the simulation-only ``/neck/truth``,
the ``neck`` metadata record of nominal constants, the ``run`` record, the MJCF attachment, plus
Foxglove's ``/tf`` (``foxglove.FrameTransforms``) and ``/neck/scene`` (``foxglove.SceneUpdate``).

    with LogWriter("logs/run.mcap", params, mjcf_xml=plant.xml, run_info={"seed": 0}) as w:
        w.motors(t, theta, force)
    log = read_log("logs/run.mcap", start=1.0, end=2.0)
    log.motors.theta            # (T, N+1) rad
"""

from neck_sim.logs.contract import LogError, TOPICS, neck_metadata, params_from_metadata
from neck_sim.logs.reader import (CameraSamples, EstimateSamples, Log, MotorSamples, ReferenceSamples,
                                  TruthSamples, read_log)
from neck_sim.logs.writer import MJCF_ATTACHMENT, LogWriter

__all__ = ["LogWriter", "read_log", "Log", "LogError", "MotorSamples", "CameraSamples", "ReferenceSamples",
           "EstimateSamples", "TruthSamples", "TOPICS", "MJCF_ATTACHMENT", "neck_metadata",
           "params_from_metadata"]
