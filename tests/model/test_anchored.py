"""model=anchored (model/anchored.py): the window's fit, errors-in-variables (anchor eiv) or band-passed least squares
(anchor ls), gated against a network by the fit's own standard error. Exact on clean consistent windows before any
training with either anchor; the gate as its formula says, against a fit computed here; the eiv anchor is
ErrorsInVariablesFit's, with the simulated fault's fix; served by load_estimator, hybrid-sysid-predict, evaluation
and init_from."""

import json

import numpy as np
import pandas as pd
import pytest
import torch
from omegaconf import OmegaConf

from hybrid_sysid.baselines import errors_in_variables
from hybrid_sysid.baselines.errors_in_variables import ErrorsInVariablesFit
from hybrid_sysid.model.anchored import AnchoredCNN
from hybrid_sysid.physics import relative_states, road_profiles, simulate
from hybrid_sysid.physics.filters import bandpass_taps
from hybrid_sysid.physics.seat_fit import fit_windows

from helpers.estimator_run import predict, trained_run

DT, W = 0.005, 500
P_MIN, P_MAX = [2.0, 300.0], [17.0, 2600.0]


def windows(noise=0.0, n=10, seed=5):
    """Seat and body windows (n, 2, W) of consistent recordings of every road class, their true p and the
    regressors integrated from t0 (the fit's reference)."""
    rng = np.random.default_rng(seed)
    m3 = rng.uniform(50, 200, n)
    c3, k3 = 615.0 * rng.uniform(0.7, 1.3, n), 98935.0 * rng.uniform(0.7, 1.3, n)
    road = road_profiles(("ABCDE" * n)[:n], 900, DT, 15.0, rng=seed)
    from hybrid_sysid.physics import QuarterCar

    car = QuarterCar(c3=c3, k3=k3)
    seat, body = simulate(road, m3, DT, car=car, measurement="consistent")
    acc = np.stack([seat, body], axis=1)[..., 300 : 300 + W] + noise * rng.standard_normal((n, 2, W))
    return acc.astype(np.float32), np.stack([c3 / m3, k3 / m3], axis=1)


def net(seed=0, **kwargs):
    torch.manual_seed(seed)
    return AnchoredCNN(P_MIN, P_MAX, dt=DT, **kwargs).eval()


@pytest.mark.parametrize("anchor", ["eiv", "ls"])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_clean_windows_give_the_true_p_before_any_training_whatever_the_head(seed, anchor):
    acc, truth = windows()
    model = net(seed, anchor=anchor)
    with torch.no_grad():
        model.head[-1].bias.copy_(torch.tensor([-20.0, 20.0, -20.0, -20.0]))  # p_net at its ends, tau at its floor
        p = model(torch.from_numpy(acc)).double().numpy()
    assert np.abs(p / truth - 1).max() <= 1e-4  # the bound: 0.01%


def test_the_gate_weighs_the_fit_by_its_own_standard_error():
    """With the head's last layer zero, p_net is the centre of its range and tau = sqrt(tau_min tau_max); the
    least-squares fit and its standard error are computed here from the window (integrated on its own,
    band-passed by np.convolve, numpy's lstsq, s^2 (A^T A)^-1)."""
    acc, _ = windows(noise=0.02)
    model = net(anchor="ls")
    with torch.no_grad():
        model.head[-1].weight.zero_()
        model.head[-1].bias.zero_()
        p = model(torch.from_numpy(acc)).double().numpy()
    lo, hi = model.output_bounds() or (None, None)
    assert lo is None  # the fit is not bounded by the head
    fir = bandpass_taps(4.0, 20.0, 151, DT)
    mid = np.exp(model.log_lo.double().numpy() + model.log_span.double().numpy() / 2)
    tau = np.sqrt(1e-3 * 1.0)
    for i, (seat, body) in enumerate(acc.astype(np.float64)):
        rv, rd = relative_states(seat, body, DT, "consistent")
        y, a, b = (np.convolve(x, fir, "valid") for x in (seat, rv, rd))
        x = np.stack([-a, -b], axis=1)
        coef, rss, _, _ = np.linalg.lstsq(x, y, rcond=None)
        se = np.sqrt(np.diag(rss[0] / (len(y) - 2) * np.linalg.inv(x.T @ x))) / np.abs(coef)
        w = np.where(coef > 0, tau**2 / (tau**2 + se**2), 0.0)
        assert p[i] == pytest.approx(w * coef + (1 - w) * mid, rel=2e-5)  # float32 output
    assert (np.abs(p - mid) > 1e-3 * mid).any()  # the fit moved some of them


