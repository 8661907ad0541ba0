"""The state a sweep's processes share through its directory (runs.sweepdir.SweepDir): the stop mark and the
progress file, written in turn by parallel workers."""

import json
import multiprocessing

import pytest

from hybrid_sysid.runs.layout import PROGRESS, STOP_MARKER
from hybrid_sysid.runs.sweepdir import SweepDir


def test_the_stop_mark_is_seen_by_another_handle_and_cleared_by_a_rerun(tmp_path):
    SweepDir(tmp_path).mark_stopped()
    assert (tmp_path / STOP_MARKER).is_file() and SweepDir(tmp_path).stopped()
    SweepDir(tmp_path).clear_stopped()
    assert not (tmp_path / STOP_MARKER).exists() and not SweepDir(tmp_path).stopped()
    SweepDir(tmp_path).clear_stopped()  # nothing to clear: no error


def test_a_sweep_directory_not_yet_made_gets_no_mark(tmp_path):
    sweep = SweepDir(tmp_path / "not_made")
    sweep.mark_stopped()
    assert not sweep.path.exists() and not sweep.stopped()


def test_the_progress_file_reads_back_its_header_and_every_event(tmp_path):
    sweep = SweepDir(tmp_path / "sw")
    sweep.start_progress({"jobs": 2, "start": 1.0})
    lines = sweep.add_progress({"start": 0, "t": 2.0})
    assert [json.loads(line) for line in lines] == [{"jobs": 2, "start": 1.0}, {"start": 0, "t": 2.0}]
    header, events = sweep.progress_with({"end": 0, "t": 3.0})
    assert header == {"jobs": 2, "start": 1.0}
    assert events == [{"start": 0, "t": 2.0}, {"end": 0, "t": 3.0}]
    assert (sweep.path / PROGRESS).read_text().count("\n") == 3


def test_an_older_file_s_bare_numbers_are_job_ends(tmp_path):
    (tmp_path / PROGRESS).write_text(json.dumps({"jobs": 9}) + "\n3\n")
    _, events = SweepDir(tmp_path).progress_with({"end": 4})
    assert events == [{"end": 3}, {"end": 4}]


def test_a_missing_progress_file_stays_missing(tmp_path):
    with pytest.raises(FileNotFoundError):
        SweepDir(tmp_path).add_progress({"start": 0})
    assert not (tmp_path / PROGRESS).exists()


def test_a_file_without_a_header_is_refused(tmp_path):
    (tmp_path / PROGRESS).write_text("[1, 2]\n")
    with pytest.raises(ValueError, match="no header"):
        SweepDir(tmp_path).progress_with({"end": 0})


def _write_ends(path: str, first: int, n: int) -> None:
    for num in range(first, first + n):
        SweepDir(path).add_progress({"end": num, "pad": "x" * 2000})  # long lines: a torn write would show


def test_processes_writing_at_once_lose_no_line_and_tear_none(tmp_path):
    SweepDir(tmp_path).start_progress({"jobs": 200})
    ctx = multiprocessing.get_context("spawn")
    workers = [ctx.Process(target=_write_ends, args=(str(tmp_path), 50 * i, 50)) for i in range(4)]
    for w in workers:
        w.start()
    for w in workers:
        w.join(timeout=120)
    assert [w.exitcode for w in workers] == [0, 0, 0, 0]
    header, events = SweepDir(tmp_path).progress_with({"end": "last"})
    assert header == {"jobs": 200}
    assert sorted(e["end"] for e in events[:-1]) == list(range(200))
