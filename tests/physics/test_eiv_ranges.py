"""noise_ratio and skew_max have one check each (physics.eiv's check_noise_ratio, the skew fix's check_skew_max):
fit_eiv, crb_relative_std, the baselines and the command line refuse a bad value with the same key and range."""

import numpy as np
import pytest

from hybrid_sysid.core.checks import ConfigError

NOISE_RANGE = "must lie in [0, 1e+06] (sigma_body^2 / sigma_seat^2)"
SKEW_RANGE = "must be >= 0 (seconds)"
WINDOWS = np.random.default_rng(0).standard_normal((2, 2, 400))  # any windows: the check comes first


@pytest.mark.parametrize("ratio", [-1.0, 2e6, float("nan")])
def test_a_bad_noise_ratio_is_refused_by_the_fit_the_bound_and_the_baseline(ratio):
    from hybrid_sysid.baselines import ErrorsInVariablesFit
    from hybrid_sysid.physics.eiv import crb_relative_std, fit_eiv

    calls = [
        lambda: fit_eiv(*WINDOWS, 0.005, noise_ratio=ratio),
        lambda: crb_relative_std(*WINDOWS, np.ones((2, 2)), 0.005, noise_ratio=ratio),
        lambda: ErrorsInVariablesFit(noise_ratio=ratio),
    ]
    for call in calls:
        with pytest.raises(ConfigError) as caught:
            call()
        assert caught.value.key == "noise_ratio" and caught.value.allowed == NOISE_RANGE


def test_the_ends_of_the_noise_ratio_range_are_taken():
    from hybrid_sysid.baselines import ErrorsInVariablesFit

    assert [ErrorsInVariablesFit(noise_ratio=r).noise_ratio for r in (0, 1e6)] == [0.0, 1e6]


def test_a_negative_skew_max_is_refused_by_the_fit_and_the_baselines():
    from hybrid_sysid.baselines import ErrorsInVariablesFit, LeastSquaresFit
    from hybrid_sysid.physics.eiv import fit_eiv

    calls = [
        lambda: fit_eiv(*WINDOWS, 0.005, skew_max=-0.01),
        lambda: ErrorsInVariablesFit(skew_max=-0.01),
        lambda: LeastSquaresFit(skew_max=-0.01),
    ]
    for call in calls:
        with pytest.raises(ConfigError) as caught:
            call()
        assert str(caught.value) == f"skew_max = -0.01 is not allowed: {SKEW_RANGE}"


@pytest.mark.parametrize(
    "arg, line",
    [
        ("baseline.noise_ratio=2e6", f"baseline.noise_ratio = 2000000.0 is not allowed: {NOISE_RANGE}"),
        ("baseline.skew_max=-0.01", f"baseline.skew_max = -0.01 is not allowed: {SKEW_RANGE}"),
    ],
)
def test_the_command_refuses_them_in_one_line_before_any_work(tmp_path, cli_in_process, arg, line):
    from hybrid_sysid.cli.train import main

    work = tmp_path / "work"
    work.mkdir()
    env = {"HYBRID_SYSID_CACHE": tmp_path / "cache"}
    code, _, err = cli_in_process(main, "data=tiny", "baseline=eiv", arg, cwd=work, env=env)
    assert code == 2 and err.strip().splitlines() == [f"error: {line}"], err[-2000:]
    assert list(work.iterdir()) == [] and not (tmp_path / "cache").exists()
