"""launcher=slurm's launcher (conf/launcher/slurm.yaml; Hydra finds it as hydra_plugins.hybrid_sysid_slurm):
hydra-submitit-launcher's, which sends a sweep's jobs to SLURM as one job array, with what a sweep needs there.

- In the job: the time-limit signal (submitit's, SIGUSR2 by default, ``signal_delay_s`` before the limit) requests
  a stop that the training's safe points raise, so the run records itself ``interrupted``; submitit's own handler
  then requeues the job (hydra.launcher.max_num_timeout times at most), and the requeued job resumes from the
  run's last checkpoint. Raised from the signal handler, submitit's exit would land in whatever code ran.
- In the sweep's process, while waiting: the queue's state from ``squeue`` and the results' files, without
  ``sacct`` (whose absence printed warnings at every poll and left the wait endless). A job that pends for a
  reason that cannot clear is one line and a cancelled array; a job that ended without a result is recorded
  failed; SIGTERM or Ctrl-C cancels the array (``scancel``) and waits for its jobs to record their interruption.

The request is checked against the partition before anything is submitted (``check_request``, from the
preflight: hybrid_sysid.launch.job).
"""

from __future__ import annotations

import logging
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any, Sequence

from hydra.core.singleton import Singleton
from hydra.core.utils import JobReturn, JobStatus, filter_overrides
from hydra_plugins.hydra_submitit_launcher.config import BaseQueueConf
from hydra_plugins.hydra_submitit_launcher.submitit_launcher import SlurmLauncher as SubmititSlurmLauncher
from omegaconf import OmegaConf, open_dict

from hybrid_sysid.core import stop
from hybrid_sysid.core.checks import ConfigError, Shown
from hybrid_sysid.launch import slurm_limits
from hybrid_sysid.launch.process import fail
from hybrid_sysid.launch.progress import count_done, job_line
from hybrid_sysid.runs.rundir import RunDir

log = logging.getLogger("hybrid_sysid")
POLL = 5.0  # seconds between two squeue calls; the results' files are looked at every second
GRACE = 30.0  # seconds a job SLURM lists as ended (or no longer lists) has to show its result file
CANCEL_WAIT = 90.0  # after scancel: SLURM's KillWait (30 s by default) for the jobs to record their interruption


def time_limit_signal() -> int:
    """The signal submitit asks SLURM to send before the time limit (its variable SUBMITIT_PREEMPT_SIGNAL)."""
    return getattr(signal, "SIG" + os.environ.get("SUBMITIT_PREEMPT_SIGNAL", "USR2"))


