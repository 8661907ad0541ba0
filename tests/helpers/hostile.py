"""Files a hostile or damaged run directory may hold."""


def laughs(levels: int, width: int = 9) -> str:
    """A "billion laughs" YAML: each level a list of ``width`` aliases of the level below (width ** levels
    leaves once expanded), from a few hundred bytes."""
    lines = ["l0: &l0 [lol]"]
    lines += [f"l{i}: &l{i} [{', '.join([f'*l{i - 1}'] * width)}]" for i in range(1, levels + 1)]
    return "\n".join(lines) + "\n"
