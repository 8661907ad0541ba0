"""The app in a process of its own, as a user starts it: ``python -m hybrid_sysid`` (or another of the package's
modules) by this interpreter, in the user's environment."""

import os
import subprocess
import sys


def user_env(env=None, cache=None) -> dict:
    """``env`` (else this process's environment) as a user has it: without HYDRA_FULL_ERROR, which the test run
    sets (conftest.py) and which would add tracebacks to what the app prints; with ``cache``, the dataset cache
    (HYBRID_SYSID_CACHE: the shared tiny_cache, whose data=tiny a run then reads instead of simulating it)."""
    env = {k: v for k, v in (os.environ if env is None else env).items() if k != "HYDRA_FULL_ERROR"}
    if cache is not None:
        env["HYBRID_SYSID_CACHE"] = str(cache)
    return env


def run_app(
    cwd, *args, cache=None, env=None, timeout=600, module="hybrid_sysid", script=None
) -> subprocess.CompletedProcess:
    """The app run to its end, its output captured (not a terminal), as `cmd > log 2>&1` would. ``script``: a
    Python file run in place of the module (the app with a function of it wrapped by a test)."""
    start = [str(script)] if script is not None else ["-m", module]
    return subprocess.run(
        [sys.executable, *start, *map(str, args)],
        cwd=cwd,
        env=user_env(env, cache),
        capture_output=True,
        text=True,
        timeout=timeout,
    )


def launch(cwd, *args, cache=None, env=None) -> subprocess.Popen:
    """The app started and left running (to be signalled), stdout and stderr in one pipe."""
    return subprocess.Popen(
        [sys.executable, "-m", "hybrid_sysid", *map(str, args)],
        cwd=cwd,
        env=user_env(env, cache),
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
