"""A job freezes what its imports left (cli.train.freeze_imports) so full garbage collections skip it, without
keeping any garbage: what was unreachable is collected first, and what the job allocates later stays collectable."""

import gc
import weakref

from hybrid_sysid.cli.train import freeze_imports


class _Node:
    def __init__(self):
        self.me = self  # a reference cycle: only the garbage collector frees it


def test_freezing_collects_an_earlier_jobs_garbage_and_later_garbage_stays_collectable():
    earlier = _Node()
    gone_before = weakref.ref(earlier)
    del earlier
    try:
        freeze_imports()
        assert gone_before() is None  # collected, not frozen
        assert gc.get_freeze_count() > 0
        later = _Node()
        gone_after = weakref.ref(later)
        del later
        gc.collect()
        assert gone_after() is None
    finally:
        gc.unfreeze()
