"""Several devices (trainer=ddp, two CPU processes over gloo): each rank draws its own training windows, and
the run is evaluated and recorded once."""

import json
import os
import signal
import socket
import subprocess
import sys
import textwrap
import time
from itertools import islice

import numpy as np
import pytest

from hybrid_sysid.data import DatasetSpec
from hybrid_sysid.data.datamodule import QuarterCarDataModule, RandomWindows

from helpers.app_process import launch, run_app, user_env
from helpers.started_early import started_early

SPEC = DatasetSpec(n_roads=6, n_masses=5, n_steps=400, seed=1)


def stream(rank):
    dm = QuarterCarDataModule(SPEC, window=100, batch_size=8, train_std=0.01)
    dm.setup("fit")
    s = dm.train_windows
    return RandomWindows(s.data, s.rows, s.batch_size, s.seed, s.noise_std, rank=rank)


def test_rank_zero_draws_the_one_device_stream_and_other_ranks_their_own():
    dm = QuarterCarDataModule(SPEC, window=100, batch_size=8, train_std=0.01)
    dm.setup("fit")
    one_device, r0, r1 = (list(islice(iter(s), 10)) for s in (dm.train_windows, stream(0), stream(1)))
    for a, b, c in zip(one_device, r0, r1):
        assert np.array_equal(a["signals"], b["signals"])
        assert not np.array_equal(b["signals"], c["signals"])
    # every rank's pass still visits each training recording once
    rows = lambda s: np.concatenate([b["index"].numpy() for b in s.one_pass(0)])  # noqa: E731
    assert sorted(rows(stream(1))) == sorted(rows(stream(0))) == sorted(stream(0).rows)


# the app, each rank writing the recordings and window starts of its first training batches to a file
RECORDING = textwrap.dedent("""
    import json, os, sys
    import numpy as np
    from hybrid_sysid.data import datamodule
    one_pass = datamodule.RandomWindows.one_pass
    def recorded(self, e, skip=0):
        for b, batch in enumerate(one_pass(self, e, skip)):
            if e < 3 and b == 0:  # tiny data: one batch a pass
                with open(f"rank{self.rank}.jsonl", "a") as f:
                    f.write(json.dumps({"rows": batch["index"].tolist(),
                                        "first": batch["signals"][:, 0, 0].tolist()}) + "\\n")
            yield batch
    datamodule.RandomWindows.one_pass = recorded
    from hybrid_sysid.cli.train import main
    main()
""")


@started_early
def ddp_run(tmp, env, tiny_cache):
    """Real processes: Lightning starts the second rank as a process of its own, with the same command."""
    script = tmp / "app.py"
    script.write_text(RECORDING)
    proc = subprocess.run(
        [
            sys.executable,
            str(script),
            "data=tiny",
            "trainer=ddp",
            "trainer.max_steps=12",
            "trainer.eval_every_n_steps=6",
            f"hydra.run.dir={tmp / 'run'}",
            f"data.cache_dir={tiny_cache}",  # data=tiny, simulated once for the test run: both ranks read it
        ],
        cwd=tmp,
        env=user_env(env),
        capture_output=True,
        text=True,
        timeout=600,
    )
    return proc, tmp


@pytest.mark.integration
def test_two_processes_draw_different_windows_and_write_one_record(ddp_run):
    proc, tmp_path = ddp_run
    assert proc.returncode == 0, proc.stderr[-3000:]
    batches = {r: [json.loads(x) for x in (tmp_path / f"rank{r}.jsonl").read_text().splitlines()] for r in (0, 1)}
    assert len(batches[0]) == len(batches[1]) == 3
    assert all(a != b for a, b in zip(batches[0], batches[1]))  # each rank its own windows
    records = list(tmp_path.rglob("metrics.json"))
    assert records == [tmp_path / "run" / "metrics.json"]
    record = json.loads(records[0].read_text())
    assert record["status"] == "completed" and record["devices"] == 2 and record["steps"] == 12
    assert (proc.stdout + proc.stderr).count("p1 mean rel. dev.") == 1  # one table printed, by rank 0


