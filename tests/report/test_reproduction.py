"""reproduction.md and the results page, from fake run records with known numbers: rows, placement of the
paper's figures and ours (checked by hand here), protocol, CLI flags, the callback and paper.yaml."""

from pathlib import Path

import numpy as np
import pytest
from omegaconf import OmegaConf

from hybrid_sysid.cli.report import main
from hybrid_sysid.report.paper import constant_guess, reproduction_markdown, write_reproduction
from hybrid_sysid.report.provenance import generated_sections

from helpers.evaluation_fakes import known_results, make_run, make_sweep, parse_markdown, plain

CONFIG = {
    "data": {
        "n_roads": 100,
        "n_masses": 100,
        "n_steps": 6000,
        "dt": 0.001,
        "speed": 15.0,
        "window": 500,
        "measurement": "consistent",
        "train_fraction": 0.8,
        "val_fraction": 0.125,
        "m3_min": 50,
        "m3_max": 200,
    },
    "noise": {"eval_std": [0.0, 0.003, 0.01], "train_std": 0.0},
    "model": {
        "net": {"_target_": "hybrid_sysid.model.networks.PaperCNN"},
        "batch_size": 100,
        "optim": {"name": "adam", "lr": 0.001, "schedule": "constant"},
    },
    "trainer": {"max_steps": 2000},
}
SEEDS = [0, 1, 2]


def _value(objective, split, noise, p, seed):
    """A distinct known number per cell and seed."""
    base = {"labelled": 0.05, "hybrid": 0.08, "combined": 0.06}[objective]
    return base + {"train": 0.0, "val": 0.001, "test": 0.002}[split] + 3 * noise + (p == "p2") * 0.01 + 0.004 * seed


def _sigma(objective, seed):
    return 0.1 + 0.01 * seed + (objective == "hybrid") * 0.02


def _make(sweep: Path, objectives=("labelled", "hybrid"), seeds=SEEDS, value=_value) -> Path:
    job = 0
    for objective in objectives:
        for seed in seeds:
            cells = {
                (s, n, p): value(objective, s, n, p, seed)
                for s, n in [("train", 0.0), ("val", 0.0), ("test", 0.0), ("test", 0.003), ("test", 0.01)]
                for p in ("p1", "p2")
            }
            make_run(
                sweep / str(job),
                [f"objective={objective}", f"seed={seed}", "experiment=paper"],
                seed,
                results=known_results(cells, n=2000, std_rel_dev=_sigma(objective, seed)),
                config=CONFIG,
                steps=2000,
            )
            job += 1
    return sweep


def _table(text: str) -> list[dict]:
    return parse_markdown(text[text.index("## Mean relative deviation") :])


