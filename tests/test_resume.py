"""A run killed mid-training and started again continues from its last checkpoint to the same numbers."""

import json
import os
import signal
import subprocess
import sys
import time

import pytest
import torch

pytestmark = pytest.mark.integration  # subprocess runs of the app: minutes, still in the default suite

ARGS = ["data=tiny", "trainer=debug", "trainer.max_steps=400", "trainer.eval_every_n_steps=200",
        "trainer.progress_bar=false", "noise.eval_std=[0.0,0.05]"]


def launch(tmp_path, run_dir, *extra):
    env = {**os.environ, "HYBRID_SYSID_CACHE": str(tmp_path / "cache")}
    return subprocess.Popen([sys.executable, "-m", "hybrid_sysid", *ARGS, *extra, f"hydra.run.dir={run_dir}"],
                            cwd=tmp_path, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)


def results(run_dir):
    return json.loads((run_dir / "metrics.json").read_text())


def test_killed_run_resumes_to_the_same_metrics(tmp_path):
    ref = tmp_path / "uninterrupted"
    first = launch(tmp_path, ref)
    first.communicate(timeout=600)
    assert first.returncode == 0

    run = tmp_path / "killed"
    proc = launch(tmp_path, run)
    last = run / "checkpoints" / "last.ckpt"
    deadline = time.time() + 600
    while not last.exists() and proc.poll() is None and time.time() < deadline:
        time.sleep(0.05)
    time.sleep(0.3)  # a few steps past the checkpoint, well before the next one (200 steps: ~1 s or more)
    assert proc.poll() is None, "the run ended before it could be killed"
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    assert not (run / "metrics.json").exists()
    saved = torch.load(last, map_location="cpu")  # torch's default weights_only loading
    assert saved["global_step"] == 200

    resumed = launch(tmp_path, run, f"resume={run}")
    err, _ = resumed.communicate(timeout=600)
    assert resumed.returncode == 0, err[-2000:]
    assert "resuming from" in err
    a, b = results(ref), results(run)
    assert b["status"] == "completed" and b["steps"] == a["steps"] == 400
    for ra, rb in zip(a["results"], b["results"]):
        assert (ra["split"], ra["noise_std"], ra["parameter"]) == (rb["split"], rb["noise_std"], rb["parameter"])
        assert rb["mean_rel_dev"] == pytest.approx(ra["mean_rel_dev"], rel=1e-5, abs=1e-7)
    # the learning curve carries on across the restart
    import pandas as pd
    assert sorted(pd.read_csv(run / "curves.csv").step.unique()) == [200, 400]
    assert sorted(p.name for p in (run / "checkpoints").iterdir()) == ["best.ckpt", "last.ckpt"]
