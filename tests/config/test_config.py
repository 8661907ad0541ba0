"""Bad config values fail before any work, with one line naming the key, the value and what is allowed."""

import os
import subprocess
import sys

import pytest
from hydra.errors import ConfigCompositionException
from omegaconf.errors import ConfigKeyError, ValidationError

from hybrid_sysid.config import ConfigError, validate

BAD = [
    (["data.window=1300"], r"data.window = 1300 is not allowed: must lie in \[16, n_steps = 1200\]"),
    (["model=paper_cnn", "data.window=40"], r"model.net.window = 40 is not allowed: must be an integer >= 59"),
    (["data.dt=0"], r"data.dt = 0.0 is not allowed: must be > 0"),
    (["data.dt=0.05"], r"data.dt = 0.05 is not allowed: the semi-implicit Euler scheme is unstable above 0.036"),
    (["data.speed=-2"], r"data.speed = -2.0 is not allowed: must be > 0"),
    (
        ["data.measurement=continuous", "data.dt=0.5"],
        r"data.dt = 0.5 is not allowed: with measurement = continuous its Nyquist frequency, 1 Hz, lies below "
        r"the road's content at speed = 15 m/s \(up to 45 Hz",
    ),
    (
        ["trainer.curve_every_n_steps=250"],
        r"trainer.curve_every_n_steps = 250 is not allowed: a multiple of "
        r"trainer.eval_every_n_steps = 200",
    ),
    (["data.n_roads=2"], r"data.n_roads = 2 is not allowed: too few for train_fraction = 0.8"),
    (["data.train_fraction=1.0"], r"data.train_fraction = 1.0 is not allowed: must lie in \(0, 1\)"),
    (["data.train_fraction=0"], r"data.train_fraction = 0.0 is not allowed: must lie in \(0, 1\)"),
    (["data.m3_min=150", "data.m3_max=100"], r"data.m3_max = 100 is not allowed: empty mass range"),
    (["data.m3_min=-10"], r"data.m3_min = -10 is not allowed: must be an integer >= 1"),
    (["road.classes=[A,X]"], r"road.classes = \['A', 'X'\] is not allowed: each class must be one of A, B, C, D, E"),
    (["noise.eval_std=[0.0,-0.01]"], r"noise.eval_std = \[0.0, -0.01\] is not allowed: every standard deviation"),
    (["noise.curve_std=[-0.01]"], r"noise.curve_std = \[-0.01\] is not allowed: a list of standard deviations >= 0"),
    (["noise.curve_std=[]"], r"noise.curve_std = \[\] is not allowed: a list of standard deviations >= 0"),
    (["noise.curve_std=[0.0,inf]"], r"noise.curve_std = \[0.0, inf\] is not allowed: every value must be finite"),
    (["noise.train_std=-1"], r"noise.train_std = -1.0 is not allowed: must be >= 0"),
    (["model.batch_size=0"], r"model.batch_size = 0 is not allowed: must be an integer >= 1"),
    (["model.optim.lr=0"], r"model.optim.lr = 0.0 is not allowed: must be > 0"),
    (["model.optim.lr=-0.1"], r"model.optim.lr = -0.1 is not allowed: must be > 0"),
    (
        ["objective=combined", "objective.labelled_weight=0", "objective.hybrid_weight=0"],
        r"objective.hybrid_weight = 0 is not allowed: .*not both be zero",
    ),
    (["trainer.max_steps=0"], r"trainer.max_steps = 0 is not allowed: must be >= 1"),
    (["data.integration=series"], r"data.integration = 'series' is not allowed: one of t0, window"),
    (
        ["objective=hybrid_bandpass", "objective.filter.high_hz=150"],
        r"objective.filter.high_hz = 150 is not allowed: must lie in \(low_hz = 4, Nyquist = 100 Hz\)",
    ),
    (
        ["objective=hybrid_bandpass", "data.window=150"],
        r"objective.filter.taps = 151 is not allowed: must be <= window - 9 = 141",
    ),
    (
        ["objective=hybrid", "objective.weighting=eiv"],
        r"objective.weighting = 'eiv' is not allowed: none without a filter",
    ),
    (["objective=hybrid", "objective.weighting=tls"], r"objective.weighting = 'tls' is not allowed: one of none, eiv"),
    (["baseline=ls_bandpass_m3", "baseline.unknown=k3"], r"baseline.unknown = 'k3' is not allowed: one of p, m3"),
    (
        ["baseline=ls_bandpass_m3", "data.seat_spread=0.3"],
        r"baseline.unknown = 'm3' is not allowed: needs the car's C3 and K3 on every recording",
    ),
    (
        ["evaluation.windows=[1,0]"],
        r"evaluation.windows = \[1, 0\] is not allowed: a non-empty list of integers K in "
        r"\[1, data.n_steps - data.window \+ 1 = 701\]",
    ),
    (["evaluation.windows=[]"], r"evaluation.windows = \[\] is not allowed: a non-empty list of integers K"),
    (["data=tiny", "evaluation.windows=[202]"], r"evaluation.windows = \[202\] is not allowed: .* = 201\]"),
    (["car.c3=-1"], r"car.c3 = -1.0 is not allowed: must be finite and > 0"),
    (["+car.c4=1"], r"car.c4 = 1.0 is not allowed: unknown; the car's constants are m1, m2, k1, k2, k3, c2, c3"),
    # non-finite values wherever a float is accepted
    (["noise.eval_std=[0.0,inf]"], r"noise.eval_std = \[0.0, inf\] is not allowed: every value must be finite"),
    (["noise.train_std=inf"], r"noise.train_std = inf is not allowed: must be finite"),
    (["model.optim.lr=inf"], r"model.optim.lr = inf is not allowed: must be finite"),
    (["model.optim.lr=nan"], r"model.optim.lr = nan is not allowed: must be finite"),
    (["model.optim.weight_decay=inf"], r"model.optim.weight_decay = inf is not allowed: must be finite"),
    (["data.speed=inf"], r"data.speed = inf is not allowed: must be finite"),
    (["data.dt=nan"], r"data.dt = nan is not allowed: must be finite"),
    (["objective=combined", "objective.hybrid_weight=inf"], r"objective.hybrid_weight = inf is not allowed"),
    # seeds: numpy's and Lightning's are 32-bit unsigned
    (["seed=-1"], r"seed = -1 is not allowed: must lie in \[0, 4294967295\]"),
    (["seed=4294967296"], r"seed = 4294967296 is not allowed: must lie in \[0, 4294967295\]"),
    (["data.seed=-3"], r"data.seed = -3 is not allowed: must lie in \[0, 4294967295\]"),
    # the optimiser, the schedule, the network's and the objective's own arguments
    (["model.optim.name=sgd"], r"model.optim.name = 'sgd' is not allowed: one of adam, adamw"),
    (["model.optim.schedule=linear"], r"model.optim.schedule = 'linear' is not allowed: one of constant, onecycle"),
    (["model.net.kernel_size=4"], r"model.net.kernel_size = 4 is not allowed: an odd integer"),
    (["model.net.downsample=avg"], r"model.net.downsample = 'avg' is not allowed: one of pool, stride"),
    (["+model.net.no_such_arg=1"], r"model.net.no_such_arg = 1 is not allowed: not an argument of FastCNN"),
    (["+objective.norm=l3"], r"objective.norm = 'l3' is not allowed: not an argument of LabelledObjective"),
    # a key the schema does not have, added with +
    (["+data.n_road=3"], r"data.n_road = 3 is not allowed: unknown key \(did you mean data.n_roads\?\)"),
    (["+trainer.max_step=3"], r"trainer.max_step = 3 is not allowed: unknown key"),
    (["+no_such_top=1"], r"no_such_top = 1 is not allowed: unknown key"),
    # a dataset larger than any memory: 40 * 50 recordings of 1e9 steps, 4 channels at 8 bytes (6.4e13 bytes), and
    # 40 road profiles of 1e9 steps twice at 8 bytes (6.4e11): 6.464e13 bytes = 6.02e4 GiB
    (
        ["data.n_steps=1000000000"],
        r"data.n_roads \* data.n_masses \* data.n_steps = '40 \* 50 \* 1000000000' is "
        r"not allowed: the dataset needs about 6.02e\+04 GiB, more than the",
    ),
]


