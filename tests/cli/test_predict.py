"""hybrid-sysid-predict: files read back give the Python API's numbers; every bad input is one line on stderr
and exit status 2; output= never replaces the input, a run's files or (without overwrite=true) any file."""

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from hybrid_sysid.cli.predict import main

from helpers.estimator_run import predict, recordings  # one trained run (fixtures tiny_run, est) serves both files
from helpers.started_early import started_early

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


def test_csv_through_the_command_gives_the_api_numbers(tiny_run, est, tmp_path, capsys, monkeypatch):
    # the module as `python -m hybrid_sysid.cli.predict` runs it, in this process: its arguments from the command
    # line, its files read back against the API (what a real process prints: the test below)
    import runpy

    seat, body, _ = recordings(3, 320, est.dt)
    names = ["front", "rear", "spare"]
    csv = write_csv(tmp_path / "rec.csv", seat, body, est.dt, names)
    argv = [f"run={tiny_run}", f"input={csv}", f"output={tmp_path / 'out.csv'}", "windows=5"]
    monkeypatch.setattr(sys, "argv", ["hybrid_sysid.cli.predict", *argv])
    try:
        runpy.run_module("hybrid_sysid.cli.predict", run_name="__main__", alter_sys=True)
        code = 0
    except SystemExit as exc:
        code = exc.code
    out = capsys.readouterr()
    done = subprocess.CompletedProcess(argv, code, out.out, out.err)
    assert done.returncode == 0, done.stderr
    got = pd.read_csv(tmp_path / "out.csv")
    want = est.predict(seat, body, est.dt, windows=5)
    assert list(got.recording) == names and (got.windows == 5).all() and (got.steps == 320).all()
    assert got[PARAMS].to_numpy() == pytest.approx(want[PARAMS].to_numpy(), rel=1e-5)
    assert done.stdout.splitlines()[0].split() == list(got.columns)


@started_early
def short_input(tmp, env, tiny_run, est):
    """A real process: all it prints, which in this process pytest would take (warnings) or earlier tests would
    have printed already (a warning shows once a process)."""
    seat, body, _ = recordings(1, 150, est.dt)
    csv = write_csv(tmp / "short.csv", seat, body, est.dt)
    cli = [sys.executable, "-m", "hybrid_sysid.cli.predict", f"run={tiny_run}", f"input={csv}"]
    return subprocess.run(cli, cwd=tmp, env=env, capture_output=True, text=True, timeout=300), csv


