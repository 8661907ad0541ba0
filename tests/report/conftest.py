from pathlib import Path

import pytest
from evaluation_fakes import make_sweep


@pytest.fixture(scope="module")
def sweep(tmp_path_factory) -> Path:
    """One fake sweep per test module, built once; tests may write summaries into it, never runs."""
    return make_sweep(tmp_path_factory.mktemp("runs") / "sweep")
