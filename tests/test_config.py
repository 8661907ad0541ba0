"""Bad config values fail before any work, with one line naming the key, the value and what is allowed."""

import os
import subprocess
import sys

import pytest
from hydra.errors import ConfigCompositionException
from omegaconf.errors import ConfigKeyError, ValidationError

from hybrid_sysid.config import ConfigError, validate

BAD = [
    (["data.window=1300"], r"data.window = 1300 is not allowed: must lie in \[16, data.n_steps = 1200\]"),
    (["model=paper_cnn", "data.window=40"], r"data.window = 40 is not allowed: must lie in \[59, data.n_steps"),
    (["data.dt=0"], r"data.dt = 0.0 is not allowed: must be > 0"),
    (["data.dt=0.05"], r"data.dt = 0.05 is not allowed: the semi-implicit Euler scheme is unstable above 0.036"),
    (["data.speed=-2"], r"data.speed = -2.0 is not allowed: must be > 0"),
    (["trainer.curve_every_n_steps=250"], r"trainer.curve_every_n_steps = 250 is not allowed: a multiple of "
                                          r"trainer.eval_every_n_steps = 200"),
    (["data.n_roads=2"], r"data.n_roads = 2 is too few for data.train_fraction = 0.8"),
    (["data.train_fraction=1.0"], r"data.train_fraction = 1.0 is not allowed: must lie in \(0, 1\)"),
    (["data.train_fraction=0"], r"data.train_fraction = 0.0 is not allowed: must lie in \(0, 1\)"),
    (["data.m3_min=150", "data.m3_max=100"], r"data.m3_max = 100 is not allowed: empty mass range"),
    (["data.m3_min=-10"], r"data.m3_min = -10 is not allowed: must be > 0 kg"),
    (["road.classes=[A,X]"], r"road.classes = \['A', 'X'\] is not allowed: each class must be one of A, B, C, D, E"),
    (["noise.eval_std=[0.0,-0.01]"], r"noise.eval_std = \[0.0, -0.01\] is not allowed: every standard deviation"),
    (["noise.train_std=-1"], r"noise.train_std = -1.0 is not allowed: must be >= 0"),
    (["model.batch_size=0"], r"model.batch_size = 0 is not allowed: must be >= 1"),
    (["model.optim.lr=0"], r"model.optim.lr = 0.0 is not allowed: must be > 0"),
    (["model.optim.lr=-0.1"], r"model.optim.lr = -0.1 is not allowed: must be > 0"),
    (["objective=combined", "objective.labelled_weight=0", "objective.hybrid_weight=0"],
     r"objective.labelled_weight / objective.hybrid_weight = \[0, 0\] is not allowed: .*not both zero"),
    (["trainer.max_steps=0"], r"trainer.max_steps = 0 is not allowed: must be >= 1"),
    (["data.integration=series"], r"data.integration = 'series' is not allowed: one of t0, window"),
    (["objective=hybrid_bandpass", "objective.filter.high_hz=150"],
     r"objective.filter.high_hz = 150 is not allowed: must lie in \(low_hz = 4, Nyquist = 100 Hz\)"),
    (["objective=hybrid_bandpass", "data.window=150"],
     r"objective.filter.taps = 151 is not allowed: must be <= data.window - 9 = 141"),
    (["objective=hybrid", "objective.weighting=eiv"],
     r"objective.weighting = 'eiv' is not allowed: needs objective.filter"),
    (["objective=hybrid", "objective.weighting=tls"], r"objective.weighting = 'tls' is not allowed: one of none, eiv"),
    (["model=ls_bandpass_m3", "model.net.unknown=k3"], r"model.net.unknown = 'k3' is not allowed: one of p, m3"),
    (["model=ls_bandpass_m3", "data.seat_spread=0.3"],
     r"model.net.unknown = 'm3' is not allowed: needs the car's C3 and K3 on every recording"),
    (["evaluation.windows=[1,0]"], r"evaluation.windows = \[1, 0\] is not allowed: a non-empty list of integers K in "
                                   r"\[1, data.n_steps - data.window \+ 1 = 701\]"),
    (["evaluation.windows=[]"], r"evaluation.windows = \[\] is not allowed: a non-empty list of integers K"),
    (["data=tiny", "evaluation.windows=[202]"], r"evaluation.windows = \[202\] is not allowed: .* = 201\]"),
    (["car.c3=-1"], r"car.c3 = -1.0 is not allowed: must be finite and > 0"),
    (["+car.c4=1"], r"car.c4 = 1.0 is not allowed: unknown; the car's constants are m1, m2, k1, k2, k3, c2, c3"),
]


@pytest.mark.parametrize("overrides, match", BAD)
def test_bad_values_are_named(make_cfg, overrides, match):
    with pytest.raises(ConfigError, match=match):
        validate(make_cfg(*overrides))


def test_the_default_config_is_valid(make_cfg):
    for extra in ([], ["model=paper_cnn"], ["data=tiny"], ["data=paper"], ["objective=combined"]):
        validate(make_cfg(*extra))


@pytest.mark.parametrize("overrides, error", [
    (["data.no_such_key=1"], ConfigKeyError),
    (["data.dt=fast"], ValidationError),
    (["trainer.max_steps=1.5"], ValidationError),
    (["evaluation.windows=[1.5]"], ValidationError),
])
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
    return subprocess.run([sys.executable, "-c", "from hybrid_sysid.app import main; main()", *args],
                          cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300)


@pytest.mark.integration
def test_cli_prints_one_line_and_exits_2_before_any_work(tmp_path):
    proc = run_cli(tmp_path, "data.speed=0")
    assert proc.returncode == 2
    assert proc.stderr.strip().splitlines()[-1] == "error: data.speed = 0.0 is not allowed: must be > 0 (m/s)"
    assert "Traceback" not in proc.stderr
    assert not (tmp_path / "cache").exists()  # nothing simulated


@pytest.mark.integration
@pytest.mark.parametrize("arg", ["data.no_such_key=1", "objective=no_such"])
def test_cli_composition_errors_exit_2_without_traceback(tmp_path, arg):
    proc = run_cli(tmp_path, arg)
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr
