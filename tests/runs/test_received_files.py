"""core.files' readers of received files: a regular file only, within a size, a nesting depth and (YAML) a count of
nodes with every alias expanded; each refusal is an UnreadableFile (a ValueError), at once, never a hang."""

import json
import os
import time

import pytest
import yaml

from hybrid_sysid.core.files import MAX_YAML_BYTES, MAX_YAML_NODES, UnreadableFile, read_json, read_text, read_yaml

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


def test_one_long_scalar_aliased_many_times_is_refused_by_its_expanded_bytes(tmp_path):
    """An 8 MiB scalar aliased 90,000 times: 90,001 nodes, within the node count, but 700 GiB of text once expanded
    (building a config from it took hours). Refused in seconds, before any value is built."""
    path = tmp_path / "config.yaml"
    path.write_text("big: &b " + "a" * 8 * 2**20 + "\nmany: [" + ", ".join(["*b"] * 90_000) + "]\n")
    started = time.monotonic()
    with pytest.raises(UnreadableFile, match=f"more than {MAX_YAML_BYTES} bytes of text with its aliases expanded"):
        read_yaml(path)
    assert time.monotonic() - started < 5


def test_text_up_to_the_expanded_bytes_is_read(tmp_path):
    """Keys and values count, in UTF-8 bytes; a file exactly at the bound reads, one more is refused."""
    path = tmp_path / "config.yaml"
    value = "ü" + "a" * ((MAX_YAML_BYTES - 2) // 2 - 2)  # twice (anchored, aliased) with the keys k and j: the bound
    path.write_text(f"k: &v {value}\nj: *v\n")
    assert read_yaml(path) == {"k": value, "j": value}
    path.write_text(f"k: &v {value}a\nj: *v\n")
    with pytest.raises(UnreadableFile, match="bytes of text"):
        read_yaml(path)


@pytest.mark.parametrize("text", ["[" * 100_000, "- " * 100_000 + "x", "".join(" " * i + "a:\n" for i in range(2000))])
def test_yaml_nested_deeper_than_the_limit_is_refused(tmp_path, text):
    path = tmp_path / "config.yaml"
    path.write_text(text)
    with pytest.raises(UnreadableFile, match="nested deeper than 64"):
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