class SlurmLauncher(SubmititSlurmLauncher):
    """hydra-submitit-launcher's SLURM launcher with the job's time-limit handling and the sweep's wait (the
    module's docstring)."""

    def __call__(self, *args: Any, **kwargs: Any) -> JobReturn:
        """One job, in the SLURM job's process."""
        signum = time_limit_signal()
        submitit_handler = signal.getsignal(signum)
        came: list[int] = []

        def at_time_limit(sig, frame):
            came.append(sig)
            stop.request(sig)

        signal.signal(signum, at_time_limit)
        stop.requeue_on(signum)
        try:
            result = super().__call__(*args, **kwargs)
        finally:
            signal.signal(signum, submitit_handler)
        record = getattr(result, "_return_value", None)
        if came and isinstance(record, dict) and record.get("status") == "interrupted" and callable(submitit_handler):
            # the run is recorded and its checkpoints are on disk: submitit saves this job again (checkpoint())
            # and requeues it, then exits; past max_num_timeout it raises, and the record says interrupted
            submitit_handler(came[0], None)
        return result

    def launch(self, job_overrides: Sequence[Sequence[str]], initial_job_idx: int) -> Sequence[JobReturn]:
        """As hydra-submitit-launcher's launch, with the sweep's own wait for the results (``_wait``)."""
        import submitit  # deferred

        params = dict(self.params)
        init = {"folder": params.pop("submitit_folder")}
        if "max_num_timeout" in params:
            init["slurm_max_num_timeout"] = params.pop("max_num_timeout")
        executor = submitit.AutoExecutor(cluster="slurm", **init)
        base = set(OmegaConf.structured(BaseQueueConf).keys())
        executor.update_parameters(**{k if k in base else f"slurm_{k}": v for k, v in params.items()})
        sweep_dir = Path(str(self.config.hydra.sweep.dir))
        sweep_dir.mkdir(parents=True, exist_ok=True)
        job_params = []
        for idx, overrides in enumerate(job_overrides, start=initial_job_idx):
            log.info("\t#%d : %s", idx, " ".join(filter_overrides(overrides)))
            job_params.append((list(overrides), "hydra.sweep.dir", idx, f"job_id_for_{idx}", Singleton.get_state()))
        try:
            jobs = executor.map_array(self, *zip(*job_params))
        except (subprocess.CalledProcessError, FileNotFoundError) as exc:
            detail = getattr(exc, "stderr", None) or getattr(exc, "output", None) or exc
            if isinstance(detail, bytes):
                detail = detail.decode(errors="replace")
            fail(f"sbatch refused the sweep's jobs: {' '.join(str(detail).split())}", status=1)
        array = str(jobs[0].job_id).split("_")[0]
        many = len(jobs) > 1  # submitit sends a single job as a plain job, not as an array
        print(
            f"SLURM job{' array' * many} {array}: {len(jobs)} job{'s' * many} submitted; scancel {array} cancels "
            f"{'them' if many else 'it'}",
            flush=True,
        )
        return self._wait(jobs, array, list(job_overrides), initial_job_idx)

    def _wait(self, jobs: list, array: str, overrides: list, first: int) -> list[JobReturn]:
        results: list[JobReturn | None] = [None] * len(jobs)
        ended_at: dict[int, float] = {}
        cancelled_at, last_poll, submitted, told = None, 0.0, time.time(), set()
        while any(r is None for r in results):
            for i, job in enumerate(jobs):
                if results[i] is None and job.paths.result_pickle.exists():
                    results[i] = _job_return(job, overrides[i])
            now = time.time()
            if stop.received() is not None and cancelled_at is None:
                cancelled_at = now
                _cancel(array, signal.Signals(stop.received()).name)
            if now - last_poll >= POLL and any(r is None for r in results):
                last_poll = now
                self._poll(jobs, array, results, ended_at, overrides, first)
            if cancelled_at is not None and now - cancelled_at > CANCEL_WAIT:
                for i, job in enumerate(jobs):  # pending when cancelled: nothing of them ran
                    if results[i] is None:
                        why = f"SLURM job {job.job_id} cancelled before its result"
                        results[i] = self._without_result(first + i, overrides[i], "interrupted", why)
            for i, ret in enumerate(results):
                if ret is not None and i not in told:
                    told.add(i)
                    self._job_line(first + i, ret, time.time() - submitted)
            if any(r is None for r in results):
                time.sleep(1.0)
        return results  # type: ignore[return-value]

    def _poll(self, jobs: list, array: str, results: list, ended_at: dict, overrides: list, first: int) -> None:
        try:
            text = slurm_limits.run("squeue", "-h", "-r", "-t", "all", "-j", array, "-o", "%i|%T|%r")
            states = slurm_limits.queue(text)
        except (subprocess.SubprocessError, OSError) as exc:  # the controller busy or restarting: the next poll
            log.warning("squeue failed (%s); waiting for SLURM job %s", exc, array)
            return
        reason = slurm_limits.never_starts(states)
        if reason:
            _cancel(array, None)
            fail(f"SLURM job {array} cannot start (Reason={reason}): {self._request_text()}; cancelled", 1)
        now = time.time()
        for i, job in enumerate(jobs):
            if results[i] is not None:
                continue
            state = states.get(str(job.job_id), ("GONE", ""))[0]
            if state.split()[0] in slurm_limits.ENDED or state == "GONE":
                ended_at.setdefault(i, now)
                if now - ended_at[i] > GRACE and not job.paths.result_pickle.exists():
                    error = f"SLURM job {job.job_id} ended {state} without a result (its log: {job.paths.stderr})"
                    log.error("job %d: %s", i, error)
                    cancelled = stop.received() is not None or state.startswith("CANCELLED")
                    status = "interrupted" if cancelled else "failed"
                    results[i] = self._without_result(first + i, overrides[i], status, error)
            else:
                ended_at.pop(i, None)  # requeued: running again

    def _without_result(self, num: int, overrides: list, status: str, error: str) -> JobReturn:
        """A job that ended without a result (killed, out of memory, cancelled while pending): recorded in its run
        directory, as the job would have, so the sweep's summary lists it."""
        try:
            cfg = self.hydra_context.config_loader.load_sweep_config(self.config, list(overrides))
            with open_dict(cfg.hydra.job):
                cfg.hydra.job.num = num
            RunDir(Path(str(cfg.hydra.sweep.dir)) / str(cfg.hydra.sweep.subdir)).record_end(
                overrides, cfg.get("seed", 0), status, error
            )
        except Exception as exc:  # noqa: BLE001 - the sweep's own return still says so
            log.warning("job %d: its %s record not written: %s: %s", num, status, type(exc).__name__, exc)
        return _no_result(overrides, status, error)

    def _job_line(self, num: int, ret: JobReturn, seconds: float) -> None:
        """The sweep's line for a job that ended (hybrid_sysid.launch.progress); its seconds count from the submission,
        time in the queue included. The job's own line went to its SLURM log."""
        try:
            header, done = count_done(Path(str(self.config.hydra.sweep.dir)), num)
            print(job_line(header, done, num, ret, seconds), flush=True)
        except Exception as exc:  # noqa: BLE001 - no .progress (a search): the job is done all the same
            log.info("no progress line: %s: %s", type(exc).__name__, exc)

    def _request_text(self) -> str:
        try:
            limit = slurm_limits.partition_limits(self.params.get("partition")).text()
        except (subprocess.SubprocessError, OSError):
            limit = "the partition's limits could not be read"
        return f"a job asks {request_of(self.params).text()}, but {limit}"


