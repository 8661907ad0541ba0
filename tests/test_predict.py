"""hybrid-sysid-predict: files read back give the Python API's numbers; every bad input is one line on stderr
and exit status 2."""

import re
import shutil
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest

from hybrid_sysid.cli.predict import main

from estimator_run import recordings  # one trained run (fixtures tiny_run, est) serves both files

PARAMS = ["p1", "p1_std", "p2", "p2_std", "m3_from_p1", "m3_from_p2"]


def write_csv(path, seat, body, dt, names=None, time=True):
    """Recordings (n, steps) as one CSV, long form: a recording column when there are several."""
    frames = []
    for i, (s, b) in enumerate(zip(np.atleast_2d(seat), np.atleast_2d(body))):
        f = pd.DataFrame({"time": np.arange(len(s)) * dt} if time else {})
        f["seat_acc"], f["body_acc"] = s, b
        if names is not None:
            f.insert(0, "recording", names[i])
        frames.append(f)
    pd.concat(frames).to_csv(path, index=False)
    return path


def predict(capsys, *argv):
    """main(argv) in process: (exit status, stdout, stderr)."""
    try:
        main(list(argv))
        code = 0
    except SystemExit as exc:
        code = exc.code
    out = capsys.readouterr()
    return code, out.out, out.err


@pytest.mark.integration
def test_csv_through_the_command_gives_the_api_numbers(tiny_run, est, tmp_path):
    seat, body, _ = recordings(3, 320, est.dt)
    names = ["front", "rear", "spare"]
    csv = write_csv(tmp_path / "rec.csv", seat, body, est.dt, names)
    done = subprocess.run(
        [
            sys.executable,
            "-m",
            "hybrid_sysid.cli.predict",
            f"run={tiny_run}",
            f"input={csv}",
            f"output={tmp_path / 'out.csv'}",
            "windows=5",
        ],
        capture_output=True,
        text=True,
    )
    assert done.returncode == 0, done.stderr
    got = pd.read_csv(tmp_path / "out.csv")
    want = est.predict(seat, body, est.dt, windows=5)
    assert list(got.recording) == names and (got.windows == 5).all() and (got.steps == 320).all()
    assert got[PARAMS].to_numpy() == pytest.approx(want[PARAMS].to_numpy(), rel=1e-5)
    assert done.stdout.splitlines()[0].split() == list(got.columns)


@pytest.mark.integration
def test_bad_input_exits_2_with_one_line_in_a_real_process(tiny_run, est, tmp_path):
    """After the run is loaded, so nothing that loading prints can slip in (warnings, tracebacks)."""
    seat, body, _ = recordings(1, 150, est.dt)
    csv = write_csv(tmp_path / "short.csv", seat, body, est.dt)
    done = subprocess.run(
        [sys.executable, "-m", "hybrid_sysid.cli.predict", f"run={tiny_run}", f"input={csv}"],
        capture_output=True,
        text=True,
    )
    assert done.returncode == 2 and done.stdout == ""
    assert done.stderr.splitlines() == [
        f"hybrid-sysid-predict: error: input = {csv}: recording 0 has 150 steps; "
        "allowed: at least the run's data.window = 200 steps (1 s)"
    ]


def test_npz_one_and_several_recordings(tiny_run, est, tmp_path, capsys):
    seat, body, _ = recordings(2, 300, est.dt)
    np.savez(tmp_path / "two.npz", seat_acc=seat, body_acc=body, dt=est.dt)
    np.savez(tmp_path / "one.npz", seat_acc=seat[1], body_acc=body[1], dt=est.dt)
    for name, rows in (("two", [0, 1]), ("one", [1])):
        code, out, err = predict(
            capsys, f"run={tiny_run}", f"input={tmp_path / name}.npz", "windows=3", f"output={tmp_path / name}.csv"
        )
        assert code == 0, err
        got = pd.read_csv(tmp_path / f"{name}.csv")
        want = est.predict(seat[rows], body[rows], est.dt, windows=3)
        assert got[PARAMS].to_numpy() == pytest.approx(want[PARAMS].to_numpy(), rel=1e-6)
        assert len(out.splitlines()) == 1 + len(rows)


