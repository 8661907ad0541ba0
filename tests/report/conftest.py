from pathlib import Path

import pytest

from hybrid_sysid.report import anchored_figure, plotting, run_figures, sweep_figures, transfer_figure, tuning

from helpers.evaluation_fakes import make_sweep


@pytest.fixture(scope="module")
def sweep(tmp_path_factory) -> Path:
    """One fake sweep per test module, built once; tests may write summaries into it, never runs."""
    return make_sweep(tmp_path_factory.mktemp("runs") / "sweep")


@pytest.fixture
def drawn(monkeypatch) -> dict:
    """The figures the report code draws, by the name of the file they go to ("robustness" for
    figures/robustness.png, also when written through a temporary name), still written to that file: a test
    asserts on the Figure what a reader sees."""
    figures, real = {}, plotting.save_figure

    def save(fig, path, title):
        real(fig, path, title)
        figures[Path(path).name.lstrip(".").split(".")[0]] = fig

    for module in (plotting, run_figures, sweep_figures, anchored_figure, transfer_figure, tuning):
        monkeypatch.setattr(module, "save_figure", save)
    return figures
