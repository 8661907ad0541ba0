"""The reliability pages (docs/reliability/) name the test that holds each promise: every test they name exists.

A reference is ``tests/<path>.py`` (the file must exist) or ``tests/<path>.py::<name>`` (a function or class of
that name must also be defined in it; a parametrized case ``name[id]`` counts by its base name)."""

import ast
import re
from functools import cache
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PAGES = ROOT / "docs" / "reliability"
# tests/<path>.py, then any ::name, each with an optional [parametrize id] (ids may hold spaces and slashes)
REFERENCE = re.compile(r"(tests/(?:[\w-]+/)*[\w-]+\.py)((?:::\w+(?:\[[^\]`]*\])?)*)")


def references(text: str) -> list[tuple[str, list[str]]]:
    """(path, [names]) of every test reference in ``text``; names without their parametrize ids."""
    return [(path, re.findall(r"::(\w+)", names)) for path, names in REFERENCE.findall(text)]


@cache
def defined_names(path: Path) -> frozenset[str]:
    """Every function and class defined in a Python file, at any depth."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    kinds = (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)
    return frozenset(node.name for node in ast.walk(tree) if isinstance(node, kinds))


def missing_references(text: str, root: Path = ROOT) -> list[str]:
    """The references in ``text`` whose file does not exist under ``root``, or whose name is not defined there."""
    missing = []
    for path, names in references(text):
        file = root / path
        if not file.is_file():
            missing.append(path)
            continue
        missing += [f"{path}::{name}" for name in names if name not in defined_names(file)]
    return missing


def test_every_test_the_reliability_pages_name_exists():
    pages = sorted(PAGES.glob("*.md"))
    assert pages, f"no pages in {PAGES}"
    found, missing = 0, []
    for page in pages:
        text = page.read_text(encoding="utf-8")
        found += len(references(text))
        missing += [f"{page.relative_to(ROOT)}: {ref}" for ref in missing_references(text)]
    assert found, "the pages name no tests"
    assert missing == [], "tests named by the pages that do not exist:\n" + "\n".join(missing)


def test_the_check_finds_a_made_up_reference():
    text = (
        "`tests/test_docs.py::test_every_test_the_reliability_pages_name_exists`, "
        "`tests/test_docs.py::defined_names[a case/with spaces]` (slow), "
        "`tests/test_docs.py::test_no_such_test`, `tests/no_such_folder/test_nothing.py::test_x`, "
        "`tests/test_no_such_file.py`"
    )
    assert len(references(text)) == 5
    assert missing_references(text) == [
        "tests/test_docs.py::test_no_such_test",
        "tests/no_such_folder/test_nothing.py",
        "tests/test_no_such_file.py",
    ]
    assert missing_references("`tests/test_docs.py`") == []
