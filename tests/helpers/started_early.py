"""Real processes that tests need, started when the test run starts and run one after another by a thread of their
own, beside the tests in this process. A process of the app spends seconds importing torch and Lightning, and runs
a tiny training, while the tests before its own run here: on two cores, it takes what these tests leave of them.
The thread and so its processes run at a low priority (nice 10), so that the tests here are not slowed (a
tiny torch operation on two threads waits for both), and with OMP_WAIT_POLICY=PASSIVE, so that their torch threads
sleep at a barrier instead of spinning for a core. Neither changes a number: they change when a process runs and
how its threads wait, not how many threads it has or what they compute.

A test module decorates a function ``name(tmp, env, **fixtures)`` with ``started_early``: it becomes a fixture of
that name, one for the whole test run, whose value is the function's result. ``tmp`` is a new directory of its own,
``env`` the environment to start processes with (tests in this process change ``os.environ`` meanwhile), the other
arguments fixtures of the whole test run (tiny_cache, tiny_run...). The function runs the process and returns what
the test asserts on. Only the functions that the selected tests read are started, in the order of their first
reader; a test that reads one through request.getfixturevalue (for one of its parameters) names it in a mark,
``pytest.param(..., marks=pytest.mark.started_early("name"))``. A test whose process has not ended yet waits for
it, and an exception the function raises (a failed wait, a skip) is raised in the test. A test whose own processes
need the cores alone takes the fixture no_process_started_early.

Under pytest-xdist (``pytest -n 2``) each worker is a process with a lane of its own, and each function runs in one
worker only: the k-th, in the order of first readers, in worker k modulo the number of workers. It publishes its
result (helpers/shared.py) and a test in another worker waits for it there. A worker's tests still wait for their
own lane at their own priority; the other workers' lanes keep theirs."""

import concurrent.futures
import contextlib
import inspect
import os
import threading
import time
import traceback
from pathlib import Path

import pytest

from helpers.shared import WORKER, WORKERS, publish, read_published, shared_root, worker_index

_STARTED = {}  # fixture name -> the function that runs the process


def started_early(fn):
    """The fixture named like ``fn`` whose value is what ``fn`` returns (see the module's docstring)."""
    if fn.__name__ in _STARTED:
        raise ValueError(f"two processes started early are named {fn.__name__}")
    _STARTED[fn.__name__] = fn

    @pytest.fixture(scope="session", name=fn.__name__)
    def result(_started_early):
        return _started_early.result(fn.__name__)

    result.__doc__ = fn.__doc__
    return result


# Nice 10, not 19: beside two busy loops at nice 0, a nice-19 process gets about 1.5% of a core, and an
# evaluation that needs 7 s of CPU outlived its 600 s timeout while no test waited for it; at nice 10 (about 10%)
# it ends in minutes, and the tests here still take about 90% of a core they share with it.
LOWEST = 10
_LANE_THREAD = {}  # "tid": the lane thread's native id, for waited_for to raise its priority
_LANE_READY = threading.Event()  # set once the lane thread has recorded its id


def _lowest_priority():
    """Nice LOWEST for the calling thread, which the processes it starts inherit (on Linux a thread's own;
    elsewhere, where it is the process's, the tests here would share it; where there is none, as on Windows, the
    default)."""
    if hasattr(os, "setpriority"):
        _LANE_THREAD["tid"] = threading.get_native_id()
        os.setpriority(os.PRIO_PROCESS, 0, LOWEST)
    _LANE_READY.set()


def _descendants(pid: int) -> list[int]:
    """Every process below ``pid``, from /proc (none where there is no /proc)."""
    parents = {}
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            parents[int(stat.parent.name)] = int(stat.read_text().rsplit(")", 1)[1].split()[1])
        except (OSError, ValueError, IndexError):
            continue
    found, frontier = [], [pid]
    while frontier:
        frontier = [child for child, parent in parents.items() if parent in frontier]
        found += frontier
    return found


@contextlib.contextmanager
def waited_for():
    """While a test waits for the lane, the lane and the processes it runs at the tests' own priority: beside
    other work on every core (a busy CI machine), a low priority would leave them little time, and the test would wait
    for them long. Raising a priority needs the right to (root, as CI runs); without it they keep LOWEST."""
    _LANE_READY.wait(5.0)  # a test that waits at once may come before the new lane thread has named itself
    tid = _LANE_THREAD.get("tid")
    mine = os.getpriority(os.PRIO_PROCESS, 0) if hasattr(os, "getpriority") else None
    if tid is None or mine is None:
        yield
        return
    for target in (tid, *_descendants(os.getpid())):
        with contextlib.suppress(OSError):  # no right to raise a priority, or the process has ended
            if os.getpriority(os.PRIO_PROCESS, target) > mine:
                os.setpriority(os.PRIO_PROCESS, target, mine)
    try:
        yield
    finally:
        with contextlib.suppress(OSError):
            os.setpriority(os.PRIO_PROCESS, tid, LOWEST)  # the next processes it starts yield to the tests again


