"""Fault injection on the app as a cluster or a user would meet it: termination signals to a run and to a
sweep, a full disk, and refusals that must leave nothing behind. A real process where the process is what is tested
(signals, another process's lock, a full disk), those of the signals and the full disk started early, beside other
tests (started_early.py); a refusal, which ends before any work, and a resume or re-run, which only reads what an
ended process left, run the command's main() in this process (cli_in_process in conftest.py). Damaged files:
tests/runs/test_reliability.py."""

import json
import shutil
import signal
import subprocess
import sys
import time
from types import SimpleNamespace

import pandas as pd
import pytest
import torch
from omegaconf import OmegaConf

from helpers import app_process
from helpers.mounts import small_tmpfs
from helpers.started_early import started_early

pytestmark = [pytest.mark.integration, pytest.mark.faults]

ARGS = [
    "data=tiny",
    "trainer=debug",
    "trainer.max_steps=400",
    "trainer.eval_every_n_steps=200",
    "trainer.progress_bar=false",
    "noise.eval_std=[0.0,0.05]",
]
TINY = [
    "data=tiny",
    "trainer=debug",
    "trainer.max_steps=10",
    "trainer.eval_every_n_steps=5",
    "trainer.progress_bar=false",
]


# the app's process (app_process.py) with the dataset cache ``cache``: the shared tiny_cache, whose data=tiny a run
# then reads instead of simulating it, else an empty one of the test's own


def launch(tmp_path, *args, cache=None, env=None):
    return app_process.launch(tmp_path, *args, cache=cache or tmp_path / "cache", env=env)


def run_app(tmp_path, *args, cache=None, env=None):
    return app_process.run_app(tmp_path, *args, cache=cache or tmp_path / "cache", env=env)


def record(run_dir):
    return json.loads((run_dir / "metrics.json").read_text())


def wait_for(path, proc, timeout=600):
    deadline = time.time() + timeout
    while not path.exists() and proc.poll() is None and time.time() < deadline:
        time.sleep(0.05)
    assert proc.poll() is None, "the run ended before the signal could be sent"


def same_numbers(a, b):
    assert b["status"] == "completed" and b["steps"] == a["steps"]
    for ra, rb in zip(a["results"], b["results"], strict=True):
        assert (ra["split"], ra["noise_std"], ra["parameter"]) == (rb["split"], rb["noise_std"], rb["parameter"])
        assert rb["mean_rel_dev"] == pytest.approx(ra["mean_rel_dev"], rel=1e-5, abs=1e-7)


@pytest.fixture(scope="module")
def reference_run(tmp_path_factory, tiny_cache):
    """The uninterrupted run of ARGS, trained in this process by the function the app's job runs (train), its
    config saved as Hydra saves it: the numbers an interrupted run must resume to, and a completed run to
    evaluate. Not a subprocess: nothing here is about the process (the tests below start theirs)."""
    from hydra import compose, initialize_config_dir

    from hybrid_sysid.config import CONF_DIR
    from hybrid_sysid.training.run import train

    run = tmp_path_factory.mktemp("reference") / "run"
    with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
        cfg = compose(config_name="config", overrides=[*ARGS, f"data.cache_dir={tiny_cache}"])
    n = torch.get_num_threads()
    try:
        assert train(cfg, run, ARGS)["status"] == "completed"
    finally:
        torch.set_num_threads(n)
    (run / ".hydra").mkdir()
    OmegaConf.save(cfg, run / ".hydra" / "config.yaml")
    return run


@pytest.fixture(scope="module")
def uninterrupted(reference_run):
    return record(reference_run)


def interrupt(tmp_path, run, how, cache, env=None):
    """Start a run, wait for its first checkpoint (step 200 of 400), then end it with ``how``."""
    proc = launch(tmp_path, *ARGS, f"hydra.run.dir={run}", cache=cache, env=env)
    wait_for(run / "checkpoints" / "last.ckpt", proc)
    time.sleep(0.3)  # a few steps past the checkpoint, well before the next one
    proc.send_signal(how)
    out, _ = proc.communicate(timeout=600)
    return proc.returncode, out


