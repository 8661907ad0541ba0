"""One run end to end, in process: the record, its files, and reproducibility."""

import json

import numpy as np
import pandas as pd
import pytest
import torch

from hybrid_sysid.report.run_figures import write_run_figures
from hybrid_sysid.training.build import build_model
from hybrid_sysid.training.run import train

TINY = ["data=tiny", "trainer=debug", "noise.eval_std=[0.0,0.05]"]


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    from hydra import compose, initialize_config_dir

    from hybrid_sysid.config import CONF_DIR

    tmp = tmp_path_factory.mktemp("run")
    with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
        cfg = compose(
            config_name="config", overrides=[*TINY, f"data.cache_dir={tmp / 'cache'}", "trainer.progress_bar=false"]
        )
    return train(cfg, tmp / "run", overrides=TINY), tmp / "run"


def test_record_follows_the_schema(tiny_run):
    record, run_dir = tiny_run
    on_disk = json.loads((run_dir / "metrics.json").read_text())
    assert on_disk == json.loads(json.dumps(record))
    assert on_disk["status"] == "completed" and on_disk["error"] is None
    assert on_disk["overrides"] == TINY and on_disk["seed"] == 0 and on_disk["steps"] == 20
    keys = {(r["split"], r["noise_std"], r["parameter"]) for r in on_disk["results"]}
    expected = {
        (s, n, p) for s, n in [("train", 0.0), ("val", 0.0), ("test", 0.0), ("test", 0.05)] for p in ("p1", "p2")
    }
    assert keys == expected
    for r in on_disk["results"]:
        assert r["mean_rel_dev"] >= 0 and r["std_rel_dev"] >= 0 and r["n"] > 0
        assert r["windows"] == 1  # evaluation.windows defaults to [1]


def test_predictions_and_curves_agree_with_the_record(tiny_run):
    record, run_dir = tiny_run
    pred = pd.read_csv(run_dir / "predictions.csv")
    assert (pred.windows == 1).all()
    for r in record["results"]:
        sub = pred[(pred.split == r["split"]) & (pred.noise_std == r["noise_std"])]
        p = r["parameter"]
        dev = (sub[f"{p}_true"] - sub[f"{p}_pred"]).abs() / sub[f"{p}_true"]
        assert len(sub) == r["n"]
        assert dev.mean() == pytest.approx(r["mean_rel_dev"], rel=1e-9)
    curves = pd.read_csv(run_dir / "curves.csv")
    assert sorted(curves.step.unique()) == [10, 20]
    assert set(curves.split) == {"train", "test"} and set(curves.noise_std) == {0.0, 0.05}
    write_run_figures(run_dir)  # the app draws them from the two files once train() returns
    for name in ("learning_curves.png", "test_predictions.png"):
        assert (run_dir / "figures" / name).stat().st_size > 10_000


def test_same_seed_same_numbers_other_seed_other_numbers(make_cfg, tmp_path, tiny_run):
    record, _ = tiny_run
    again = train(make_cfg(*TINY), tmp_path / "again")
    assert again["results"] == record["results"]
    other = train(make_cfg(*TINY, "seed=1"), tmp_path / "other")
    assert other["results"] != record["results"]


def test_a_run_puts_torchs_thread_count_back(make_cfg, tmp_path):
    """A run with trainer.threads = 1 trains on one thread (its record says so) and leaves the process on the
    count it had; the next run without the key then runs on that count, as in a new process."""
    import torch

    torch.set_num_threads(2)  # not the one a pinned run takes (the suite runs on one); the autouse fixture restores
    before = torch.get_num_threads()
    pinned = train(make_cfg(*TINY, "trainer.max_steps=2", "trainer.threads=1"), tmp_path / "pinned")
    assert pinned["threads"] == 1 and torch.get_num_threads() == before
    default = train(make_cfg(*TINY, "trainer.max_steps=2"), tmp_path / "default")
    assert default["threads"] == before


