"""A termination signal never raises into whatever code runs when it lands: the handler of a job only requests a
stop (hybrid_sysid.core.stop), and the work raises Interrupted at its safe points (training and evaluation
batches, the dataset cache's lock, before scoring and before the record). Real signals, sent to this process."""

import os
import signal

import pytest

from hybrid_sysid.core import stop
from hybrid_sysid.launch import job
from hybrid_sysid.launch.process import PROCESS, SIGNALS
from hybrid_sysid.runs import locks


@pytest.fixture
def fresh_job_state(monkeypatch):
    """run_job keeps what a command's process shares (the signal received, its handlers): restored after."""
    handlers = {s: signal.getsignal(s) for s in SIGNALS}
    PROCESS.reset()
    yield
    for s, handler in handlers.items():
        signal.signal(s, handler)
    locks.release_all()
    PROCESS.reset()


@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGINT])
def test_a_signal_is_a_request_that_the_next_safe_point_raises(tmp_path, fresh_job_state, signum):
    events = []

    def work():
        try:
            os.kill(os.getpid(), signum)  # the handler runs in this thread, before the next line
            events.append("went on")
        except BaseException as exc:  # noqa: BLE001 - what a library's broad handler would do to a raised signal
            events.append(f"raised into the work: {exc!r}")
        stop.check()
        events.append("past the safe point")

    record = job.run_job(work, tmp_path / "job", ["seed=0"], 0, multirun=True)
    assert events == ["went on"]
    assert record["status"] == "interrupted" and signal.Signals(signum).name in record["error"]


def test_a_sigterm_during_training_ends_the_run_at_the_next_batch(make_cfg, tmp_path, fresh_job_state):
    from hybrid_sysid.training import build, run

    steps = []

    class Terminate(build.L.Callback):
        def on_train_batch_end(self, trainer, *args):
            steps.append(trainer.global_step)
            if trainer.global_step == 3:
                os.kill(os.getpid(), signal.SIGTERM)  # Lightning's handler and the job's both run

    cfg = make_cfg("data=tiny", "trainer=debug")
    real = build.build_trainer

    def trainer(cfg, run_dir, callbacks=(), *args, **kwargs):
        return real(cfg, run_dir, [*callbacks, Terminate()], *args, **kwargs)

    run_dir = tmp_path / "run"
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(run, "build_trainer", trainer)
        record = job.run_job(lambda: run.train(cfg, run_dir, ["data=tiny"]), run_dir, ["data=tiny"], 0, multirun=True)
    assert record["status"] == "interrupted" and "SIGTERM" in record["error"]
    # a safe point right after (Lightning's at the batch's end, or the job's after the next batch) ended it
    assert steps[-1] <= 4 < cfg.trainer.max_steps
    assert not (run_dir / "predictions.csv").exists()  # never scored