@pytest.mark.slow  # SIGKILL; the SIGTERM case below resumes the same way
def test_killed_run_resumes_to_the_same_metrics(tmp_path, uninterrupted, tiny_cache):
    run = tmp_path / "killed"
    code, _ = interrupt(tmp_path, run, signal.SIGKILL, tiny_cache)
    assert code == -signal.SIGKILL and not (run / "metrics.json").exists()
    saved = torch.load(run / "checkpoints" / "last.ckpt", map_location="cpu")  # torch's default weights_only
    assert saved["global_step"] == 200

    resumed = run_app(tmp_path, *ARGS, f"resume={run}", cache=tiny_cache)
    assert resumed.returncode == 0, resumed.stderr[-2000:]
    assert "resuming from" in resumed.stdout + resumed.stderr
    same_numbers(uninterrupted, record(run))
    # the learning curve carries on across the restart
    assert sorted(pd.read_csv(run / "curves.csv").step.unique()) == [200, 400]
    assert sorted(p.name for p in (run / "checkpoints").iterdir()) == ["best.ckpt", "last.ckpt"]


@started_early
def terminated_run(tmp, env, tiny_cache):
    """A real process: a SIGTERM to the app's process and its exit status (what interrupt() returns, and the run's
    directory)."""
    return *interrupt(tmp, tmp / "run", signal.SIGTERM, tiny_cache, env), tmp / "run"


@started_early
def interrupted_run(tmp, env, tiny_cache):
    """As terminated_run, with SIGINT."""
    return *interrupt(tmp, tmp / "run", signal.SIGINT, tiny_cache, env), tmp / "run"


@pytest.mark.parametrize(
    "how",
    [
        pytest.param(signal.SIGTERM, marks=pytest.mark.started_early("terminated_run")),
        pytest.param(signal.SIGINT, marks=[pytest.mark.slow, pytest.mark.started_early("interrupted_run")]),
    ],
    ids=["SIGTERM", "SIGINT"],
)
def test_a_terminated_run_records_it_and_resumes_moved_to_the_same_numbers(
    request, tmp_path, uninterrupted, how, tiny_cache, cli_in_process
):
    # the resume, which only reads the files the first process left, through the command's main() in this process
    from hybrid_sysid.cli.train import main

    code, out, run = request.getfixturevalue("terminated_run" if how == signal.SIGTERM else "interrupted_run")
    assert code == 128 + how, out[-2000:]
    rec = record(run)
    assert rec["status"] == "interrupted" and signal.Signals(how).name in rec["error"]
    moved = tmp_path / "moved"  # a copied or moved run directory resumes from its own files
    run.rename(moved)
    code, _, err = cli_in_process(main, *ARGS, f"resume={moved}", cwd=tmp_path, env={"HYBRID_SYSID_CACHE": tiny_cache})
    resumed = subprocess.CompletedProcess(main, code, "", err)
    assert resumed.returncode == 0, resumed.stderr[-2000:]
    same_numbers(uninterrupted, record(moved))
    assert sorted(p.name for p in (moved / "checkpoints").iterdir()) == ["best.ckpt", "last.ckpt"]  # no -v1


@pytest.mark.parametrize("key", ["hydra.run.dir", "hydra.sweep.dir"])
def test_a_directory_another_process_holds_is_refused_before_anything_is_written(tmp_path, key):
    """The lock alone, held here as another writer would hold it: the command is refused in one line, exit 2,
    and nothing in the directory changes (the test below has a real first writer finish)."""
    # a new process: the lock is another process's (this one holds it)
    from hybrid_sysid.runs.locks import hold_for_writing

    where = tmp_path / "held"
    where.mkdir()
    (where / "mine.txt").write_text("the first writer's file")
    lock = hold_for_writing(where, key)
    try:
        sweep = ["-m", "launcher=basic"] if key == "hydra.sweep.dir" else []
        proc = run_app(tmp_path, *sweep, *ARGS, f"{key}={where}")
    finally:
        lock.release()
    assert proc.returncode == 2, proc.stderr[-2000:]
    assert proc.stderr.strip().splitlines() == [
        f"error: {key} = {where} is not allowed: another process is writing there (a run or sweep of hybrid-sysid); "
        f"wait until it ends, or choose another {key}"
    ]
    assert sorted(p.name for p in where.iterdir()) == [".writer.lock", "mine.txt"]