@pytest.mark.integration
def test_bad_input_exits_2_with_one_line_in_a_real_process(short_input):
    """After the run is loaded, so nothing that loading prints can slip in (warnings, tracebacks)."""
    done, csv = short_input
    assert done.returncode == 2 and done.stdout == ""
    assert done.stderr.splitlines() == [
        f"hybrid-sysid-predict: error: input = {csv}: recording 0 = 150 steps is not allowed: "
        "at least the run's data.window = 200 steps (1 s)"
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
        out = tmp_path / f"out_{path.stem}.csv"
        code, _, err = predict(capsys, f"run={tiny_run}", f"input={path}", f"dt={est.dt}", f"output={out}")
        assert code == 0, err
        assert pd.read_csv(out).p1.item() == pytest.approx(want.p1.item(), rel=1e-6)


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
        r"input = .*bad.csv: recording 0 = 150 steps is not allowed: at least the run's data.window = 200 steps",
    ),
    "nan": (
        lambda df: edit(df, seat_acc=(5, "nan")).to_csv(index=False),
        r"seat_acc of recording 0 at step 5 = nan is not allowed: finite values",
    ),
    "empty cell": (
        lambda df: edit(df, seat_acc=(5, "")).to_csv(index=False),
        r"seat_acc of recording 0 at step 5 = nan is not allowed: finite values",
    ),
    "inf": (
        lambda df: edit(df, seat_acc=(7, "-inf")).to_csv(index=False),
        r"seat_acc of recording 0 at step 7 = -inf is not allowed: finite values",
    ),
    "text": (
        lambda df: edit(df, seat_acc=(3, "1.2.3")).to_csv(index=False),
        r"column seat_acc in data row 4 = '1.2.3' is not allowed: numbers",
    ),
    "missing column": (
        lambda df: df.drop(columns="body_acc").to_csv(index=False),
        r"bad.csv is not allowed: columns seat_acc, body_acc, and time or dt= \(it has no body_acc; its columns: time, "
        r"seat_acc\)",
    ),
    "no time": (
        lambda df: df.drop(columns="time").to_csv(index=False),
        r"is not allowed: columns seat_acc, body_acc, and time or dt= \(it has no time; its columns: seat_acc, "
        r"body_acc\)",
    ),
    "empty": (lambda df: "", r"bad.csv is not allowed: a CSV or .npz file of recordings, not an empty one"),
    "header only": (lambda df: "time,seat_acc,body_acc\n", r"bad.csv is not allowed: .*it holds a header but no rows"),
    "not uniform": (
        lambda df: df.drop(index=100).to_csv(index=False),
        r"column time of recording 0 = a step of 0.01 s from 0.495 s to 0.505 s is not allowed: uniform, increasing "
        r"times, every step within 1% of the mean, 0.005\d* s",
    ),
    "decreasing": (lambda df: df[::-1].to_csv(index=False), r"is not allowed: uniform, increasing times"),
    "other dt": (
        lambda df: df.assign(time=df.time * 0.8).to_csv(index=False),
        r"input = .*bad.csv: dt = 0.004 is not allowed: the run's data.dt = 0.005 s within 1e-09 relative, or "
        r"resample=true",
    ),
    "two rates": (
        lambda df: pd.concat([df.assign(recording="a"), df.assign(recording="b", time=df.time / 2)]).to_csv(
            index=False
        ),
        r"the time step of recording 'b' = 0.0025 s is not allowed: one sample rate per file, recording 'a''s 0.005 s",
    ),
    "binary": (
        lambda df: b"\x89PNG\r\n\x1a\n\x00\x00\xff\xfe\xfd" * 50,
        r"bad.csv is not allowed: a file that can be read as CSV \(Unicode",
    ),
    "beyond float32": (
        lambda df: edit(df, seat_acc=(5, "1e300")).to_csv(index=False),
        r"seat_acc of recording 0 at step 5 = 1e\+300 is not allowed: magnitudes up to 3.40282e\+38, float32's "
        r"range, in which the network reads it",
    ),
    "beyond float32, negative": (
        lambda df: edit(df, body_acc=(9, -3.5e38)).to_csv(index=False),
        r"body_acc of recording 0 at step 9 = -3.5e\+38 is not allowed: magnitudes up to",
    ),
    "column twice": (
        lambda df: duplicated(df).to_csv(index=False),
        r"input = .*bad.csv: column seat_acc = 2 times in the header \(columns 2, 4\) is not allowed: each of "
        r"seat_acc, body_acc, time, recording once",
    ),
    "column twice, spaced": (
        lambda df: duplicated(df).to_csv(index=False).replace(",", ", ", 3),  # the header's three commas
        r"column seat_acc = 2 times in the header \(columns 2, 4\)",
    ),
    "time twice": (
        lambda df: df.assign(t2=df.time).rename(columns={"t2": "time"}).to_csv(index=False),
        r"column time = 2 times in the header \(columns 1, 4\)",
    ),
    "true/false": (
        lambda df: df.assign(seat_acc=np.where(df.seat_acc > 0, "True", "False")).to_csv(index=False),
        r"input = .*bad.csv: column seat_acc in data row 1 = (True|False) is not allowed: numbers, not true/false",
    ),
    "true/false with an empty cell": (
        lambda df: df.assign(body_acc=[""] + ["true", "false"] * ((len(df) - 1) // 2) + ["true"]).to_csv(index=False),
        r"column body_acc in data row 2 = True is not allowed: numbers, not true/false",
    ),
}


def duplicated(df):
    """The frame with a second seat_acc column (another sensor's values) after body_acc."""
    return df.assign(other=-df.seat_acc).rename(columns={"other": "seat_acc"})


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
    (tmp_path / "untrained" / ".hydra").mkdir(parents=True)
    shutil.copy(tiny_run / ".hydra" / "config.yaml", tmp_path / "untrained" / ".hydra")
    run, inp = f"run={tiny_run}", f"input={csv}"
    cases = [
        ((run, inp, "windows=0"), r"windows = '0' is not allowed: an integer >= 1"),
        ((run, inp, "windows=two"), r"windows = 'two' is not allowed: an integer >= 1"),
        (
            (run, inp, "windows=202"),
            r"windows = 202 is not allowed: 1 to 201 for recording 0: its 400 steps offer 201 "
            r"distinct starts of a 200-step window",
        ),
        ((run, inp, "resample=maybe"), r"resample = 'maybe' is not allowed: true or false"),
        ((run, inp, "dt=0"), r"dt = '0' is not allowed: a sampling interval > 0 in seconds"),
        (
            (run, inp, "dt=0.0025"),
            r"dt = 0.0025 is not allowed: the time step of recording 0 of input = .*rec.csv, 0.005 s, within 1%, "
            r"or no dt= at all",
        ),
        (
            (run, inp, "seed=3"),
            r"seed is not allowed: a key one of run, input, output, overwrite, windows, resample, dt "
            r"\(in 'seed=3'\)",
        ),
        ((run, inp, "windows"), r"windows is not allowed: key=value, a key one of run"),
        ((run, inp, inp), r"input is not allowed: once \(it is given twice"),
        ((run,), r"input is missing: usage: hybrid-sysid-predict run=DIR input=FILE"),
        (
            (run, inp, f"output={tmp_path / 'nowhere' / 'out.csv'}"),
            r"output = .*out.csv is not allowed: a file in a directory that exists \(.*nowhere "
            r"does not\)",
        ),
        ((run, f"input={tmp_path}"), r"is not allowed: a regular file \(a CSV or .npz file\), not a device"),
        (
            (run, f"input={tmp_path / 'no_dt.npz'}"),
            r"no_dt.npz is not allowed: .*\(it has no array dt; its arrays: seat_acc, body_acc\)",
        ),
        ((run, f"input={tmp_path / 'two_dt.npz'}"), r"array dt = \[0.005, 0.005\] is not allowed: one number > 0"),
        ((run, f"input={tmp_path / 'text.npz'}"), r"text.npz is not allowed: a file that can be read as .npz"),
        (
            (f"run={tmp_path / 'nothing'}", inp),
            r"run = .*nothing is not allowed: it has no .hydra/config.yaml \(a run "
            r"directory written by hybrid-sysid\)",
        ),
        (
            (f"run={tmp_path / 'untrained'}", inp),
            r"run = .*untrained is not allowed: a run that trained a network, with checkpoints/best.ckpt or "
            r"last.ckpt",
        ),
    ]
    for argv, message in cases:
        code, out, err = predict(capsys, *argv)
        assert code == 2 and out == "", argv
        assert len(err.splitlines()) == 1 and re.search(message, err), (argv, err)


def test_help_prints_usage(capsys):
    code, out, _ = predict(capsys, "--help")
    assert code == 0 and "hybrid-sysid-predict run=DIR input=FILE" in out


def files_under(folder):
    """{path: bytes} of every file below folder (links followed), to show nothing changed or appeared."""
    return {p: p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def test_output_never_replaces_the_input(tiny_run, est, tmp_path, capsys, monkeypatch):
    """Its own path, another spelling of it, a symbolic and a hard link: refused with or without overwrite=true."""
    seat, body, _ = recordings(1, 300, est.dt)
    csv = write_csv(tmp_path / "rec.csv", seat, body, est.dt)
    (tmp_path / "sub").mkdir()
    (tmp_path / "link.csv").symlink_to(csv)
    os.link(csv, tmp_path / "hard.csv")
    before = files_under(tmp_path)
    monkeypatch.chdir(tmp_path)
    for output in (str(csv), "rec.csv", "./rec.csv", "sub/../rec.csv", "link.csv", "hard.csv"):
        for extra in ((), ("overwrite=true",)):
            code, out, err = predict(capsys, f"run={tiny_run}", f"input={csv}", f"output={output}", *extra)
            assert code == 2 and out == "", (output, extra, err)
            assert err.splitlines() == [
                f"hybrid-sysid-predict: error: output = {output} is not allowed: it is the input file (input = {csv}); "
                "another file, an output never replaces its input"
            ]
            assert files_under(tmp_path) == before, (output, extra)


def test_output_never_replaces_a_runs_files(tiny_run, est, tmp_path, capsys):
    """Inside run= (its files, a new file, a link to its record) or inside any directory above the output that
    holds a run's record or config: refused with or without overwrite=true, every file as it was."""
    seat, body, _ = recordings(1, 300, est.dt)
    csv = write_csv(tmp_path / "rec.csv", seat, body, est.dt)
    run = tmp_path / "run"
    shutil.copytree(tiny_run, run)  # a copy: a failing check must not damage the shared run
    other = tmp_path / "other"
    (other / "plots").mkdir(parents=True)
    (other / "metrics.json").write_text('{"status": "completed"}\n')
    configured = tmp_path / "configured"
    (configured / ".hydra").mkdir(parents=True)
    (configured / ".hydra" / "config.yaml").write_text("seed: 0\n")
    (tmp_path / "to_record.csv").symlink_to(run / "metrics.json")
    before = files_under(tmp_path)
    assert run / "metrics.json" in before and run / "checkpoints" / "best.ckpt" in before
    in_run = rf"is not allowed: it lies inside the run directory run = {re.escape(str(run))}; a path outside run "
    in_run += "and sweep directories"
    cases = [
        (run / "metrics.json", in_run),
        (run / "checkpoints" / "best.ckpt", in_run),
        (run / ".hydra" / "config.yaml", in_run),
        (run / "estimates.csv", in_run),
        (tmp_path / "to_record.csv", in_run),
        (
            other / "estimates.csv",
            r"is not allowed: it lies inside the run or sweep directory .*other; a",
        ),
        (other / "plots" / "estimates.csv", r"is not allowed: it lies inside the run or sweep directory .*other; a"),
        (
            configured / "estimates.csv",
            r"is not allowed: it lies inside the run or sweep directory .*configured; a",
        ),
    ]
    for output, message in cases:
        for extra in ((), ("overwrite=true",)):
            code, out, err = predict(capsys, f"run={run}", f"input={csv}", f"output={output}", *extra)
            assert code == 2 and out == "", (output, extra, err)
            assert len(err.splitlines()) == 1 and re.search(
                rf"error: output = {re.escape(str(output))} " + message, err
            )
            assert files_under(tmp_path) == before, (output, extra)


def test_existing_output_needs_overwrite_true(tiny_run, est, tmp_path, capsys, monkeypatch):
    seat, body, _ = recordings(2, 300, est.dt)
    csv = write_csv(tmp_path / "rec.csv", seat, body, est.dt, names=["a", "b"])
    out = tmp_path / "estimates.csv"
    out.write_text("keep me\n")
    run, inp = f"run={tiny_run}", f"input={csv}"
    code, printed, err = predict(capsys, run, inp, f"output={out}")
    assert code == 2 and printed == "" and out.read_text() == "keep me\n"
    assert err.splitlines() == [
        f"hybrid-sysid-predict: error: output = {out} is not allowed: it exists; a new file, or overwrite=true to "
        "replace it"
    ]
    code, _, err = predict(capsys, run, inp, f"output={out}", "overwrite=maybe")
    assert code == 2 and re.search(r"overwrite = 'maybe' is not allowed: true or false", err)
    code, _, err = predict(capsys, run, inp, f"output={out}", "overwrite=true", "windows=3")
    assert code == 0, err
    got, want = pd.read_csv(out), est.predict(seat, body, est.dt, windows=3)
    assert list(got.recording) == ["a", "b"]
    assert got[PARAMS].to_numpy() == pytest.approx(want[PARAMS].to_numpy(), rel=1e-6)

    # a file that appears under the output's name while the recordings are estimated is kept too
    import hybrid_sysid.cli.predict as cli

    late, load = tmp_path / "late.csv", cli.load_estimator

    class Racing:  # the run's estimator; someone else writes late.csv while it works
        def __init__(self, run):
            self.est = load(run)

        def predict(self, *args, **kwargs):
            late.write_text("someone else's\n")
            return self.est.predict(*args, **kwargs)

    monkeypatch.setattr(cli, "load_estimator", Racing)
    code, _, err = predict(capsys, run, inp, f"output={late}")
    assert code == 2 and late.read_text() == "someone else's\n"
    assert err.splitlines() == [
        f"hybrid-sysid-predict: error: output = {late} is not allowed: it appeared while the recordings were "
        "estimated and is left as it is; a new file, or overwrite=true to replace it"
    ]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["estimates.csv", "late.csv", "rec.csv"]  # no temp file


def test_bool_complex_and_overflowing_npz_arrays(tiny_run, est, tmp_path, capsys):
    seat, body, _ = recordings(2, 300, est.dt)
    big = body.copy()
    big[1, 9] = -1e39
    arrays = {
        "bool": dict(seat_acc=seat > 0, body_acc=body),
        "complex": dict(seat_acc=seat, body_acc=body + 0.5j),
        "big": dict(seat_acc=seat, body_acc=big),
    }
    messages = {
        "bool": r"bool.npz: array seat_acc = dtype bool, shape \(2, 300\) is not allowed: real numbers \(a float or "
        r"integer array, not bool or complex\)",
        "complex": r"complex.npz: array body_acc = dtype complex128, shape \(2, 300\) is not allowed: real numbers "
        r"\(a float or integer array, not bool or complex\)",
        "big": r"big.npz: body_acc of recording 1 at step 9 = -1e\+39 is not allowed: magnitudes up to 3.40282e\+38, "
        r"float32's range, in which the network reads it",
    }
    for name, content in arrays.items():
        np.savez(tmp_path / f"{name}.npz", dt=est.dt, **content)
        code, out, err = predict(capsys, f"run={tiny_run}", f"input={tmp_path / name}.npz")
        assert code == 2 and out == "", (name, err)
        assert len(err.splitlines()) == 1 and re.search(messages[name], err), (name, err)


def test_a_column_named_like_pandas_renames_a_duplicate_is_read(tiny_run, est, tmp_path, capsys):
    """Duplicates are found in the header itself: a column really named seat_acc.1 is another column."""
    seat, body, _ = recordings(1, 300, est.dt)
    csv = write_csv(tmp_path / "rec.csv", seat, body, est.dt)
    pd.read_csv(csv).assign(**{"seat_acc.1": 1e3}).to_csv(csv, index=False)
    code, _, err = predict(capsys, f"run={tiny_run}", f"input={csv}", f"output={tmp_path / 'out.csv'}")
    assert code == 0, err
    got, want = pd.read_csv(tmp_path / "out.csv"), est.predict(seat, body, est.dt)
    assert got[PARAMS].to_numpy() == pytest.approx(want[PARAMS].to_numpy(), rel=1e-6)


def test_windows_beyond_the_memory_available_are_refused(tiny_run, est, tmp_path, capsys, monkeypatch):
    """A window of 2 x 200 steps takes 8000 bytes: 3200 as float64, twice (cut, then stacked), and 1600 as the
    float32 copy the network reads. With 800 kB available, 100 windows fit and 101 do not."""
    import hybrid_sysid.inference.memory as estimator

    monkeypatch.setattr(estimator, "tightest_memory", lambda: (800_000, "free memory (MemAvailable)"))
    seat, body, _ = recordings(1, 400, est.dt)
    csv = write_csv(tmp_path / "rec.csv", seat, body, est.dt)
    code, out, err = predict(capsys, f"run={tiny_run}", f"input={csv}", "windows=101")
    assert code == 2 and out == ""
    assert err.splitlines() == [
        f"hybrid-sysid-predict: error: input = {csv}: windows = 101 is not allowed: 1 to 100 for recording 0 (400 "
        f"steps): 101 windows of 2 x 200 steps need {101 * 8000 / 2**30:.3g} GiB of memory (float64, cut and "
        f"stacked, plus a float32 copy of up to 4096 windows) and {800_000 / 2**30:.3g} GiB is available (free memory "
        "(MemAvailable))"
    ]
    code, out, err = predict(capsys, f"run={tiny_run}", f"input={csv}", "windows=100")
    assert code == 0 and len(out.splitlines()) == 2, err


def test_ctrl_c_exits_130_with_one_line_and_no_output(tiny_run, est, tmp_path, capsys, monkeypatch):
    """Interrupted while reading, or while writing output= (the partial file is removed)."""
    import hybrid_sysid.cli.predict as cli

    seat, body, _ = recordings(1, 300, est.dt)
    csv = write_csv(tmp_path / "rec.csv", seat, body, est.dt)
    out = tmp_path / "out.csv"

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    def half_written(self, path, **kwargs):
        Path(path).write_text("recording,steps\n")
        raise KeyboardInterrupt

    for target, name, replacement in ((cli, "read_input", interrupted), (pd.DataFrame, "to_csv", half_written)):
        with monkeypatch.context() as patch:
            patch.setattr(target, name, replacement)
            try:
                with pytest.raises(SystemExit) as ended:
                    main([f"run={tiny_run}", f"input={csv}", f"output={out}"])
            except KeyboardInterrupt:
                pytest.fail(f"KeyboardInterrupt from {name} escaped main()")
        assert ended.value.code == 130
        assert capsys.readouterr().err.splitlines() == ["hybrid-sysid-predict: interrupted (Ctrl-C)"]
        assert sorted(p.name for p in tmp_path.iterdir()) == ["rec.csv"], name


def test_a_npy_array_named_npz_is_one_line(tiny_run, tmp_path, capsys):
    np.save(tmp_path / "x.npy", np.zeros(400))
    (tmp_path / "x.npy").rename(tmp_path / "x.npz")
    with pytest.raises(SystemExit) as exit_:
        main([f"run={tiny_run}", f"input={tmp_path / 'x.npz'}"])
    err = capsys.readouterr().err.strip().splitlines()
    assert exit_.value.code == 2 and len(err) == 1 and "is a single .npy array, not an .npz archive" in err[0]
