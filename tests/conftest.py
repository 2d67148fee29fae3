import numpy as np
import pytest

from neck_sim.params import default_params

# The test files that take longest (seconds of work, measured at rest with `-n 2`), longest first.
# pytest-xdist's `--dist loadfile` hands each worker whole files, the next one when it runs dry;
# collected in this order (and with `--no-loadscope-reorder`, pyproject.toml, which otherwise
# puts the files with most tests first, i.e. these last), the long files start at once and the
# short ones fill in at the end, so the two workers finish together (longest-processing-time
# first).  Order only: every file runs as before; a file missing here runs after these.
LONGEST_FIRST = (
    "test_docs.py",
    "test_identify_coverage.py",
    "test_diagnosis_verdicts.py",
    "test_output_error.py",
    "test_identify.py",
    "test_figures.py",
    "test_discovery_cli.py",
    "test_effect_open.py",
    "test_reproduce.py",
    "test_campaign_dask.py",
    "test_typing.py",
    "test_simulate_any_neck.py",
)


def pytest_collection_modifyitems(config, items):
    rank = {name: i for i, name in enumerate(LONGEST_FIRST)}
    items.sort(key=lambda item: rank.get(item.path.name, len(rank)))      # stable: files keep their test order


@pytest.fixture
def params():
    return default_params(3)


@pytest.fixture
def rng():
    return np.random.default_rng(12345)