@pytest.mark.parametrize("anchor", ["eiv", "ls"])
def test_a_window_without_a_fit_gets_the_network(anchor):
    model = net(anchor=anchor)
    with torch.no_grad():
        p = model(torch.zeros(2, 2, W)).numpy()
    lo, hi = np.exp(model.log_lo.numpy()), np.exp(model.log_lo.numpy() + model.log_span.numpy())
    assert np.isfinite(p).all() and (p >= lo).all() and (p <= hi).all()


def test_the_eiv_anchor_is_the_errors_in_variables_fit_with_the_least_squares_statistics():
    """p and se of ErrorsInVariablesFit (noise ratio 1, the model's band as its start) on the same windows, the
    unexplained share and correlation of the band-passed least squares; the gate weighs that p by that se."""
    acc, _ = windows(noise=0.02, n=16)
    model = net(anchor="eiv")
    x = acc.astype(np.float64)
    fit = model.anchor(torch.from_numpy(acc))
    p, se = ErrorsInVariablesFit(noise_ratio=1.0, dt=DT).fit_windows(x[:, 0], x[:, 1], DT, "consistent")
    ls = fit_windows(x[:, 0], x[:, 1], DT, "consistent", bandpass_taps(4.0, 20.0, 151, DT))
    assert np.array_equal(fit.p, p) and np.array_equal(fit.se, se)
    assert np.array_equal(fit.unexplained, ls.unexplained) and np.array_equal(fit.correlation, ls.correlation)
    assert not np.array_equal(fit.p, ls.p)  # the anchor is not the least squares under noise
    with torch.no_grad():
        model.head[-1].weight.zero_()
        model.head[-1].bias.zero_()
        out = model(torch.from_numpy(acc)).double().numpy()
    mid = np.exp(model.log_lo.double().numpy() + model.log_span.double().numpy() / 2)
    w = 1e-3 / (1e-3 + se**2)  # tau^2 = tau_min tau_max
    np.testing.assert_allclose(out, w * p + (1 - w) * mid, rtol=2e-5)


def test_the_config_anchors_on_eiv_and_model_net_anchor_ls_is_the_least_squares_one(make_cfg):
    from hybrid_sysid.training.build import build_model

    acc, _ = windows(noise=0.02, n=4)
    x = acc.astype(np.float64)
    ls = fit_windows(x[:, 0], x[:, 1], DT, "consistent", bandpass_taps(4.0, 20.0, 151, DT))
    built = {}
    for anchor in ("eiv", "ls"):
        overrides = ["model=anchored", "data.seat_spread=0.3"] + ([] if anchor == "eiv" else ["model.net.anchor=ls"])
        cfg = make_cfg(*overrides)
        assert cfg.model.net.anchor == anchor and cfg.model.net.fix == "none"
        torch.manual_seed(0)
        built[anchor] = build_model(cfg).net.eval()
    fit = built["ls"].anchor(torch.from_numpy(acc))
    assert all(np.array_equal(a, b) for a, b in zip(fit, ls))
    assert not np.array_equal(built["eiv"].anchor(torch.from_numpy(acc)).p, ls.p)
    # the least-squares anchor is the model as it was before the choice existed, to the bit
    cfg = make_cfg("model=anchored", "data.seat_spread=0.3")
    net_args = {k: v for k, v in cfg.model.net.items() if k not in ("_target_", "anchor", "fix")}
    torch.manual_seed(0)
    before = AnchoredCNN(**net_args).eval()
    with torch.no_grad():
        assert torch.equal(before(torch.from_numpy(acc)), built["ls"](torch.from_numpy(acc)))


def test_the_fault_the_config_simulates_reaches_the_errors_in_variables_fit(make_cfg, monkeypatch):
    """fix: ${fault_fix:} in conf/model/anchored.yaml; both fits (the likelihood and the MAP) get ``fix`` when
    there is a fault, nothing more when there is none (so a fit without the argument still serves clean data)."""
    given = []

    class Recorder(ErrorsInVariablesFit):
        def __init__(self, **arguments):
            given.append(arguments)

    monkeypatch.setattr(errors_in_variables, "ErrorsInVariablesFit", Recorder)  # model.arguments reads it
    for fault, fix in (("clean", "none"), ("gain", "gain"), ("skewed", "skew"), ("hardening", "hardening")):
        cfg = make_cfg("model=anchored", f"fault={fault}")
        assert cfg.model.net.fix == fix
        net_args = {k: v for k, v in cfg.model.net.items() if k != "_target_"}
        AnchoredCNN(**net_args)
        ml, map_ = given[-2:]  # the likelihood fit, then the MAP fit of the config's prior
        assert "prior" not in ml and map_["prior"] == net_args["prior"]
        for arguments in (ml, map_):
            assert arguments.get("fix") == (None if fix == "none" else fix) and arguments["noise_ratio"] == 1.0
    AnchoredCNN(P_MIN, P_MAX, dt=DT, anchor="ls", fix="gain")  # the least-squares anchor has no fix to take
    assert len(given) == 8