def test_k_windows_add_test_rows_and_leave_the_k1_rows_unchanged(make_cfg, tmp_path, tiny_run):
    record, _ = tiny_run
    run = train(make_cfg(*TINY, "evaluation.windows=[1,4]"), tmp_path / "k")
    k1 = [r for r in run["results"] if r["windows"] == 1]
    assert k1 == record["results"]  # same training, same K = 1 windows and noise: bit for bit
    k4 = [r for r in run["results"] if r["windows"] == 4]
    assert {(r["split"], r["noise_std"]) for r in k4} == {("test", 0.0), ("test", 0.05)}
    pred = pd.read_csv(tmp_path / "k" / "predictions.csv")
    assert sorted(pred[pred.split == "test"].windows.unique()) == [1, 4]
    assert sorted(pred[pred.split != "test"].windows.unique()) == [1]
    write_run_figures(tmp_path / "k")
    assert (tmp_path / "k" / "figures" / "test_predictions.png").stat().st_size > 10_000


def test_a_nan_loss_stops_the_run_and_records_why(tmp_path, tiny_cache, cli_in_process, monkeypatch):
    # the command's main() in this process: the app records the failure of its job and exits non-zero. No allowed
    # value makes the loss NaN (a learning rate that would is refused: model.optim.lr <= 10), so the objective's
    # loss turns NaN from its fourth call on
    import subprocess

    from hybrid_sysid.cli.train import main
    from hybrid_sysid.model.objectives import LabelledObjective

    calls, forward = [], LabelledObjective.forward

    def nan_from_the_fourth(self, pred, batch):
        calls.append(1)
        loss = forward(self, pred, batch)
        return loss * float("nan") if len(calls) > 3 else loss

    monkeypatch.setattr(LabelledObjective, "forward", nan_from_the_fourth)
    args = [*TINY, "trainer.progress_bar=false", f"hydra.run.dir={tmp_path / 'run'}"]
    # data=tiny, simulated once for the test run
    code, out, err = cli_in_process(main, *args, cwd=tmp_path, env={"HYBRID_SYSID_CACHE": tiny_cache})
    proc = subprocess.CompletedProcess(args, code, out, err)
    assert proc.returncode != 0
    record = json.loads((tmp_path / "run" / "metrics.json").read_text())
    assert record["status"] == "failed"
    assert record["error"].startswith("FloatingPointError: training loss is nan at step")
    step = int(record["error"].split("at step ")[1].split(";")[0])
    assert step < 20  # stopped at once, not at max_steps


# (C3, K3) of the paper's car: 615 Ns/m, 98935 N/m (sec. 2.2); seat masses 50-200 kg by default
@pytest.mark.parametrize(
    "overrides, c3, k3, m3_min, m3_max",
    [
        ([], 615.0, 98935.0, 50, 200),
        (["car.c3=700"], 700.0, 98935.0, 50, 200),
        (["car.k3=90000", "data.m3_min=80"], 615.0, 90000.0, 80, 200),
        (["data.m3_max=150"], 615.0, 98935.0, 50, 150),
    ],
)
def test_the_prior_follows_the_car_and_the_mass_range(make_cfg, overrides, c3, k3, m3_min, m3_max):
    p_min, p_max = np.array([c3, k3]) / m3_max, np.array([c3, k3]) / m3_min
    scale = torch.tensor((p_min + p_max) / 2, dtype=torch.float32)
    model = build_model(make_cfg(*overrides))  # fast_cnn, labelled
    torch.testing.assert_close(model.objective.p_scale, scale)
    head = model.net.head
    widen = (p_max / p_min) ** 0.1  # FastCNN's default margin: a tenth of the log range on each side
    for bias, bound in ((-50.0, p_min / widen), (50.0, p_max * widen)):  # a saturated head gives the bound
        with torch.no_grad():
            head.weight.zero_()
            head.bias.fill_(bias)
        out = model.net(torch.randn(2, 2, 500)).detach().numpy()
        np.testing.assert_allclose(out, np.tile(bound, (2, 1)), rtol=1e-5)

    paper = build_model(make_cfg(*overrides, "model=paper_cnn", "objective=combined"))
    torch.testing.assert_close(paper.net.p_scale, scale)
    torch.testing.assert_close(paper.objective.labelled.p_scale, scale)