def request_of(params: dict) -> slurm_limits.Request:
    """One job's request from hydra.launcher's (resolved) values."""
    mem = params.get("mem_gb")
    return slurm_limits.Request(
        cpus_per_task=int(params.get("cpus_per_task") or 1),
        tasks_per_node=int(params.get("tasks_per_node") or 1),
        mem_gb=None if mem is None else float(mem),
        minutes=int(params.get("timeout_min") or 0),
        nodes=int(params.get("nodes") or 1),
    )


def check_request(launcher) -> None:
    """The preflight of launcher=slurm: SLURM's commands on PATH and one job's request within the partition; a
    refusal is one line (ConfigError) before anything is written or submitted."""
    params = OmegaConf.to_container(launcher, resolve=True)
    try:
        limit = slurm_limits.partition_limits(params.get("partition"))
    except FileNotFoundError as exc:
        raise ConfigError(
            "launcher",
            Shown("slurm"),
            f"{exc.filename} is not on PATH: start the sweep where SLURM's commands are (a login node)",
        ) from None
    except subprocess.CalledProcessError as exc:
        said = " ".join(f"{exc.stdout or ''} {exc.stderr or ''}".split()) or f"{exc.cmd[0]} failed"
        raise ConfigError("hydra.launcher.partition", params.get("partition"), said) from None
    refusal = slurm_limits.too_big(request_of(params), limit)
    if refusal is not None:
        raise refusal


def _cancel(array: str, signal_name: str | None) -> None:
    """scancel the array; on failure, one line saying what is left running and how to cancel it."""
    try:
        subprocess.run(["scancel", array], capture_output=True, timeout=60, check=True)
        if signal_name:
            print(
                f"{signal_name}: SLURM job {array} cancelled; its running jobs record their interruption",
                file=sys.stderr,
                flush=True,
            )
    except (subprocess.SubprocessError, OSError) as exc:
        print(
            f"SLURM job {array} left running ({type(exc).__name__}); cancel it with: scancel {array}",
            file=sys.stderr,
            flush=True,
        )


def _job_return(job, overrides: list) -> JobReturn:
    """The job's own return (its record), or a failed one when submitit's result holds an error."""
    try:
        return job.results()[0]
    except Exception as exc:  # noqa: BLE001 - e.g. requeued past max_num_timeout: its record says interrupted
        last = str(exc).strip().splitlines()[-1:] or [type(exc).__name__]
        return _no_result(overrides, "failed", f"SLURM job {job.job_id}: {last[0]}")


def _no_result(overrides: list, status: str, error: str) -> JobReturn:
    ret = JobReturn(overrides=list(overrides), status=JobStatus.COMPLETED)
    ret.return_value = {"status": status, "error": error}
    return ret
