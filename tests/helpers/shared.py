"""What the whole test run shares, built once also under pytest-xdist (``pytest -n 2``). Its workers are processes
of their own, each with a temporary directory below one the run's workers share. The first worker to need a shared
fixture builds it there under a file lock; the others wait for it, then read the same files. Without xdist the
directory is the run's own, and nothing waits."""

import os
import pickle
import shutil
import time

from filelock import FileLock

WORKER = os.environ.get("PYTEST_XDIST_WORKER")  # gw0, gw1...: set in each worker of pytest -n N, else None
WORKERS = int(os.environ.get("PYTEST_XDIST_WORKER_COUNT", "1"))
# a worker that waits for another's result gives up after this long (a process started early takes up to 15
# minutes on a loaded machine); a worker that died leaves nothing to wait for
PATIENCE = 3600.0


def shared_root(tmp_path_factory):
    """The directory every worker of this test run sees: the workers' common parent under xdist, else the run's
    own temporary directory."""
    base = tmp_path_factory.getbasetemp()
    return base.parent if WORKER else base


def worker_index() -> int:
    """This worker's number, 0 to WORKERS - 1 (0 without xdist)."""
    return int(WORKER.removeprefix("gw")) if WORKER else 0


def built_once(tmp_path_factory, name, build):
    """``root / name`` after ``build(root / name)`` ran in exactly one worker of the test run. A build that raised
    leaves no mark, so the next worker to need it tries again on a clean directory."""
    root = shared_root(tmp_path_factory)
    path, done = root / name, root / f"{name}.built"
    if not WORKER:
        build(path)
        return path
    with FileLock(str(root / f"{name}.lock")):
        if not done.exists():
            shutil.rmtree(path, ignore_errors=True)
            build(path)
            done.touch()
    return path


def publish(root, name, outcome):
    """Write ``outcome`` (("value", v), ("skip", reason) or ("error", text)) for the workers that read ``name``;
    written whole, then renamed, so a reader never sees half of it."""
    final = root / "started_early" / f"{name}.pickle"
    final.parent.mkdir(exist_ok=True)
    try:
        data = pickle.dumps(outcome)
    except Exception as exc:  # noqa: BLE001 - a value another worker cannot read is that worker's error
        data = pickle.dumps(("error", f"{name}'s result cannot be passed to another worker: {exc!r}"))
    partial = final.with_suffix(f".{os.getpid()}.tmp")
    partial.write_bytes(data)
    partial.replace(final)


def read_published(root, name):
    """The outcome another worker published for ``name``, waited for."""
    final, deadline = root / "started_early" / f"{name}.pickle", time.monotonic() + PATIENCE
    while not final.exists():
        if time.monotonic() > deadline:
            raise TimeoutError(f"no worker published {name} in {PATIENCE:.0f} s")
        time.sleep(0.2)
    return pickle.loads(final.read_bytes())