@pytest.mark.parametrize("overrides, match", BAD)
def test_bad_values_are_named(make_cfg, overrides, match):
    with pytest.raises(ConfigError, match=match):
        validate(make_cfg(*overrides))


def test_the_default_config_is_valid(make_cfg):
    for extra in (
        [],
        ["model=paper_cnn"],
        ["data=tiny"],
        ["data=paper"],
        ["objective=combined"],
        ["objective=hybrid"],
        ["baseline=ls_bandpass"],
        ["seed=4294967295", "data.seed=0"],
    ):
        validate(make_cfg(*extra))


def test_every_experiment_is_valid(make_cfg):
    from pathlib import Path

    from hybrid_sysid.config import CONF_DIR

    for name in sorted(p.stem for p in (Path(CONF_DIR) / "experiment").glob("*.yaml")):
        validate(make_cfg(f"experiment={name}"))


def test_a_misspelt_experiment_fails_at_composition(make_cfg):
    # an optional group would silently drop it and run a plain single run
    with pytest.raises(ConfigCompositionException, match="Could not find 'experiment/robustnes'"):
        make_cfg("experiment=robustnes")


def test_the_size_bound_compares_with_the_memory_available(make_cfg, monkeypatch):
    import hybrid_sysid.config.memory as config

    cfg = make_cfg("data=tiny")  # 6 roads * 8 masses * 400 steps
    need = 6 * 8 * 400 * 4 * 8 + 2 * 6 * 400 * 8  # the channels at 8 bytes, the road profiles twice
    assert config.dataset_bytes(6, 8, 400) == need
    monkeypatch.setattr(config, "available_memory", lambda: need - 1)
    with pytest.raises(ConfigError, match="data.n_roads \\* data.n_masses \\* data.n_steps"):
        validate(cfg)
    monkeypatch.setattr(config, "available_memory", lambda: need)
    validate(cfg)


