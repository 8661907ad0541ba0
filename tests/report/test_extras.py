"""report.extras: every experiment preset decides what it adds to its report (EXTRAS or NO_EXTRAS), and the
experiment a sweep's runs recorded selects its extras; runs that recorded none, or one not named there, fall back
to the extras whose row key is a level of the table's rows."""

from pathlib import Path

import pytest

from hybrid_sysid.config import CONF_DIR
from hybrid_sysid.report.collect import load_runs
from hybrid_sysid.report.extras import ANCHORED, EXTRAS, NO_EXTRAS, SCENARIOS, TUNED
from hybrid_sysid.report.summary import tested_table as with_extras
from hybrid_sysid.report.summary import write_summary
from hybrid_sysid.report.tables import compared_level

from helpers.evaluation_fakes import known_results, make_run


def undecided(presets: set[str]) -> set[str]:
    return presets - set(EXTRAS) - set(NO_EXTRAS)


def test_every_experiment_preset_is_in_extras_or_declared_without():
    presets = {p.stem for p in (Path(CONF_DIR) / "experiment").glob("*.yaml")}
    assert {"anchored", "robustness", "transfer", "tuned"} <= presets  # the glob found the presets
    assert not undecided(presets), f"conf/experiment presets missing from report/extras.py: {undecided(presets)}"
    assert not set(EXTRAS) & set(NO_EXTRAS), "a preset both with and without extras"
    stale = (set(EXTRAS) | set(NO_EXTRAS)) - presets
    assert not stale, f"report/extras.py names experiments without a conf/experiment preset: {stale}"
    # the check fails for a preset nobody decided on
    assert undecided(presets | {"new_preset"}) == {"new_preset"}


def test_the_extras_are_of_the_experiments_own_kind():
    # anchored's variants draw by estimator, transfer's and field's by scenario, tuned's by tuning
    assert EXTRAS["anchored"] == EXTRAS["anchored_clean"] == (ANCHORED,)
    assert EXTRAS["transfer"] == EXTRAS["field"] == (SCENARIOS,)
    assert EXTRAS["tuned"] == (TUNED,)
    assert (ANCHORED.row_key, SCENARIOS.row_key, TUNED.row_key) == ("estimator", "scenario", "tuning")


def make_sweep(root: Path, experiment: str | None) -> Path:
    """2 faults x 2 estimators x 2 seeds, rows (fault, estimator), recorded with ``experiment`` (None: none)."""
    for fault in ("clean", "skewed"):
        for estimator, value in (("ls", 0.02), ("eiv", 0.05)):
            for seed in (0, 1):
                overrides = [f"fault={fault}", f"estimator={estimator}", f"seed={seed}"]
                make_run(
                    root / f"{fault}_{estimator}_{seed}",
                    overrides + ([f"experiment={experiment}"] if experiment else []),
                    seed,
                    results=known_results({("test", 0.0, p): value + 0.001 * seed for p in ("p1", "p2")}),
                )
    return root


@pytest.mark.parametrize(
    "experiment, extras, level",
    [
        ("anchored_clean", (ANCHORED,), "estimator"),  # from the dict
        ("robustness", (), "fault"),  # the dict says none, whatever the rows: the first row level is compared
        (None, (ANCHORED,), "estimator"),  # no experiment recorded: by the table's row levels
        ("my_lab_preset", (ANCHORED,), "estimator"),  # an experiment the dict does not name: likewise
    ],
)
def test_the_recorded_experiment_selects_the_extras(tmp_path, experiment, extras, level):
    root, df = load_runs(make_sweep(tmp_path / "sweep", experiment))
    table = with_extras(df, root)
    assert list(table.index.names) == ["fault", "estimator"]
    assert table.attrs["extras"] == extras
    assert compared_level(table) == level


def test_an_extra_applies_only_where_its_row_key_is_a_row_level(tmp_path):
    # experiment=transfer declares the scenario figure, but these rows have no scenario level: nothing to draw by
    root, df = load_runs(make_sweep(tmp_path / "sweep", "transfer"))
    assert with_extras(df, root).attrs["extras"] == ()


def test_the_summary_draws_the_dicts_figures_alone(tmp_path):
    drawn = make_sweep(tmp_path / "anchored", "anchored")
    write_summary(drawn)
    assert (drawn / "figures" / "anchored.png").is_file()
    declared_none = make_sweep(tmp_path / "robustness", "robustness")
    write_summary(declared_none)
    assert (declared_none / "figures" / "robustness.png").is_file()  # the shared figures are drawn
    assert not (declared_none / "figures" / "anchored.png").exists()
