"""A search's study opened in its storage (hydra.sweeper.storage) when several searches may start at once, on one
machine or on several that share the database. A study belongs to one search, whose one process asks for its trials
and spreads them through its launcher (hybrid_sysid.launch.search); a second search on it is refused in one line. What
must not happen is a start-up race that ends in a database's traceback, or in two searches both taking one study.

- SQLite: the tables and the study are made under a file lock beside the database file, so searches that start
  together meet one at a time: the first makes the study and takes it, the others find it taken.
- A server (PostgreSQL, MySQL): making the tables at the same moment as another process may fail once the other has
  made them; it is tried again. Which search made the study is the database's to decide (a study's name is unique
  there); a search that finds it already made waits a few seconds for its maker to take it, then reads whose it is.
- A storage that cannot be opened (no server, its driver not installed, a bad URL) is one line naming
  hydra.sweeper.storage.
"""

from __future__ import annotations

import contextlib
import time
from pathlib import Path
from typing import Callable

import optuna
from filelock import FileLock
from sqlalchemy.engine import make_url
from sqlalchemy.exc import SQLAlchemyError

from hybrid_sysid.launch.process import fail

ATTEMPTS = 5  # tries at making a server's tables, while another process may be making them
CLAIM_WAIT = 10.0  # seconds a search waits for the maker of a study it found to take it


def open_owned(s, url: str, owner_dir: Path | None, own: Callable) -> object:
    """The study ``s.name`` in the storage at ``url``, made or loaded, then taken or refused by ``own(study,
    owner_dir, s)`` (which ends the command in one line when the study is another search's)."""
    lock = _sqlite_lock(url)
    with lock:
        storage = _storage(url)
        try:
            study = optuna.create_study(study_name=s.name, storage=storage, direction=s.direction)
        except optuna.exceptions.DuplicatedStudyError:
            study = optuna.load_study(study_name=s.name, storage=storage)
            if isinstance(lock, contextlib.nullcontext):  # no lock: its maker may not have taken it yet
                _wait_for_claim(study)
        own(study, owner_dir, s)
    return study


def _sqlite_lock(url: str):
    """A file lock beside a SQLite database file (no lock for a server, an in-memory database, or a directory that
    does not exist: opening the storage then says what is wrong)."""
    if not url.startswith("sqlite:///"):
        return contextlib.nullcontext()
    path = Path(url[len("sqlite:///") :])
    if not path.name or path.name == ":memory:" or not path.parent.is_dir():
        return contextlib.nullcontext()

    return FileLock(str(path) + ".lock")


def _storage(url: str):
    """optuna's database storage at ``url``, its tables made if missing (tried again while another process makes
    them); one line naming hydra.sweeper.storage when it cannot be opened."""
    error: Exception | None = None
    for attempt in range(ATTEMPTS):
        try:
            return optuna.storages.RDBStorage(url)
        except SQLAlchemyError as exc:  # e.g. the tables or their version row made by another process meanwhile
            error = exc
            time.sleep(0.2 * (attempt + 1))
        except Exception as exc:  # noqa: BLE001 - a driver missing, a URL optuna refuses: no use trying again
            error = exc
            break
    first = " ".join(str(error).split("\n")[0].split())
    fail(f"hydra.sweeper.storage = {_shown(url)} cannot be opened: {type(error).__name__}: {first}")


def _wait_for_claim(study) -> None:
    deadline = time.monotonic() + CLAIM_WAIT
    while "search" not in study.user_attrs and time.monotonic() < deadline:
        time.sleep(0.2)


def _shown(url: str) -> str:
    """The URL without its password."""
    try:
        return make_url(url).render_as_string(hide_password=True)
    except Exception:  # noqa: BLE001 - not a URL SQLAlchemy reads: shown up to its credentials
        return url.split("@")[-1]
