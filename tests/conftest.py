import numpy as np
import pytest

from neck_sim.params import default_params

# Wall seconds of each long test file: the sum of its tests among the 40 slowest of the last
# fresh-clone CI at rest (2 xdist workers; a lower bound for each file).  `--dist loadfile` with
# `--no-loadscope-reorder` (pyproject.toml; pytest-xdist >= 3.8) hands files to the workers in
# collection order; xdist's default orders them by their number of tests, which put the few-test,
# long files (test_reproduce.py 34 s, test_effect_open.py 25 s) among the last handed out, where one
# worker can run alone.  Longest first, the short files fill in at the end.
FILE_SECONDS = {
    "test_docs.py": 114.3,
    "test_discovery_open.py": 98.6,
    "test_any_neck.py": 87.2,
    "test_diagnosis_verdicts.py": 50.4,
    "test_discovery_cli.py": 47.6,
    "test_identify.py": 45.0,
    "test_discovery.py": 35.7,
    "test_reproduce.py": 32.3,
    "test_effect_open.py": 26.1,
    "test_figures.py": 24.4,
    "test_identify_coverage.py": 23.5,
    "test_typing.py": 22.4,
    "test_output_error_jacobian.py": 19.6,
    "test_simulate_any_neck.py": 19.0,
    "test_output_error.py": 14.2,
}


def pytest_collection_modifyitems(session, config, items):
    """Longest files first (:data:`FILE_SECONDS`), the others after them in collection order; the
    tests of a file keep their order (a stable sort on the file's key)."""
    first = {}
    for i, item in enumerate(items):
        first.setdefault(item.path.name, i)
    items.sort(key=lambda item: (-FILE_SECONDS.get(item.path.name, 0.0), first[item.path.name]))


@pytest.fixture
def params():
    return default_params(3)


@pytest.fixture
def rng():
    return np.random.default_rng(12345)
