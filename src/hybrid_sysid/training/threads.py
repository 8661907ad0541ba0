"""torch's thread count around a run: a run sets its own (trainer.threads) and leaves the process as it found it."""

from __future__ import annotations

import functools

import torch


def keeps_thread_count(fn):
    """Run ``fn`` and put torch's thread count back as it was: a run sets its own (``trainer.threads``), and one run
    called after another in the same process (a test, a notebook, the basic launcher's jobs) must start from the
    count the process had, or its numbers would depend on the runs before it (docs/reliability/reproducibility.md)."""

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        threads = torch.get_num_threads()
        try:
            return fn(*args, **kwargs)
        finally:
            if torch.get_num_threads() != threads:
                torch.set_num_threads(threads)

    return wrapper
