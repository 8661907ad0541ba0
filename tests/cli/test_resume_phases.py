"""Resume is exact wherever the signal lands. A real process of the app sends itself SIGTERM at one chosen point of
its run: inside a training step, a validation batch, a checkpoint write, the test evaluation, or the drawing of the
run's figures. The signal lands there deterministically (the process signals itself, so no timing decides where),
which a signal from outside cannot promise on a busy machine. The run is then resumed with ``resume=`` and its
record compared bit for bit with the uninterrupted run's. A signal after the completed record (the figures) ends
the process with status 0 and one line, and the record is the uninterrupted one as it stands."""

import json
import signal
import textwrap

import pytest

from helpers import app_process
from helpers.started_early import started_early

pytestmark = [pytest.mark.integration, pytest.mark.faults]

ARGS = [
    "data=tiny",
    "trainer=debug",
    "trainer.max_steps=40",
    "trainer.eval_every_n_steps=20",
    "trainer.progress_bar=false",
    "noise.eval_std=[0.0,0.05]",
]

# The app with one function wrapped so that it sends this process SIGTERM at the chosen phase, then goes on: the
# handler only requests the stop, and the run's next safe point ends it (hybrid_sysid.core.stop).
SCRIPT = textwrap.dedent("""
    import os
    import signal
    import sys

    PHASE = sys.argv.pop(1)

    def terminate():
        os.kill(os.getpid(), signal.SIGTERM)

    from hybrid_sysid.training import callbacks, run

    build_model = run.build_model

    def build(cfg, *args):
        model = build_model(cfg, *args)
        if PHASE in ("step", "validation"):
            name = "training_step" if PHASE == "step" else "validation_step"
            original = getattr(model, name)

            def wrapped(*a, **k):
                # step 30 lies between the checkpoints of steps 20 and 40; the validation is the one at step 40
                if model.trainer.global_step == (30 if PHASE == "step" else 40) and not wrapped.sent:
                    wrapped.sent = True
                    terminate()
                return original(*a, **k)

            wrapped.sent = False
            setattr(model, name, wrapped)
        return model

    run.build_model = build

    if PHASE == "checkpoint":
        save = callbacks.AtomicCheckpointIO.save_checkpoint

        def save_checkpoint(self, checkpoint, path, storage_options=None):
            if checkpoint.get("global_step") == 40:
                terminate()  # the file is then written as the signal's handler has run
            return save(self, checkpoint, path, storage_options)

        callbacks.AtomicCheckpointIO.save_checkpoint = save_checkpoint

    if PHASE == "evaluation":
        score = run.score

        def scored(*a, **k):
            terminate()
            return score(*a, **k)

        run.score = scored

    if PHASE == "figures":
        from hybrid_sysid.report import run_figures

        write = run_figures.write_run_figures

        def figures(*a, **k):
            terminate()
            return write(*a, **k)

        run_figures.write_run_figures = figures

    from hybrid_sysid.cli.train import main

    main()
""")

PHASES = ["step", "validation", "checkpoint", "evaluation", "figures"]


def record(run_dir):
    return json.loads((run_dir / "metrics.json").read_text())


def numbers(rec):
    """What a resumed run must reproduce to the bit: its steps and every test row."""
    rows = [
        (r["split"], r["noise_std"], r["parameter"], r.get("windows"), r["mean_rel_dev"], r["std_rel_dev"])
        for r in rec["results"]
    ]
    return rec["steps"], rows, rec.get("best_score")


def terminated_at(phase):
    def run(tmp, env, tiny_cache):
        script = tmp / "terminated.py"
        script.write_text(SCRIPT)
        proc = app_process.run_app(
            tmp, phase, *ARGS, f"hydra.run.dir={tmp / 'run'}", cache=tiny_cache, env=env, script=script
        )
        return proc, tmp / "run"

    run.__name__ = f"terminated_in_{phase}"
    run.__doc__ = f"The app's process, terminated by its own SIGTERM in phase {phase!r}: (process, run directory)."
    return run


for _phase in PHASES:
    globals()[f"terminated_in_{_phase}"] = started_early(terminated_at(_phase))


@pytest.fixture(scope="module")
def uninterrupted(tmp_path_factory, tiny_cache):
    """The same run, uninterrupted, trained in this process by the function the app's job runs: a run leaves the
    process's torch thread count as it found it, so this one and the app's own process compute alike."""
    from hydra import compose, initialize_config_dir

    from hybrid_sysid.config import CONF_DIR
    from hybrid_sysid.training.run import train

    run = tmp_path_factory.mktemp("uninterrupted") / "run"
    with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
        cfg = compose(config_name="config", overrides=[*ARGS, f"data.cache_dir={tiny_cache}"])
    rec = train(cfg, run, ARGS)
    assert rec["status"] == "completed"
    return rec


@pytest.mark.parametrize(
    "phase", [pytest.param(p, marks=pytest.mark.started_early(f"terminated_in_{p}")) for p in PHASES]
)
def test_a_run_terminated_in_any_phase_resumes_to_the_uninterrupted_numbers_bit_for_bit(
    request, tmp_path, phase, uninterrupted, tiny_cache, cli_in_process
):
    from hybrid_sysid.cli.train import main

    proc, run = request.getfixturevalue(f"terminated_in_{phase}")
    if phase == "figures":  # after the completed record: nothing to resume, and the status says the run is whole
        assert proc.returncode == 0, proc.stderr[-2000:]
        last = proc.stderr.strip().splitlines()[-1]
        assert last.startswith("SIGTERM received after the run completed"), proc.stderr[-2000:]
        assert numbers(record(run)) == numbers(uninterrupted)
        assert (run / "figures").is_dir() and any((run / "figures").iterdir())
        return
    assert proc.returncode == 128 + signal.SIGTERM, proc.stderr[-2000:]
    assert record(run)["status"] == "interrupted"
    code, _, err = cli_in_process(main, *ARGS, f"resume={run}", cwd=tmp_path, env={"HYBRID_SYSID_CACHE": tiny_cache})
    assert code == 0, err[-2000:]
    resumed = record(run)
    assert resumed["status"] == "completed"
    assert numbers(resumed) == numbers(uninterrupted)  # equal, not close
