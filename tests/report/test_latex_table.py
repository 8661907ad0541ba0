"""The LaTeX table: the noise levels in blocks, each headed by a \\multicolumn per level over its parameters, every
row as wide as the tabular's column spec, the same numbers as the markdown table, and (where a TeX engine is on
PATH) that it compiles and is no wider than the text of a plain article."""

import math
import re
import shutil
import subprocess

import numpy as np
import pytest

from hybrid_sysid.report.collect import load_runs
from hybrid_sysid.report.latex import to_latex
from hybrid_sysid.report.markdown import to_markdown
from hybrid_sysid.report.tables import summary_table

from helpers.evaluation_fakes import interval, known_results, make_run, parse_markdown, plain

LEVELS = [0.0, 0.003, 0.01, 0.03, 0.1]  # the main job's ladder
PARAMS = ["p1", "p2"]
KS = [1, 8]
ENGINES = ("pdflatex", "xelatex", "lualatex", "latex", "tectonic")


def make_table(root, objectives=("labelled", "hybrid", "combined"), train_std=None):
    """objective (x noise.train_std) x K rows, 3 seeds, every level and parameter; errors up to 60%, so some
    cells have two digits before the point."""
    rng, job = np.random.default_rng(5), 0
    for objective in objectives:
        for std in train_std or [None]:
            for seed in range(3):
                values = {
                    ("test", n, k, p): rng.uniform(0.01, 0.1) * (1 + 50 * n) / (1 + (k > 1))
                    for n in LEVELS
                    for k in KS
                    for p in PARAMS
                }
                overrides = [f"objective={objective}", f"seed={seed}"] + ([f"noise.train_std={std}"] if std else [])
                make_run(root / str(job), overrides, seed, results=known_results(values))
                job += 1
    _, df = load_runs(root)
    return summary_table(df)


def tabular(tex: str) -> tuple[str, list[str]]:
    """The column spec and the rows (lines ending in \\\\) of the tabular in tex."""
    spec = re.search(r"\\begin\{tabular\}\{([lcr]+)\}", tex).group(1)
    body = tex[tex.index(r"\begin{tabular}") : tex.index(r"\end{tabular}")]
    return spec, [ln for ln in body.splitlines() if ln.endswith(r"\\")]


def width(row: str) -> int:
    """Columns a row spans: one per cell, n for a \\multicolumn{n}."""
    cells = row.removesuffix(r"\\").split(" & ")
    return sum(int(m.group(1)) if (m := re.match(r"\s*\\multicolumn\{(\d+)\}", c)) else 1 for c in cells)


def blocks(tex: str) -> list[dict]:
    """Per block of the tabular: its noise levels (from the \\multicolumn headers), its \\cmidrule ranges, its
    header row and its body rows (cells split)."""
    lines = tex[tex.index(r"\toprule") : tex.index(r"\bottomrule")].splitlines()
    out = []
    for i, ln in enumerate(lines):
        if r"\multicolumn" in ln:
            levels = [float(v) for v in re.findall(r"\\multicolumn\{\d+\}\{c\}\{noise ([\d.]+)\}", ln)]
            ranges = [tuple(map(int, r)) for r in re.findall(r"\\cmidrule\(lr\)\{(\d+)-(\d+)\}", lines[i + 1])]
            rows, j = [], i + 4  # header, cmidrules, names, midrule
            while j < len(lines) and lines[j] != r"\midrule":
                rows.append(lines[j].removesuffix(r" \\").split(" & "))
                j += 1
            out.append({"levels": levels, "ranges": ranges, "names": lines[i + 2], "rows": rows, "head": ln})
    return out


def test_noise_levels_are_grouped_under_multicolumn_headers_with_the_markdown_numbers(tmp_path):
    table = make_table(tmp_path / "sweep")
    tex = to_latex(table, caption="mean relative deviation on the test split [%]")
    spec, rows = tabular(tex)
    nl, per = 2, (len(spec) - 2) // len(PARAMS)
    assert spec == "ll" + "r" * per * len(PARAMS) and per >= 2  # the main job's shape: levels side by side
    assert all(width(r) == len(spec) for r in rows)  # every row as wide as the spec, headers included
    found = blocks(tex)
    assert len(found) == math.ceil(len(LEVELS) / per)  # stacked blocks of `per` levels
    assert [n for b in found for n in b["levels"]] == LEVELS  # each level headed once, in order
    for b in found:
        assert b["head"].count(r"\multicolumn{2}{c}{") == per  # the last block padded with empty groups
        # a rule under each level's header spans exactly its parameters' columns
        assert b["ranges"] == [(nl + 1 + 2 * i, nl + 2 + 2 * i) for i in range(len(b["levels"]))]
        names = b["names"].removesuffix(r" \\").split(" & ")
        assert names[:nl] == ["objective", "K"] and names[nl : nl + 2 * len(b["levels"])] == PARAMS * len(b["levels"])
    # the same numbers as the markdown table, cell by cell: "m ± s" on a row's line, its interval below
    md = {(r["objective"], r["K"]): r for r in parse_markdown(to_markdown(table))}
    for b in found:
        for top, below in zip(b["rows"][0::2], b["rows"][1::2]):
            assert below[:nl] == ["", ""]
            row = md[(top[0], top[1])]
            for i, n in enumerate(b["levels"]):
                for j, p in enumerate(PARAMS):
                    cell, ci = top[nl + 2 * i + j], below[nl + 2 * i + j]
                    mean, std = plain(row[f"noise {n:g} {p} [%]"]).split(" ± ")
                    assert re.sub(r"\\mathbf\{(.*)\}", r"\1", cell.removesuffix("^{\\dagger}$").strip("$")) == (
                        rf"{mean} \pm {std}"
                    )
                    assert ("dagger" in cell) == row[f"noise {n:g} {p} [%]"].endswith("†")
                    assert ("mathbf" in cell) == row[f"noise {n:g} {p} [%]"].startswith("**")
                    low, high = interval(row[f"noise {n:g} {p} [%]"])
                    assert ci == rf"{{\scriptsize $[{low:.2f}, {high:.2f}]$}}"
    assert "Completed seeds per row: 3; failed or unreadable jobs per row: 0." in tex  # the counts, once


