"""The command itself on bad values of issue 46: exit 2, one line on stderr naming the key, no traceback, and
no directory or file made, under the working directory or at the filesystem's root."""

import pytest

CASES = [
    (["noise.train_std=1e300"], {}, "noise.train_std"),
    (["trainer.threads=100000"], {}, "trainer.threads"),
    (["trainer.devices=0"], {}, "trainer.devices"),
    (["car.seat_hardening=1e30"], {}, "car.seat_hardening"),
    (["objective=nonexistent"], {}, "objective"),
    (["trainer.max_steps=abc"], {}, "trainer.max_steps"),
    (["paths.root=''"], {}, "paths.root"),
    ([], {"HYBRID_SYSID_CACHE": ""}, "paths.cache_dir"),
]


@pytest.mark.parametrize("args, env, key", CASES)
def test_a_bad_value_is_one_line_naming_its_key_and_makes_nothing(tmp_path, cli_in_process, args, env, key):
    from hybrid_sysid.cli.train import main

    work = tmp_path / "work"
    work.mkdir()
    env = {"HYBRID_SYSID_CACHE": tmp_path / "cache", **env}
    code, out, err = cli_in_process(main, "data=tiny", "trainer=debug", *args, cwd=work, env=env)
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1, err[-2000:]
    assert lines[0].startswith(f"error: {key} "), lines[0]
    assert list(work.iterdir()) == [] and not (tmp_path / "cache").exists()


EDGES = ["noise.train_std=0", "noise.eval_std=[0]", "trainer.threads=1", "car.seat_hardening=0", "seed=4294967295"]


def test_values_at_the_edge_of_their_ranges_train_and_record(tmp_path, cli_in_process, tiny_cache):
    """Values at an end of what the checks allow, in one run: exit 0 and a completed record that holds them."""
    import json

    from hybrid_sysid.cli.train import main

    args = ["data=tiny", "trainer=debug", "trainer.max_steps=2", *EDGES, f"hydra.run.dir={tmp_path / 'run'}"]
    code, out, err = cli_in_process(main, *args, cwd=tmp_path, env={"HYBRID_SYSID_CACHE": tiny_cache})
    assert code == 0, err[-2000:]
    record = json.loads((tmp_path / "run" / "metrics.json").read_text())
    assert record["status"] == "completed" and record["seed"] == 4294967295 and record["threads"] == 1
    assert {r["noise_std"] for r in record["results"]} == {0.0}
    assert all(r["mean_rel_dev"] >= 0 for r in record["results"])
