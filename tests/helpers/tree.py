"""What a command may not change: every path under some folders, with its size and modification time."""

import os
from pathlib import Path


def snapshot(*roots) -> dict:
    """{path: (is a directory, size, mtime_ns)} of each root and everything under it (symbolic links not
    followed); a root that does not exist is absent."""
    found = {}
    for root in map(Path, roots):
        if not os.path.lexists(root):
            continue
        for path in [root, *root.rglob("*")]:
            st = path.lstat()
            found[str(path)] = (path.is_dir() and not path.is_symlink(), st.st_size, st.st_mtime_ns)
    return found