def test_dt_argument_stands_in_for_the_time_column(tiny_run, est, tmp_path, capsys):
    seat, body, _ = recordings(1, 300, est.dt)
    want = est.predict(seat, body, est.dt)
    no_time = write_csv(tmp_path / "no_time.csv", seat, body, est.dt, time=False)
    rounded = write_csv(tmp_path / "rounded.csv", seat, body, est.dt)
    df = pd.read_csv(rounded)
    df["time"] = (df.time * 1.00001).round(4)  # a clock off by 10 ppm, written to 0.1 ms
    df.to_csv(rounded, index=False)
    for path in (no_time, rounded):
        code, _, err = predict(
            capsys, f"run={tiny_run}", f"input={path}", f"dt={est.dt}", f"output={tmp_path / 'out.csv'}"
        )
        assert code == 0, err
        assert pd.read_csv(tmp_path / "out.csv").p1.item() == pytest.approx(want.p1.item(), rel=1e-6)


def test_resample_true_reads_another_rate(tiny_run, est, tmp_path, capsys):
    seat, body, _ = recordings(2, 600, est.dt / 2)
    csv = write_csv(tmp_path / "fast.csv", seat, body, est.dt / 2, names=[1, 2])
    code, _, err = predict(capsys, f"run={tiny_run}", f"input={csv}", "resample=true", f"output={tmp_path / 'o.csv'}")
    assert code == 0, err
    got, want = pd.read_csv(tmp_path / "o.csv"), est.predict(seat, body, est.dt / 2, resample=True)
    assert list(got.steps) == [300, 300]
    assert got[PARAMS].to_numpy() == pytest.approx(want[PARAMS].to_numpy(), rel=1e-6)


def edit(df, **changes):
    """A copy of the CSV frame with cells changed: column=(row, value)."""
    df = df.astype({"seat_acc": object, "time": object})
    for column, (row, value) in changes.items():
        df.loc[row, column] = value
    return df


BAD_CSV = {  # name: (frame -> text written as the input file, message)
    "short": (
        lambda df: df.head(150).to_csv(index=False),
        r"input = .*bad.csv: recording 0 has 150 steps; allowed: at least the run's data.window = 200 steps",
    ),
    "nan": (
        lambda df: edit(df, seat_acc=(5, "nan")).to_csv(index=False),
        r"seat_acc of recording 0 holds nan at step 5: every value must be finite",
    ),
    "empty cell": (
        lambda df: edit(df, seat_acc=(5, "")).to_csv(index=False),
        r"seat_acc of recording 0 holds nan at step 5: every value must be finite",
    ),
    "inf": (
        lambda df: edit(df, seat_acc=(7, "-inf")).to_csv(index=False),
        r"seat_acc of recording 0 holds -inf at step 7: every value must be finite",
    ),
    "text": (
        lambda df: edit(df, seat_acc=(3, "1.2.3")).to_csv(index=False),
        r"column seat_acc holds '1.2.3' in data row 4; allowed: numbers",
    ),
    "missing column": (
        lambda df: df.drop(columns="body_acc").to_csv(index=False),
        r"bad.csv has no column body_acc \(its columns: time, seat_acc\); needed: seat_acc, body_acc",
    ),
    "no time": (
        lambda df: df.drop(columns="time").to_csv(index=False),
        r"has no column time \(its columns: seat_acc, body_acc\); needed: .* and time or dt=",
    ),
    "empty": (lambda df: "", r"bad.csv is empty"),
    "header only": (lambda df: "time,seat_acc,body_acc\n", r"bad.csv holds a header but no rows"),
    "not uniform": (
        lambda df: df.drop(index=100).to_csv(index=False),
        r"column time of recording 0 is not uniform: from 0.495 s to 0.505 s is a step of 0.01 s "
        r"against a mean of 0.005\d* s; allowed: increasing times, every step within 1% of the mean",
    ),
    "decreasing": (lambda df: df[::-1].to_csv(index=False), r"is not uniform: .*allowed: increasing times"),
    "other dt": (
        lambda df: df.assign(time=df.time * 0.8).to_csv(index=False),
        r"input = .*bad.csv: dt = 0.004 s differs from the run's data.dt = 0.005 s; allowed: within 1e-09 "
        r"relative, or pass resample=true",
    ),
    "two rates": (
        lambda df: pd.concat([df.assign(recording="a"), df.assign(recording="b", time=df.time / 2)]).to_csv(
            index=False
        ),
        r"recording 'b' has a time step of 0.0025 s, recording 'a' 0.005 s; allowed: one sample rate",
    ),
    "binary": (lambda df: b"\x89PNG\r\n\x1a\n\x00\x00\xff\xfe\xfd" * 50, r"bad.csv cannot be read as CSV \(Unicode"),
}