def test_rows_and_placement_of_paper_and_our_figures(tmp_path):
    sweep = _make(tmp_path / "sw", objectives=("labelled", "hybrid", "combined"))
    rows = _table(reproduction_markdown(sweep))
    # the paper's splits and noise levels only (no 0.003, no val, no noisy training row); paper objectives first
    assert [(r["split"], r["noise std"], r["objective"]) for r in rows] == [
        (s, n, o)
        for s, n in [("train", "0"), ("test", "0"), ("test", "0.01")]
        for o in ("labelled", "hybrid", "combined")
    ]
    for r in rows:
        noise = float(r["noise std"])
        for p in ("p1", "p2"):
            v = np.array([_value(r["objective"], r["split"], noise, p, s) for s in SEEDS])
            assert r[f"{p} ours"] == f"{100 * v.mean():.2f} ± {100 * v.std(ddof=1):.2f}"
            sigma = np.mean([_sigma(r["objective"], s) for s in SEEDS])
            assert r[f"{p} σ ours"] == f"{100 * sigma:.2f}"
        assert r["seeds"] == "3"
    by = {(r["split"], r["noise std"], r["objective"]): r for r in rows}
    # the paper's numbers, placed by hand from the text (sec. 3.1-3.3)
    assert (by[("train", "0", "labelled")]["p1 paper"], by[("train", "0", "labelled")]["p1 σ paper"]) == ("6.2", "9.1")
    assert (by[("train", "0", "labelled")]["p2 paper"], by[("train", "0", "labelled")]["p2 σ paper"]) == ("4.3", "8.3")
    assert (by[("test", "0", "labelled")]["p1 paper"], by[("test", "0", "labelled")]["p2 paper"]) == ("6.0", "4.2")
    test_labelled = by[("test", "0", "labelled")]
    assert (test_labelled["p1 σ paper"], test_labelled["p2 σ paper"]) == ("7.9", "8.4")
    assert (by[("train", "0", "hybrid")]["p1 paper"], by[("train", "0", "hybrid")]["p2 σ paper"]) == ("10.2", "13.1")
    assert (by[("test", "0", "hybrid")]["p1 paper"], by[("test", "0", "hybrid")]["p2 paper"]) == ("9.7", "7.6")
    assert by[("test", "0", "hybrid")]["p1 σ paper"] == by[("test", "0", "hybrid")]["p2 σ paper"] == "12.7"
    assert by[("test", "0.01", "labelled")]["p1 paper"] == by[("test", "0.01", "labelled")]["p2 paper"] == "26-28"
    assert by[("test", "0.01", "hybrid")]["p1 paper"] == by[("test", "0.01", "hybrid")]["p2 paper"] == "≈16"
    for o in ("labelled", "hybrid"):
        assert by[("test", "0.01", o)]["p1 σ paper"] == "not reported"
    assert all(by[(s, n, "combined")][c] == "not reported" for s, n, _ in by for c in ("p1 paper", "p2 σ paper"))


def test_protocol_header_reads_the_run_configs(tmp_path):
    text = reproduction_markdown(_make(tmp_path / "sw"))
    header = {r[""]: (r["paper"], r["ours"]) for r in parse_markdown(text[text.index("## Protocol") :])}
    assert header["steps"] == ("500,000 (sec. 3.1-3.3, figure captions)", "2000")
    assert header["dt"][1] == "1 ms" and header["dt"][0].startswith("not stated")
    assert header["data"][1].startswith("100 roads x 100 masses x 6000 steps")
    assert header["seeds"][1] == "0-2" and header["measurement"][1] == "consistent"
    assert header["optimiser"][1] == "adam, lr 0.001, constant schedule, batch 100"
    assert header["model"][1] == "paper_cnn (PaperCNN)" and header["test recordings"][1] == "2000"
    assert header["windows per test recording"][1] == "1"
    assert header["seat masses"][1] == "m3 uniform on the integers 50-200 kg"


def test_constant_guess_against_a_brute_force_search_and_no_generated_reading(tmp_path):
    m = np.arange(50, 201, dtype=float)
    grid = np.linspace(1 / 200, 1 / 50, 30001)
    brute = min(np.abs(1 - k * m).mean() for k in grid)
    assert constant_guess() == pytest.approx(brute, abs=1e-6) and constant_guess() <= brute
    text = reproduction_markdown(_make(tmp_path / "sw"))
    assert f"scores {100 * brute:.1f}% on either parameter" in text  # a reference figure for the reader
    # the numbers side by side, no verdict drawn from them: the reading is written by hand
    assert [ln for ln in text.splitlines() if ln.startswith("## ")] == ["## Protocol", "## Mean relative deviation [%]"]


def test_failed_jobs_only_still_give_a_page(tmp_path):
    make_run(tmp_path / "sw" / "0", ["objective=labelled", "seed=0"], 0, status="failed", error="boom")
    text = write_reproduction(tmp_path / "sw")
    rows = _table(text)
    assert (tmp_path / "sw" / "reproduction.md").read_text() == text
    assert all(r["p1 ours"] == "not run" for r in rows) and len(rows) == 6  # the paper's 12 figures, 6 rows


def test_cli_reproduction_flag_writes_and_prints(tmp_path, capsys):
    sweep = _make(tmp_path / "sw")
    assert main([str(sweep), "reproduction=true"]) == 0
    out = capsys.readouterr().out
    assert (sweep / "reproduction.md").read_text() in out and (sweep / "summary.md").is_file()


