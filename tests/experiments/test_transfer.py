"""Another car than the one trained on: car presets, evaluating a trained run elsewhere, label-free adaptation
(init_from), and the plan of experiment=transfer."""

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch
from omegaconf import OmegaConf

from hybrid_sysid.config import ConfigError, validate
from hybrid_sysid.physics import QuarterCar, stable_dt_limit
from hybrid_sysid.training.build import build_model
from hybrid_sysid.training.run import evaluate_checkpoint, train

TINY = ["data=tiny", "trainer=debug"]
# the paper's car (sec. 2.2) and the two shifted cars of experiment=transfer
PAPER = dict(m1=145.0, m2=2160.0, k1=40000.0, k2=149171.0, k3=98935.0, c2=4741.0, c3=615.0, seat_hardening=0.0)

# the presets the refusal lists, read from the package's conf/baseline folder itself
BASELINE_PRESETS = sorted(
    p.stem for p in (Path(__file__).parents[2] / "src" / "hybrid_sysid" / "conf" / "baseline").glob("*.yaml")
)


def save_config(cfg, run_dir: Path):
    (run_dir / ".hydra").mkdir(parents=True, exist_ok=True)
    (run_dir / ".hydra" / "config.yaml").write_text(OmegaConf.to_yaml(cfg))


@pytest.mark.parametrize(
    "preset, factors",
    [
        ("paper", {}),
        ("soft_seat", {"c3": 1.12, "k3": 0.90}),
        ("compact", {"m1": 0.9, "m2": 0.6, "k1": 1.3, "k2": 1.4, "c2": 0.6}),
    ],
)
def test_car_presets_are_the_paper_car_scaled(make_cfg, preset, factors):
    cfg = make_cfg(f"car={preset}") if preset != "paper" else make_cfg()
    want = {k: v * factors.get(k, 1.0) for k, v in PAPER.items()}
    assert set(cfg.car) == set(want)
    for k, v in want.items():
        assert cfg.car[k] == pytest.approx(v, rel=1e-12), k


@pytest.mark.parametrize(
    "overrides, match",
    [
        (["car.c3=0"], r"car.c3 = 0.0 is not allowed: must be finite and > 0"),
        (["car=compact", "car.m2=nan"], r"car.m2 = nan is not allowed: must be finite and > 0"),
        (["car.k1=inf"], r"car.k1 = inf is not allowed: must be finite and > 0"),
        (["data.seat_spread=1.0"], r"data.seat_spread = 1.0 is not allowed: must lie in \[0, 1\)"),
    ],
)
def test_bad_car_values_are_named(make_cfg, overrides, match):
    with pytest.raises(ConfigError, match=match):
        validate(make_cfg(*overrides))


def test_the_stable_time_step_follows_the_car(make_cfg):
    # a seat spring 20x stiffer: the seat mode at 50 kg is sqrt(20) times faster, the limit about that much lower
    stiff = make_cfg("car.k3=1978700", "data.dt=0.01")
    with pytest.raises(
        ConfigError,
        match=r"data.dt = 0.01 is not allowed: .*unstable above 0.00\d+ s for this car "
        r"\(m1=145, .*k3=1\.9787e\+06",
    ):
        validate(stiff)
    limit = stable_dt_limit(QuarterCar(k3=1978700.0))
    # the limit is where the eq.-11 step map's spectral radius crosses 1: check it by eigenvalues directly
    c = QuarterCar(k3=1978700.0)
    for dt, stable in ((0.99 * limit, True), (1.01 * limit, False)):
        p1, p2 = c.parameters(50.0)
        # the step is linear: its matrix is the image of the unit states (road 0)
        from hybrid_sysid.physics import step

        cols = np.array(step(*np.eye(6), 0.0, p1, p2, dt, c.coefficients(), True)[:6])
        assert (max(abs(np.linalg.eigvals(cols))) <= 1 + 1e-9) == stable
    validate(make_cfg("car.k3=1978700", f"data.dt={0.99 * limit}"))  # below it: fine
    # the continuous measurement takes no step: no limit
    validate(make_cfg("car.k3=1978700", "data.dt=0.01", "data.measurement=continuous"))


