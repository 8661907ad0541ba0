"""The package's folders are its layers and import one way (docs/design.md, "Architecture"); no two modules import
each other, directly or round a loop; no private name crosses modules, and no module reads another object's
private attribute or a network's buffers (what a network provides is declared: model/base.py)."""

import ast
import sys
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src" / "hybrid_sysid"
# bottom up; a module may import its own layer and those below it. A __main__ module is an entry point wherever
# it sits (``python -m hybrid_sysid.report``), so it counts as cli.
LAYERS = [
    {"core"},
    {"physics"},
    {"data"},
    {"model", "baselines"},
    {"config"},
    {"runs"},
    {"training"},
    {"report"},
    {"experiments", "inference"},
    {"launch"},
    {"cli", "__main__", "__init__"},
]


def layer_of(module: str) -> int:
    """hybrid_sysid.<folder>... -> the index of <folder>'s layer."""
    parts = module.split(".")
    part = "__main__" if parts[-1] == "__main__" else (parts[1] if len(parts) > 1 else "__init__")
    return next(i for i, names in enumerate(LAYERS) if part in names)


def modules():
    for path in sorted(SRC.rglob("*.py")):
        rel = path.relative_to(SRC.parent).with_suffix("")
        name = ".".join(rel.parts[:-1] if rel.parts[-1] == "__init__" and len(rel.parts) > 2 else rel.parts)
        yield name, ast.parse(path.read_text())


def project_imports(tree):
    """(imported module, names) for every import of hybrid_sysid, at any depth (lazy imports count too)."""
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("hybrid_sysid"):
            yield node.module, [a.name for a in node.names]
        elif isinstance(node, ast.Import):
            for a in node.names:
                if a.name.startswith("hybrid_sysid"):
                    yield a.name, []


def targets(module: str, names: list[str], known: set[str]) -> list[str]:
    """The modules an import reaches: "from hybrid_sysid.report import summary" reaches the submodule."""
    subs = [f"{module}.{n}" for n in names if f"{module}.{n}" in known]
    return subs or [module]


def test_every_module_is_in_a_layer():
    for name, _ in modules():
        layer_of(name)  # raises StopIteration for a module no layer names


def test_the_top_level_holds_only_the_package_files():
    """Every module lives in the folder of its layer: no module beside __init__ and __main__ at the top."""
    assert sorted(p.name for p in SRC.glob("*.py")) == ["__init__.py", "__main__.py"]


@pytest.mark.parametrize("name, tree", list(modules()), ids=lambda x: x if isinstance(x, str) else "")
def test_imports_go_down_only_and_take_no_private_names(name, tree):
    for module, names in project_imports(tree):
        target = module
        if module == "hybrid_sysid" and names:  # "from hybrid_sysid import config"
            target = f"hybrid_sysid.{names[0]}"
        assert layer_of(target) <= layer_of(name), f"{name} imports {module} from a higher layer"
        private = [n for n in names if n.startswith("_")]
        assert not private, f"{name} imports the private name(s) {private} from {module}"


def private_attributes(tree) -> list[str]:
    """``obj._name`` where obj is not the object itself (self, cls): another object's internals, a library's
    included. Dunder names (``__class__``) are public, and so are a config's ``_target_`` (a key of the data)
    and ``os._exit`` (documented)."""
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and node.attr.startswith("_") and not node.attr.startswith("__"):
            owner = ast.unparse(node.value)
            if owner not in ("self", "cls") and node.attr != "_target_" and f"{owner}.{node.attr}" != "os._exit":
                found.append(f"{ast.unparse(node)} (line {node.lineno})")
    return found


def buffer_reads(tree) -> list[str]:
    """Calls that reach into a module's registered buffers by name (a network's head, say)."""
    return [
        f"{ast.unparse(node)} (line {node.lineno})"
        for node in ast.walk(tree)
        if isinstance(node, ast.Call)
        and isinstance(node.func, ast.Attribute)
        and node.func.attr in ("named_buffers", "get_buffer", "buffers")
    ]


@pytest.mark.parametrize("name, tree", list(modules()), ids=lambda x: x if isinstance(x, str) else "")
def test_no_private_attribute_of_another_object(name, tree):
    assert not private_attributes(tree), f"{name} reads private attributes: {private_attributes(tree)}"
    if layer_of(name) != layer_of("hybrid_sysid.model"):
        assert not buffer_reads(tree), f"{name} reads a network's buffers: {buffer_reads(tree)}"


def test_the_private_attribute_check_finds_one():
    """The checks above are not vacuous: a network's buffers and a logger's private client are found."""
    tree = ast.parse("bounds = dict(net.named_buffers())\nclient = logger._mlflow_client\nself._own = 1")
    assert private_attributes(tree) == ["logger._mlflow_client (line 2)"]
    assert buffer_reads(tree) == ["net.named_buffers() (line 1)"]


def test_no_import_cycle():
    """Within a layer too: the graph of module imports (lazy ones included, a package counted through its
    __init__) has no cycle."""
    found = dict(modules())
    known = set(found)
    graph = {
        name: {t for m, ns in project_imports(tree) for t in targets(m, ns, known) if t in known and t != name}
        for name, tree in found.items()
    }
    state: dict[str, int] = {}  # 1: on the current path, 2: done

    def visit(node, path):
        state[node] = 1
        for nxt in sorted(graph[node]):
            if state.get(nxt) == 1:
                cycle = path[path.index(nxt) :] + [nxt]
                pytest.fail("import cycle: " + " -> ".join(cycle))
            if nxt not in state:
                visit(nxt, path + [nxt])
        state[node] = 2

    for name in sorted(graph):
        if name not in state:
            visit(name, [name])


def test_the_cycle_check_finds_a_cycle(monkeypatch):
    """The check above is not vacuous: two modules that import each other fail it."""
    trees = {
        "hybrid_sysid.cli.a": ast.parse("from hybrid_sysid.cli.b import x"),
        "hybrid_sysid.cli.b": ast.parse("from hybrid_sysid.cli import a"),
    }
    monkeypatch.setattr(sys.modules[__name__], "modules", lambda: iter(trees.items()))
    with pytest.raises(pytest.fail.Exception, match="import cycle"):
        test_no_import_cycle()