def test_available_memory_is_at_most_what_the_kernel_reports():
    from hybrid_sysid.config import available_memory

    kb = next(int(ln.split()[1]) for ln in open("/proc/meminfo") if ln.startswith("MemAvailable:"))
    got = available_memory()
    assert 0 < got <= kb * 1024 * 1.05  # the kernel's figure moves a little between the two reads


@pytest.mark.parametrize(
    "overrides, error",
    [
        (["data.no_such_key=1"], ConfigKeyError),
        (["data.dt=fast"], ValidationError),
        (["trainer.max_steps=1.5"], ValidationError),
        (["evaluation.windows=[1.5]"], ValidationError),
    ],
)
def test_unknown_keys_and_wrong_types_fail_at_composition(make_cfg, overrides, error):
    with pytest.raises((ConfigCompositionException, error)):
        make_cfg(*overrides)


@pytest.mark.parametrize("overrides", [["objective=no_such"], ["model=no_such"]])
def test_unknown_group_options_fail_at_composition(make_cfg, overrides):
    with pytest.raises(ConfigCompositionException, match="Could not find"):
        make_cfg(*overrides)


def run_cli(tmp_path, *args):
    env = {k: v for k, v in os.environ.items() if k != "HYDRA_FULL_ERROR"}
    env["HYBRID_SYSID_CACHE"] = str(tmp_path / "cache")
    return subprocess.run(
        [sys.executable, "-c", "from hybrid_sysid.cli.train import main; main()", *args],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )


@pytest.mark.integration
def test_cli_prints_one_line_and_exits_2_before_any_work(tmp_path):
    # a real process: all it prints (imports' warnings too) and its exit status, as the shell sees them
    proc = run_cli(tmp_path, "data.speed=0")
    assert proc.returncode == 2
    assert proc.stderr.strip().splitlines()[-1] == "error: data.speed = 0.0 is not allowed: must be > 0 (m/s)"
    assert "Traceback" not in proc.stderr
    assert not (tmp_path / "cache").exists()  # nothing simulated


@pytest.mark.integration
@pytest.mark.parametrize("arg", ["data.no_such_key=1", "objective=no_such"])
def test_cli_composition_errors_exit_2_without_traceback(tmp_path, arg):
    # a real process: all it prints and its exit status, as the shell sees them
    proc = run_cli(tmp_path, arg)
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr
