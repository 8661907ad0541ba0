"""Every table of a results page names where it comes from: the command that re-creates its sweeps, the commit and
the CPU of its runs. Fake sweeps carry records of a known commit and CPU and a multirun.yaml of a known command
line; the page must name exactly those. A real run's record must hold its checkout's commit and its CPU."""

import json
import re
import shlex
import subprocess
from pathlib import Path

import pytest
import yaml

from hybrid_sysid.cli.report import main
from hybrid_sysid.report.provenance import (
    generated_sections,
    page_sections,
    read_provenance,
    sections_without_provenance,
)

from helpers.evaluation_fakes import make_run, make_sweep

REPO = Path(__file__).resolve().parents[2]
COMMIT_A = "0123456789abcdef0123456789abcdef01234567"
COMMIT_B = "fedcba9876543210fedcba9876543210fedcba98"
CPU = "Test CPU 9000 @ 3.00GHz"


def stamp(run_dir: Path, commit: str | None, dirty: bool = False, cpu: str | None = CPU) -> None:
    """Give a fake run's record the fields a run writes about its code and processor."""
    record = json.loads((run_dir / "metrics.json").read_text())
    record.update(git_commit=commit, git_dirty=dirty, cpu=cpu)
    (run_dir / "metrics.json").write_text(json.dumps(record))


def sweep_file(sweep: Path, task: list[str], hydra: list[str] = (), config_name: str = "config") -> None:
    """The multirun.yaml Hydra writes in a sweep directory: the command line's overrides, split in two lists."""
    content = {
        "hydra": {
            "mode": "MULTIRUN",
            "overrides": {"hydra": [f"hydra.sweep.dir={sweep}", *hydra], "task": list(task)},
            "job": {"name": "train", "config_name": config_name},
        }
    }
    (sweep / "multirun.yaml").write_text(yaml.safe_dump(content))


def fake_sweep(path: Path, task: list[str], commits=(COMMIT_A,), hydra=()) -> Path:
    """2 objectives x 2 seeds, all completed; run i gets commits[i % len(commits)]."""
    make_sweep(path, failed=False)
    sweep_file(path, task, hydra)
    for i, run in enumerate(sorted(p for p in path.iterdir() if p.is_dir())):
        stamp(run, commits[i % len(commits)])
    return path


def page(tmp_path: Path, *args) -> str:
    out = tmp_path / "docs" / "results.md"
    assert main([*map(str, args), f"results={out}"]) == 0
    return out.read_text()


def block(text: str) -> list[str]:
    """The lines under the first section's heading, up to the first blank line after them."""
    return page_sections(text)[0][1].strip("\n").split("\n\n", 1)[0].splitlines()


def first(text: str):
    """The provenance read back from the first section of a page."""
    return read_provenance(page_sections(text)[0][1])


def test_the_page_names_the_command_commit_and_cpu_of_a_sweep(tmp_path):
    sweep = fake_sweep(
        tmp_path / "robust",
        ["experiment=robustness", "trainer.max_steps=300"],
        hydra=["hydra.launcher.n_jobs=2"],
    )
    text = page(tmp_path, sweep)
    # right under the heading; the sweep's location (this machine's path) is not part of the command
    assert block(text) == [
        "- command: `hybrid-sysid experiment=robustness trainer.max_steps=300 hydra.launcher.n_jobs=2`",
        f"- commit: `{COMMIT_A[:7]}`",
        f"- CPU: {CPU}",
    ]
    assert sections_without_provenance(text) == []


def test_runs_of_two_commits_name_both_with_their_counts(tmp_path):
    sweep = fake_sweep(tmp_path / "mixed", ["experiment=robustness"], commits=(COMMIT_A, COMMIT_B))
    stamp(sweep / "3", COMMIT_B, dirty=True)  # runs 1 and 3 had B, run 3 with changes not committed
    text = page(tmp_path, sweep)
    assert sorted(first(text).commits) == [(COMMIT_A[:7], False, 2), (COMMIT_B[:7], False, 1), (COMMIT_B[:7], True, 1)]
    assert block(text)[1].startswith("- commits, which differ between the runs: ")


def test_a_dirty_tree_and_a_missing_commit_are_said(tmp_path):
    sweep = fake_sweep(tmp_path / "d", ["experiment=robustness"])
    for run in ("0", "1", "2", "3"):
        stamp(sweep / run, COMMIT_A, dirty=True)
    assert block(page(tmp_path, sweep))[1] == f"- commit: `{COMMIT_A[:7]}` (dirty)"
    for run in ("0", "1", "2", "3"):  # records made before the fields existed
        record = json.loads((sweep / run / "metrics.json").read_text())
        (sweep / run / "metrics.json").write_text(json.dumps({k: v for k, v in record.items() if k != "git_commit"}))
    text = page(tmp_path, sweep)
    assert block(text)[1] == "- commit: not recorded"
    assert sections_without_provenance(text) == ["d: a commit not recorded"]


def test_a_merged_table_names_each_sweeps_command(tmp_path):
    noisy = fake_sweep(tmp_path / "noisy", ["experiment=noise_robust", "noise.train_std=0.01"])
    clean = fake_sweep(tmp_path / "clean", ["experiment=noise_robust", "noise.train_std=0.0"], commits=(COMMIT_B,))
    other = fake_sweep(tmp_path / "other", ["experiment=best"])
    text = page(tmp_path, noisy, other, f"merge={noisy},{clean}")
    # the merged section follows the section of its first sweep
    assert [h for h, _ in page_sections(text)] == ["noisy", "All rows: noisy and clean", "other"]
    p = read_provenance(dict(page_sections(text))["All rows: noisy and clean"])
    assert p.commands == (
        ("hybrid-sysid experiment=noise_robust noise.train_std=0.01", "noisy"),
        ("hybrid-sysid experiment=noise_robust noise.train_std=0.0", "clean"),
    )
    assert sorted(p.commits) == [(COMMIT_A[:7], False, 4), (COMMIT_B[:7], False, 4)]
    assert sections_without_provenance(text) == []


def test_merge_needs_two_sweeps_and_a_results_page(tmp_path, capsys):
    sweep = fake_sweep(tmp_path / "s", ["experiment=best"])
    assert main([str(sweep), f"merge={sweep}", f"results={tmp_path / 'r.md'}"]) == 2
    assert main([str(sweep), f"merge={sweep},{sweep}"]) == 2
    assert main([str(sweep), f"merge={sweep},{tmp_path / 'typo'}", f"results={tmp_path / 'r.md'}"]) == 2
    errors = capsys.readouterr().err.splitlines()
    assert len(errors) == 3 and all(line.startswith("hybrid-sysid-report: error: ") for line in errors)
    assert not (tmp_path / "r.md").exists()


@pytest.mark.parametrize(
    ("task", "config_name", "expected"),
    [
        # a sweep given on the command line needs -m; an experiment preset starts a multirun by itself
        (["objective=labelled,hybrid", "seed=0,1"], "config", "hybrid-sysid -m objective=labelled,hybrid seed=0,1"),
        (["experiment=paper", "evaluation.windows=[1,8]"], "config", None),
        # hybrid-sysid-eval composes eval.yaml
        (["run=outputs/runs/a", "noise.eval_std=0.0,0.01"], "eval", "hybrid-sysid-eval -m run=outputs/runs/a "),
    ],
)
def test_the_command_is_the_command_line_hydra_recorded(tmp_path, task, config_name, expected):
    sweep = make_sweep(tmp_path / "s", failed=False)
    sweep_file(sweep, task, config_name=config_name)
    (command, _), *rest = first(page(tmp_path, sweep)).commands
    assert rest == []
    assert command.startswith(expected or "hybrid-sysid experiment=paper")
    # a shell reads back the overrides as Hydra recorded them, brackets included
    assert [a for a in shlex.split(command)[1:] if a != "-m"] == task


def test_a_single_run_is_named_by_its_own_overrides(tmp_path):
    run = make_run(tmp_path / "runs" / "one", ["objective=hybrid", "trainer.max_steps=50"], seed=0)
    stamp(run, COMMIT_A)
    assert first(page(tmp_path, run)).commands == (("hybrid-sysid objective=hybrid trainer.max_steps=50", ""),)


def test_a_section_without_provenance_is_found(tmp_path):
    text = page(tmp_path, fake_sweep(tmp_path / "s", ["experiment=best"]), "notes=" + str(notes(tmp_path)))
    assert sections_without_provenance(text) == []
    # the notes' own sections are hand-written: only the generated ones are checked
    assert [h for h, _ in generated_sections(text)] == ["s"]
    stripped = re.sub(r"^- (command|commit|CPU).*\n", "", text, flags=re.M)
    assert sections_without_provenance(stripped) == ["s: no provenance block under the heading"]


def notes(tmp_path: Path) -> Path:
    path = tmp_path / "notes.md"
    path.write_text("## A reading\n\nHand-written, with a table of its own:\n\n| a |\n| --- |\n| 1 |\n")
    return path


def test_every_generated_section_of_the_results_pages_names_its_commit_and_command():
    """docs/results/ as committed: a table whose section does not name the command, or whose runs' commit is not
    recorded, fails here (regenerate the pages: docs/make_results.sh); the index lists every page."""
    pages = sorted(p for p in (REPO / "docs" / "results").glob("*.md") if p.name != "index.md")
    index = (REPO / "docs" / "results" / "index.md").read_text(encoding="utf-8")
    assert pages and all(f"]({p.name})" in index for p in pages)
    for page in pages:
        text = page.read_text(encoding="utf-8")
        assert len(generated_sections(text)) == 1, f"{page.name} holds no or several generated sections"
        missing = sections_without_provenance(text)
        assert missing == [], f"regenerate docs/results/ (docs/make_results.sh): {page.name}\n" + "\n".join(missing)


def test_a_runs_record_holds_its_checkouts_commit_and_its_cpu(tiny_run):
    record = json.loads((tiny_run / "metrics.json").read_text())
    git = subprocess.run(["git", "rev-parse", "--is-inside-work-tree"], cwd=REPO, capture_output=True, text=True)
    if git.returncode != 0:
        assert record["git_commit"] is None
    else:
        assert re.fullmatch(r"[0-9a-f]{40}", record["git_commit"])
        # the checkout's history holds it (HEAD itself may have moved on since the run)
        ancestor = ["git", "merge-base", "--is-ancestor", record["git_commit"], "HEAD"]
        assert subprocess.run(ancestor, cwd=REPO, capture_output=True).returncode == 0
        assert isinstance(record["git_dirty"], bool)
    cpuinfo = Path("/proc/cpuinfo")
    if not cpuinfo.exists():
        pytest.skip("no /proc/cpuinfo to compare the CPU's name with")
    names = {" ".join(m.split()) for m in re.findall(r"^model name\s*:\s*(.+)$", cpuinfo.read_text(), flags=re.M)}
    assert record["cpu"] in names