def test_the_spread_widens_the_networks_bounds(make_cfg):
    cfg = make_cfg("data.seat_spread=0.3", "car=soft_seat")
    c3, k3 = 615.0 * 1.12, 98935.0 * 0.90
    np.testing.assert_allclose(cfg.model.net.p_min, [0.7 * c3 / 200, 0.7 * k3 / 200], rtol=1e-12)
    np.testing.assert_allclose(cfg.model.net.p_max, [1.3 * c3 / 50, 1.3 * k3 / 50], rtol=1e-12)


@pytest.fixture(scope="module")
def source(tmp_path_factory, tiny_cache):
    """A tiny labelled run on the paper's car, with its config saved as the app saves it. Its data.cache_dir, the
    shared tiny_cache, holds data=tiny on both cars, so an evaluation of it (in process or not) simulates nothing."""
    from hydra import compose, initialize_config_dir

    from hybrid_sysid.config import CONF_DIR

    tmp = tmp_path_factory.mktemp("source")
    with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
        cfg = compose(
            config_name="config",
            overrides=[
                *TINY,
                f"data.cache_dir={tiny_cache}",
                "trainer.progress_bar=false",
                "evaluation.windows=[1,4]",
            ],
        )
    run_dir = tmp / "run"
    save_config(cfg, run_dir)
    return cfg, train(cfg, run_dir, overrides=TINY), run_dir


def test_evaluating_a_run_on_its_own_config_reproduces_its_metrics(source, tmp_path):
    cfg, record, run_dir = source
    again = evaluate_checkpoint(cfg, run_dir, tmp_path / "eval", overrides=["run=x"])
    assert again["results"] == record["results"]  # exactly: same weights, windows and noise
    on_disk = json.loads((tmp_path / "eval" / "metrics.json").read_text())
    assert on_disk["source_run"] == str(run_dir) and on_disk["status"] == "completed"
    stamp = (tmp_path / "eval" / "metrics.json").stat().st_mtime_ns
    assert evaluate_checkpoint(cfg, run_dir, tmp_path / "eval", overrides=["run=x"]) == on_disk  # a re-run skips it
    assert (tmp_path / "eval" / "metrics.json").stat().st_mtime_ns == stamp


def test_a_run_saved_by_another_version_is_one_line_naming_it(source, tmp_path):
    """A saved config holding a key this version lacks (data.amplitude, removed in 0.2) cannot be evaluated as if
    it were this version's: one ConfigError naming the run and the key, before any work."""
    from hybrid_sysid.cli.evaluate import evaluation_config

    _, _, run_dir = source
    saved = OmegaConf.load(run_dir / ".hydra" / "config.yaml")
    saved.data.amplitude = "paper"
    save_config(saved, tmp_path)
    with pytest.raises(ConfigError, match=r"^run = .* not allowed: .*data\.amplitude.*another version"):
        evaluation_config(tmp_path, saved, [])


def test_evaluation_on_another_car_changes_the_labels_not_the_network(source, tmp_path):
    cfg, record, run_dir = source
    other = OmegaConf.merge(cfg, {"car": {"c3": 615.0 * 1.12}})
    evaluate_checkpoint(other, run_dir, tmp_path / "eval", overrides=[])
    import pandas as pd

    pred = pd.read_csv(tmp_path / "eval" / "predictions.csv")
    np.testing.assert_allclose(pred.p1_true, 615.0 * 1.12 / pred.m3, rtol=1e-6)  # the target's labels


def adapt(source_dir, tmp_path, name, poison=None):
    from hydra import compose, initialize_config_dir

    from hybrid_sysid.config import CONF_DIR

    with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
        cfg = compose(
            config_name="config",
            overrides=[
                *TINY,
                f"data.cache_dir={tmp_path / 'cache'}",
                "trainer.progress_bar=false",
                "objective=hybrid",
                "car=soft_seat",
                f"init_from={source_dir}",
                "model.optim.lr=5e-3",
            ],
        )
    if poison is not None:  # the target's labels replaced by garbage: a label-free adaptation must not notice
        poison()
    record = train(cfg, tmp_path / name, overrides=[])
    state = torch.load(tmp_path / name / "checkpoints" / "best.ckpt", weights_only=True)["state_dict"]
    return record, state