def test_curve_points_every_n_steps_and_at_the_end(make_cfg, tmp_path):
    train(make_cfg(*TINY, "trainer.max_steps=50", "trainer.curve_every_n_steps=20"), tmp_path / "c")
    curves = pd.read_csv(tmp_path / "c" / "curves.csv")
    assert sorted(curves.step.unique()) == [20, 40, 50]  # validations at 10, 20, ..., 50; the last one too


def test_curves_at_fewer_noise_levels_are_the_same_points(tiny_run, make_cfg, tmp_path):
    """noise.curve_std: the curves at those levels only, each point the one a run at every level takes (the
    same training: curve points draw nothing from the training's random streams); the final evaluation still
    at every level of noise.eval_std."""
    _, full_dir = tiny_run
    cfg = make_cfg(*TINY, "noise.curve_std=[0.05]")
    cfg.data.cache_dir = str(full_dir.parent / "cache")  # tiny_run's dataset, not simulated again
    train(cfg, tmp_path / "c")
    full, few = (pd.read_csv(d / "curves.csv") for d in (full_dir, tmp_path / "c"))
    assert set(zip(few.split, few.noise_std)) == {("train", 0.0), ("test", 0.05)}
    kept = full[(full.split == "train") | (full.noise_std == 0.05)]
    key = ["step", "split", "noise_std", "parameter"]
    pd.testing.assert_frame_equal(
        few.drop(columns="seconds").sort_values(key, ignore_index=True),
        kept.drop(columns="seconds").sort_values(key, ignore_index=True),
    )
    pred = pd.read_csv(tmp_path / "c" / "predictions.csv")
    assert set(pred[pred.split == "test"].noise_std) == {0.0, 0.05}


def test_test_errors_per_road_class_recombine_into_the_whole_split(tiny_run):
    """metrics.json's by_road_class: per class, the mean of predictions.csv's deviations; weighted by n they
    give back the split's figure."""
    record, run_dir = tiny_run
    pred = pd.read_csv(run_dir / "predictions.csv")
    rows = record["by_road_class"]
    assert rows and {r["road_class"] for r in rows} == set(pred[pred.split == "test"].road_class)
    for whole in (r for r in record["results"] if r["split"] == "test"):
        parts = [
            r
            for r in rows
            if (r["noise_std"], r["windows"], r["parameter"])
            == (whole["noise_std"], whole["windows"], whole["parameter"])
        ]
        assert sum(r["n"] for r in parts) == whole["n"]
        assert sum(r["mean_rel_dev"] * r["n"] for r in parts) / whole["n"] == pytest.approx(whole["mean_rel_dev"])
        for r in parts:
            sub = pred[
                (pred.split == "test") & (pred.noise_std == r["noise_std"]) & (pred.road_class == r["road_class"])
            ]
            p = r["parameter"]
            assert r["mean_rel_dev"] == pytest.approx(
                ((sub[f"{p}_true"] - sub[f"{p}_pred"]).abs() / sub[f"{p}_true"]).mean()
            )


def test_a_stop_swallowed_during_the_work_ends_the_run_at_its_next_safe_point(make_cfg, tmp_path):
    """A job's signal handler only requests a stop (hybrid_sysid.core.stop); a stop requested before the work
    ends the run at its first safe point, and no completed record is written."""
    import signal

    from hybrid_sysid.core import stop

    stop.request(signal.SIGTERM)
    try:
        with pytest.raises(stop.Interrupted, match="SIGTERM"):
            train(make_cfg(*TINY), tmp_path / "run")
    finally:
        stop.clear()
    assert not (tmp_path / "run" / "metrics.json").exists()
    assert train(make_cfg(*TINY), tmp_path / "run")["status"] == "completed"  # once cleared, the run completes