def test_wide_row_labels_put_fewer_levels_side_by_side_and_a_choice_is_kept(tmp_path):
    wide = make_table(
        tmp_path / "sweep", objectives=("labelled_bandpass", "hybrid_bandpass"), train_std=["0.0", "0.01"]
    )
    spec, rows = tabular(to_latex(wide))
    assert spec == "lll" + "rr"  # one level per block
    assert all(width(r) == len(spec) for r in rows)
    assert len(blocks(to_latex(wide))) == len(LEVELS)
    narrow = make_table(tmp_path / "narrow")
    spec, rows = tabular(to_latex(narrow, levels_per_block=3))
    assert spec == "ll" + "r" * 6 and all(width(r) == len(spec) for r in rows)
    assert [len(b["levels"]) for b in blocks(to_latex(narrow, levels_per_block=3))] == [3, 2]


def engine() -> str | None:
    return next((e for e in ENGINES if shutil.which(e)), None)


def compile_tex(tmp_path, body: str) -> tuple[subprocess.CompletedProcess, str]:
    """body in a minimal article (booktabs), compiled in tmp_path; (the process, the log)."""
    doc = "\n".join(
        [
            r"\documentclass{article}",
            r"\usepackage[T1]{fontenc}",
            r"\usepackage[utf8]{inputenc}",
            r"\usepackage{booktabs}",
            r"\newsavebox\measured",
            r"\begin{document}",
            body,
            r"\end{document}",
            "",
        ]
    )
    (tmp_path / "doc.tex").write_text(doc, encoding="utf-8")
    name = engine()
    command = [name, "--keep-logs", "doc.tex"] if name == "tectonic" else [name, "-interaction=nonstopmode", "doc.tex"]
    done = subprocess.run(command, cwd=tmp_path, capture_output=True, text=True, timeout=120)
    log = tmp_path / "doc.log"
    return done, log.read_text(errors="replace") if log.exists() else ""


@pytest.mark.skipif(
    engine() is None,
    reason=f"no TeX engine on PATH ({', '.join(ENGINES)}); on Debian: "
    "apt-get install texlive-latex-base texlive-latex-recommended",
)
@pytest.mark.parametrize("shape", ["main job", "wide labels"])
def test_the_latex_table_compiles_and_is_no_wider_than_the_text(tmp_path, shape):
    if (
        shutil.which("kpsewhich")
        and not subprocess.run(["kpsewhich", "booktabs.sty"], capture_output=True, text=True).stdout.strip()
    ):
        pytest.skip("booktabs.sty is not installed (Debian: texlive-latex-recommended)")
    if shape == "main job":
        table = make_table(tmp_path / "sweep")
    else:
        table = make_table(
            tmp_path / "sweep", objectives=("labelled_bandpass", "hybrid_bandpass"), train_std=["0.0", "0.01"]
        )
    # as summary.tex has it, a float with its caption and notes; then the bare table, measured
    tex = to_latex(table, caption="mean relative deviation on the test split [%], mean ± std over seeds")
    bare = to_latex(table)
    bare = bare[: bare.index(r"\end{tabular}}") + len(r"\end{tabular}}")]
    done, log = compile_tex(
        tmp_path,
        tex
        + "\n"
        + rf"\sbox\measured{{{bare}}}"
        + "\n"
        + r"\typeout{TABLE WIDTH \the\wd\measured, TEXT WIDTH \the\textwidth}",
    )
    assert done.returncode == 0, done.stdout[-3000:]
    assert "Overfull \\hbox" not in log, re.findall(r"Overfull \\hbox.*", log)
    table_pt, text_pt = map(float, re.search(r"TABLE WIDTH ([\d.]+)pt, TEXT WIDTH ([\d.]+)pt", log).groups())
    assert 0 < table_pt <= text_pt