def test_adaptation_starts_from_the_source_and_never_reads_labels(source, tmp_path, poison_labels):
    _, _, run_dir = source
    clean, weights = adapt(run_dir, tmp_path, "clean")
    poisoned, weights_poisoned = adapt(run_dir, tmp_path, "poisoned", poison=poison_labels)
    assert clean["init_from"] == str(run_dir) and clean["monitor"] == "val/loss"
    assert weights.keys() == weights_poisoned.keys()
    for key in weights:
        assert torch.equal(weights[key], weights_poisoned[key]), key
    assert clean["results"] != poisoned["results"]  # the poison was there: the scores (which use labels) differ


def test_adaptation_starts_from_the_sources_weights(source, tmp_path, make_cfg):
    _, _, run_dir = source
    cfg = make_cfg(*TINY, "objective=hybrid", f"init_from={run_dir}")
    model = build_model(cfg)
    from hybrid_sysid.training.build import load_network

    load_network(model.net, cfg, run_dir, "init_from")
    best = torch.load(run_dir / "checkpoints" / "best.ckpt", weights_only=True)["state_dict"]
    for key, value in model.net.state_dict().items():
        assert torch.equal(value, best[f"net.{key}"]), key


def test_another_architecture_is_one_named_error(source, tmp_path, make_cfg):
    _, _, run_dir = source
    cfg = make_cfg(*TINY, "objective=hybrid", f"init_from={run_dir}", "model.net.channels=16")
    with pytest.raises(
        ConfigError,
        match=r"^init_from = .* is not allowed: its network differs from model.net "
        r"in channels \(32 there, 16 here\)$",
    ):
        train(cfg, tmp_path / "other", overrides=[])
    assert not (tmp_path / "other").exists()  # before any work
    with pytest.raises(ConfigError, match=r"init_from = .*nowhere is not allowed: it has no .hydra/config.yaml"):
        train(make_cfg(*TINY, f"init_from={tmp_path / 'nowhere'}"), tmp_path / "other", overrides=[])


def rows_of(runs) -> dict:
    """{(scenario, row): (kind, config, directory, source)} of a plan's sub-runs."""
    return {tuple(o.split("=", 1)[1] for o in r[3]): (r[0], r[1], r[2], r[4]) for r in runs}


def test_the_transfer_plan(make_cfg, tmp_path):
    from hybrid_sysid.experiments.transfer import plan

    cfg = make_cfg("experiment=transfer", "data=tiny", "seed=2")
    runs = plan(cfg, tmp_path)
    rows = rows_of(runs)
    assert len(runs) == len(rows) == 1 + 6 * 3  # the source, then per scenario: eval, 3 adapted, scratch, oracle
    kind, source, where, _ = rows[("paper", "1 labelled, paper's car")]
    assert kind == "train" and where == tmp_path / "source" and runs[0][2] == where
    assert source.objective._target_.endswith("LabelledObjective") and dict(source.car) == PAPER
    assert [r for s, r in rows if s == "seat_shift"] == [
        "1 labelled, paper's car",
        "2 + hybrid adaptation",
        "2 + hybrid_bandpass adaptation",
        "2 + label_free adaptation",
        "3 hybrid from scratch",
        "4 labelled oracle",
    ]
    _, seat, where, _ = rows[("seat_shift", "2 + hybrid adaptation")]
    assert where == tmp_path / "seat_shift" / "adapted"  # hybrid's runs keep the names sweeps already have
    assert seat.objective._target_.endswith("HybridObjective") and seat.init_from == str(tmp_path / "source")
    assert seat.trainer.max_steps == cfg.transfer.adapt_steps and seat.car.c3 == pytest.approx(615 * 1.12)
    _, bandpass, where, _ = rows[("seat_shift", "2 + hybrid_bandpass adaptation")]
    assert where.name == "adapted_hybrid_bandpass" and bandpass.objective.filter.taps == 151
    assert bandpass.init_from == str(tmp_path / "source") and bandpass.model.optim.lr == cfg.transfer.adapt_lr
    assert rows[("seat_shift", "3 hybrid from scratch")][2].name == "scratch"
    assert rows[("continuous", "4 labelled oracle")][1].data.measurement == "continuous"
    assert rows[("body_shift", "3 hybrid from scratch")][1].car.m2 == pytest.approx(2160 * 0.6)
    assert all(r[1].transfer is None and r[1].seed == 2 and r[1].baseline is None for r in runs)
    # the rows sort, as text (the table's order), in the order the chain runs them
    assert [r for s, r in rows if s == "body_shift"] == sorted(r for s, r in rows if s == "body_shift")