# a rank above 0 lists every file it opens for writing, makes, moves or removes inside the run directory (Python's
# audit events: every write of Hydra, Lightning's Python side and the project), then runs the recording app
AUDITED = textwrap.dedent("""
    import os, sys
    RUN = os.path.abspath(sys.argv[-1].split("=", 1)[1]) + os.sep
    if os.environ.get("NODE_RANK", "0") != "0":
        out = os.open(f"writes{os.environ['NODE_RANK']}.txt", os.O_WRONLY | os.O_CREAT | os.O_APPEND)
        CHANGES = {"os.mkdir", "os.rename", "os.replace", "os.remove", "os.rmdir", "os.symlink", "os.link"}
        WRITE = os.O_WRONLY | os.O_RDWR | os.O_CREAT | os.O_APPEND
        def audit(event, args):
            if event == "open" and isinstance(args[0], (str, bytes, os.PathLike)):
                mode, flags = args[1], args[2] or 0
                writes = any(c in mode for c in "wax+") if isinstance(mode, str) else bool(flags & WRITE)
            else:
                writes = event in CHANGES and isinstance(args[0], (str, bytes, os.PathLike))
            if writes and os.path.abspath(os.fsdecode(args[0])).startswith(RUN):
                os.write(out, f"{event} {os.fsdecode(args[0])}\\n".encode())
        sys.addaudithook(audit)
""")


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@started_early
def two_node_run(tmp, env, tiny_cache):
    """Two nodes of one device each on this machine, as Lightning's environment starts them (each node's process
    started by hand with MASTER_ADDR, MASTER_PORT, NODE_RANK, WORLD_SIZE and LOCAL_RANK), writing into one run
    directory as nodes on a shared file system do. Otherwise the command of ddp_run."""
    script = tmp / "app.py"
    script.write_text(AUDITED + RECORDING)
    port = str(free_port())
    args = ["data=tiny", "trainer=ddp", "trainer.devices=1", "trainer.num_nodes=2", "trainer.max_steps=12"]
    args += ["trainer.eval_every_n_steps=6", f"data.cache_dir={tiny_cache}", f"hydra.run.dir={tmp / 'run'}"]
    nodes = []
    for node in (0, 1):
        node_env = {"MASTER_ADDR": "127.0.0.1", "MASTER_PORT": port, "WORLD_SIZE": "2", "NODE_RANK": str(node)}
        node_env["LOCAL_RANK"] = "0"
        nodes.append(
            subprocess.Popen(
                [sys.executable, str(script), *args],
                cwd=tmp,
                env={**user_env(env), **node_env},
                stdout=subprocess.PIPE,
                stderr=subprocess.STDOUT,
                text=True,
            )
        )
    try:
        outputs = [p.communicate(timeout=300)[0] for p in nodes]
    finally:  # a node that waits in the rendezvous for one that ended would wait 30 minutes
        for p in nodes:
            p.kill()
    return [p.returncode for p in nodes], outputs, tmp


def results(run_dir):
    record = json.loads((run_dir / "metrics.json").read_text())
    keys = ("split", "noise_std", "windows", "parameter")
    return record, {tuple(r[k] for k in keys): (r["mean_rel_dev"], r["std_rel_dev"]) for r in record["results"]}


@pytest.mark.integration
def test_two_nodes_share_one_run_directory_and_give_the_numbers_of_one_node_with_two_devices(two_node_run, ddp_run):
    (codes, outputs, tmp), (one_node, one_tmp) = two_node_run, ddp_run
    assert codes == [0, 0], "\n".join(o[-3000:] for o in outputs)
    assert not (tmp / "writes1.txt").exists() or (tmp / "writes1.txt").read_text() == ""
    records = list(tmp.rglob("metrics.json"))
    assert records == [tmp / "run" / "metrics.json"]
    assert not list((tmp / "run").glob("*process_1*")) and len(list((tmp / "run").glob("*.log"))) == 1
    record, two = results(tmp / "run")
    assert record["status"] == "completed" and record["devices"] == 2 and record["steps"] == 12
    # the global rank picks the window stream: node 1's one rank draws what rank 1 of one node with two devices does
    for r in (0, 1):
        assert (tmp / f"rank{r}.jsonl").read_text() == (one_tmp / f"rank{r}.jsonl").read_text()
    assert one_node.returncode == 0
    _, one = results(one_tmp / "run")
    assert one.keys() == two.keys()
    # the same ranks, streams and gradient average: equal up to the order of floating-point sums
    np.testing.assert_allclose([two[k] for k in one], [one[k] for k in one], rtol=1e-6)