def test_cli_results_page_one_section_per_sweep_with_figures(tmp_path, capsys):
    paper = _make(tmp_path / "paper_sweep")
    robust = make_sweep(tmp_path / "robust", extra=("experiment=robustness",))  # with a failed and a corrupt job
    page = tmp_path / "docs" / "results.md"
    assert main([str(robust), str(paper), f"results={page}"]) == 1  # a job failed
    text = page.read_text()
    assert capsys.readouterr().out == text
    assert not (robust / "summary.csv").exists() and not (paper / "summary.csv").exists()  # no out=
    assert text.index("## experiment=robustness") < text.index("## experiment=paper")
    assert f"results={page}" in text and "hybrid-sysid-report" in text  # the command that regenerates it
    for name in ("robust", "paper_sweep"):
        assert f"](figures/{name}.png)" in text
        assert (page.parent / "figures" / f"{name}.png").read_bytes()[:4] == b"\x89PNG"
    assert "Failed jobs:" in text and "RuntimeError: loss is nan" in text
    section = text[text.index("## experiment=paper") :]
    rows = parse_markdown(section)
    assert [r["objective"] for r in rows] == ["hybrid", "labelled"] and rows[0]["seeds"] == "3"
    mean = np.mean([_value("labelled", "test", 0.0, "p1", s) for s in SEEDS])
    assert plain(rows[1]["noise 0 p1 [%]"]).startswith(f"{100 * mean:.2f} ± ")
    assert "steps 2000" in section and "The paper's figures beside ours" not in text
    # reproduction=true adds the comparison per section; out= also writes the summary
    assert main([str(paper), f"results={page}", "reproduction=true", f"out={tmp_path / 'o'}"]) == 0
    text = page.read_text()
    assert "### The paper's figures beside ours" in text and "26-28" in text
    assert (tmp_path / "o" / "summary.md").is_file() and (tmp_path / "o" / "reproduction.md").is_file()


def test_cli_results_page_places_the_notes_after_the_header(tmp_path, capsys):
    paper = _make(tmp_path / "paper_sweep")
    notes = tmp_path / "reading.md"
    notes.write_text("## Reading\n\nHybrid is not more robust here.\n")
    page = tmp_path / "docs" / "results.md"
    assert main([str(paper), f"results={page}", f"notes={notes}"]) == 0
    text = page.read_text()
    assert text.index("Generated from the run records") < text.index("## Reading") < text.index("## experiment=paper")
    assert f"notes={notes}" in text  # the regeneration command keeps the notes
    missing = tmp_path / "none.md"
    page.unlink()
    capsys.readouterr()
    assert main([str(paper), f"results={page}", f"notes={missing}"]) == 2
    assert f"notes = {missing} is not allowed: a markdown file that exists" in capsys.readouterr().err
    assert not page.exists()  # nothing written


def test_cli_results_directory_has_an_index_a_page_per_sweep_and_links_the_notes(tmp_path, capsys):
    """results=DIR: DIR/index.md lists a page per section, links the hand-written reading instead of copying it,
    and each page holds its section as the one-page form does, figures beside the pages."""
    paper = _make(tmp_path / "paper_sweep")
    robust = make_sweep(tmp_path / "robust", extra=("experiment=robustness",))
    notes = tmp_path / "docs" / "reading.md"
    notes.parent.mkdir()
    notes.write_text("## Reading\n\nHybrid is not more robust here.\n")
    out = tmp_path / "docs" / "results"
    assert main([str(robust), str(paper), f"results={out}", f"notes={notes}"]) == 1  # a job failed
    index = (out / "index.md").read_text()
    assert capsys.readouterr().out == index
    assert "](../reading.md)" in index and "Hybrid is not more robust" not in index
    assert (
        "- [experiment=robustness (robust)](robust.md): " in index
        and "- [experiment=paper (paper_sweep)](paper_sweep.md)" in index
    )
    single = tmp_path / "one" / "results.md"
    assert main([str(robust), str(paper), f"results={single}"]) == 1
    one = single.read_text()
    for name in ("robust", "paper_sweep"):
        page = (out / f"{name}.md").read_text()
        [(heading, body)] = generated_sections(page)
        assert f"## {heading}\n{body}" in one  # the same section as on the one page
        assert (out / "figures" / f"{name}.png").read_bytes()[:4] == b"\x89PNG" and f"](figures/{name}.png)" in page


