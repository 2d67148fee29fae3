import numpy as np
import pytest

from neck_sim.params import default_params


@pytest.fixture
def params():
    return default_params(3)


@pytest.fixture
def rng():
    return np.random.default_rng(12345)
