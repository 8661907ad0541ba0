"""Four jobs on two cores: Hydra's basic launcher (one job at a time, two torch threads) against the joblib
launcher (two jobs at a time, one torch thread each). Wall time of the whole sweep, summary included.

    python benchmarks/sweep_launchers.py [overrides...]     # default: trainer.max_steps=400

The dataset is generated once beforehand so both sweeps load it from the same cache.
"""

import subprocess
import sys
import tempfile
import time
from pathlib import Path


def sweep(tmp, launcher_args, overrides):
    out = Path(tmp) / launcher_args[0].replace("=", "_")
    cmd = [
        sys.executable,
        "-m",
        "hybrid_sysid",
        "-m",
        "seed=0,1,2,3",
        "trainer.progress_bar=false",
        *launcher_args,
        *overrides,
        f"hydra.sweep.dir={out}",
    ]
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True, capture_output=True, text=True)
    return time.perf_counter() - t0


def main():
    overrides = sys.argv[1:] or ["trainer.max_steps=400"]
    with tempfile.TemporaryDirectory() as tmp:
        # warm the dataset cache (and numba's) so neither sweep pays for generation
        subprocess.run(
            [
                sys.executable,
                "-m",
                "hybrid_sysid",
                "trainer.max_steps=1",
                "trainer.eval_every_n_steps=1",
                "trainer.progress_bar=false",
                *overrides,
                f"hydra.run.dir={tmp}/warm",
            ],
            check=True,
            capture_output=True,
        )
        basic = sweep(tmp, ["launcher=basic", "trainer.threads=2"], overrides)
        joblib = sweep(tmp, ["launcher=joblib"], overrides)
    print(f"4 jobs ({' '.join(overrides)}):")
    print("| launcher | wall time |\n| --- | ---: |")
    print(f"| basic, 1 job at a time x 2 torch threads | {basic:.1f} s |")
    print(f"| joblib, 2 jobs at a time x 1 torch thread | {joblib:.1f} s |")
    print(f"joblib / basic: {joblib / basic:.2f}")


if __name__ == "__main__":
    main()