@pytest.mark.parametrize("objective", ["hybrid", "hybrid_bandpass", "hybrid_eiv", "label_free"])
def test_a_chain_composes_an_objective_as_hydra_does(make_cfg, objective):
    # hybrid_bandpass, hybrid_eiv and label_free build on other presets through their defaults lists
    from hybrid_sysid.experiments.transfer import variant

    cfg = make_cfg("experiment=field", "data=tiny", "data.n_steps=900")  # cross_segment leaves a segment
    mine, hydras = variant(cfg, objective).objective, make_cfg("data=tiny", f"objective={objective}").objective
    assert OmegaConf.to_container(mine) == OmegaConf.to_container(hydras)  # interpolations unresolved


def test_the_field_plan(make_cfg, tmp_path):
    import hydra.utils

    from hybrid_sysid.experiments.transfer import _reads_labels, plan

    cfg = make_cfg("experiment=field", "data=tiny", "data.n_steps=900")  # cross_segment leaves a segment
    rows = rows_of(plan(cfg, tmp_path))
    assert list(rows) == [
        ("paper", "1 labelled, paper's car"),
        ("field", "1 labelled, paper's car"),
        ("field", "2 + hybrid adaptation"),
        ("field", "2 + hybrid_bandpass adaptation"),
        ("field", "2 + label_free adaptation"),
        ("field", "3 label_free from scratch"),
        ("field", "3 label_free from scratch, anchored"),
        ("field", "3 cross_segment from scratch, anchored"),
        ("field", "4 labelled oracle"),
        ("field", "5 ls_bandpass (no network)"),
    ]
    source = rows[("paper", "1 labelled, paper's car")][1]
    assert dict(source.car) == PAPER and source.data.seat_spread == 0.3 and source.data.measurement == "consistent"
    for (_, row), (kind, sub, _, from_run) in list(rows.items())[1:]:
        assert sub.car.c3 == pytest.approx(615 * 1.12) and sub.car.k3 == pytest.approx(98935 * 0.9), row
        assert sub.data.seat_spread == 0.3 and sub.data.measurement == "continuous", row
        assert (kind == "eval") == row.startswith("1") and (from_run is not None) == row.startswith("1"), row
        assert (sub.init_from is not None) == row.startswith("2"), row
        # the target's prior: the labelled objective's scale of the oracle, the label_free target's scale
        np.testing.assert_allclose(sub.model.net.p_max, [1.3 * 615 * 1.12 / 50, 1.3 * 98935 * 0.9 / 50])
    scratch = rows[("field", "3 label_free from scratch")]
    assert scratch[2].name == "scratch_label_free" and scratch[1].objective.target == "least_squares"
    assert scratch[1].init_from is None and scratch[1].trainer.max_steps == cfg.trainer.max_steps
    for objective in ("label_free", "cross_segment"):  # model=anchored from scratch, each label-free
        _, sub, where, _ = rows[("field", f"3 {objective} from scratch, anchored")]
        assert where.name == f"anchored_{objective}" and sub.init_from is None
        assert sub.model.net._target_.endswith("AnchoredCNN") and not _reads_labels(cfg, objective)
    _, base, where, _ = rows[("field", "5 ls_bandpass (no network)")]
    assert where == tmp_path / "field" / "baseline_ls_bandpass" and base.task == "train"
    assert base.baseline == make_cfg("data=tiny", "baseline=ls_bandpass").baseline
    # an adapted network keeps the source's output bounds (init_from loads them): the target's prior lies inside
    net = hydra.utils.instantiate(source.model.net)
    low, high = net.log_lo.exp().numpy(), (net.log_lo + net.log_span).exp().numpy()
    target = rows[("field", "4 labelled oracle")][1]
    assert (low < np.array(target.model.net.p_min)).all() and (np.array(target.model.net.p_max) < high).all()


