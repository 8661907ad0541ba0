"""Values of the errors-in-variables fits and the anchored estimator that once passed the checks, or were named
under another key: each is one ConfigError naming its own key (docs/reliability/adversarial_physical_limit.md)."""

import pytest

from hybrid_sysid.config import validate
from hybrid_sysid.core.checks import ConfigError

TINY = ["data=tiny", "data.n_steps=1000", "trainer=debug"]


@pytest.mark.parametrize(
    "overrides, key",
    [
        (["estimator=eiv_map", "baseline.prior.m3_min=0"], "baseline.prior.m3_min"),  # was baseline.m3_min
        (["estimator=eiv_map", "baseline.prior.seat_spread=1.5"], "baseline.prior.seat_spread"),
        (["estimator=eiv_map", "+baseline.prior.seat_sprad=0.3"], "baseline.prior.seat_sprad"),  # was ignored
        (["estimator=eiv_map", "baseline.prior=5"], "baseline.prior"),  # was "baseline" and a TypeError
        (["model=anchored", "model.net.prior=5"], "model.net.prior"),  # was "model.net" and a TypeError
        (["estimator=eiv", "baseline.fix=skew", "baseline.skew_max=10"], "baseline.skew_max"),  # was "seat", at work
        (["model=anchored", "model.net.dt=0.01"], "model.net.dt"),  # trained and tested 50% off, exit 0
        (["estimator=anchored_cross_segment", "objective.dt=0.002"], "objective.dt"),
        (["estimator=eiv", "baseline.dt=0.01"], "baseline.dt"),
    ],
)
def test_a_bad_value_of_the_fits_is_named_under_its_own_key(make_cfg, overrides, key):
    with pytest.raises(ConfigError) as err:
        validate(make_cfg(*TINY, *overrides))
    assert err.value.key == key, str(err.value)
    assert "\n" not in str(err.value)


@pytest.mark.parametrize(
    "overrides",
    [
        ["estimator=eiv", "baseline.fix=skew"],  # the preset's skew_max fits a window of 200 samples
        ["model=anchored", "data.dt=0.002"],  # dt follows the data's through ${data.dt}
        ["estimator=eiv_map", "baseline.prior=null"],  # the likelihood fit alone
    ],
)
def test_the_presets_and_the_data_step_pass(make_cfg, overrides):
    validate(make_cfg(*TINY, *overrides))


def test_a_band_pass_of_a_billion_taps_is_refused_before_it_is_built():
    """baseline.taps (and every filter's taps) of 10^9 asked for 7.45 GiB while the baseline was built, before
    the window's check: a received run's config got hybrid-sysid-predict killed by the kernel."""
    from hybrid_sysid.physics.filters import MAX_TAPS, bandpass_taps, check_bandpass

    with pytest.raises(ConfigError) as err:
        check_bandpass(4.0, 20.0, 1_000_000_001, 0.005)
    assert err.value.key == "taps" and f"<= {MAX_TAPS}" in str(err.value)
    assert len(bandpass_taps(4.0, 20.0, MAX_TAPS, 0.005)) == MAX_TAPS
