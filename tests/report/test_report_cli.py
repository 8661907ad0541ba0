"""hybrid-sysid-report: files written, tables printed, exit codes 0 / 1 / 2, and the sweep figures."""

import matplotlib.image as mpimg
import numpy as np
import pandas as pd
import pytest

from hybrid_sysid.cli.report import main
from hybrid_sysid.runs.rundir import RunDir

from helpers.evaluation_fakes import OBJECTIVES, make_run, make_sweep, parse_markdown

PNG = b"\x89PNG\r\n\x1a\n"


def assert_real_png(path):
    """A PNG with a drawn plot in it, not an empty canvas."""
    assert path.read_bytes()[:8] == PNG and path.stat().st_size > 10_000
    img = mpimg.imread(path)[..., :3]
    assert img.shape[0] > 300 and img.shape[1] > 500
    colours = np.unique((img * 255).astype(np.uint8).reshape(-1, 3), axis=0)
    assert len(colours) > 50 and (img < 0.5).mean() > 0.005  # anti-aliased lines, text and markers


def test_report_on_sweep_with_failures_writes_everything_and_returns_1(sweep, capsys):
    assert main([str(sweep)]) == 1  # default out=: the single PATH
    out = capsys.readouterr().out
    for name in ("summary.csv", "summary.md"):
        assert (sweep / name).is_file()
    rows = parse_markdown(out)
    assert [r["objective"] for r in rows] == sorted(OBJECTIVES) and out in (sweep / "summary.md").read_text()
    assert set(pd.read_csv(sweep / "summary.csv").status) == {"completed", "failed", "unreadable"}
    assert_real_png(sweep / "figures" / "robustness.png")
    assert_real_png(sweep / "figures" / "learning_curves_compared.png")


def test_report_on_a_sweep_with_an_interrupted_job_writes_everything_and_returns_1(tmp_path, capsys):
    sweep = make_sweep(tmp_path / "sweep", failed=False)
    # the record a job writes when a signal stops it (launch/job.py), by the same writer
    RunDir(sweep / "4").record_end(["objective=hybrid", "seed=2", "noise=ladder"], 2, "interrupted", "by SIGTERM")
    assert main([str(sweep)]) == 1
    assert set(pd.read_csv(sweep / "summary.csv").status) == {"completed", "interrupted"}
    failed = (sweep / "summary.md").read_text().split("## Failed jobs", 1)[1]
    assert "`4` (objective=hybrid, seed=2): interrupted: by SIGTERM" in failed
    assert (sweep / "figures" / "robustness.png").is_file()
    assert main([str(sweep / "0")]) == 0  # a completed run alone: the interrupted one made the 1