@pytest.mark.parametrize(
    "change, match",
    [
        (
            {"transfer.adapt_objectives": ["hybrid", "labelled"]},
            r"transfer.adapt_objectives = \['hybrid', 'labelled'\] is not allowed: labelled: it reads labels; "
            r"a label-free objective preset \(conf/objective\): cross_segment, hybrid, hybrid_bandpass, hybrid_eiv, "
            r"label_free$",
        ),
        (
            {"transfer.adapt_objectives": ["label_free", "hybrid", "label_free"]},
            r"transfer.adapt_objectives = .* is not allowed: label_free twice; each objective once \(one row each\)$",
        ),
        (
            {"transfer.adapt_objectives": ["hybird"]},
            r"transfer.adapt_objectives = \['hybird'\] is not allowed: hybird: no such objective preset; "
            r"a label-free objective preset",
        ),
        (
            {"transfer.scratch_objective": "combined"},
            r"transfer.scratch_objective = 'combined' is not allowed: combined: it reads labels; a label-free",
        ),
        (
            {"transfer.baseline": "ls_bandpas"},
            r"transfer.baseline = 'ls_bandpas' is not allowed: null or a baseline preset \(conf/baseline\): "
            + ", ".join(BASELINE_PRESETS)
            + "$",
        ),
        # a lighter seat on the target: p beyond the bounds the adapted networks keep from the source. The target's
        # p1 range: 0.7 * 688.8 / 200 to 1.3 * 688.8 / 30; the source's bounds: 0.7 * 615 / 200 = 2.1525 to
        # 1.3 * 615 / 50 = 15.99, widened by FastCNN's margin, a tenth of the log range (x 7.43**0.1) each side
        (
            {"transfer.scenarios.field.data.m3_min": 30},
            r"transfer.scenarios.field is not allowed: with adaptation the target's p1 range 2.411 to 29.85 leaves "
            r"the source network's output bounds 1.761 to 19.54, which the adapted networks keep; widen",
        ),
    ],
    ids=["labelled", "twice", "misspelt", "scratch", "baseline", "bounds"],
)
def test_bad_transfer_settings_are_one_line_before_any_work(make_cfg, tmp_path, change, match):
    from hybrid_sysid.experiments.transfer import plan

    cfg = make_cfg("experiment=field", "data=tiny", "data.n_steps=900")  # cross_segment leaves a segment
    for key, value in change.items():
        OmegaConf.update(cfg, key, value, merge=True, force_add=True)
    with pytest.raises(ConfigError, match=match) as refused:
        plan(cfg, tmp_path / "job")
    assert "\n" not in str(refused.value)
    assert not (tmp_path / "job").exists()
    # without adaptation the lighter seat is only evaluated: allowed
    if "m3_min" in str(change):
        OmegaConf.update(cfg, "transfer.adapt_objectives", [], merge=False)
        assert [r[3][1] for r in plan(cfg, tmp_path / "job")][2:] == [
            "row=3 label_free from scratch",
            "row=3 label_free from scratch, anchored",
            "row=3 cross_segment from scratch, anchored",
            "row=4 labelled oracle",
            "row=5 ls_bandpass (no network)",
        ]


