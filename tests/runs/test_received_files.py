"""core.files' readers of received files: a regular file only, within a size, a nesting depth and (YAML) a count of
nodes with every alias expanded; each refusal is an UnreadableFile (a ValueError), at once, never a hang."""

import json
import os

import pytest
import yaml

from hybrid_sysid.core.files import MAX_YAML_NODES, UnreadableFile, read_json, read_text, read_yaml

from helpers.hostile import laughs


def test_a_fifo_is_refused_at_once_without_waiting_for_a_writer(tmp_path):
    fifo = tmp_path / "metrics.json"
    os.mkfifo(fifo)
    with pytest.raises(UnreadableFile, match="not a regular file"):
        read_json(fifo)


def test_a_link_to_a_device_or_a_folder_is_refused(tmp_path):
    (tmp_path / "zero").symlink_to("/dev/zero")
    for path in (tmp_path / "zero", tmp_path):
        with pytest.raises(UnreadableFile, match="not a regular file"):
            read_text(path)


def test_a_file_above_the_limit_is_refused_and_one_at_it_is_read(tmp_path):
    path = tmp_path / "f"
    path.write_text("x" * 1001)
    with pytest.raises(UnreadableFile, match="larger than 1000 bytes"):
        read_text(path, limit=1000)
    assert read_text(path, limit=1001) == "x" * 1001


@pytest.mark.parametrize("depth", [100, 100_000])
def test_json_nested_deeper_than_the_limit_is_refused(tmp_path, depth):
    path = tmp_path / "metrics.json"
    path.write_text("[" * depth + "]" * depth)
    with pytest.raises(UnreadableFile, match="nested deeper than 64"):
        read_json(path)


def test_json_within_the_limits_reads_as_json_does(tmp_path):
    record = {"status": "completed", "test": [{"noise_std": 0.0, "p": [[1.5, 2.5]] * 3}], "seed": 3}
    path = tmp_path / "metrics.json"
    path.write_text(json.dumps(record))
    assert read_json(path) == record


def test_a_billion_laughs_is_refused_before_any_expansion(tmp_path):
    path = tmp_path / "config.yaml"
    path.write_text(laughs(9))  # 9 ** 9 = 387 million leaves: expanded, gigabytes
    with pytest.raises(UnreadableFile, match=f"more than {MAX_YAML_NODES} nodes with its aliases expanded"):
        read_yaml(path)


def test_a_few_aliases_and_plain_yaml_read_as_yaml_does(tmp_path):
    path = tmp_path / "config.yaml"
    text = laughs(3) + "data:\n  window: 200\n  dt: 0.005\n"
    path.write_text(text)
    assert read_yaml(path) == yaml.safe_load(text)


def test_an_alias_within_its_own_anchor_is_refused(tmp_path):
    path = tmp_path / "config.yaml"
    path.write_text("a: &a [1, *a]\n")
    with pytest.raises(UnreadableFile, match="within its own anchor"):
        read_yaml(path)
