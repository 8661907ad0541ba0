"""How to install an optional extra, as the user's own install was made: ``pip install -e ".[search]"`` in a
checkout installed in editable mode, ``pip install "hybrid-sysid[search]"`` for an installed wheel."""

from __future__ import annotations

import importlib.metadata
import json

DIST = "hybrid-sysid"


def editable_install() -> bool:
    """Whether the package runs from a checkout: installed in editable mode (pip's direct_url.json says
    ``dir_info.editable``), or not installed at all (imported from the source tree)."""
    try:
        text = importlib.metadata.distribution(DIST).read_text("direct_url.json")
    except importlib.metadata.PackageNotFoundError:
        return True
    try:
        return bool(json.loads(text or "{}").get("dir_info", {}).get("editable", False))
    except (ValueError, AttributeError):  # an unreadable file: a plain install
        return False


def install_command(extra: str) -> str:
    """The pip command that brings ``extra`` to this install."""
    if editable_install():
        return f'pip install -e ".[{extra}]"'
    return f'pip install "{DIST}[{extra}]"'
