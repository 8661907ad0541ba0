"""The README's install: its first command installs torch's CPU build (PyTorch's own command for it) before the
package, so pip never pulls the CUDA build on a machine without a GPU; its test command is the one CI runs
(.ci/run, which installs its own pinned torch first); the page stays a newcomer's page under 8 KB."""

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
README = ROOT / "README.md"
CPU_TORCH = "pip install torch --index-url https://download.pytorch.org/whl/cpu"


def bash_blocks(text: str) -> list[list[str]]:
    """The README's bash blocks, each as its command lines without comments."""
    blocks = re.findall(r"```bash\n(.*?)```", text, flags=re.S)
    return [[line.split("#")[0].strip() for line in b.splitlines() if line.split("#")[0].strip()] for b in blocks]


def test_the_first_command_installs_torch_s_cpu_build_before_the_package():
    first = bash_blocks(README.read_text(encoding="utf-8"))[0]
    assert CPU_TORCH in first, first
    package = next(i for i, line in enumerate(first) if "pip install -e ." in line)
    assert first.index(CPU_TORCH) < package  # once torch is there, the package's install keeps it


def test_ci_runs_the_readme_s_test_command_after_its_own_pinned_torch():
    tests = [b for b in bash_blocks(README.read_text(encoding="utf-8")) if any("pytest" in line for line in b)]
    assert len(tests) == 1 and len(tests[0]) == 1, tests  # one test command, one line
    ci = [line.strip() for line in (ROOT / ".ci" / "run").read_text(encoding="utf-8").splitlines()]
    assert tests[0][0] in ci, f"{tests[0][0]!r} is not a line of .ci/run"
    pinned = next(i for i, line in enumerate(ci) if re.fullmatch(r"python -m pip install -q torch==[\d.]+", line))
    assert pinned < ci.index(tests[0][0])


def test_the_readme_stays_under_8_kb():
    assert len(README.read_bytes()) <= 8192
