"""windows= has one range, the estimator's (inference.inputs.check_windows): hybrid-sysid-predict refuses a bad K
with it while parsing, before it reads a run or a recording, and the Python API with the same words."""

import pytest

ALLOWED = "an integer >= 1"


@pytest.mark.parametrize("text", ["0", "-3", "2.5", "two"])
def test_predict_refuses_a_bad_k_in_one_line_before_reading_anything(tmp_path, cli_in_process, text):
    from hybrid_sysid.cli.predict import main

    # neither the run nor the input exists: the refusal of windows= comes before either is read
    args = (f"run={tmp_path / 'no_run'}", f"input={tmp_path / 'no_input.csv'}", f"windows={text}")
    code, out, err = cli_in_process(main, *args, cwd=tmp_path)
    assert code == 2 and out == ""
    assert err.strip().splitlines() == [f"hybrid-sysid-predict: error: windows = '{text}' is not allowed: {ALLOWED}"]


def test_the_estimators_check_takes_what_predict_takes():
    from hybrid_sysid.cli.predict import parse_args
    from hybrid_sysid.core.checks import InputError
    from hybrid_sysid.inference.inputs import check_windows

    assert parse_args(["run=r", "input=i", "windows=1"])["windows"] == check_windows(1) == 1
    assert parse_args(["run=r", "input=i"])["windows"] == 8
    for k in (0, -3, 2.5, True, "1"):
        with pytest.raises(InputError) as caught:
            check_windows(k)
        assert (caught.value.key, caught.value.allowed) == ("windows", ALLOWED)