def test_the_field_chain_runs_end_to_end_and_a_rerun_skips_it(make_cfg, tmp_path):
    # debug=fast experiment=field: the chain of one seed in this process, one record per row
    from hybrid_sysid.experiments.transfer import run_chain
    from hybrid_sysid.report.collect import load_runs
    from hybrid_sysid.report.tables import summary_table

    cfg = make_cfg("debug=fast", "experiment=field")
    job = tmp_path / "sweep" / "0"
    out = run_chain(cfg, job, ["debug=fast", "experiment=field", "seed=0"])
    assert out["status"] == "completed"
    records = {p.parent.relative_to(job).as_posix(): json.loads(p.read_text()) for p in job.rglob("metrics.json")}
    assert (
        sorted(records)
        == sorted(out["runs"])
        == [
            "field/adapted",
            "field/adapted_hybrid_bandpass",
            "field/adapted_label_free",
            "field/anchored_label_free",
            "field/baseline_ls_bandpass",
            "field/oracle",
            "field/scratch_label_free",
            "field/source",
            "source",
        ]
    )
    assert all(r["status"] == "completed" for r in records.values())
    assert {r["overrides"][-1] for r in records.values()} == {"seed=0"}
    assert records["field/source"]["source_run"] == str(job / "source")
    for name in ("adapted", "adapted_hybrid_bandpass", "adapted_label_free"):
        assert records[f"field/{name}"]["init_from"] == str(job / "source")
        assert records[f"field/{name}"]["monitor"] == "val/loss" and records[f"field/{name}"]["steps"] == 20
    assert records["field/scratch_label_free"]["monitor"] == "val/loss"
    assert records["field/anchored_label_free"]["monitor"] == "val/loss"  # debug=fast keeps the label_free one
    assert (
        records["field/baseline_ls_bandpass"]["steps"] == 0 and records["field/baseline_ls_bandpass"]["monitor"] is None
    )
    # the adapted networks kept the source's output bounds
    bounds = [
        torch.load(job / d / "checkpoints" / "best.ckpt", weights_only=True)["state_dict"]["net.log_lo"]
        for d in ("source", "field/adapted_label_free")
    ]
    assert torch.equal(*bounds)
    # the table: one row per (scenario, row, K) in reading order
    table = summary_table(load_runs(job.parent)[1])
    assert [r for s, r, k in table.index if s == "field" and k == 1] == [
        "1 labelled, paper's car",
        "2 + hybrid adaptation",
        "2 + hybrid_bandpass adaptation",
        "2 + label_free adaptation",
        "3 label_free from scratch",
        "3 label_free from scratch, anchored",
        "4 labelled oracle",
        "5 ls_bandpass (no network)",
    ]
    assert (table[("n_seeds", "", "")] == 1).all()
    # a re-run (the sweep run again) skips every completed sub-run
    stamps = {p: p.stat().st_mtime_ns for p in job.rglob("metrics.json")}
    assert run_chain(cfg, job, ["debug=fast", "experiment=field", "seed=0"]) == out
    assert {p: p.stat().st_mtime_ns for p in job.rglob("metrics.json")} == stamps


@pytest.mark.integration
def test_eval_cli_sweeps_cars_and_refuses_another_objective(source, tmp_path, cli_in_process):
    # a new process for the refusal: what a user sees of it (one line, no traceback: an import's warnings
    # included) and its exit status; the sweep, whose jobs the basic launcher runs in the command's own process,
    # through the command's main() in this process
    from hybrid_sysid.cli.evaluate import main

    _, _, run_dir = source
    env = {k: v for k, v in os.environ.items() if k != "HYDRA_FULL_ERROR"}
    cli = [sys.executable, "-c", "from hybrid_sysid.cli.evaluate import main; main()"]
    bad = subprocess.run(
        cli + [f"run={run_dir}", "objective=hybrid"], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300
    )
    assert bad.returncode == 2 and "Traceback" not in bad.stderr
    assert (
        bad.stderr.strip()
        .splitlines()[-1]
        .startswith("error: objective is not allowed: a key of data, car, road, noise")
    )
    sweep_args = ["-m", f"run={run_dir}", "car=paper,soft_seat", "hydra.sweep.dir=sweep"]
    code, _, err = cli_in_process(main, *sweep_args, cwd=tmp_path)
    sweep = subprocess.CompletedProcess(main, code, "", err)
    assert sweep.returncode == 0, sweep.stderr[-2000:]
    import pandas as pd

    summary = pd.read_csv(tmp_path / "sweep" / "summary.csv")
    assert set(summary.car) == {"paper", "soft_seat"} and (summary.status == "completed").all()
    for job in ("0", "1"):
        assert json.loads((tmp_path / "sweep" / job / "metrics.json").read_text())["source_run"] == str(run_dir)
