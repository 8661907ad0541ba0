"""data=recordings' files (hybrid_sysid.data.recordings_files, recordings_labels and the module's split): names,
labels in either form, the split by recording, and a split's samples read only when that split is asked for."""

import numpy as np
import pytest
from hydra import compose, initialize_config_dir

from hybrid_sysid.config import CONF_DIR
from hybrid_sysid.data import recordings_files
from hybrid_sysid.data.recordings_files import scan, split_recordings
from hybrid_sysid.data.recordings_labels import read_labels
from hybrid_sysid.training.build import build_datamodule

from helpers.recordings import seat_recordings, write_folder, write_labels

DT = 0.005


@pytest.fixture
def folder(tmp_path):
    seat, body, p, m3 = seat_recordings(20, 240, DT, seed=5)
    names = write_folder(tmp_path / "files", seat, body, DT, npz_from=12)
    return tmp_path / "files", names, seat, body, p, m3


def test_a_folder_is_indexed_by_name_in_file_order_with_each_length(folder):
    root, names, seat, *_ = folder
    idx = scan(root)
    # files in name order (batch.npz before rec000.csv), a file's recordings in its own order
    assert [r.name for r in idx.recordings] == names[12:] + names[:12]
    assert [r.file for r in idx.recordings] == ["batch.npz"] * 8 + [f"{n}.csv" for n in names[:12]]
    assert idx.dt == pytest.approx(DT, rel=1e-12) and set(idx.steps) == {240}


def test_labels_as_c3_k3_m3_equal_labels_as_p1_p2(folder, tmp_path):
    root, names, _, _, p, m3 = folder
    order = names[::-1]  # rows in another order than the recordings
    back = [names.index(n) for n in order]
    by_p = read_labels(write_labels(tmp_path / "p.csv", order, p[back], form="p"), names)
    by_c = read_labels(write_labels(tmp_path / "c.csv", order, p[back], m3[back], form="c3k3m3"), names)
    np.testing.assert_allclose(by_c[0], by_p[0], rtol=1e-12)
    np.testing.assert_allclose(by_p[0], p, rtol=1e-12)  # in the recordings' order, whatever the file's
    np.testing.assert_allclose(by_c[1], m3, rtol=1e-12)
    assert np.isnan(by_p[1]).all()  # p1, p2 without an m3 column: m3 unknown


@pytest.mark.parametrize("n", [3, 10, 48, 1001])
def test_the_split_puts_each_recording_in_one_split_and_depends_on_data_seed_alone(n):
    split = split_recordings(n, 0.8, 0.125, seed=0)
    parts = [split.train, split.val, split.test]
    assert sorted(np.concatenate(parts).tolist()) == list(range(n))  # each recording once
    assert all(len(part) >= 1 for part in parts)
    assert len(split.test) == n - round(0.8 * n)  # the test share as data.splits counts roads
    again = split_recordings(n, 0.8, 0.125, seed=0)
    assert all(np.array_equal(a, b) for a, b in zip(parts, [again.train, again.val, again.test]))
    if n >= 10:
        other = split_recordings(n, 0.8, 0.125, seed=1)
        assert not np.array_equal(split.test, other.test)


def test_too_few_recordings_to_split_name_data_path():
    with pytest.raises(ValueError, match=r"^data\.path = 2 recordings is not allowed: too few"):
        split_recordings(2, 0.8, 0.125, seed=0)


def test_a_split_is_read_from_the_files_only_when_it_is_asked_for(folder, monkeypatch):
    """Training holds the training split; validation and test are read when asked, one at a time: a folder's
    samples are never all in memory at once (docs/recordings.md)."""
    root, names, *_ = folder
    with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
        cfg = compose(
            config_name="config",
            overrides=["data=recordings", f"data.path={root}", "data.window=200", "objective=hybrid"],
        )
    recordings_files.index(root)  # the scan, as the command's checks make it
    read = []
    real = recordings_files.read_file
    monkeypatch.setattr(recordings_files, "read_file", lambda path: read.append(path.name) or real(path))
    dm = build_datamodule(cfg)
    split = dm.split

    def files_of(rows):  # rows index the recordings in the scan's order
        return {dm.index.recordings[i].file for i in rows}

    assert read == []  # the scan was made before: building reads nothing
    dm.setup("fit")
    assert set(read) == files_of(split.train) and len(read) == len(files_of(split.train))
    for part in ("val", "test"):
        read.clear()
        batch = dm.eval_batch(part, 0.0)
        assert set(read) == files_of(getattr(split, part)) and len(batch["signals"]) == len(getattr(split, part))
        assert dm.held_splits == ("train", part)  # the other split is released before this one is read