@pytest.mark.integration
def test_a_node_count_that_does_not_match_the_world_size_is_one_line_and_writes_nothing(tmp_path, tiny_cache):
    env = {**os.environ, "WORLD_SIZE": "3", "MASTER_ADDR": "127.0.0.1", "NODE_RANK": "0", "LOCAL_RANK": "0"}
    args = ["data=tiny", "trainer=ddp", "trainer.num_nodes=1", f"hydra.run.dir={tmp_path / 'run'}"]
    proc = run_app(tmp_path, *args, f"data.cache_dir={tiny_cache}", env=env)
    assert proc.returncode == 2, proc.stderr[-2000:]
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "trainer.num_nodes" in lines[0] and "WORLD_SIZE = 3" in lines[0], proc.stderr
    assert not (tmp_path / "run").exists()


def listening(port: int) -> bool:
    """Whether a socket on this machine listens on TCP ``port`` (/proc/net/tcp, tcp6): the rendezvous's store."""
    for table in ("/proc/net/tcp", "/proc/net/tcp6"):
        try:
            rows = [line.split() for line in open(table).read().splitlines()[1:]]
        except OSError:
            continue
        if any(row[3] == "0A" and int(row[1].rsplit(":", 1)[1], 16) == port for row in rows):
            return True
    return False


@started_early
def rendezvous_terminated(tmp, env, tiny_cache):
    """Rank 0 of two nodes, node 1 never started, sent SIGTERM in torch's rendezvous: (its exit status, its
    output, its run directory). Started early: the process imports torch and Lightning before it waits."""
    port = free_port()
    env = {**env, "MASTER_ADDR": "127.0.0.1", "MASTER_PORT": str(port), "NODE_RANK": "0"}
    args = ["data=tiny", "trainer=debug", "trainer.max_steps=2", "trainer.num_nodes=2"]
    proc = launch(tmp, *args, f"hydra.run.dir={tmp / 'run'}", cache=tiny_cache, env=env)
    try:
        started = time.monotonic()
        while not listening(port):
            assert proc.poll() is None, proc.communicate()[0][-3000:]
            assert time.monotonic() - started < 300, "rank 0 never reached the rendezvous"
            time.sleep(0.2)
        time.sleep(1.0)
        proc.send_signal(signal.SIGTERM)
        out = proc.communicate(timeout=60)[0]  # without the watcher: the rendezvous's 30-minute timeout
    finally:
        proc.kill()
    return proc.returncode, out, tmp / "run"


@pytest.mark.integration
def test_a_rendezvous_with_a_node_never_started_ends_on_sigterm_with_its_record(rendezvous_terminated):
    """MASTER_ADDR and NODE_RANK given by hand for two nodes, and node 1 never started: rank 0 waits in torch's
    rendezvous, C code that runs no Python handler. It once waited there 30 minutes, deaf to SIGTERM. The signal
    is sent once rank 0's store listens, so it lands in that wait; the run must end as any interrupted run does."""
    returncode, out, run = rendezvous_terminated
    errors = [line for line in out.splitlines() if line.startswith("error:")]
    assert returncode == 143 and len(errors) == 1 and "SIGTERM" in errors[0], out[-3000:]
    assert "Traceback" not in out
    record = json.loads((run / "metrics.json").read_text())
    assert record["status"] == "interrupted" and "SIGTERM" in record["error"]
