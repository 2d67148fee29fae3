"""Workflows as a Python API: the composition layer (with :mod:`neck_sim.cli`) that may import
``controllers`` and ``identification``; the command line only parses arguments and calls these.

* :func:`reproduce` -- the paper, end to end, in simulation (``neck-sim reproduce``).
"""

from neck_sim.experiments.reproduce import ReproduceSettings, Reproduction, paper_runs, reproduce, run_experiments

__all__ = ["ReproduceSettings", "Reproduction", "reproduce", "paper_runs", "run_experiments"]
