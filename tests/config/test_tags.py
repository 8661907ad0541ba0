"""``tags``: a run's labels (lightning-hydra-template's convention). Given as ``tags=[a,b]`` or ``'tags=["a","b"]'``,
they are recorded in metrics.json and sent to every tracker (CSV and TensorBoard hyperparameters, TensorBoard's
HPARAMS table, an MLflow tag); anything but a list of short labels is one line naming ``tags``, before any work. A
run saved before tags existed still resumes and evaluates."""

import json

import pytest
import yaml
from hydra import compose, initialize_config_dir
from omegaconf import OmegaConf

from hybrid_sysid.config import CONF_DIR, ConfigError
from hybrid_sysid.config.tags import TAG_LENGTH, TAGS_MAX, check_tags


def composed(*overrides):
    with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
        return compose(config_name="config", overrides=["data=tiny", "trainer=debug", *overrides])


def test_the_documented_limits_hold_at_their_edges():
    longest = ["t" * TAG_LENGTH] * TAGS_MAX
    assert check_tags(longest) == longest
    assert check_tags(["dt2ms", "road-E", "v1.2", "group/a", "k:8", "äöü_9"]) == [
        "dt2ms",
        "road-E",
        "v1.2",
        "group/a",
        "k:8",
        "äöü_9",
    ]
    for bad_tags in (longest + ["one"], ["t" * (TAG_LENGTH + 1)], [""], ["a b"], ["a,b"], "ab", [1], [["a"]], {"a": 1}):
        with pytest.raises(ConfigError, match=r"^tags = .* is not allowed: a list of at most 20 tags"):
            check_tags(bad_tags)


@pytest.mark.parametrize(
    "arg",
    [
        "tags=baseline",  # no list
        "tags=null",
        "tags=[[a]]",
        'tags=["a b"]',
        'tags=["x,y"]',  # a comma would split the trackers' one field
        f"tags=[{'x' * (TAG_LENGTH + 1)}]",
        f"tags=[{','.join(f't{i}' for i in range(TAGS_MAX + 1))}]",
    ],
)
def test_a_bad_tags_value_is_one_line_naming_tags_and_makes_nothing(tmp_path, cli_in_process, arg):
    from hybrid_sysid.cli.train import main

    work = tmp_path / "work"
    work.mkdir()
    env = {"HYBRID_SYSID_CACHE": tmp_path / "cache"}
    code, out, err = cli_in_process(main, "data=tiny", "trainer=debug", arg, cwd=work, env=env)
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1, err[-2000:]
    assert lines[0].startswith("error: tags "), lines[0]
    assert list(work.iterdir()) == [] and not (tmp_path / "cache").exists()


def hparams_tab(logdir) -> dict:
    """TensorBoard's HPARAMS values of the run logged in ``logdir``."""
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator
    from tensorboard.plugins.hparams import metadata

    content = EventAccumulator(str(logdir)).Reload().PluginTagToContent(metadata.PLUGIN_NAME)
    start = metadata.parse_session_start_info_plugin_data(content[metadata.SESSION_START_INFO_TAG])
    return {k: getattr(v, v.WhichOneof("kind")) for k, v in start.hparams.items()}


def test_tags_are_recorded_and_sent_to_every_tracker(tmp_path, cli_in_process, tiny_cache):
    pytest.importorskip("mlflow", reason='needs the loggers extra: pip install -e ".[loggers]"')
    pytest.importorskip("tensorboard", reason='needs the loggers extra: pip install -e ".[loggers]"')
    from mlflow import MlflowClient

    from hybrid_sysid.cli.train import main

    uri = f"sqlite:///{tmp_path / 'mlflow.db'}"
    run = tmp_path / "run"
    args = ["data=tiny", "trainer=debug", "trainer.max_steps=2", 'tags=["baseline","dt2ms"]', f"hydra.run.dir={run}"]
    trackers = ["logger=[csv,tensorboard,mlflow]", f"logger.mlflow.tracking_uri={uri}"]
    code, out, err = cli_in_process(main, *args, *trackers, cwd=tmp_path, env={"HYBRID_SYSID_CACHE": tiny_cache})
    assert code == 0, err[-2000:]
    assert json.loads((run / "metrics.json").read_text())["tags"] == ["baseline", "dt2ms"]
    hparams = yaml.safe_load((run / "csv" / "hparams.yaml").read_text())
    assert hparams["tags"] == str(["baseline", "dt2ms"])  # the resolved config's values, lists as text
    tab = hparams_tab(run / "tensorboard")
    assert tab["tags"] == "baseline,dt2ms" and tab["objective"] == "labelled"
    (found,) = MlflowClient(uri).search_runs([e.experiment_id for e in MlflowClient(uri).search_experiments()])
    assert found.data.tags["tags"] == "baseline,dt2ms" and found.data.tags["run_dir"] == str(run.resolve())