def test_a_runs_damaged_curves_predictions_and_figures_are_skipped_and_the_run_reported(tiny_run, tmp_path, capsys):
    import shutil

    runs = {name: shutil.copytree(tiny_run, tmp_path / name / "run") for name in ("whole", "damaged")}
    damaged = runs["damaged"]
    curves = (damaged / "curves.csv").read_bytes()
    (damaged / "curves.csv").write_bytes(curves[: len(curves) // 2] + b"\x00\xff,,\n")  # cut mid-line, garbage
    (damaged / "predictions.csv").write_bytes(b"\x89PNG not a table\x00\xff")
    (damaged / "figures").mkdir(exist_ok=True)
    (damaged / "figures" / "test_predictions.png").write_bytes(b"half a png")
    tables = {}
    for name, run in runs.items():
        assert main([run, f"out={tmp_path / name / 'report'}"]) == 0
        out, err = capsys.readouterr()
        assert "Traceback" not in err and "1 run, 0 failed or unreadable" in err
        tables[name] = (out, pd.read_csv(tmp_path / name / "report" / "summary.csv"))
    # the run is reported from its record, as the undamaged copy is
    assert tables["damaged"][0] == tables["whole"][0]
    pd.testing.assert_frame_equal(tables["damaged"][1], tables["whole"][1])


def test_report_merges_sweeps_into_report_dir_and_returns_0(tmp_path, monkeypatch, capsys):
    a = make_sweep(tmp_path / "a", failed=False)
    b = make_sweep(tmp_path / "b", failed=False, extra=("road=C",))
    monkeypatch.chdir(tmp_path)
    assert main([str(a), str(b), "metric=std_rel_dev"]) == 0
    df = pd.read_csv(tmp_path / "report" / "summary.csv", keep_default_na=False)
    assert sorted(df.run.unique()) == sorted(f"{s}/{j}" for s in "ab" for j in range(4))  # no name clash
    rows = parse_markdown(capsys.readouterr().out)
    assert [(r["objective"], r["road"], r["seeds"]) for r in rows] == [
        ("hybrid", "(default)", "2"),
        ("hybrid", "C", "2"),
        ("labelled", "(default)", "2"),
        ("labelled", "C", "2"),
    ]
    assert (tmp_path / "report" / "figures" / "robustness.png").is_file()


def test_report_on_a_single_run_and_out_option(tmp_path, capsys):
    run = make_run(tmp_path / "runs" / "2026-01-01_12-00-00", ["seed=0"], 0)
    assert main([str(run), f"out={tmp_path / 'out'}", "split=val"]) == 0
    [row] = parse_markdown(capsys.readouterr().out)
    assert row["all"] == "all" and list(row)[1] == "noise 0 p1 [%]"  # val is evaluated at noise 0 only
    assert pd.read_csv(tmp_path / "out" / "summary.csv").run.unique().tolist() == [run.name]


@pytest.mark.parametrize("case", ["missing", "empty"])
def test_report_returns_2_with_one_line_for_a_path_without_runs(tmp_path, sweep, capsys, case):
    bad = tmp_path / "nope"
    if case == "empty":
        bad.mkdir()
    assert main([str(sweep), str(bad), f"out={tmp_path / 'out'}"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and str(bad) in err and "error" in err
    assert not (tmp_path / "out").exists()


def test_latex_and_compare_options(tmp_path, capsys):
    a = make_sweep(tmp_path / "a", failed=False)
    assert main([str(a), "latex=true"]) == 0
    tex = (a / "summary.tex").read_text()
    assert r"\begin{tabular}" in tex and r"\mathbf{" in tex and "hybrid &" in tex and "labelled &" in tex
    assert "summary.tex" in capsys.readouterr().err
    assert main([str(a), "compare=objective"]) == 0
    assert "`objective`" in capsys.readouterr().out
    assert main([str(a), "compare=road", f"out={tmp_path / 'o'}"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "compare = 'road' is not allowed" in err and not (tmp_path / "o").exists()


@pytest.mark.parametrize(
    "arg, message",
    [
        ("split=nonsense", "split = 'nonsense' is not allowed: one of train, val, test"),
        ("spilt=val", "spilt is not allowed: a key one of split, metric"),
        ("metric=nonsense", "metric = 'nonsense' is not allowed: one of mean_rel_dev, std_rel_dev"),
        ("latex=maybe", "latex = 'maybe' is not allowed: true or false"),
        ("--nonsense", "--nonsense is not allowed: key=value without dashes"),
    ],
)
def test_a_bad_argument_is_one_line_and_status_2(sweep, tmp_path, capsys, arg, message):
    assert main([str(sweep), arg, f"out={tmp_path / 'out'}"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and message in err and err.startswith("hybrid-sysid-report: error: ")
    assert not (tmp_path / "out").exists()


def test_dashed_flags_are_refused_with_the_key_value_form(tmp_path, capsys):
    """The former --key value flags are gone: each is one line naming the key=value form."""
    a = make_sweep(tmp_path / "a", failed=False)
    assert main([str(a), "--split", "val", f"out={tmp_path / 'flags'}"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--split is not allowed: key=value without dashes (split=VALUE)" in err
    assert not (tmp_path / "flags").exists()


def test_help_says_what_the_command_does(capsys):
    assert main(["--help"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("hybrid-sysid-report: rebuild the comparison table") and "split=test" in out
    assert "examples:" in out


def test_an_out_that_cannot_be_written_is_one_line_and_status_2(sweep, tmp_path, capsys):
    blocker = tmp_path / "a_file"
    blocker.write_text("")
    assert main([str(sweep), f"out={blocker / 'report'}"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "cannot write the report: NotADirectoryError" in err[0]