def test_bad_values_are_one_line_errors_naming_the_key():
    from hybrid_sysid.config import ConfigError

    with pytest.raises(ConfigError, match=r"^tau_max = 0.0005 is not allowed"):
        AnchoredCNN(P_MIN, P_MAX, dt=DT, tau_max=5e-4)
    with pytest.raises(ConfigError, match=r"^anchor = 'tls' is not allowed: one of eiv, ls"):
        AnchoredCNN(P_MIN, P_MAX, dt=DT, anchor="tls")
    with pytest.raises(ConfigError, match=r"^fix = 'delay' is not allowed"):
        AnchoredCNN(P_MIN, P_MAX, dt=DT, fix="delay")
    with pytest.raises(ConfigError, match=r"^filter.taps = 150 is not allowed"):
        AnchoredCNN(P_MIN, P_MAX, dt=DT, filter={"low_hz": 4.0, "high_hz": 20.0, "taps": 150})
    assert AnchoredCNN.window_bounds(n_layers=4, filter={"taps": 151})[0] == 160  # the band-pass leaves 10


@pytest.fixture(scope="module")
def anchored_run(tmp_path_factory, tiny_cache):
    """An anchored network trained 40 steps on data=tiny (noisy training windows), saved as Hydra would."""

    run_dir = tmp_path_factory.mktemp("anchored") / "run"
    overrides = [
        "model=anchored",
        "data=tiny",
        "trainer=debug",
        "trainer.max_steps=40",
        "trainer.eval_every_n_steps=20",
        "noise.train_std=0.01",
        f"data.cache_dir={tiny_cache}",
    ]
    return trained_run(run_dir, overrides)


def test_a_trained_run_is_served_like_any_run(anchored_run, tmp_path, capsys):
    from hybrid_sysid import load_estimator
    from hybrid_sysid.training.build import build_datamodule

    record = json.loads((anchored_run / "metrics.json").read_text())
    assert record["status"] == "completed"
    est = load_estimator(anchored_run)
    dm = build_datamodule(est.config)
    batch = dm.eval_batch("test")
    written = pd.read_csv(anchored_run / "predictions.csv").query("split == 'test' and noise_std == 0")
    signals = batch["signals"][:4].numpy().astype(np.float64)
    got = est.predict(signals[:, 0], signals[:, 1], est.dt, windows=1)
    for (_, g), row in zip(got.iterrows(), batch["index"][:4].numpy()):
        want = written[written.recording == row].iloc[0]
        assert g.p1 == pytest.approx(want.p1_pred, rel=1e-5) and g.p2 == pytest.approx(want.p2_pred, rel=1e-5)
    # clean test windows: the fit, exact, whatever 40 steps taught the network
    assert (written.p1_pred / written.p1_true - 1).abs().max() <= 1e-4
    npz = tmp_path / "rec.npz"
    np.savez(npz, seat_acc=signals[:, 0], body_acc=signals[:, 1], dt=est.dt)
    code, out, err = predict(
        capsys, f"run={anchored_run}", f"input={npz}", f"output={tmp_path / 'out.csv'}", "windows=1"
    )
    assert code == 0, err
    table = pd.read_csv(tmp_path / "out.csv")
    assert table.p1.to_numpy() == pytest.approx(got.p1.to_numpy(), rel=1e-5) and "flag" in table


def test_a_trained_run_evaluates_elsewhere_and_starts_another(anchored_run, tmp_path, tiny_cache):
    from hydra import compose, initialize_config_dir

    from hybrid_sysid.config import CONF_DIR
    from hybrid_sysid.training.run import evaluate_checkpoint, train

    saved = OmegaConf.load(anchored_run / ".hydra" / "config.yaml")
    other = OmegaConf.merge(saved, {"car": {"c3": 700.0}})
    scores = evaluate_checkpoint(other, anchored_run, tmp_path / "eval")
    assert json.loads((tmp_path / "eval" / "metrics.json").read_text())["status"] == "completed" and scores
    overrides = [
        "model=anchored",
        "objective=label_free",
        "data=tiny",
        "trainer=debug",
        "trainer.max_steps=4",
        f"init_from={anchored_run}",
        f"data.cache_dir={tiny_cache}",
    ]
    with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
        cfg = compose(config_name="config", overrides=overrides)
    train(cfg, tmp_path / "adapted", overrides)
    assert json.loads((tmp_path / "adapted" / "metrics.json").read_text())["status"] == "completed"
