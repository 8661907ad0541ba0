"""A search's space and budget are checked before any trial (hybrid_sysid.experiments.search.check_search), both
for hparams_search (the preflight of hybrid-sysid) and experiment=tuned."""

import os
import subprocess
import sys

import pytest

from hybrid_sysid.config import ConfigError

optuna = pytest.importorskip("optuna")
from hybrid_sysid.experiments.search import check_search, search_space  # noqa: E402

GOOD = {"model.optim.lr": "tag(log, interval(0.002, 0.05))", "model.net.channels": "choice(16, 32, 48)"}


@pytest.mark.parametrize(
    "params, n_trials, match",
    [
        (GOOD, 0, r"hydra.sweeper.n_trials = 0 is not allowed: must be an integer >= 1"),
        ({"model.optim.lr": "tag(log, interval(-1, 0.05))"}, 3, r"a log interval needs bounds > 0"),
        ({"model.optim.lr": "interval(0.05, 0.01)"}, 3, r"interval\(a, b\) needs a < b"),
        ({"model.optim.lr": "choice(a, b)"}, 3, r"'a' is not of the type of model.optim.lr \(float"),
        ({"model.net.channels": "choice(16.5, 32)"}, 3, r"16.5 is not of the type of model.net.channels \(int"),
        ({"model.net.no_such": "choice(1, 2)"}, 3, r"the config has no value at model.net.no_such"),
        ({"model.optim.lr": "range(1, 4)"}, 3, r"choice\(...\) or interval\(a, b\)"),
    ],
)
def test_a_bad_space_or_budget_is_one_named_error(make_cfg, params, n_trials, match):
    with pytest.raises(ConfigError, match=match):
        check_search(make_cfg(), params, n_trials)


@pytest.mark.parametrize(
    "change, match",
    [
        ({"n_jobs": 0}, r"hydra.sweeper.n_jobs = 0 is not allowed: must be an integer >= 1"),
        ({"direction": "up"}, r"hydra.sweeper.direction = 'up' is not allowed: one of minimize, maximize"),
        ({"sampler": {"nope": 1}}, r"hydra.sweeper.sampler.nope = 1 is not allowed: a setting of the TPE sampler"),
        ({"sampler": {"seed": 0.5}}, r"hydra.sweeper.sampler.seed = 0.5 is not allowed: an integer >= 0, or null"),
        ({"sampler": {"seed": -5}}, r"hydra.sweeper.sampler.seed = -5 is not allowed: an integer >= 0, or null"),
    ],
)
def test_a_bad_parallelism_direction_or_sampler_is_one_named_error(make_cfg, change, match):
    from hybrid_sysid.experiments.search import study_settings

    settings = {"params": GOOD, "n_trials": 3, "n_jobs": 2, "direction": "minimize", "sampler": {"seed": 1}}
    study_settings(make_cfg(), settings, [])  # the settings as they are pass
    with pytest.raises(ConfigError, match=match):
        study_settings(make_cfg(), {**settings, **change}, [])


def test_a_good_space_is_the_search_space(make_cfg):
    assert check_search(make_cfg(), GOOD, 3) == search_space(GOOD)


@pytest.mark.parametrize(
    "argument, expected",
    [
        ("model.optim.lr=interval(0.01,0.05)", optuna.distributions.FloatDistribution(0.01, 0.05)),
        ("model.optim.lr=tag(log,interval(0.01,0.05))", optuna.distributions.FloatDistribution(0.01, 0.05, log=True)),
        ("model.net.channels=8,16", optuna.distributions.CategoricalDistribution([8, 16])),
    ],
)
def test_a_space_on_the_command_line_is_a_dimension_of_the_search(make_cfg, argument, expected):
    """The documented command-line space (docs/usage/search.md): Hydra cannot print a sweep back as text, which once
    broke the preflight (a warning) and then the search (a traceback)."""
    from hybrid_sysid.experiments.search import study_settings

    settings = {"params": GOOD, "n_trials": 3}
    s = study_settings(make_cfg(), settings, [argument, "objective=hybrid"])
    assert s.space[argument.split("=")[0]] == expected and s.fixed == ["objective=hybrid"]