@pytest.mark.parametrize("case", list(BAD_CSV))
def test_bad_csv_is_one_line_and_status_2(case, tiny_run, est, tmp_path, capsys):
    seat, body, _ = recordings(1, 400, est.dt)
    df = pd.read_csv(write_csv(tmp_path / "good.csv", seat, body, est.dt))
    content, message = BAD_CSV[case]
    text = content(df)
    path = tmp_path / "bad.csv"
    path.write_bytes(text) if isinstance(text, bytes) else path.write_text(text)
    code, out, err = predict(capsys, f"run={tiny_run}", f"input={path}")
    assert code == 2 and out == ""
    assert len(err.splitlines()) == 1 and err.startswith("hybrid-sysid-predict: error: ")
    assert re.search(message, err), err


def test_bad_arguments_and_runs(tiny_run, est, tmp_path, capsys):
    seat, body, _ = recordings(1, 400, est.dt)
    csv = write_csv(tmp_path / "rec.csv", seat, body, est.dt)
    np.savez(tmp_path / "no_dt.npz", seat_acc=seat, body_acc=body)
    np.savez(tmp_path / "two_dt.npz", seat_acc=seat, body_acc=body, dt=[0.005, 0.005])
    (tmp_path / "text.npz").write_text("seat_acc,body_acc\n1,2\n")
    (tmp_path / "baseline" / ".hydra").mkdir(parents=True)
    cfg = (tiny_run / ".hydra" / "config.yaml").read_text()
    (tmp_path / "baseline" / ".hydra" / "config.yaml").write_text(
        cfg.replace("baseline: null", "baseline:\n  _target_: hybrid_sysid.baselines.LeastSquaresFit")
    )
    (tmp_path / "untrained" / ".hydra").mkdir(parents=True)
    shutil.copy(tiny_run / ".hydra" / "config.yaml", tmp_path / "untrained" / ".hydra")
    run, inp = f"run={tiny_run}", f"input={csv}"
    cases = [
        ((run, inp, "windows=0"), r"windows = '0' is not allowed: an integer >= 1"),
        ((run, inp, "windows=two"), r"windows = 'two' is not allowed: an integer >= 1"),
        (
            (run, inp, "windows=202"),
            r"windows = 202 is not allowed for recording 0: its 400 steps offer 201 "
            r"distinct starts of a 200-step window; allowed: 1 to 201",
        ),
        ((run, inp, "resample=maybe"), r"resample = 'maybe' is not allowed: true or false"),
        ((run, inp, "dt=0"), r"dt = '0' is not allowed: a sampling interval > 0 in seconds"),
        (
            (run, inp, "dt=0.0025"),
            r"dt = 0.0025 s disagrees with the time step of recording 0 of input = .*rec.csv "
            r"\(0.005 s\); allowed: within 1%, or leave dt= out",
        ),
        (
            (run, inp, "seed=3"),
            r"unknown key 'seed' in 'seed=3'; allowed keys: run, input, output, windows, "
            r"resample, dt",
        ),
        ((run, inp, "windows"), r"argument 'windows' is not key=value"),
        ((run, inp, inp), r"input is given twice"),
        ((run,), r"input= is missing; usage: hybrid-sysid-predict run=DIR input=FILE"),
        (
            (run, inp, f"output={tmp_path / 'nowhere' / 'out.csv'}"),
            r"output = .*out.csv: its directory .*nowhere "
            r"does not exist",
        ),
        ((run, f"input={tmp_path}"), r"cannot be read as CSV \(IsADirectoryError"),
        ((run, f"input={tmp_path / 'no_dt.npz'}"), r"no_dt.npz has no array dt \(its arrays: seat_acc, body_acc\)"),
        ((run, f"input={tmp_path / 'two_dt.npz'}"), r"array dt is \[0.005, 0.005\]; allowed: one number > 0"),
        ((run, f"input={tmp_path / 'text.npz'}"), r"text.npz cannot be read as .npz"),
        (
            (f"run={tmp_path / 'nothing'}", inp),
            r"run = .*nothing has no .hydra/config.yaml; allowed: a run "
            r"directory written by hybrid-sysid",
        ),
        (
            (f"run={tmp_path / 'untrained'}", inp),
            r"run = .*untrained has no checkpoint .*best.ckpt or "
            r".*last.ckpt; allowed: a run that trained a network",
        ),
        (
            (f"run={tmp_path / 'baseline'}", inp),
            r"is a baseline \(baseline._target_ = "
            r"hybrid_sysid.baselines.LeastSquaresFit\) without a trained",
        ),
    ]
    for argv, message in cases:
        code, out, err = predict(capsys, *argv)
        assert code == 2 and out == "", argv
        assert len(err.splitlines()) == 1 and re.search(message, err), (argv, err)


def test_help_prints_usage(capsys):
    code, out, _ = predict(capsys, "--help")
    assert code == 0 and "hybrid-sysid-predict run=DIR input=FILE" in out
