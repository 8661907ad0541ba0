"""Searches starting together on one fresh study storage (hybrid_sysid.launch.study): one takes the study, each other
one is refused in one line naming hydra.sweeper.storage and the search that has it, and none prints a traceback.
SQLite here; PostgreSQL where a throwaway server can start in the test (its binaries and psycopg 3 present)."""

import contextlib
import os
import pwd
import shutil
import socket
import subprocess
import sys
import tempfile
import textwrap
from glob import glob
from pathlib import Path

import pytest

from helpers.app_process import user_env

# one search's start, up to its study: every process, once imported, marks itself ready and waits until all are,
# then opens the study (a barrier, so the opens race within milliseconds, not after a fixed, generous delay)
START = textwrap.dedent("""
    import sys, time
    from pathlib import Path
    from optuna.distributions import FloatDistribution
    from hybrid_sysid.launch.search import open_study
    from hybrid_sysid.experiments.search import StudySettings
    url, sweep, n = sys.argv[1], Path(sys.argv[2]), int(sys.argv[3])
    space = {"model.optim.lr": FloatDistribution(0.002, 0.05, log=True)}
    s = StudySettings(space, [], {"seed": 0}, 4, 1, "minimize", "race", url)
    sweep.mkdir(parents=True, exist_ok=True)
    (sweep.parent / f"ready-{sweep.name}").touch()
    end = time.time() + 60
    while len(list(sweep.parent.glob("ready-*"))) < n and time.time() < end:
        time.sleep(0.001)  # leaves the cores to the processes still importing
    study = open_study(s, sweep)
    print("taken by", study.user_attrs["search"]["sweep_dir"])
""")
SEARCHES = 3


def start_together(tmp: Path, url: str, searches: int = SEARCHES) -> list[subprocess.CompletedProcess]:
    script = tmp / "start.py"
    script.write_text(START)
    procs = [
        subprocess.Popen(
            [sys.executable, str(script), url, str(tmp / f"search{i}"), str(searches)],
            env=user_env(),
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        for i in range(searches)
    ]
    return [subprocess.CompletedProcess(p.args, p.wait(120), *p.communicate()) for p in procs]


def check_one_takes_it(tmp: Path, done: list) -> None:
    taken = [p for p in done if p.returncode == 0]
    assert len(taken) == 1, [p.stderr for p in done]
    owner = taken[0].stdout.strip().removeprefix("taken by ")
    assert owner == str(Path(taken[0].args[3]).resolve())
    for p in done:
        assert "Traceback" not in p.stderr + p.stdout, p.stderr
        if p is not taken[0]:
            lines = p.stderr.strip().splitlines()
            assert p.returncode == 2 and len(lines) == 1, p.stderr
            assert "hydra.sweeper.storage" in lines[0] and f"search in {owner}" in lines[0], lines[0]


def test_searches_starting_together_on_a_fresh_sqlite_file(tmp_path):
    for round in range(2):  # a race lost once could be luck
        where = tmp_path / f"round{round}"
        where.mkdir()
        check_one_takes_it(where, start_together(where, f"sqlite:///{where / 'shared.db'}"))


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture(scope="module")
def postgres():
    """A throwaway PostgreSQL server (initdb and pg_ctl in a temporary directory, as an unprivileged user), or a
    skip saying what is missing. Yields a function that makes a fresh database and returns its URL."""
    found = sorted(glob("/usr/lib/postgresql/*/bin/initdb")) or [shutil.which("initdb")]
    if found[-1] is None:
        pytest.skip("no PostgreSQL server binaries (initdb, pg_ctl): apt-get install postgresql")
    bin_dir = Path(found[-1]).parent
    try:
        import psycopg
    except ImportError:
        pytest.skip("psycopg 3 is not installed: pip install 'psycopg[binary]'")
    user = pwd.getpwnam("nobody") if os.geteuid() == 0 else pwd.getpwuid(os.geteuid())  # initdb refuses root

    def as_user():
        if os.geteuid() == 0:
            os.setgid(user.pw_gid)
            os.setuid(user.pw_uid)

    home = Path(tempfile.mkdtemp(prefix="hybrid-sysid-pg-"))
    os.chown(home, user.pw_uid, user.pw_gid)
    data, port = home / "data", free_port()
    env = {**os.environ, "LC_ALL": "C"}
    run = dict(preexec_fn=as_user, env=env, capture_output=True, text=True, timeout=120)
    # UTF8: with the C locale's default, SQL_ASCII, psycopg returns bytes that SQLAlchemy cannot read
    initdb = [bin_dir / "initdb", "-D", data, "-U", "hs", "--auth=trust", "--encoding=UTF8", "--locale=C"]
    made = subprocess.run(initdb, **run)
    if made.returncode != 0:
        shutil.rmtree(home, ignore_errors=True)
        pytest.skip(f"initdb could not make a server's directory: {made.stderr.strip()[-300:]}")
    options = f"-p {port} -k {home} -c listen_addresses=127.0.0.1"
    up = subprocess.run([bin_dir / "pg_ctl", "-D", data, "-o", options, "-l", home / "log", "-w", "start"], **run)
    if up.returncode != 0:
        shutil.rmtree(home, ignore_errors=True)
        pytest.skip(f"pg_ctl could not start a server: {up.stderr.strip()[-300:]}")
    names = iter(range(100))

    def database() -> str:
        name = f"race{next(names)}"
        with contextlib.closing(psycopg.connect(f"host=127.0.0.1 port={port} user=hs dbname=postgres")) as c:
            c.autocommit = True
            c.execute(f"CREATE DATABASE {name}")
        return f"postgresql+psycopg://hs@127.0.0.1:{port}/{name}"

    try:
        yield database
    finally:
        subprocess.run([bin_dir / "pg_ctl", "-D", data, "-m", "immediate", "stop"], **run)
        shutil.rmtree(home, ignore_errors=True)


def test_searches_starting_together_on_a_fresh_postgresql_database(tmp_path, postgres):
    for round in range(2):
        where = tmp_path / f"round{round}"
        where.mkdir()
        check_one_takes_it(where, start_together(where, postgres()))


def test_a_storage_that_cannot_be_opened_is_one_line(tmp_path):
    url = f"postgresql+psycopg://someone:secret@127.0.0.1:{free_port()}/nothing"  # no server listens there
    done = start_together(tmp_path, url, searches=1)[0]  # no race: one process that cannot open it
    lines = done.stderr.strip().splitlines()
    assert done.returncode == 2 and len(lines) == 1, done.stderr
    assert lines[0].startswith("error: hydra.sweeper.storage = ") and "secret" not in lines[0]
