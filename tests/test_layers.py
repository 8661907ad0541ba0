"""The package's layers import one way (docs/design.md, "Architecture"), and no private name crosses modules."""

import ast
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src" / "hybrid_sysid"
# bottom up; a module may import its own layer and those below it
LAYERS = [
    {"files"},
    {"physics"},
    {"data"},
    {"model", "baselines"},
    {"config", "train", "records", "callbacks", "tracking"},
    {"report"},
    {"app", "estimator", "predict", "evaluate", "transfer", "tuned", "chain", "__main__", "__init__"},
]


def layer_of(module: str) -> int:
    """hybrid_sysid.<part>... -> the index of <part>'s layer."""
    part = module.split(".")[1] if "." in module else "__init__"
    return next(i for i, names in enumerate(LAYERS) if part in names)


def modules():
    for path in sorted(SRC.rglob("*.py")):
        rel = path.relative_to(SRC.parent).with_suffix("")
        yield ".".join(rel.parts), ast.parse(path.read_text())


def project_imports(tree):
    """(imported module, names) for every import of hybrid_sysid, at any depth (lazy imports count too)."""
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("hybrid_sysid"):
            yield node.module, [a.name for a in node.names]
        elif isinstance(node, ast.Import):
            for a in node.names:
                if a.name.startswith("hybrid_sysid"):
                    yield a.name, []


def test_every_module_is_in_a_layer():
    for name, _ in modules():
        layer_of(name)  # raises StopIteration for a module no layer names


@pytest.mark.parametrize("name, tree", list(modules()), ids=lambda x: x if isinstance(x, str) else "")
def test_imports_go_down_only_and_take_no_private_names(name, tree):
    for module, names in project_imports(tree):
        target = module
        if module == "hybrid_sysid" and names:  # "from hybrid_sysid import config"
            target = f"hybrid_sysid.{names[0]}"
        assert layer_of(target) <= layer_of(name), f"{name} imports {module} from a higher layer"
        private = [n for n in names if n.startswith("_")]
        assert not private, f"{name} imports the private name(s) {private} from {module}"
