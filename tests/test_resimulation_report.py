"""The summary's re-simulation line says nothing it cannot: when every block diverged open loop,
it says there is no comparison instead of printing the run-up errors as if they measured the model."""

import numpy as np

from identification.diagnosis.report import resimulation_line
from identification.diagnosis.resimulation import Resimulation, ResimulationErrors


def _resim(status, theta, n_blocks, n_diverged):
    errors = ResimulationErrors(theta, (1.0, 2.0), 1.5, 0.3)
    empty = np.zeros(0)
    return Resimulation(status, errors, errors, empty, empty, empty, empty, n_blocks=n_blocks, n_diverged=n_diverged)


def test_every_block_diverged_gives_no_comparison_and_no_numbers():
    b = _resim("diverged in 8 of 8 blocks (...): 0.6-11.0 s at 6.31 s", (16.1, 18.9), 8, 8)
    line = resimulation_line(b, b)
    assert "no comparison" in line and "8 of 8" in line
    assert "16.1" not in line and "theta RMS" not in line
    assert b.to_dict()["diverged_blocks"] == 8 and b.diverged_everywhere


def test_some_blocks_diverged_keeps_the_numbers_and_says_the_status_once():
    b = _resim("diverged in 2 of 8 blocks (...)", (0.01, 0.02), 8, 2)
    a = _resim("diverged in 2 of 8 blocks (...)", (0.005, 0.02), 8, 2)
    line = resimulation_line(b, a)
    assert not b.diverged_everywhere
    assert "theta RMS" in line and "0.01" in line and line.count("diverged in 2 of 8") == 1
    both = resimulation_line(b, _resim("ok", (0.005, 0.02), 8, 0))
    assert "diverged in 2 of 8 blocks (...) / ok" in both