def test_callback_writes_reproduction_when_asked(tmp_path, capsys):
    from hybrid_sysid.launch.sweep import SweepSummary

    sweep = _make(tmp_path / "sw")
    config = OmegaConf.create({"hydra": {"sweep": {"dir": str(sweep)}}})
    SweepSummary().on_multirun_end(config)
    assert not (sweep / "reproduction.md").exists()
    SweepSummary(reproduction=True).on_multirun_end(config)
    assert (sweep / "reproduction.md").read_text() in capsys.readouterr().out


def test_paper_experiment_asks_for_the_reproduction_within_a_cpu_budget():
    from hydra import compose, initialize_config_dir

    from hybrid_sysid.config import CONF_DIR

    with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
        cfg = compose(config_name="config", overrides=["experiment=paper"], return_hydra_config=True)
    assert cfg.hydra.callbacks.sweep_summary.reproduction is True
    assert cfg.model.optim.name == "adam" and cfg.model.optim.lr == 1e-3 and cfg.model.batch_size == 100
    assert cfg.data.n_roads == 100 and list(cfg.noise.eval_std) == [0.0, 0.01]
    t = cfg.trainer
    # ~195 ms per paper_cnn step at batch 100 on 2 cores (benchmarks/README.md, "Time to the paper's labelled figures")
    assert t.max_steps * 0.195 <= 450
    assert t.max_steps // t.eval_every_n_steps <= 10 and t.max_steps % t.eval_every_n_steps == 0


def test_objective_of_a_run_without_override_comes_from_hydra_choices(tmp_path):
    cells = {("test", 0.0, p): 0.3 for p in ("p1", "p2")}
    make_run(tmp_path / "run", ["seed=4"], 4, results=known_results(cells), config=CONFIG)  # choice: labelled
    rows = {(r["split"], r["noise std"], r["objective"]): r for r in _table(reproduction_markdown(tmp_path / "run"))}
    assert rows[("test", "0", "labelled")]["p1 ours"] == "30.00" and rows[("test", "0", "labelled")]["seeds"] == "1"
    assert rows[("test", "0", "hybrid")]["p1 ours"] == "not run"


def test_several_k_become_a_column_and_train_keeps_its_single_k(tmp_path):
    for seed in range(2):
        cells = {("train", 0.0, 1, p): 0.1 for p in ("p1", "p2")}
        cells.update(
            {
                ("test", n, k, p): 0.2 + k / 100 + seed / 100
                for n in (0.0, 0.01)
                for k in (16, 1, 4)
                for p in ("p1", "p2")
            }
        )
        make_run(
            tmp_path / "sw" / str(seed),
            ["objective=hybrid", f"seed={seed}"],
            seed,
            results=known_results(cells),
            config=CONFIG,
        )
    rows = _table(reproduction_markdown(tmp_path / "sw"))
    hybrid = [(r["split"], r["noise std"], r["K"], r["p1 ours"]) for r in rows if r["objective"] == "hybrid"]
    assert hybrid == [("train", "0", "1", "10.00 ± 0.00")] + [
        ("test", n, k, v)
        for n in ("0", "0.01")
        for k, v in (("1", "21.50 ± 0.71"), ("4", "24.50 ± 0.71"), ("16", "36.50 ± 0.71"))
    ]  # K in numeric order
    # the paper's labelled figures, not run here: one row each, not one per K
    labelled = [
        (r["split"], r["noise std"], r["K"], r["p1 paper"], r["p1 ours"], r["seeds"])
        for r in rows
        if r["objective"] == "labelled"
    ]
    assert labelled == [
        ("train", "0", "", "6.2", "not run", "0"),
        ("test", "0", "", "6.0", "not run", "0"),
        ("test", "0.01", "", "26-28", "not run", "0"),
    ]
