"""A time step's range has one home, core.checks.check_dt: a finite number of seconds > 0. Each entry point that
takes a dt (the simulator, the road, the filters, the integrators, the EIV fit, the data spec, an .npz file's dt,
predict's dt= and the estimator) goes through it and keeps its own one-line error naming its key or file."""

import ast
import math
from pathlib import Path

import numpy as np
import pytest

from hybrid_sysid.core.checks import ConfigError, InputError, check_dt

SRC = Path(__file__).resolve().parents[2] / "src" / "hybrid_sysid"
NUMBERS = [0.005, 1, 5e-324, 1e300, np.float32(0.002), np.int64(2), 0, 0.0, -0.0, -1e-9, math.nan, math.inf, -math.inf]


@pytest.mark.parametrize("value", NUMBERS + [True, "0.002", None, [0.1]])
def test_a_time_step_is_a_finite_real_number_above_zero(value):
    real = isinstance(value, (int, float, np.floating, np.integer)) and not isinstance(value, bool)
    good = real and math.isfinite(float(value)) and float(value) > 0
    if good:
        assert check_dt(value) == float(value) and isinstance(check_dt(value), float)
    else:
        with pytest.raises(ConfigError, match=r"^dt = .* is not allowed: must be > 0 \(seconds\)$"):
            check_dt(value)


@pytest.mark.parametrize(("text", "good"), [("0.002", True), ("2e-3", True), (" 1 ", True), ("0", False)])
def test_text_counts_where_the_entry_point_reads_text(text, good):
    if good:
        assert check_dt(text, text=True) == float(text)
    for bad in ["abc", "", "inf", "nan", "-1", None] if good else [text]:
        with pytest.raises(InputError, match=r"^where = .* is not allowed: its words$"):
            check_dt(bad, "where", "its words", InputError, text=True)


def test_each_entry_point_keeps_its_own_line():
    from hybrid_sysid.cli.arguments import UsageError, parse
    from hybrid_sysid.cli.predict import KEYS
    from hybrid_sysid.data.spec import DatasetSpec
    from hybrid_sysid.physics import road_profiles
    from hybrid_sysid.physics.filters import check_bandpass
    from hybrid_sysid.physics.integrate import integrate

    with pytest.raises(ConfigError, match=r"^dt = 0\.0 is not allowed: must be > 0 \(seconds\)$"):
        road_profiles(["A"], 10, 0.0, 15.0)
    with pytest.raises(ConfigError, match=r"^dt = nan is not allowed: must be > 0 \(seconds; the data's time step\)$"):
        check_bandpass(4.0, 20.0, 101, math.nan)
    with pytest.raises(ConfigError, match=r"^dt = -0\.1 is not allowed: must be > 0 \(seconds\)$"):
        integrate(np.zeros(10), -0.1)
    with pytest.raises(ConfigError, match=r"^dt = 0 is not allowed: must be > 0 \(seconds\)$"):
        DatasetSpec(dt=0).validate_values()
    with pytest.raises(UsageError, match=r"^dt = '-2' is not allowed: a sampling interval > 0 in seconds$"):
        parse(["run=r", "input=i", "dt=-2"], KEYS)
    assert parse(["run=r", "input=i", "dt=0.002"], KEYS)[0]["dt"] == 0.002


@pytest.mark.parametrize(("saved", "shown"), [(np.float64(-1.0), "-1.0"), (np.array([0.0, 1.0]), r"\[0.0, 1.0\]")])
def test_an_npz_dt_is_checked_there_too_and_named_by_its_file(tmp_path, saved, shown):
    from hybrid_sysid.data.readers import read_input

    path = tmp_path / "r.npz"
    np.savez(path, seat_acc=np.zeros(50), body_acc=np.zeros(50), dt=saved)
    with pytest.raises(InputError, match=rf"^input = .*r\.npz: array dt = {shown} is not allowed: one number > 0"):
        read_input(path)
    np.savez(path, seat_acc=np.zeros(50), body_acc=np.zeros(50), dt=np.array([0.004]))  # one number, as 1-D
    assert read_input(path).dt == 0.004


def test_no_module_checks_a_dt_s_range_itself():
    """No comparison of a dt with 0 and no check_positive/check_number of "dt" outside core.checks: a new entry
    point calls check_dt."""
    found = []
    for path in SRC.rglob("*.py"):
        if path.name == "checks.py" and path.parent.name == "core":
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Compare) and len(node.ops) == 1:
                sides = [node.left, node.comparators[0]]
                named = any(isinstance(s, ast.Name) and s.id == "dt" or getattr(s, "attr", "") == "dt" for s in sides)
                zero = any(isinstance(s, ast.Constant) and s.value == 0 for s in sides)
                if named and zero:
                    found.append(f"{path.relative_to(SRC)}:{node.lineno}")
            if isinstance(node, ast.Call) and getattr(node.func, "id", "") in ("check_positive", "check_number"):
                if node.args and isinstance(node.args[0], ast.Constant) and node.args[0].value == "dt":
                    found.append(f"{path.relative_to(SRC)}:{node.lineno}")
    assert found == []