def test_a_run_without_tags_sends_no_empty_field(make_cfg, tmp_path):
    from hybrid_sysid.training.tracking import Naming
    from hybrid_sysid.training.tracking.hparams import hparams_values
    from hybrid_sysid.training.tracking.mlflow_store import run_tags

    plain, tagged = make_cfg(), make_cfg("tags=[a]")
    assert "tags" not in hparams_values(plain, Naming()) and "tags" not in run_tags(plain, Naming(), tmp_path)
    assert hparams_values(tagged, Naming())["tags"] == run_tags(tagged, Naming(), tmp_path)["tags"] == "a"


def saved_without_tags(tmp_path):
    """A run directory whose saved config was written before tags existed."""
    old = OmegaConf.to_container(composed(), resolve=False)
    del old["tags"]
    del old["schema_version"]  # saved before the schema had versions
    (tmp_path / ".hydra").mkdir()
    (tmp_path / ".hydra" / "config.yaml").write_text(yaml.safe_dump(old))
    return OmegaConf.create(old)


def test_a_run_saved_before_tags_existed_resumes_with_any_tags(tmp_path):
    from hybrid_sysid.runs.resume import check_resume
    from hybrid_sysid.runs.rundir import RunDir

    saved_without_tags(tmp_path)
    for extra in ([], ["tags=[resumed]"]):  # tags label a run; they change none of its numbers
        check_resume(RunDir(tmp_path), composed(*extra))
    with pytest.raises(ConfigError, match=r"seed"):  # what changes the numbers still refuses
        check_resume(RunDir(tmp_path), composed("seed=7"))


def test_a_run_saved_before_tags_existed_is_no_file_cut_short(tmp_path):
    """hybrid-sysid-eval reads a saved config lacking a key the schema has as a file cut short, but for keys
    added since whose default does what that run did: tags=[] is one."""
    from hybrid_sysid.cli.evaluate import lacking
    from hybrid_sysid.config import Config

    saved = saved_without_tags(tmp_path)
    merged = OmegaConf.merge(OmegaConf.structured(Config), saved)
    assert merged.tags == [] and "tags" not in lacking(saved, merged)
    del saved["seed"]  # a key that was always there, missing: cut short
    assert "seed" in lacking(saved, OmegaConf.merge(OmegaConf.structured(Config), saved))


def test_an_evaluation_keeps_the_trained_run_s_tags_or_takes_its_own(tmp_path, cli_in_process, tiny_cache, monkeypatch):
    import hybrid_sysid.report.run_figures as run_figures
    from hybrid_sysid.cli.evaluate import main

    from helpers.estimator_run import trained_run

    monkeypatch.setattr(run_figures, "write_run_figures", lambda run_dir: None)  # seconds, and not what is tested
    tiny = ["data=tiny", "trainer=debug", "trainer.max_steps=2", f"data.cache_dir={tiny_cache}"]
    run = trained_run(tmp_path / "run", [*tiny, "tags=[trained]"])
    env = {"HYBRID_SYSID_CACHE": tiny_cache}
    for name, extra, tags in (("kept", [], ["trained"]), ("own", ["tags=[soft_seat,check]"], ["soft_seat", "check"])):
        args = [f"run={run}", "car=soft_seat", *extra, f"hydra.run.dir={tmp_path / name}"]
        code, out, err = cli_in_process(main, *args, cwd=tmp_path, env=env)
        assert code == 0, err[-2000:]
        assert json.loads((tmp_path / name / "metrics.json").read_text())["tags"] == tags