@pytest.mark.parametrize(
    "argument, message",
    [
        ("hydra.sweeper.n_trials=0", "hydra.sweeper.n_trials = 0 is not allowed: must be an integer >= 1"),
        ("hydra.sweeper.n_jobs=0", "hydra.sweeper.n_jobs = 0 is not allowed: must be an integer >= 1"),
        ("model.net.channels=choice(16.5,32)", "16.5 is not of the type of model.net.channels"),
    ],
)
def test_a_refused_search_is_one_line_and_status_2_before_any_directory(tmp_path, cli_in_process, argument, message):
    from hybrid_sysid.cli.train import main

    sweep = tmp_path / "sweep"
    args = ["hparams_search=fast_cnn", "data=tiny", argument, f"hydra.sweep.dir={sweep}"]
    code, _, err = cli_in_process(main, *args, cwd=tmp_path)
    assert code == 2 and err.startswith("error: ") and err.count("\n") == 1 and message in err, err[-2000:]
    assert not sweep.exists() and list(tmp_path.iterdir()) == []


@pytest.mark.integration
@pytest.mark.slow  # the check itself is tested in process above; this one, the preflight's call, from a shell
def test_a_search_with_no_trials_is_refused_before_any_directory(tmp_path):
    env = {k: v for k, v in os.environ.items() if k != "HYDRA_FULL_ERROR"}
    sweep = tmp_path / "sweep"
    cli = [
        sys.executable,
        "-m",
        "hybrid_sysid",
        "hparams_search=fast_cnn",
        "data=tiny",
        "hydra.sweeper.n_trials=0",
        f"hydra.sweep.dir={sweep}",
    ]
    proc = subprocess.run(cli, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600)
    assert (
        proc.returncode == 2
        and proc.stderr.strip() == "error: hydra.sweeper.n_trials = 0 is not allowed: must be an integer >= 1"
    ), proc.stderr[-2000:]
    assert not sweep.exists()


def test_a_stored_study_of_another_search_is_refused_in_one_line(make_cfg, tmp_path, capsys, monkeypatch):
    monkeypatch.delenv("HYDRA_FULL_ERROR", raising=False)  # with it, a refusal adds its traceback
    from hybrid_sysid.experiments.search import study_settings
    from hybrid_sysid.launch.search import _own

    settings = {"params": GOOD, "n_trials": 3, "study_name": "s", "storage": "sqlite:///elsewhere.db"}
    mine = study_settings(make_cfg(), settings, ["objective=hybrid"])
    study = optuna.create_study(study_name="s")  # in memory: what matters is the attributes it holds
    _own(study, tmp_path / "a", mine)  # a new study becomes this search's
    _own(study, tmp_path / "a", mine)  # and resumes
    for sweep_dir, arguments, what in [
        (tmp_path / "b", ["objective=hybrid"], "of the search in"),
        (tmp_path / "a", ["objective=labelled"], "of other overrides or another space"),
        (tmp_path / "a", ["objective=hybrid", "model.net.kernel_size=5,7"], "of other overrides or another space"),
    ]:
        with pytest.raises(SystemExit) as exit_:
            _own(study, sweep_dir, study_settings(make_cfg(), settings, arguments))
        err = capsys.readouterr().err.strip()
        assert exit_.value.code == 2 and err.startswith("error: hydra.sweeper.storage holds study 's'") and what in err
        assert "\n" not in err


def test_each_jobs_record_becomes_its_trials_state():
    """A job's value is its record's best_score; a failed job, a job without that figure or one whose exception
    escaped is a failed trial, and the study goes on; an interrupted job's trial stays running, for the re-run."""
    from hybrid_sysid.launch.search import _tell

    class Ret:
        def __init__(self, record=None, raises=None):
            self.record, self.raises = record, raises

        @property
        def return_value(self):
            if self.raises:
                raise self.raises
            return self.record

    returns = [
        Ret({"status": "completed", "best_score": 0.25}),
        Ret({"status": "failed", "error": "RuntimeError: a failing trial"}),
        Ret({"status": "completed", "best_score": None}),
        Ret({"status": "completed", "best_score": float("nan")}),
        Ret(raises=RuntimeError("escaped")),
        Ret({"status": "interrupted", "error": "interrupted by SIGTERM"}),
    ]
    study = optuna.create_study()
    for number, ret in enumerate(returns):
        study.ask({"x": optuna.distributions.FloatDistribution(0, 1)})
        _tell(study, number, ret)
    states = [t.state.name for t in study.trials]
    assert states == ["COMPLETE", "FAIL", "FAIL", "FAIL", "FAIL", "RUNNING"]
    assert study.trials[0].value == 0.25
