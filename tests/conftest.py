import os
import sys

# numpy's OpenBLAS runs one thread, in this process and in the app processes the tests start (they inherit it),
# set before numpy is first imported. The fits' matrices are small; beside the processes started early
# (helpers/started_early.py) a second BLAS thread waits for a busy core, and a product of 192 x 27 by 27 x 251
# complex numbers then took 12.7 ms instead of 0.28 (benchmarks/README.md, "The default suite").
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
# torch too runs one thread, set before torch is first imported: the processes started early run beside the
# tests here, so two threads a process would be four on two cores, and torch's threads spin at each operation's
# end waiting for one that has no core. Beside two busy processes, test_model_overfit.py and
# test_debug_overfit_fits_one_batch took 302 s of CPU on two threads against 17 s on one
# (benchmarks/README.md, "The default suite"). A run sets its own count from trainer.threads either way.
os.environ.setdefault("OMP_NUM_THREADS", "1")

import pytest  # noqa: E402
from hydra import compose, initialize_config_dir  # noqa: E402

pytest.register_assert_rewrite("helpers")  # a plugin below, imported here first
from helpers.app_process import run_app  # noqa: E402
from helpers.mounts import small_tmpfs  # noqa: E402
from helpers.shared import built_once  # noqa: E402
from helpers.started_early import started_early  # noqa: E402

pytest_plugins = [
    "helpers.estimator_run",  # the trained run test_estimator.py and test_predict.py share (tiny_run, est)
    "helpers.started_early",  # the processes the tests start early (started_early)
]

# the datasets the app's subprocesses read in the shared cache (tiny_cache): data=tiny on each car they use
TINY_DATA = (["data=tiny"], ["data=tiny", "car=soft_seat"])


@pytest.fixture(scope="session")
def tiny_cache(tmp_path_factory):
    """One dataset cache for the whole test run, holding data=tiny (on the paper's car and car=soft_seat),
    simulated here once (by one worker under pytest -n). A subprocess of the app that reads it (HYBRID_SYSID_CACHE
    or data.cache_dir) starts training at once: it neither simulates the data nor compiles the numba kernel
    (seconds a process). Tests of the cache itself, and tests that check nothing was simulated, keep a cache of
    their own."""
    from hybrid_sysid.config import CONF_DIR
    from hybrid_sysid.training.build import build_datamodule

    def simulate(cache):
        for overrides in TINY_DATA:
            with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
                cfg = compose(config_name="config", overrides=[*overrides, f"data.cache_dir={cache}"])
            build_datamodule(cfg).prepare_data()  # simulates into the cache, then puts torch's thread count back

    return built_once(tmp_path_factory, "tiny_cache", simulate)  # once for all workers of pytest -n


TINY_SWEEP = [
    "-m",
    "objective=labelled,hybrid",
    "seed=0,1",
    "data=tiny",
    "trainer=debug",
    "trainer.max_steps=10",
    "trainer.eval_every_n_steps=5",
]


@started_early
def tiny_sweep(tmp, env, tiny_cache):
    """One sweep of four jobs (two objectives, two seeds) as a user launches it, which test_sweep.py and
    test_console.py read, never write: (its process, its sweep directory). A new process, its output captured (not
    a terminal), as `cmd > log 2>&1` would: what a sweep prints, Hydra's multirun, its callbacks and its exit
    status. trainer.progress_bar stays auto, so that no bar in the output shows auto's choice off a terminal."""
    return run_app(tmp, *TINY_SWEEP, f"hydra.sweep.dir={tmp / 'sw'}", cache=tiny_cache, env=env), tmp / "sw"


@pytest.fixture
def make_cfg(tmp_path):
    """Compose the app's config with overrides; the dataset cache goes to a per-test folder."""
    from hybrid_sysid.config import CONF_DIR  # here, so tests that need no torch start fast

    def _make(*overrides):
        with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
            return compose(
                config_name="config",
                overrides=[f"data.cache_dir={tmp_path / 'cache'}", "trainer.progress_bar=false", *overrides],
            )

    return _make


@pytest.fixture
def cli_in_process(monkeypatch, capfd):
    """A console script's main() run in this process as the shell would start it: (exit status, stdout, stderr).
    For a refusal, which ends before any work, a new process would only add seconds of imports; a test that needs
    a real process (signals, another process's lock, an interpreter's own output) starts one. Reset around the
    call: the working directory, the environment (no HYDRA_FULL_ERROR, as a user has it), sys.argv, the state the
    command keeps for its one process (hybrid_sysid.launch.process), the locks it took and Hydra's global instance."""
    from hydra.core.global_hydra import GlobalHydra

    from hybrid_sysid.launch.process import PROCESS
    from hybrid_sysid.runs import locks

    def run(main, *args, cwd, env=None):
        monkeypatch.chdir(cwd)
        monkeypatch.delenv("HYDRA_FULL_ERROR", raising=False)
        for key, value in (env or {}).items():
            monkeypatch.setenv(key, str(value))
        monkeypatch.setattr(sys, "argv", [main.__module__, *map(str, args)])
        PROCESS.reset()  # as a new process has it (a test may run several commands)
        capfd.readouterr()
        try:
            main()
            code = 0
        except SystemExit as exc:
            code = exc.code
        finally:
            locks.release_all()
            PROCESS.reset()
            GlobalHydra.instance().clear()
        out = capfd.readouterr()
        return code, out.out, out.err

    return run


@pytest.fixture
def poison_labels(monkeypatch):
    """A call that replaces every label of the datasets loaded afterwards by garbage: a label-free run, its
    model selection and its search must not notice."""

    def _poison():
        import numpy as np

        import hybrid_sysid.data.datamodule as dm_module

        real = dm_module.get_dataset

        def poisoned(spec, cache_dir=None):
            ds = real(spec, cache_dir)
            ds.params = np.random.default_rng(1).uniform(1.0, 5000.0, ds.params.shape)
            return ds

        monkeypatch.setattr(dm_module, "get_dataset", poisoned)

    return _poison


@pytest.fixture(autouse=True)
def _two_threads():
    import torch

    n = torch.get_num_threads()
    yield
    torch.set_num_threads(n)  # the basic launcher and tests share one process: restore global state


os.environ.setdefault("HYDRA_FULL_ERROR", "1")


@pytest.fixture
def small_fs(tmp_path):
    """A 1 MiB tmpfs, another file system than the system's temp folder, where a full or read-only disk can be made
    (root only: the test skips without it), unmounted after."""
    with small_tmpfs(tmp_path / "mnt") as mnt:
        yield mnt
