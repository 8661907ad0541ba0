"""What SLURM's accounting says of a job once it has settled. sacct lags a job's end: right after ``sbatch --wait``
returns, or after an array's last job ended, it may still say RUNNING or COMPLETING (seen on the one-node cluster of
scripts/slurm/setup.sh). A test reads the states once none of them is one that a job leaves by itself."""

import subprocess
import time

UNSETTLED = {"PENDING", "RUNNING", "COMPLETING", "CONFIGURING", "REQUEUED", "RESIZING", "SUSPENDED"}


def sacct(job: str, all_attempts: bool = False) -> list[tuple[str, str]]:
    """sacct's (job id, state) rows for the job or array, requeued attempts too with ``all_attempts``."""
    command = ["sacct", "-n", "-X", "-P", "-j", job, "-o", "JobID,State"] + (["-D"] if all_attempts else [])
    out = subprocess.run(command, capture_output=True, text=True, check=True).stdout
    rows = [line.split("|") for line in out.splitlines() if "|" in line]
    return [(job_id, state.split()[0] if state.strip() else "") for job_id, state in rows]


def settled(job: str, all_attempts: bool = False, timeout: float = 120) -> list[tuple[str, str]]:
    """``sacct``'s rows once the newest attempt of every job has a state it does not leave by itself (or once
    ``timeout`` seconds have passed: the rows as they are then, for the test's assertion to show)."""
    deadline = time.monotonic() + timeout
    while True:
        rows = sacct(job, all_attempts)
        newest = dict(rows)  # the last row of a job id is its newest attempt
        if (rows and not set(newest.values()) & UNSETTLED) or time.monotonic() > deadline:
            return rows
        time.sleep(1)