@pytest.mark.slow  # a real first writer; the test above refuses a held directory in the default run
@pytest.mark.parametrize("mode", ["run", "sweep"])
def test_a_second_writer_is_refused_and_the_first_finishes_untouched(tmp_path, mode):
    """One writer per run or sweep directory: while one command writes there, another into the same directory is
    refused in one line, exit 2, before Hydra writes anything, and the first ends with its own config and record."""
    where = tmp_path / "shared"
    key = "hydra.run.dir" if mode == "run" else "hydra.sweep.dir"
    sweep = ["-m", "launcher=basic"] if mode == "sweep" else []
    first = launch(tmp_path, *sweep, *ARGS, "seed=0", f"{key}={where}")
    config = where / ".hydra" / "config.yaml" if mode == "run" else where / "0" / ".hydra" / "config.yaml"
    wait_for(config, first)
    second = run_app(tmp_path, *sweep, *ARGS, "seed=1", f"{key}={where}")
    assert second.returncode == 2, second.stderr[-2000:]
    assert "another process is writing there" in second.stderr and len(second.stderr.strip().splitlines()) == 1
    out, _ = first.communicate(timeout=600)
    assert first.returncode == 0, out[-2000:]
    job = where if mode == "run" else where / "0"
    assert record(job)["status"] == "completed" and record(job)["seed"] == 0
    assert OmegaConf.load(job / ".hydra" / "config.yaml").seed == 0


@pytest.fixture
def truncated_run(tmp_path, reference_run):
    """A copy of the reference run whose best.ckpt is cut to its first kilobyte."""
    run = tmp_path / "truncated"
    shutil.copytree(reference_run, run)
    best = run / "checkpoints" / "best.ckpt"
    best.write_bytes(best.read_bytes()[:1000])
    return run


@pytest.mark.parametrize(
    "case",
    [
        "eval without run=",
        "eval of a truncated checkpoint",
        pytest.param("init_from a truncated one", marks=pytest.mark.slow),  # the same check_weights as eval's
    ],
)
def test_a_refused_evaluation_or_init_from_is_one_line_and_leaves_no_directory(
    tmp_path, truncated_run, case, cli_in_process
):
    # in this process (the command's main()): a refusal ends before any work; an evaluation refused in a real
    # process: tests/experiments/test_transfer.py::test_eval_cli_sweeps_cars_and_refuses_another_objective
    from hybrid_sysid.cli.evaluate import main as evaluate
    from hybrid_sysid.cli.train import main as train

    out = tmp_path / "out"
    if case.startswith("eval"):
        cli = [evaluate, f"hydra.run.dir={out}"] + ([] if case == "eval without run=" else [f"run={truncated_run}"])
    else:
        cli = [train, *ARGS, f"init_from={truncated_run}", f"hydra.run.dir={out}"]
    code, stdout, stderr = cli_in_process(*cli, cwd=tmp_path, env={"HYBRID_SYSID_CACHE": tmp_path / "cache"})
    proc = subprocess.CompletedProcess(cli, code, stdout, stderr)
    assert proc.returncode == 2, proc.stderr[-2000:]
    assert len(proc.stderr.strip().splitlines()) == 1, proc.stderr[-2000:]
    expected = "run is missing" if case == "eval without run=" else "checkpoints/best.ckpt cannot be read"
    assert expected in proc.stderr
    assert not out.exists() and not (tmp_path / "outputs").exists()


