"""Joint-space reference trajectories (re-exported from :mod:`neck_sim.trajectory`).

The cycloidal segments and the paper's two trajectories are defined once, in the model core,
so that the dm_control environment (:mod:`neck_sim.env`) can use them without importing
``controllers`` (layer rule).  Import them from here or from ``neck_sim.trajectory``.
"""

from neck_sim.trajectory import (HOLD_TIME, MOVE_TIME, TRAJECTORIES, Trajectory, TrajectorySample,
                                 control_test_trajectory, cycloidal_path, identification_trajectory,
                                 make_trajectory)

__all__ = ["MOVE_TIME", "HOLD_TIME", "TrajectorySample", "Trajectory", "cycloidal_path",
           "control_test_trajectory", "identification_trajectory", "TRAJECTORIES", "make_trajectory"]
