"""runs.layout.check_outside_runs, the one refusal of an output inside a run or sweep directory: train's and
eval's directories, predict's output=, the report's results= and out= (tests/cli/test_outputs_outside_runs.py)."""

import pytest

from hybrid_sysid.core.checks import ConfigError
from hybrid_sysid.runs.layout import check_outside_runs

WHERE = "a path outside run and sweep directories, whose files are their record"


@pytest.mark.parametrize("marker", ["metrics.json", "multirun.yaml", ".hydra"])
def test_an_output_inside_a_run_or_sweep_is_refused_naming_the_key_and_the_directory(tmp_path, marker):
    holder = tmp_path / "run"
    (holder / "checkpoints").mkdir(parents=True)
    (holder / marker).mkdir() if marker == ".hydra" else (holder / marker).write_text("{}")
    inside = holder / "checkpoints" / "out.csv"
    with pytest.raises(ConfigError) as caught:
        check_outside_runs("output", inside)
    assert (
        str(caught.value)
        == f"output = {inside} is not allowed: it lies inside the run or sweep directory {holder}; {WHERE}"
    )
    # a new directory is looked for from its parent: the run's own directory is not inside itself
    check_outside_runs("hydra.run.dir", tmp_path / "new", under=tmp_path)
    with pytest.raises(ConfigError, match=r"^hydra.run.dir = "):
        check_outside_runs("hydra.run.dir", holder / "new", under=holder)


def test_an_output_elsewhere_passes_and_the_error_class_is_the_callers(tmp_path):
    check_outside_runs("results", tmp_path / "results.md")
    (tmp_path / "metrics.json").write_text("{}")

    class UsageError(ConfigError):
        pass

    with pytest.raises(UsageError):
        check_outside_runs("results", tmp_path / "results.md", error=UsageError)