class _Lane:
    """One thread that runs the functions, in the order they were started."""

    def __init__(self, request, tmp_path_factory):
        self.request, self.tmp_path_factory = request, tmp_path_factory
        self.env = {**os.environ, "OMP_WAIT_POLICY": "PASSIVE"}
        self.pool = concurrent.futures.ThreadPoolExecutor(1, "started-early", initializer=_lowest_priority)
        self.futures = {}
        self.seconds = {}  # name -> (seconds its function ran, seconds the tests waited for it)
        self.changed = threading.Condition()
        self.busy = False  # a function runs
        self.alone = 0  # tests that need the cores alone, waiting or running: no function starts meanwhile
        self.root = shared_root(tmp_path_factory) if WORKER else None  # where the workers publish results

    def start(self, name, here=True):
        """The future of ``name``'s function, started in this worker's lane; None where ``here`` is false: another
        worker runs it and publishes its result."""
        if name not in self.futures and not here:
            self.futures[name] = None
        if name not in self.futures:
            fn = _STARTED[name]
            given = {"tmp": lambda: self.tmp_path_factory.mktemp(name), "env": lambda: dict(self.env)}
            kwargs = {
                p: given[p]() if p in given else self.request.getfixturevalue(p)
                for p in inspect.signature(fn).parameters
            }
            self.futures[name] = self.pool.submit(self._run, fn, kwargs)
        return self.futures[name]

    def _run(self, fn, kwargs):
        with self.changed:
            self.changed.wait_for(lambda: not self.alone)
            self.busy = True
        start = time.perf_counter()
        try:
            value = fn(**kwargs)
            if self.root is not None:
                publish(self.root, fn.__name__, ("value", value))
            return value
        except BaseException as exc:
            if self.root is not None:
                skipped = isinstance(exc, pytest.skip.Exception)
                publish(self.root, fn.__name__, ("skip", exc.msg) if skipped else ("error", _text(exc)))
            raise
        finally:
            self.seconds[fn.__name__] = (time.perf_counter() - start, 0.0)
            with self.changed:
                self.busy = False
                self.changed.notify_all()

    @contextlib.contextmanager
    def cores_alone(self):
        with self.changed:
            self.alone += 1
            self.changed.wait_for(lambda: not self.busy)
        try:
            yield
        finally:
            with self.changed:
                self.alone -= 1
                self.changed.notify_all()

    def result(self, name):
        future, start = self.start(name), time.perf_counter()
        try:
            if future is None:
                return _unpacked(name, read_published(self.root, name))
            if future.done():
                return future.result()
            with waited_for():
                return future.result()
        finally:
            ran, waited = self.seconds.get(name, (0.0, 0.0))
            self.seconds[name] = (ran, waited + time.perf_counter() - start)

    def summary(self):
        """One line a process (slowest first): what --durations cannot show, its time being spent beside tests."""
        rows = sorted(self.seconds.items(), key=lambda kv: -kv[1][0])
        ran, waited = sum(r for r, _ in self.seconds.values()), sum(w for _, w in self.seconds.values())
        return [
            f"{len(rows)} processes started early: {ran:.1f} s on their thread; tests waited {waited:.1f} s for them",
            *(f"{r:6.2f}s ran, {w:6.2f}s waited for (queued or running)  {name}" for name, (r, w) in rows),
        ]


def _text(exc) -> str:
    return "".join(traceback.format_exception(type(exc), exc, exc.__traceback__))


def _unpacked(name, outcome):
    """What another worker's function returned, raised as a skip, or its error raised here."""
    kind, value = outcome
    if kind == "skip":
        pytest.skip(value)
    if kind == "error":
        raise RuntimeError(f"{name}, started early in another worker, failed there:\n{value}")
    return value


@pytest.fixture
def no_process_started_early(_started_early):
    """For a test whose processes must have the cores to themselves (it bounds how soon they end): the process
    started early that runs now ends first, and the next one starts after the test. Such a test reads no process
    started early: it would wait for a function that waits for the test."""
    with _started_early.cores_alone():
        yield


def pytest_configure(config):
    config.addinivalue_line("markers", "started_early(name): the test reads the process started early as name")


def pytest_terminal_summary(terminalreporter, config):
    lane = config.stash.get(_LANE, None)
    if lane is not None and lane.seconds:
        terminalreporter.write_sep("=", "processes started early (tests/helpers/started_early.py)")
        for line in lane.summary():
            terminalreporter.write_line(line)


_LANE = pytest.StashKey()


@pytest.fixture(scope="session", autouse=True)
def _started_early(request, tmp_path_factory):
    lane = request.config.stash[_LANE] = _Lane(request, tmp_path_factory)
    order = []  # under xdist every worker collects every test, in the same order: the same list in each
    for item in request.node.items:  # the test run's node: every selected test
        marked = [name for mark in item.iter_markers("started_early") for name in mark.args]
        for name in [*item.fixturenames, *marked]:
            if name in _STARTED and name not in order:
                order.append(name)
                lane.start(name, here=(len(order) - 1) % WORKERS == worker_index())
    yield lane
    # a worker that ran out of tests still runs what the others wait for; alone, what no test read is dropped
    lane.pool.shutdown(wait=True, cancel_futures=WORKER is None)
