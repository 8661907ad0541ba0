"""A path outside ASCII given as an override: Hydra's grammar allows no such character in an unquoted value, and
under an ASCII locale Python hands it over as lone surrogates (hybrid_sysid.launch.overrides quotes it)."""

import os

import pytest

from hybrid_sysid.launch.overrides import quoted_overrides

from helpers.app_process import run_app

ASCII_LOCALE = {"LC_ALL": "C", "LANG": "C", "PYTHONUTF8": "0"}
TINY = ["data=tiny", "trainer=debug", "trainer.max_steps=2", "trainer.eval_every_n_steps=1"]


@pytest.mark.parametrize(
    "given, read",
    [
        ("hydra.run.dir=lauf_ü", "hydra.run.dir='lauf_ü'"),
        ("init_from=lauf_\udcc3\udcbc/run", "init_from='lauf_\udcc3\udcbc/run'"),  # LC_ALL=C's argv
        ("init_from=a/run,lauf_ü/run", "init_from=a/run,'lauf_ü/run'"),  # a sweep's items stay items
        ("hydra.run.dir=lauf", "hydra.run.dir=lauf"),
        ("init_from='lauf_ü'", "init_from='lauf_ü'"),  # quoted by the user: as written
        ("paths.root=${oc.env:HOME}/ü", "paths.root=${oc.env:HOME}/ü"),  # Hydra syntax: left to Hydra
        ("seed=٣", "seed=٣"),  # an Arabic-Indic 3: Hydra refuses it, never read as the number 3
        ("-m", "-m"),
        ("lauf_ü", "lauf_ü"),  # no override: Hydra names it
    ],
)
def test_a_plain_value_outside_ascii_is_quoted_and_nothing_else_changes(given, read):
    assert quoted_overrides([given]) == [read]


def test_an_options_own_argument_is_no_override():
    assert quoted_overrides(["--config-dir", "conf=ü", "seed=1"]) == ["--config-dir", "conf=ü", "seed=1"]


def test_paths_outside_ascii_as_arguments_under_an_ascii_locale(tmp_path, tiny_cache):
    """Two runs swept into hydra.sweep.dir=<dir>/lauf_ü/src, two runs started from them (init_from=, swept) and an
    evaluation in hydra.run.dir=<dir>/lauf_ü/ev: each exit 0 (each was a lexer error naming the override), no
    traceback; the sweep's table names the paths in UTF-8 and its figures are drawn (a font refused surrogates)."""
    where = tmp_path / "lauf_ü"
    env = {**{k: v for k, v in os.environ.items() if k != "PYTHONIOENCODING"}, **ASCII_LOCALE}
    sources = f"{where / 'src' / '0'},{where / 'src' / '1'}"
    commands = [
        ("hybrid_sysid", "-m", *TINY, "seed=0,1", f"hydra.sweep.dir={where / 'src'}"),
        ("hybrid_sysid", "-m", *TINY, f"init_from={sources}", f"hydra.sweep.dir={where / 'sw'}"),
        ("hybrid_sysid.cli.evaluate", f"run={where / 'src' / '0'}", f"hydra.run.dir={where / 'ev'}"),
    ]
    for module, *args in commands:
        proc = run_app(tmp_path, *args, module=module, cache=tiny_cache, env=env)
        assert proc.returncode == 0, proc.stderr[-2000:]
        assert "Traceback" not in proc.stderr and "Logging error" not in proc.stderr, proc.stderr[-2000:]
    assert (where / "ev" / "metrics.json").is_file()
    assert f"{where / 'src' / '1'}".encode() in (where / "sw" / "summary.md").read_bytes()
    assert (where / "sw" / "figures" / "robustness.png").is_file()
