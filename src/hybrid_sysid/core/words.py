"""Words a message builds from numbers."""

from __future__ import annotations


def count(n: int, noun: str, plural: str | None = None) -> str:
    """'1 job', '0 jobs', '2 jobs'; ``plural`` where adding an s is wrong ('1 directory', '2 directories')."""
    return f"{n} {noun if n == 1 else plural or noun + 's'}"
