"""Several devices (trainer=ddp, two CPU processes over gloo): each rank draws its own training windows, and
the run is evaluated and recorded once."""

import json
import subprocess
import sys
import textwrap
from itertools import islice

import numpy as np
import pytest

from hybrid_sysid.data import DatasetSpec
from hybrid_sysid.data.datamodule import QuarterCarDataModule, RandomWindows

from helpers.app_process import user_env
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