def test_an_evaluation_never_writes_into_a_completed_run(tmp_path, reference_run, cli_in_process):
    """hybrid-sysid-eval's preflight refuses, before Hydra writes .hydra/, a directory that holds a completed run
    of other overrides; the run's saved config and record stay as they were."""
    # in this process (the command's main()): the refusal comes before any work, and before Hydra writes anything
    from hybrid_sysid.cli.evaluate import main as evaluate

    saved = {p: p.read_bytes() for p in (reference_run / ".hydra").iterdir()}
    rec = (reference_run / "metrics.json").read_bytes()
    cli = [evaluate, f"run={reference_run}", "car=soft_seat", f"hydra.run.dir={reference_run}"]
    code, out, err = cli_in_process(*cli, cwd=tmp_path, env={"HYBRID_SYSID_CACHE": tmp_path / "cache"})
    proc = subprocess.CompletedProcess(cli, code, out, err)
    assert proc.returncode == 2, proc.stderr[-2000:]
    assert "holds a completed run of other overrides" in proc.stderr and len(proc.stderr.splitlines()) == 1
    assert {p: p.read_bytes() for p in (reference_run / ".hydra").iterdir()} == saved
    assert (reference_run / "metrics.json").read_bytes() == rec


@started_early
def terminated_evaluation(tmp, env, tiny_run):
    """A real process: a SIGTERM to it and its exit status; its cache stays its own and empty (see below). What the
    test asserts on: whether the evaluation still ran when the signal was sent, its exit status and output, its
    command and its directory."""
    out = tmp / "eval"
    # the default data: simulating it (an empty cache) outlasts the signal's way there
    cli = [sys.executable, "-m", "hybrid_sysid.cli.evaluate", f"run={tiny_run}", "data=default", f"hydra.run.dir={out}"]
    proc = subprocess.Popen(
        cli,
        cwd=tmp,
        env=app_process.user_env(env, tmp / "cache"),
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    deadline = time.time() + 600  # until the evaluation locks the dataset cache to simulate the data
    while not any((tmp / "cache").glob("*.lock")) and proc.poll() is None and time.time() < deadline:
        time.sleep(0.05)
    running = proc.poll() is None
    if running:
        proc.send_signal(signal.SIGTERM)
    text, _ = proc.communicate(timeout=600)
    return running, proc.returncode, text, cli, out


def test_a_terminated_evaluation_records_it_and_a_rerun_completes_it(terminated_evaluation, tiny_run, cli_in_process):
    # the re-run, which only reads what the first process left, through the command's main() in this process
    from hybrid_sysid.cli.evaluate import main as evaluate

    running, code, text, cli, out = terminated_evaluation
    assert running, "the evaluation ended before the signal could be sent"
    assert code == 128 + signal.SIGTERM, text[-3000:]
    assert record(out)["status"] == "interrupted" and "SIGTERM" in record(out)["error"]
    cwd = out.parent
    code, _, err = cli_in_process(evaluate, *cli[3:], cwd=cwd, env={"HYBRID_SYSID_CACHE": cwd / "cache"})
    again = subprocess.CompletedProcess(cli, code, "", err)
    assert again.returncode == 0, again.stderr[-3000:]
    assert record(out)["status"] == "completed" and record(out)["source_run"] == str(tiny_run)


def sweep_statuses(sw):
    summary = pd.read_csv(sw / "summary.csv", dtype={"run": str})
    return summary.drop_duplicates("run").set_index("run").status.to_dict()


def terminated_sweep(tmp, env, cache, launcher, how):
    """A sweep signalled once its first job has recorded, then the same command again. Real processes: a signal to
    the sweep's parent, which passes it on to its workers, and its exit status. What the test asserts on: whether
    the sweep still ran when the signal was sent, its exit status and output, the statuses, summary.md and the
    completed records it left, the second command's process and the sweep's directory."""
    sw = tmp / "sw"
    args = ["-m", f"launcher={launcher}", "seed=0,1,2", *TINY, f"hydra.sweep.dir={sw}"]
    proc = launch(tmp, *args, cache=cache, env=env)
    deadline = time.time() + 600
    while not any(sw.glob("*/metrics.json")) and proc.poll() is None and time.time() < deadline:
        time.sleep(0.05)
    running = proc.poll() is None
    if running:
        proc.send_signal(how)  # the parent only, as `timeout` or `kill` would
    out, _ = proc.communicate(timeout=600)
    first = SimpleNamespace(running=running, returncode=proc.returncode, out=out, sw=sw)
    first.statuses = sweep_statuses(sw)
    first.summary = (sw / "summary.md").read_text()
    first.done = {
        run: (sw / run / "metrics.json").read_bytes() for run, s in first.statuses.items() if s == "completed"
    }
    first.again = run_app(tmp, *args, cache=cache, env=env)
    return first


@started_early
def interrupted_sweep(tmp, env, tiny_cache):
    """terminated_sweep() through joblib's parallel workers, ended with SIGINT."""
    return terminated_sweep(tmp, env, tiny_cache, "joblib", signal.SIGINT)


@started_early
def terminated_basic_sweep(tmp, env, tiny_cache):
    """terminated_sweep() through the basic launcher, ended with SIGTERM."""
    return terminated_sweep(tmp, env, tiny_cache, "basic", signal.SIGTERM)


@pytest.mark.parametrize(
    "launcher, how",
    [
        pytest.param(
            "basic", signal.SIGTERM, marks=[pytest.mark.slow, pytest.mark.started_early("terminated_basic_sweep")]
        ),
        pytest.param("joblib", signal.SIGINT, marks=pytest.mark.started_early("interrupted_sweep")),
    ],
)
def test_a_terminated_sweep_writes_its_summary_and_a_rerun_completes_it(request, launcher, how):
    first = request.getfixturevalue("interrupted_sweep" if launcher == "joblib" else "terminated_basic_sweep")
    sw = first.sw
    assert first.running, "the sweep ended before the signal could be sent"
    assert first.returncode == 128 + how, first.out[-3000:]
    statuses = first.statuses
    assert set(statuses.values()) <= {"completed", "interrupted"} and "interrupted" in statuses.values()
    assert "completed" in statuses.values()
    assert "interrupted" in first.summary

    again = first.again
    assert again.returncode == 0, again.stderr[-3000:]
    assert set(sweep_statuses(sw).values()) == {"completed"} and len(sweep_statuses(sw)) == 3
    assert all((sw / run / "metrics.json").read_bytes() == b for run, b in first.done.items())  # not trained again


@started_early
def full_disk(tmp, env, tiny_cache):
    """A real process: what it prints and its exit status when its own files cannot be written. What the test
    asserts on: the process, the record it left (None if none) and the temporary files left behind."""
    with small_tmpfs(tmp / "small", "192k") as mnt:
        proc = run_app(tmp, *TINY, f"hydra.run.dir={mnt / 'run'}", cache=tiny_cache, env=env)
        stored = record(mnt / "run") if (mnt / "run" / "metrics.json").exists() else None
        return proc, stored, list((mnt / "run").rglob("*.tmp"))


def test_a_full_disk_ends_with_a_record_or_one_line(full_disk):
    proc, rec, left = full_disk
    assert proc.returncode != 0
    if rec is not None:
        assert rec["status"] == "failed" and ("No space" in rec["error"] or "write" in rec["error"])
    else:
        assert "error: could not record the failed job" in proc.stderr
    assert not left


@started_early
def evaluations_onto_a_full_disk(tmp, env, tiny_run, tiny_cache):
    """Real processes: hybrid-sysid-eval onto a tmpfs too small for it. At 8 KiB Hydra cannot write the .hydra/
    files (before the job); at the larger sizes the job's own files meet the full disk. What the test asserts on:
    per size, the exit status, stderr and what is left on the filesystem."""
    ended = {}
    for size in ("8k", "20k", "28k"):
        with small_tmpfs(tmp / f"small_{size}", size) as mnt:
            cli = [f"run={tiny_run}", f"hydra.run.dir={mnt / 'eval'}"]
            proc = app_process.run_app(tmp, *cli, cache=tiny_cache, env=env, module="hybrid_sysid.cli.evaluate")
            ended[size] = proc.returncode, proc.stderr, sorted(p.name for p in mnt.rglob("*"))
    return ended


def test_an_evaluation_onto_a_full_disk_is_one_line_and_leaves_no_directory(evaluations_onto_a_full_disk):
    ended = evaluations_onto_a_full_disk
    for size, (_, err, left) in ended.items():
        assert err.count("\n") == 1 and err.startswith("error: ") and "No space left" in err, (size, err)
        assert not left, (size, left)  # neither the evaluation's directory nor a half-written file in it
    # before the job (Hydra's .hydra/): an OS error before any job; during it: a failure of the work
    assert ended["8k"][0] == 2
    assert {code for code, _, _ in ended.values()} == {1, 2}


def refused(proc, *words):
    assert proc.returncode == 2, proc.stderr[-2000:]
    last = proc.stderr.strip().splitlines()[-1]
    assert last.startswith("error: ") and all(w in last for w in words), last
    assert "Traceback" not in proc.stderr


# one case per kind of refusal (every value's own check: tests/config/test_config.py, through the same validate)
@pytest.mark.parametrize(
    "args, words",
    [
        (["experiment=robustnes"], ["experiment = 'robustnes' is not allowed: one of", "robustness"]),
        (["+data.n_road=3"], ["data.n_road", "unknown key"]),
        (["resume=no/such/dir"], ["resume", "no such directory"]),
        (["hydra.run.dir=a_file/run"], ["hydra.run.dir", "cannot be created"]),
    ],
)
def test_refusals_are_one_line_and_leave_nothing_behind(tmp_path, args, words, cli_in_process):
    # the command's main() in this process: each refusal ends before any work; a refusal in a real process, one
    # line and exit 2 as the shell sees them:
    # tests/config/test_config.py::test_cli_prints_one_line_and_exits_2_before_...
    from hybrid_sysid.cli.train import main

    (tmp_path / "a_file").write_text("not a directory")
    code, out, err = cli_in_process(main, *TINY, *args, cwd=tmp_path, env={"HYBRID_SYSID_CACHE": tmp_path / "cache"})
    proc = subprocess.CompletedProcess(args, code, out, err)
    if "Could not find" in words[0]:  # Hydra's own composition error: several lines, no traceback, exit 2
        assert proc.returncode == 2 and words[0] in proc.stderr and "Traceback" not in proc.stderr
    else:
        refused(proc, *words)
    assert not (tmp_path / "outputs").exists() and not (tmp_path / "cache").exists()
    assert not (tmp_path / "no").exists()


@pytest.mark.slow  # test_reliability.py checks the same guard in-process
def test_no_command_replaces_a_completed_record(tmp_path):
    run = tmp_path / "run"
    first = run_app(tmp_path, *TINY, f"hydra.run.dir={run}")
    assert first.returncode == 0, first.stderr[-2000:]
    files = [run / "metrics.json", *(run / ".hydra").iterdir()]
    before = [p.read_bytes() for p in files]
    refused(run_app(tmp_path, *TINY, "seed=1", f"resume={run}"), "resume", "seed = 0 there, 1 here")
    refused(run_app(tmp_path, *TINY, "seed=1", f"hydra.run.dir={run}"), "holds a completed run of other overrides")
    assert [p.read_bytes() for p in files] == before  # Hydra's saved config of the run included
    again = run_app(tmp_path, *TINY, f"resume={run}")
    assert again.returncode == 0 and "already completed" in again.stdout + again.stderr
    assert (run / "metrics.json").read_bytes() == before[0]

    sw = tmp_path / "sw"
    sweep = run_app(tmp_path, "-m", "model.optim.lr=0.001,-1", *TINY, f"hydra.sweep.dir={sw}")
    records = {p: p.read_bytes() for p in sw.glob("*/metrics.json")}
    assert sweep.returncode == 1 and len(records) == 2
    refused(
        run_app(tmp_path, "-m", "model.optim.lr=-1,0.001", *TINY, f"hydra.sweep.dir={sw}"),
        "hydra.sweep.dir",
        "holds a sweep of other overrides",
    )
    assert {p: p.read_bytes() for p in sw.glob("*/metrics.json")} == records
