"""A trained run as someone else might send it: a copy whose saved config has one line changed."""

import shutil


def received(tiny_run, tmp_path, line, replaced):
    """A copy of the trained run whose saved config has ``line`` (as saved, indented) replaced."""
    run = tmp_path / "received"
    shutil.copytree(tiny_run, run)
    config = run / ".hydra" / "config.yaml"
    text = config.read_text()
    assert f"\n{line}\n" in text
    config.write_text(text.replace(f"\n{line}\n", f"\n{replaced}\n"))
    return run
