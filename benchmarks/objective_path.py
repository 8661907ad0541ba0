"""The path of ``objective`` from the command line to the table: how many functions and files it passes through.

Runs ``hybrid-sysid objective=hybrid`` on the tiny data (a few training steps), then ``hybrid-sysid-report`` on
that run, in this process, with a profiler that notes the first call of every package function that receives
the objective: the config holding it (a DictConfig with an ``objective`` key, or the objective's own node), the
objective object (anything with ``uses_labels``), a list of overrides naming it, or a table with its column.

Printed: the stops (those first calls, in order), the files they lie in, the climbs (a stop on a higher floor than
the stop before it; the floors are the package's folders, its layers, each 1 + the highest floor of the folders
it imports) and the returns (a stop in a file the path had entered and left before). Fewer of each is a path that
reads straight down the layers. ``--list`` prints the stops.

    python benchmarks/objective_path.py [--list]
"""

from __future__ import annotations

import argparse
import ast
import os
import sys
import tempfile
from pathlib import Path

SRC = Path(__file__).resolve().parents[1] / "src" / "hybrid_sysid"


def folder_of(path: Path) -> str:
    """A file's room: its folder under the package (a layer: core, physics, data, ...), or the package's own
    files at the top (__init__, __main__)."""
    rel = path.relative_to(SRC)
    return rel.parts[0] if len(rel.parts) > 1 else rel.stem


def floors() -> dict[str, int]:
    """Each folder's floor: 1 for a folder that imports no other folder of the package, else 1 + the highest
    floor of the folders it imports (lazy imports inside functions count)."""
    imports: dict[str, set[str]] = {}
    for path in SRC.rglob("*.py"):
        room = folder_of(path)
        found = imports.setdefault(room, set())
        for node in ast.walk(ast.parse(path.read_text())):
            names = []
            if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("hybrid_sysid."):
                names = [node.module]
            elif isinstance(node, ast.Import):
                names = [a.name for a in node.names if a.name.startswith("hybrid_sysid.")]
            found.update(n.split(".")[1] for n in names)
        found.discard(room)
    memo: dict[str, int] = {}

    def floor(room: str, seen=()) -> int:
        if room not in memo:
            below = [floor(r, (*seen, room)) for r in imports.get(room, ()) if r in imports and r not in seen]
            memo[room] = 1 + max(below, default=0)
        return memo[room]

    return {room: floor(room) for room in imports}


def carries_objective(value) -> bool:
    """Whether an argument holds the objective (see the module docstring)."""
    try:
        from omegaconf import DictConfig

        if isinstance(value, DictConfig):
            if "objective" in value:
                return True
            target = value.get("_target_", None) if "_target_" in value else None
            return isinstance(target, str) and target.endswith("Objective")
        if hasattr(type(value), "uses_labels"):
            return True
        if isinstance(value, str):
            return value.startswith("objective=")
        if isinstance(value, (list, tuple)) and value and all(isinstance(v, str) for v in value):
            return any(v.startswith("objective=") for v in value)
        if isinstance(value, dict):
            return "objective" in value or carries_objective(value.get("overrides"))
        columns = getattr(value, "columns", None)
        names = getattr(getattr(value, "index", None), "names", None)
        return (columns is not None and "objective" in list(columns)) or (names is not None and "objective" in names)
    except Exception:  # noqa: BLE001 - an argument that cannot be inspected carries nothing we can see
        return False


def trace(work) -> list[tuple[Path, str]]:
    """The first call of each package function that receives the objective, in order, while ``work()`` runs."""
    src, seen, stops = str(SRC), set(), []

    def profile(frame, event, arg):
        if event != "call":
            return
        code = frame.f_code
        if not code.co_filename.startswith(src) or code in seen:
            return
        names = code.co_varnames[: code.co_argcount + code.co_kwonlyargcount]
        values = [frame.f_locals.get(n) for n in names]
        if any(carries_objective(v) for v in values):
            seen.add(code)
            stops.append((Path(code.co_filename), getattr(code, "co_qualname", code.co_name)))

    sys.setprofile(profile)
    try:
        work()
    finally:
        sys.setprofile(None)
    return stops


def run(tmp: Path) -> None:
    """One tiny run of the hybrid objective, then the report of its directory (its table)."""
    from hybrid_sysid.cli import report, train

    run_dir = tmp / "run"
    sys.argv = [
        "hybrid-sysid",
        "objective=hybrid",
        "data=tiny",
        "trainer=debug",
        "trainer.max_steps=4",
        "trainer.eval_every_n_steps=2",
        "trainer.progress_bar=false",
        "run_figures=false",
        f"hydra.run.dir={run_dir}",
        f"paths.root={tmp}",
    ]
    train.main()
    if report.main([str(run_dir), f"out={tmp / 'report'}"]) != 0:
        raise SystemExit("the report failed")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--list", action="store_true", help="print every stop")
    args = parser.parse_args()
    level = floors()
    with tempfile.TemporaryDirectory() as tmp:
        os.environ.pop("HYDRA_FULL_ERROR", None)
        stops = trace(lambda: run(Path(tmp)))
    files = [path for path, _ in stops]
    rooms = [level[folder_of(p)] for p in files]
    climbs = sum(b > a for a, b in zip(rooms, rooms[1:]))
    returns, left = 0, set()
    for a, b in zip(files, files[1:]):
        if b != a:
            returns += b in left
            left.add(a)
    if args.list:
        for path, name in stops:
            print(f"  floor {level[folder_of(path)]:2d}  {path.relative_to(SRC.parent)}:{name}")
    print(
        f"objective from the command line to the table: {len(stops)} stops in {len(set(files))} files, "
        f"{climbs} climbs back up, {returns} returns to a file already left"
    )


if __name__ == "__main__":
    main()
