"""A path outside ASCII given as an override: Hydra's grammar allows no such character in an unquoted value, and
under an ASCII locale Python hands it over as lone surrogates (hybrid_sysid.launch.overrides quotes it)."""

import pytest

from hybrid_sysid.launch.overrides import quoted_overrides

from helpers.app_process import run_app
from helpers.started_early import started_early

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


@started_early
def ascii_locale_paths(tmp, env, tiny_cache):
    """Two runs swept into hydra.sweep.dir=<dir>/lauf_ü/src, two runs started from them (init_from=, swept) and an
    evaluation in hydra.run.dir=<dir>/lauf_ü/ev, one after another under an ASCII locale: (their processes, <dir>/
    lauf_ü). Started early: each starts Python, torch and Lightning (about 20 s in all)."""
    where = tmp / "lauf_ü"
    env = {**{k: v for k, v in env.items() if k != "PYTHONIOENCODING"}, **ASCII_LOCALE}
    sources = f"{where / 'src' / '0'},{where / 'src' / '1'}"
    commands = [
        ("hybrid_sysid", "-m", *TINY, "seed=0,1", f"hydra.sweep.dir={where / 'src'}"),
        ("hybrid_sysid", "-m", *TINY, f"init_from={sources}", f"hydra.sweep.dir={where / 'sw'}"),
        ("hybrid_sysid.cli.evaluate", f"run={where / 'src' / '0'}", f"hydra.run.dir={where / 'ev'}"),
    ]
    procs = []
    for module, *args in commands:
        procs.append(run_app(tmp, *args, module=module, cache=tiny_cache, env=env))
        if procs[-1].returncode != 0:
            break  # the next reads what this one should have written
    return procs, where


def test_paths_outside_ascii_as_arguments_under_an_ascii_locale(ascii_locale_paths):
    """Each exits 0 (each was a lexer error naming the override), no traceback; the sweep's table names the paths
    in UTF-8 and its figures are drawn (a font refused surrogates)."""
    procs, where = ascii_locale_paths
    assert len(procs) == 3
    for proc in procs:
        assert proc.returncode == 0, proc.stderr[-2000:]
        assert "Traceback" not in proc.stderr and "Logging error" not in proc.stderr, proc.stderr[-2000:]
    assert (where / "ev" / "metrics.json").is_file()
    assert f"{where / 'src' / '1'}".encode() in (where / "sw" / "summary.md").read_bytes()
    assert (where / "sw" / "figures" / "robustness.png").is_file()
